//! Spherical triangles and polygons: solid angles (Van Oosterom–Strackee), uniform sampling by
//! solid angle (Arvo 1995), and the spherical polygon that the projection strategy samples.

use arrayvec::ArrayVec;
use glam::{DVec2, DVec3, Vec2, Vec3};

use super::polygon::{MAX_CLIP_VERTICES, Plane, sample_polygon_area};

/// Below this solid angle (sr) a [`SphericalPolygon`] is sampled by area instead of by solid angle.
///
/// 1e-4 sr is a cone of half-angle ≈ 0.0056 rad (a 1 cm square at 1 m). Below it, solid-angle
/// sampling has little left to gain: `d² / |cos θ|` varies across a polygon seen head-on by about
/// its angular size (< 1 %), so area sampling is nearly as good, and it needs no trigonometry.
/// It is also where spherical sampling in f32 stops being trustworthy: with Arvo's angle-based
/// formulas (pbrt-v4's form) the sampled point is off by ~8 % of the triangle's size at 1e-2 sr
/// and by all of it at 1e-4 sr (`tests/sampling.rs` measures this). The form used here stays within
/// a few f32 ulps (5e-5 of the size at 1e-4 sr, 6e-4 at 1e-6 sr), so the threshold is a margin,
/// not a cliff; area sampling's pdf stays exact at any size.
pub const SMALL_SOLID_ANGLE: f32 = 1e-4;

/// Triangles below this solid angle (sr) count as degenerate: their vertices are within ~1e-6 rad,
/// about 20 f32 ulps of a unit vector, so rounding has erased their shape. (A polygon's fan
/// triangle this small is picked with probability ≤ 1e-8, since such polygons are area-sampled.)
const MIN_TRIANGLE_SOLID_ANGLE: f32 = 1e-12;

/// Slack of the inside test, in radians off an edge: a sample on an edge can round to ~1e-7 rad
/// outside (measured: 3e-8), and it must still get a non-zero pdf. The price is a band this wide
/// around the polygon where the pdf is non-zero but no sample lands: a relative excess of
/// `perimeter × 2.4e-7 / Ω`, 1e-3 for a square of 1e-6 sr, negligible above `SMALL_SOLID_ANGLE`.
const EDGE_TOLERANCE: f32 = 2.0 * f32::EPSILON;

/// `x` closer to the polygon's plane than this, relative to its distance to the vertices, sees the
/// polygon edge-on: no usable solid angle.
const PLANE_TOLERANCE: f64 = 1e-6;

/// The solid angle of the spherical triangle with unit vertices `a`, `b`, `c` (Van Oosterom and
/// Strackee 1983): `2·atan2(|a·(b×c)|, 1 + a·b + b·c + c·a)`, either winding.
pub fn spherical_triangle_solid_angle(a: Vec3, b: Vec3, c: Vec3) -> f32 {
    solid_angle_f64(a.as_dvec3(), b.as_dvec3(), c.as_dvec3()) as f32
}

/// Van Oosterom–Strackee in f64: products of f32 inputs are exact there, so neither the triple
/// product of a small triangle nor the denominator of a near-hemisphere one (where `1 + c·a` and
/// `a·b` are tiny differences of O(1) products) loses the digits that f32 would.
fn solid_angle_f64(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let z = half_solid_angle_phasor(a, b, c);
    2.0 * z.y.atan2(z.x)
}

/// Van Oosterom–Strackee as a complex number `z = (1 + a·b + b·c + c·a) + i·|a·(b×c)|`, whose
/// argument is half the solid angle: a fan's half-angles add, so its cumulative solid angles
/// are products of these, and one `atan2` of the last product gives the polygon's.
#[inline(always)]
fn half_solid_angle_phasor(a: DVec3, b: DVec3, c: DVec3) -> DVec2 {
    DVec2::new(
        1.0 + a.dot(b) + b.dot(c) + c.dot(a),
        a.dot((b - a).cross(c - a)).abs(),
    )
}

/// The product of two complex numbers `(re, im)`: their arguments add.
#[inline(always)]
fn complex_mul(p: DVec2, q: DVec2) -> DVec2 {
    DVec2::new(p.x * q.x - p.y * q.y, p.x * q.y + p.y * q.x)
}

/// A uniformly distributed direction in the spherical triangle with unit vertices `a`, `b`, `c`
/// (pdf [`spherical_triangle_pdf`]); `None` for a degenerate triangle.
///
/// Arvo's (1995) map, structured as pbrt-v4's `SampleSphericalTriangle`: `u.x` picks the point `c'`
/// on the arc `a → c` that cuts off the sub-triangle `(a, b, c')` of area `u.x · Ω`, and `u.y`
/// picks a point on the arc `b → c'` with `1 − cos θ` uniform (see
/// [`sample_spherical_triangle_part`]).
pub fn sample_spherical_triangle(a: Vec3, b: Vec3, c: Vec3, u: Vec2) -> Option<Vec3> {
    let area = spherical_triangle_solid_angle(a, b, c);
    if area.is_nan() || area <= MIN_TRIANGLE_SOLID_ANGLE {
        return None;
    }
    let (sin_half, cos_half) = (0.5 * u.x * area).sin_cos();
    sample_spherical_triangle_part(a, b, c, sin_half, cos_half, u.y)
}

/// Arvo's map for the sub-triangle `(a, b, c')` of solid angle `A'` given by
/// `(sin A'/2, cos A'/2)`, and `v` for the arc `b → c'`; uniform over the triangle when `A'` is
/// uniform in `[0, Ω]` (pdf [`spherical_triangle_pdf`]). `None` for a degenerate triangle.
///
/// Arvo's and pbrt's closed forms go through the vertex angles and `cos β'`, which cancel
/// catastrophically in f32 for small or thin triangles; here `c'` is solved from the Van
/// Oosterom–Strackee formula instead (same map), with every quantity formed from vertex
/// differences, and without trigonometry: the half-angle `s/2` of the arc `a → c'` is kept as
/// the vector `(cos, sin)` it is the argument of.
#[inline(always)]
pub fn sample_spherical_triangle_part(
    a: Vec3,
    b: Vec3,
    c: Vec3,
    sin_half: f32,
    cos_half: f32,
    v: f32,
) -> Option<Vec3> {
    // The arc a → c: unit tangent `t` at `a`.
    let ac = c - a;
    let t = (ac - ac.dot(a) * a).try_normalize()?;
    // With c'(s) = cos s·a + sin s·t, the area of (a, b, c') is
    //   2·atan2(sin s·k, (1 + a·b)(1 + cos s) + sin s·(b·t)),   k = |a·(b×t)|,
    // and setting it to A' gives tan(s/2) = sin(A'/2)·(1 + a·b) / (cos(A'/2)·k − sin(A'/2)·b·t)
    // (half-angle substitution): s/2 ∈ [0, π] is the argument of (x, y) below.
    let ab = b - a;
    let k = ab.dot(t.cross(a)).abs();
    let b_t = ab.dot(t);
    // 1 + a·b = |a + b|²/2, accurate also when b is nearly opposite a.
    let one_plus_cos_ab = 0.5 * (a + b).length_squared();
    let y = sin_half * one_plus_cos_ab;
    let x = cos_half * k - sin_half * b_t;
    let r = (x * x + y * y).sqrt();
    // c' − a = (cos s − 1)·a + sin s·t = −2 sin²(s/2)·a + 2 sin(s/2) cos(s/2)·t, without
    // cancelling cos s − 1. Past the arc's half-length (sin, cos) = (|c − a|, |c + a|)/2,
    // c' is c itself (rounding only).
    let cp_minus_a = if r > 0.0 {
        // Past the arc ⇔ sin(s/2)·|c + a| > cos(s/2)·|c − a|, i.e. y·|c + a| > x·|c − a| (r > 0,
        // y >= 0): true for x < 0 (s/2 > π/2, the half-arc is at most π/2), else compared
        // squared, without the two lengths.
        let past_arc = x < 0.0 || y * y * (a + c).length_squared() > x * x * ac.length_squared();
        if past_arc {
            ac
        } else {
            let inverse_r = r.recip();
            let (sin_s, cos_s) = (y * inverse_r, x * inverse_r);
            2.0 * sin_s * (cos_s * t - sin_s * a)
        }
    } else {
        Vec3::ZERO
    };
    // The arc b → c': cos θ uniform in [b·c', 1], with 1 − b·c' = |c' − b|²/2.
    let bcp = cp_minus_a - ab;
    let one_minus_cos = v * 0.5 * bcp.length_squared();
    let sin_theta = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0).sqrt();
    let Some(e) = (bcp - bcp.dot(b) * b).try_normalize() else {
        return Some(b);
    };
    (b + (sin_theta * e - one_minus_cos * b)).try_normalize()
}

/// The pdf (in solid angle) of [`sample_spherical_triangle`] for the unit direction `w`:
/// `1/Ω` inside the triangle (boundary included), else 0.
pub fn spherical_triangle_pdf(a: Vec3, b: Vec3, c: Vec3, w: Vec3) -> f32 {
    let area = spherical_triangle_solid_angle(a, b, c);
    if area.is_nan() || area <= MIN_TRIANGLE_SOLID_ANGLE {
        return 0.0;
    }
    let orientation = a.dot((b - a).cross(c - a)).signum();
    let inside = [(a, b), (b, c), (c, a)]
        .iter()
        .all(|&(p, q)| orientation * w.dot(p.cross(q - p)) >= 0.0);
    if inside { 1.0 / area } else { 0.0 }
}

/// The sample `u` that [`sample_spherical_triangle`] maps to the unit direction `w` (inside the
/// triangle); `None` for a degenerate triangle or `w` at vertex `b`.
pub fn invert_spherical_triangle_sample(a: Vec3, b: Vec3, c: Vec3, w: Vec3) -> Option<Vec2> {
    let area = spherical_triangle_solid_angle(a, b, c);
    if area.is_nan() || area <= MIN_TRIANGLE_SOLID_ANGLE {
        return None;
    }
    // c' is where the great circle through b and w meets the arc a → c.
    let mut cp = b.cross(w).cross(a.cross(c)).try_normalize()?;
    if cp.dot(a + c) < 0.0 {
        cp = -cp;
    }
    let ux = spherical_triangle_solid_angle(a, b, cp) / area;
    let uy = (w - b).length_squared() / (cp - b).length_squared();
    uy.is_finite()
        .then(|| Vec2::new(ux, uy).clamp(Vec2::ZERO, Vec2::ONE))
}

/// The point of the convex polygon `vertices` (relative to x, wound so that `v_i × v_{i+1}`
/// points inside) nearest x, given the foot of x on its plane and those edge-plane normals
/// `m_i = v_i × v_{i+1}`.
#[inline(always)]
fn nearest_point(vertices: &[DVec3], edge_normals: &[DVec3], foot: DVec3) -> DVec3 {
    // Outside, the nearest point is on an edge that has the foot on its outer side (at a
    // vertex, on one of its two edges): only those are searched.
    let mut nearest = foot;
    let mut nearest_distance = f64::INFINITY;
    let n = vertices.len().min(edge_normals.len());
    for i in 0..n {
        if foot.dot(edge_normals[i]) >= 0.0 {
            continue;
        }
        let (a, b) = (vertices[i], vertices[if i + 1 == n { 0 } else { i + 1 }]);
        let e = b - a;
        let p = a + (-a.dot(e) / e.length_squared()).clamp(0.0, 1.0) * e;
        let distance = p.length_squared();
        if distance < nearest_distance {
            nearest = p;
            nearest_distance = distance;
        }
    }
    nearest
}

/// A planar convex polygon seen from a point `x`: the directions through it, sampled uniformly by
/// solid angle (or by area when it subtends less than [`SMALL_SOLID_ANGLE`]).
///
/// Sampling picks a triangle of a fan by solid angle, then samples it with
/// [`sample_spherical_triangle_part`]. The fan's apex is the polygon's point nearest `x` rather
/// than a vertex, so that no fan triangle joins nearly opposite directions when `x` is close to a
/// large polygon.
///
/// Built once per shading point, in place ([`Self::set`]): everything is stored inline, in
/// fixed arrays of which the first `len` entries hold the polygon (written by index, without
/// a length check per entry).
#[derive(Clone, Debug)]
pub struct SphericalPolygon {
    origin: Vec3,
    /// The number of vertices (0 for an empty polygon).
    len: usize,
    /// Wound clockwise as seen from `origin`: the vertices minus `origin` when the polygon is
    /// area-sampled, else the unit directions to them (each sampler reads only its own).
    points: [Vec3; MAX_CLIP_VERTICES],
    /// Unit direction to the polygon's point nearest `origin`: the apex of the fan.
    apex: Vec3,
    /// Normals of the planes through `origin` and each edge `(v_i, v_{i+1})`, pointing inside,
    /// of length `sin` of the edge's arc (`u_i × u_{i+1}` for the unit directions `u_i`).
    edge_normals: [Vec3; MAX_CLIP_VERTICES],
    /// Per edge, `(EDGE_TOLERANCE · |m̂_i|)²`: the inside test's slack without normalising.
    edge_slack: [f32; MAX_CLIP_VERTICES],
    /// Per fan triangle `(apex, v_i, v_{i+1})`, `i = 0..n`: the cumulative half solid angle
    /// `Φ_i = Σ_{k ≤ i} Ω_k / 2` as the complex number `ρ_i·(cos Φ_i, sin Φ_i)`, `ρ_i > 0`.
    fan: [DVec2; MAX_CLIP_VERTICES],
    /// Bit `i` is set when fan triangle `i` exceeds [`MIN_TRIANGLE_SOLID_ANGLE`]: the others
    /// are never picked.
    fan_usable: u64,
    /// `Φ_n = Ω/2`.
    half_solid_angle: f64,
    solid_angle: f32,
    /// The polygon's plane, with `origin` on its positive side.
    plane: Plane,
    /// Distance from `origin` to the plane.
    height: f32,
    area: f32,
}

impl SphericalPolygon {
    /// The convex planar polygon `vertices` (world space, either winding, at most
    /// [`MAX_CLIP_VERTICES`]) seen from `x`. `None` if there are fewer than 3 vertices, `x` is
    /// on the polygon's plane, or the solid angle is zero.
    pub fn new(x: Vec3, vertices: &[Vec3]) -> Option<SphericalPolygon> {
        let mut polygon = SphericalPolygon::empty();
        polygon.set(x, vertices).then_some(polygon)
    }

    /// A polygon with no directions, to be filled by [`Self::set`].
    pub fn empty() -> SphericalPolygon {
        SphericalPolygon {
            origin: Vec3::ZERO,
            len: 0,
            points: [Vec3::ZERO; MAX_CLIP_VERTICES],
            apex: Vec3::ZERO,
            edge_normals: [Vec3::ZERO; MAX_CLIP_VERTICES],
            edge_slack: [0.0; MAX_CLIP_VERTICES],
            fan: [DVec2::ZERO; MAX_CLIP_VERTICES],
            fan_usable: 0,
            half_solid_angle: 0.0,
            solid_angle: 0.0,
            plane: Plane { n: Vec3::Z, d: 0.0 },
            height: 0.0,
            area: 0.0,
        }
    }

    /// [`Self::new`] in place (a polygon is over a kilobyte: a shading point builds it where it
    /// is kept rather than moving it there). Returns false, leaving the polygon empty, where
    /// `new` returns `None`.
    #[inline(always)]
    pub fn set(&mut self, x: Vec3, vertices: &[Vec3]) -> bool {
        self.len = 0;
        self.fan_usable = 0;
        self.half_solid_angle = 0.0;
        self.solid_angle = 0.0;
        let n = vertices.len();
        if !(3..=MAX_CLIP_VERTICES).contains(&n) || !x.is_finite() {
            return false;
        }
        // Set-up runs in f64, where differences of f32 positions are exact: a small polygon far
        // from `x` or from the world origin keeps its shape, and solid angles near 2π keep their
        // digits. (Plain index loops over fixed arrays: iterator adapters were left out of line
        // here, compiled without the renderer's instruction-set features, and pushes checked
        // the capacity per entry.)
        let xd = x.as_dvec3();
        // The sum of `r_i × (r_{i+1} − r_i)` (= r_i × r_{i+1}, without its cancellation for a
        // small polygon far away) is twice the vector area (Newell's, about x); its terms are
        // the edge-plane normals of this winding.
        let mut offsets: ArrayVec<DVec3, MAX_CLIP_VERTICES> = ArrayVec::new();
        let mut normals: ArrayVec<DVec3, MAX_CLIP_VERTICES> = ArrayVec::new();
        let mut offset_sum = DVec3::ZERO;
        let mut twice_area = DVec3::ZERO;
        for i in 0..n {
            let next = if i + 1 == n { 0 } else { i + 1 };
            // `r_{i+1}` is formed again from its vertex: the same number as `offsets[i + 1]`.
            let (r, r_next) = (vertices[i].as_dvec3() - xd, vertices[next].as_dvec3() - xd);
            offsets.push(r);
            offset_sum += r;
            let m = r.cross(r_next - r);
            normals.push(m);
            twice_area += m;
        }
        // Offsets of f32 positions cannot overflow f64, so the sum is finite exactly when every
        // vertex is.
        if !offset_sum.is_finite() {
            return false;
        }
        let twice_area_length = twice_area.length();
        if !(twice_area_length > 0.0 && twice_area_length.is_finite()) {
            return false;
        }
        let winding_normal = twice_area / twice_area_length;
        let mean_offset = offset_sum / n as f64;
        // Orient the polygon so that its winding normal points away from x: then the edge-plane
        // normals `m_i = r_i × (r_{i+1} − r_i)` point inside.
        let mut away = winding_normal;
        if away.dot(mean_offset) < 0.0 {
            away = -away;
            offsets[..n].reverse();
            for i in 0..n {
                let (r, r_next) = (offsets[i], offsets[if i + 1 == n { 0 } else { i + 1 }]);
                normals[i] = r.cross(r_next - r);
            }
        }
        // One length per vertex: the scale of the edge-on test, and the unit directions
        // `u_i = r_i / |r_i|` (formed where they are used).
        let mut inverse_length: ArrayVec<f64, MAX_CLIP_VERTICES> = ArrayVec::new();
        let mut scale = 0.0f64;
        for r in &offsets {
            let length = r.length();
            scale = scale.max(length);
            inverse_length.push(length.recip());
        }
        let height = away.dot(mean_offset);
        if height.is_nan() || height <= PLANE_TOLERANCE * scale {
            return false;
        }
        // The fan's apex is the polygon's point nearest x, not a vertex: every polygon point is
        // then less than 90° from it, whereas from x close to a large polygon the diagonals of
        // a vertex fan join nearly opposite directions, whose great circles f32 cannot pin down.
        let apex = nearest_point(&offsets, &normals, height * away).normalize();
        // The fan's half-angles add as the arguments of their Van Oosterom–Strackee complex
        // numbers multiply. Every fan triangle is within 90° of the apex, so each half-angle is
        // below π/2 and their sum, Ω/2, below π; and `|z| <= 4.2`, `|z| >= 1 + v_i·v_{i+1}`,
        // so the products stay far inside f64's range unless x is within ~1e-10 of the plane
        // of a polygon of many vertices, when they are rescaled (their arguments stay).
        //
        // Per edge, `m̂_i = m_i / (|r_i| |r_{i+1}|)` is `u_i × u_{i+1}` (unit directions) from
        // the accurate normal: it gives the fan triangle's triple product `apex · m̂_i` and the
        // edge's plane for the inside test, without a second square root per vertex. The unit
        // direction and `apex · u_i` of a vertex serve the two triangles that share it.
        let unit_of = |i: usize| offsets[i] * inverse_length[i];
        let edge_normal =
            |i: usize, next: usize| normals[i] * (inverse_length[i] * inverse_length[next]);
        // `(apex, u_i, u_{i+1})`'s Van Oosterom–Strackee number, given `apex · u` of both.
        let phasor =
            |(unit, apex_dot): (DVec3, f64), (unit_next, apex_dot_next): (DVec3, f64), m| {
                DVec2::new(
                    1.0 + apex_dot + unit.dot(unit_next) + apex_dot_next,
                    apex.dot(m).abs(),
                )
            };
        let first_unit = unit_of(0);
        let first = (first_unit, apex.dot(first_unit));
        let mut vertex = first;
        let mut cumulative = DVec2::X;
        let (mut smallest, mut largest) = (1.0f64, 1.0f64);
        for i in 0..n {
            let next = if i + 1 == n { 0 } else { i + 1 };
            let vertex_next = if next == 0 {
                first
            } else {
                let u = unit_of(next);
                (u, apex.dot(u))
            };
            let m = edge_normal(i, next);
            let z = phasor(vertex, vertex_next, m);
            // Ω_i > MIN ⇔ tan(Ω_i/2) > MIN/2 (to f64 rounding of the tangent).
            if z.y > 0.0 && z.y > 0.5 * f64::from(MIN_TRIANGLE_SOLID_ANGLE) * z.x {
                self.fan_usable |= 1 << i;
            }
            // The products' range is checked after the loop, off its chain of multiplications
            // (a rescale in the loop put a division into every step).
            cumulative = complex_mul(cumulative, z);
            let magnitude = cumulative.x.abs() + cumulative.y.abs();
            smallest = smallest.min(magnitude);
            largest = largest.max(magnitude);
            self.fan[i] = cumulative;
            // `m̂ · ω >= −ε |m̂|` as `d >= 0 || d² <= ε² |m̂|²` (see `contains`).
            self.edge_normals[i] = m.as_vec3();
            self.edge_slack[i] =
                (f64::from(EDGE_TOLERANCE) * f64::from(EDGE_TOLERANCE) * m.length_squared()) as f32;
            // Solid-angle sampling's points; replaced by the offsets below if area-sampled.
            self.points[i] = vertex.0.as_vec3();
            vertex = vertex_next;
        }
        if !(1e-150..=1e150).contains(&smallest) || !(1e-150..=1e150).contains(&largest) {
            // Rare: redone with each product rescaled as it leaves the range (the numbers
            // formed again as above, not kept: that cost every polygon a copy).
            cumulative = DVec2::X;
            for i in 0..n {
                let next = if i + 1 == n { 0 } else { i + 1 };
                let (u, u_next) = (unit_of(i), unit_of(next));
                let z = phasor(
                    (u, apex.dot(u)),
                    (u_next, apex.dot(u_next)),
                    edge_normal(i, next),
                );
                cumulative = complex_mul(cumulative, z);
                let magnitude = cumulative.x.abs() + cumulative.y.abs();
                if !(1e-150..=1e150).contains(&magnitude) {
                    cumulative /= magnitude;
                }
                self.fan[i] = cumulative;
            }
        }
        let half_solid_angle = cumulative.y.atan2(cumulative.x);
        let solid_angle = (2.0 * half_solid_angle) as f32;
        if !(solid_angle > 0.0 && solid_angle.is_finite()) {
            self.fan_usable = 0;
            return false;
        }
        if solid_angle < SMALL_SOLID_ANGLE {
            for i in 0..n {
                self.points[i] = offsets[i].as_vec3();
            }
        }
        self.len = n;
        self.origin = x;
        self.apex = apex.as_vec3();
        self.half_solid_angle = half_solid_angle;
        self.solid_angle = solid_angle;
        self.plane = Plane {
            n: -away.as_vec3(),
            d: -away.dot(xd + mean_offset) as f32,
        };
        self.height = height as f32;
        self.area = (0.5 * twice_area_length) as f32;
        true
    }

    /// The polygon's points: the unit directions to its vertices, or their offsets from the
    /// origin when area-sampled.
    #[inline(always)]
    fn points(&self) -> &[Vec3] {
        &self.points[..self.len]
    }

    /// The point the polygon is seen from.
    pub fn origin(&self) -> Vec3 {
        self.origin
    }

    /// The polygon's plane, oriented so that the origin is on its positive side.
    pub fn plane(&self) -> Plane {
        self.plane
    }

    /// The polygon's area.
    pub fn area(&self) -> f32 {
        self.area
    }

    /// The solid angle Ω the polygon subtends from the origin (sr).
    #[inline(always)]
    pub fn solid_angle(&self) -> f32 {
        self.solid_angle
    }

    /// Whether the polygon is too small to sample by solid angle (see [`SMALL_SOLID_ANGLE`]);
    /// depends on the origin only, so [`Self::sample`] and [`Self::pdf`] always agree.
    #[inline(always)]
    pub fn is_area_sampled(&self) -> bool {
        self.solid_angle < SMALL_SOLID_ANGLE
    }

    /// A unit direction `wi` through the polygon and its pdf in solid angle.
    #[inline(always)]
    pub fn sample(&self, u: Vec2) -> Option<(Vec3, f32)> {
        if self.is_area_sampled() {
            let wi = sample_polygon_area(self.points(), u).try_normalize()?;
            return Some((wi, self.area_pdf(wi)));
        }
        let (i, sin_half, cos_half) = self.pick_fan_triangle(u.x)?;
        let d = self.points();
        let next = if i + 1 == d.len() { 0 } else { i + 1 };
        let wi = sample_spherical_triangle_part(self.apex, d[i], d[next], sin_half, cos_half, u.y)?;
        Some((wi, 1.0 / self.solid_angle))
    }

    /// The pdf in solid angle of [`Self::sample`] for the unit direction `wi`: 0 unless the ray
    /// `origin + t·wi`, `t > 0`, passes through the polygon (boundary included).
    #[inline(always)]
    pub fn pdf(&self, wi: Vec3) -> f32 {
        if !self.contains(wi) {
            0.0
        } else if self.is_area_sampled() {
            self.area_pdf(wi)
        } else {
            1.0 / self.solid_angle
        }
    }

    /// Whether the unit direction `wi` is inside the polygon's cone, up to [`EDGE_TOLERANCE`].
    #[inline(always)]
    fn contains(&self, wi: Vec3) -> bool {
        // The edge planes alone bound the cone; the first test rejects the opposite hemisphere
        // early and keeps `area_pdf` away from grazing directions.
        // `m̂ · wi >= −EDGE_TOLERANCE · |m̂|`, squared on the negative side: the edge normals
        // are not normalised.
        if self.plane.n.dot(wi) >= 0.0 {
            return false;
        }
        let n = self.len;
        for (m, &slack) in self.edge_normals[..n].iter().zip(&self.edge_slack[..n]) {
            let d = m.dot(wi);
            if d < 0.0 && d * d > slack {
                return false;
            }
        }
        true
    }

    /// Area sampling's pdf in solid angle, `d² / (A·|cos θ|)`: here `d = h / |cos θ|` with `h`
    /// the origin's distance to the plane, so sample and pdf use the same expression.
    #[inline(always)]
    fn area_pdf(&self, wi: Vec3) -> f32 {
        let cos_theta = self.plane.n.dot(wi).abs();
        self.height * self.height / (self.area * cos_theta * cos_theta * cos_theta)
    }

    /// The fan triangle `(apex, v_i, v_{i+1})` for `u`, picked by solid angle, with
    /// `(sin, cos)` of half the solid angle `A'` that `u` puts in it. This is the map that
    /// rescales `u` into the triangle's bin of the cumulative solid angles (so stratification
    /// carries over to the triangle), `A' = 2·(u·Ω/2 − Φ_{i−1})`, done on the complex numbers
    /// of the fan: one `sin_cos` per sample, no angle per triangle.
    #[inline(always)]
    fn pick_fan_triangle(&self, u: f32) -> Option<(usize, f32, f32)> {
        let target = f64::from(u) * self.half_solid_angle;
        let (sin_t, cos_t) = target.sin_cos();
        let mut picked = None;
        let mut before = DVec2::X;
        for (i, &after) in self.fan[..self.len].iter().enumerate() {
            if self.fan_usable & (1 << i) != 0 {
                picked = Some((i, before));
                // sin(Φ_i − T) ≥ 0 ⇔ Φ_i ≥ T, both angles being in [0, π).
                if after.y * cos_t - after.x * sin_t >= 0.0 {
                    break;
                }
            }
            before = after;
        }
        // Past the loop (T rounded just beyond Φ_n) the last usable triangle is kept; its part
        // then slightly exceeds it, and Arvo's map clamps `c'` to its far vertex.
        let (i, before) = picked?;
        let before = before.normalize();
        // (cos, sin) of T − Φ_{i−1}; a rounding below zero means the triangle's first edge.
        let sin_part = sin_t * before.x - cos_t * before.y;
        let cos_part = cos_t * before.x + sin_t * before.y;
        Some((i, sin_part.max(0.0) as f32, cos_part as f32))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;
    use std::f32::consts::{FRAC_PI_2, PI};

    fn random_unit(rng: &mut Rng) -> Vec3 {
        let z = 1.0 - 2.0 * rng.uniform();
        let phi = 2.0 * PI * rng.uniform();
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }

    #[test]
    fn octant_is_an_eighth_of_the_sphere() {
        let omega = spherical_triangle_solid_angle(Vec3::X, Vec3::Y, Vec3::Z);
        assert!((omega - FRAC_PI_2).abs() < 1e-6, "{omega}");
    }

    #[test]
    fn solid_angle_ignores_vertex_order() {
        let mut rng = Rng::new(7, 0);
        for _ in 0..100 {
            let (a, b, c) = (
                random_unit(&mut rng),
                random_unit(&mut rng),
                random_unit(&mut rng),
            );
            let omega = spherical_triangle_solid_angle(a, b, c);
            assert!(omega >= 0.0);
            for (p, q, r) in [(b, c, a), (c, a, b), (a, c, b), (c, b, a), (b, a, c)] {
                let other = spherical_triangle_solid_angle(p, q, r);
                assert!(
                    (other - omega).abs() <= 1e-5 * omega.max(1.0),
                    "{omega} {other}"
                );
            }
        }
    }

    #[test]
    fn small_triangle_solid_angle_is_accurate() {
        // A right triangle with legs `e` on the plane z = 1, seen from the origin:
        // tan(Ω/2) = e² / (1 + √(1 + e²))² (Van Oosterom–Strackee with unnormalised vertices).
        for e in [1e-1_f64, 1e-2, 1e-3, 1e-4] {
            let exact = 2.0 * (e * e / (1.0 + (1.0 + e * e).sqrt()).powi(2)).atan();
            let a = Vec3::Z;
            let b = Vec3::new(e as f32, 0.0, 1.0).normalize();
            let c = Vec3::new(0.0, e as f32, 1.0).normalize();
            let omega = spherical_triangle_solid_angle(a, b, c) as f64;
            // Rounding the vertices to f32 (~6e-8 rad) bounds the attainable accuracy.
            assert!(
                ((omega - exact) / exact).abs() < 2e-7 / e,
                "e = {e}: {omega} vs {exact}"
            );
        }
    }

    #[test]
    fn samples_stay_inside_and_invert() {
        let mut rng = Rng::new(11, 0);
        for _ in 0..200 {
            let (a, b, c) = (
                random_unit(&mut rng),
                random_unit(&mut rng),
                random_unit(&mut rng),
            );
            if spherical_triangle_solid_angle(a, b, c) < 1e-3 {
                continue;
            }
            for _ in 0..20 {
                let u = rng.uniform2();
                let w = sample_spherical_triangle(a, b, c, u).unwrap();
                assert!((w.length() - 1.0).abs() < 1e-5);
                let orientation = a.dot(b.cross(c)).signum();
                for (p, q) in [(a, b), (b, c), (c, a)] {
                    let side = orientation * w.dot(p.cross(q).normalize());
                    assert!(side > -1e-5, "outside by {side}");
                }
                let back = invert_spherical_triangle_sample(a, b, c, w).unwrap();
                assert!(back.abs_diff_eq(u, 2e-3), "{u} -> {back}");
            }
        }
    }

    #[test]
    fn triangle_pdf_is_uniform_inside() {
        let (a, b, c) = (Vec3::X, Vec3::Y, Vec3::Z);
        let inside = Vec3::ONE.normalize();
        assert!((spherical_triangle_pdf(a, b, c, inside) - 1.0 / FRAC_PI_2).abs() < 1e-6);
        assert_eq!(spherical_triangle_pdf(a, b, c, -inside), 0.0);
        assert_eq!(
            spherical_triangle_pdf(a, c, b, Vec3::new(1.0, 1.0, -0.1).normalize()),
            0.0
        );
    }

    #[test]
    fn degenerate_triangles_give_none() {
        let u = Vec2::splat(0.5);
        assert!(sample_spherical_triangle(Vec3::X, Vec3::X, Vec3::Y, u).is_none());
        let mid = (Vec3::X + Vec3::Y).normalize();
        assert!(sample_spherical_triangle(Vec3::X, mid, Vec3::Y, u).is_none());
    }

    /// Arvo's map as it was before the trigonometry-free form: `c'` from the angle `s`
    /// (`atan2`, clamped to the arc by `asin`), then `sin`; the reference for the new form.
    fn sample_by_angles(a: Vec3, b: Vec3, c: Vec3, u: Vec2) -> Option<Vec3> {
        let area = spherical_triangle_solid_angle(a, b, c);
        let ac = c - a;
        let t = (ac - ac.dot(a) * a).try_normalize()?;
        let arc_ac = if a.dot(c) < 0.0 {
            PI - 2.0 * (0.5 * (a + c).length()).min(1.0).asin()
        } else {
            2.0 * (0.5 * (c - a).length()).min(1.0).asin()
        };
        let ab = b - a;
        let k = ab.dot(t.cross(a)).abs();
        let b_t = ab.dot(t);
        let one_plus_cos_ab = 0.5 * (a + b).length_squared();
        let (sin_half, cos_half) = (0.5 * u.x * area).sin_cos();
        let half_s = (sin_half * one_plus_cos_ab).atan2(cos_half * k - sin_half * b_t);
        let s = (2.0 * half_s).min(arc_ac);
        let sin_quarter = (0.5 * s).sin();
        let cp_minus_a = -2.0 * sin_quarter * sin_quarter * a + s.sin() * t;
        let bcp = cp_minus_a - ab;
        let one_minus_cos = u.y * 0.5 * bcp.length_squared();
        let sin_theta = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0).sqrt();
        let e = (bcp - bcp.dot(b) * b).try_normalize()?;
        (b + (sin_theta * e - one_minus_cos * b)).try_normalize()
    }

    #[test]
    fn trigonometry_free_map_matches_the_angle_form() {
        // Same u, same map: the two forms differ by f32 rounding only, for triangles from
        // 2 sr down to 1e-6 sr (errors relative to the triangle's angular size √Ω).
        let mut rng = Rng::new(23, 0);
        let mut compared = 0;
        for size in [1.5f32, 0.3, 3e-2, 3e-3] {
            for _ in 0..200 {
                let centre = random_unit(&mut rng);
                let frame = crate::sampling::Frame::from_normal(centre);
                let mut vertex = || {
                    let o = size * (2.0 * rng.uniform2() - Vec2::ONE);
                    (centre + o.x * frame.t + o.y * frame.b).normalize()
                };
                let (a, b, c) = (vertex(), vertex(), vertex());
                let omega = spherical_triangle_solid_angle(a, b, c);
                if omega < 0.05 * size * size {
                    continue; // a sliver
                }
                for _ in 0..10 {
                    let u = rng.uniform2();
                    let (Some(new), Some(old)) = (
                        sample_spherical_triangle(a, b, c, u),
                        sample_by_angles(a, b, c, u),
                    ) else {
                        panic!("no sample for ({a}, {b}, {c}), u = {u}");
                    };
                    let error = (new - old).length() / omega.sqrt();
                    assert!(error < 2e-3, "Ω = {omega}: {new} vs {old} ({error})");
                    compared += 1;
                }
            }
        }
        assert!(compared > 4000, "{compared}");
    }

    /// A random convex polygon (a circle's points at sorted random angles) in a random plane
    /// near the origin, and a point in front of it.
    fn random_polygon(rng: &mut Rng) -> (Vec3, Vec<Vec3>) {
        let n = 3 + (rng.uniform() * 8.0) as usize;
        let mut angles: Vec<f32> = (0..n).map(|_| 2.0 * PI * rng.uniform()).collect();
        angles.sort_by(f32::total_cmp);
        let normal = random_unit(rng);
        let frame = crate::sampling::Frame::from_normal(normal);
        let centre = random_unit(rng) * rng.uniform();
        let radius = 0.05 + 2.0 * rng.uniform();
        let vertices = angles
            .iter()
            .map(|&a| centre + radius * (a.cos() * frame.t + a.sin() * frame.b))
            .collect();
        let height = 0.02 + 3.0 * rng.uniform();
        let o = 2.0 * radius * (2.0 * rng.uniform2() - Vec2::ONE);
        (
            centre + height * normal + o.x * frame.t + o.y * frame.b,
            vertices,
        )
    }

    #[test]
    fn fan_products_match_summed_solid_angles() {
        // The fan's cumulative complex products against the sum of its triangles' solid
        // angles by Van Oosterom–Strackee (an atan2 each, as before), on random polygons.
        let mut rng = Rng::new(31, 0);
        let mut checked = 0;
        for _ in 0..2000 {
            let (x, vertices) = random_polygon(&mut rng);
            let Some(polygon) = SphericalPolygon::new(x, &vertices) else {
                continue;
            };
            if polygon.is_area_sampled() {
                continue;
            }
            let (apex, d) = (polygon.apex.as_dvec3(), polygon.points());
            let mut sum = 0.0f64;
            for (i, (p, q)) in crate::sampling::cyclic_pairs(d).enumerate() {
                sum += solid_angle_f64(apex, p.as_dvec3(), q.as_dvec3());
                let cumulative = polygon.fan[i];
                let half = cumulative.y.atan2(cumulative.x);
                // The stored directions are the f64 ones rounded to f32 (~6e-8 rad).
                assert!(
                    (2.0 * half - sum).abs() < 1e-6 * (1.0 + sum),
                    "{half} vs {sum}"
                );
            }
            let omega = polygon.solid_angle() as f64;
            assert!((omega - sum).abs() < 1e-6 * (1.0 + sum), "{omega} vs {sum}");
            checked += 1;
        }
        assert!(checked > 1000, "{checked}");
    }

    #[test]
    fn fan_pick_matches_rescaling_u_into_its_bin() {
        // `pick_fan_triangle` against the old map: the triangle whose bin of the cumulative
        // solid angles holds u·Ω, and u rescaled into it; compared by the sub-triangle's area.
        let mut rng = Rng::new(37, 0);
        for _ in 0..500 {
            let (x, vertices) = random_polygon(&mut rng);
            let Some(polygon) = SphericalPolygon::new(x, &vertices) else {
                continue;
            };
            if polygon.is_area_sampled() {
                continue;
            }
            let (apex, d) = (polygon.apex.as_dvec3(), polygon.points());
            let areas: Vec<f64> = crate::sampling::cyclic_pairs(d)
                .map(|(p, q)| solid_angle_f64(apex, p.as_dvec3(), q.as_dvec3()))
                .collect();
            let total: f64 = areas.iter().sum();
            for _ in 0..20 {
                let u = rng.uniform();
                let (i, sin_half, _) = polygon.pick_fan_triangle(u).unwrap();
                let target = f64::from(u) * total;
                let lower: f64 = areas[..i].iter().sum();
                // Near a bin's edge rounding may pick the neighbour, with a part near 0 or Ω_i.
                let part = 2.0 * f64::from(sin_half).asin();
                let expected = target - lower;
                assert!(
                    (part - expected).abs() < 1e-5 * total,
                    "triangle {i}: part {part} vs {expected} (Ω = {total})"
                );
                assert!(expected >= -1e-5 * total && expected <= areas[i] + 1e-5 * total);
            }
        }
    }

    /// [`SphericalPolygon::set`] as it was before it took the normal and area from the edge
    /// normals, the triple products from `apex · m̂_i`, and left the edge normals unnormalised
    /// (the inside test squares instead): the reference for the new form.
    fn set_by_old_form(polygon: &mut SphericalPolygon, x: Vec3, vertices: &[Vec3]) -> bool {
        polygon.len = 0;
        polygon.fan_usable = 0;
        polygon.half_solid_angle = 0.0;
        polygon.solid_angle = 0.0;
        let n = vertices.len();
        if !(3..=MAX_CLIP_VERTICES).contains(&n)
            || !x.is_finite()
            || vertices.iter().any(|v| !v.is_finite())
        {
            return false;
        }
        // Set-up runs in f64, where differences of f32 positions are exact: a small polygon far
        // from `x` or from the world origin keeps its shape, and solid angles near 2π keep their
        // digits.
        let xd = x.as_dvec3();
        let v0 = vertices[0].as_dvec3();
        // Normal and area from edge vectors (Newell's sum of `v_i × v_{i+1}` cancels far from the
        // world origin).
        let twice_area: DVec3 = vertices[1..]
            .windows(2)
            .map(|w| (w[0].as_dvec3() - v0).cross(w[1].as_dvec3() - v0))
            .sum();
        let twice_area_length = twice_area.length();
        if !(twice_area_length > 0.0 && twice_area_length.is_finite()) {
            return false;
        }
        let winding_normal = twice_area / twice_area_length;
        let mut offsets: ArrayVec<DVec3, MAX_CLIP_VERTICES> = ArrayVec::new();
        offsets.extend(vertices.iter().map(|v| v.as_dvec3() - xd));
        let mean_offset = offsets.iter().copied().sum::<DVec3>() / n as f64;
        // Orient the polygon so that its winding normal points away from x: then `r_i × r_{i+1}`
        // points inside for every edge.
        let mut away = winding_normal;
        if away.dot(mean_offset) < 0.0 {
            away = -away;
            offsets.reverse();
        }
        // One length per vertex: the scale of the edge-on test, and the unit directions.
        let mut unit: ArrayVec<DVec3, MAX_CLIP_VERTICES> = ArrayVec::new();
        let mut scale = 0.0f64;
        for r in &offsets {
            let length = r.length();
            scale = scale.max(length);
            unit.push(*r * length.recip());
        }
        let height = away.dot(mean_offset);
        if height.is_nan() || height <= PLANE_TOLERANCE * scale {
            return false;
        }
        let mut normals: ArrayVec<DVec3, MAX_CLIP_VERTICES> = ArrayVec::new();
        normals
            .extend(crate::sampling::cyclic_pairs(&offsets).map(|(r, r_next)| r.cross(r_next - r)));
        // The fan's apex is the polygon's point nearest x, not a vertex: every polygon point is
        // then less than 90° from it, whereas from x close to a large polygon the diagonals of
        // a vertex fan join nearly opposite directions, whose great circles f32 cannot pin down.
        let apex = nearest_point(&offsets, &normals, height * away).normalize();
        // The fan's half-angles add as the arguments of their Van Oosterom–Strackee complex
        // numbers multiply. Every fan triangle is within 90° of the apex, so each half-angle is
        // below π/2 and their sum, Ω/2, below π; and `|z| <= 4.2`, `|z| >= 1 + v_i·v_{i+1}`,
        // so the products stay far inside f64's range unless x is within ~1e-10 of the plane
        // of a polygon of many vertices, when they are rescaled (their arguments stay).
        let mut cumulative = DVec2::X;
        for (i, (a, b)) in crate::sampling::cyclic_pairs(&unit).enumerate() {
            let z = half_solid_angle_phasor(apex, a, b);
            // Ω_i > MIN ⇔ tan(Ω_i/2) > MIN/2 (to f64 rounding of the tangent).
            if z.y > 0.0 && z.y > 0.5 * f64::from(MIN_TRIANGLE_SOLID_ANGLE) * z.x {
                polygon.fan_usable |= 1 << i;
            }
            cumulative = complex_mul(cumulative, z);
            let magnitude = cumulative.x.abs() + cumulative.y.abs();
            if !(1e-150..=1e150).contains(&magnitude) {
                cumulative /= magnitude;
            }
            polygon.fan[i] = cumulative;
        }
        let half_solid_angle = cumulative.y.atan2(cumulative.x);
        let solid_angle = (2.0 * half_solid_angle) as f32;
        if !(solid_angle > 0.0 && solid_angle.is_finite()) {
            polygon.fan_usable = 0;
            return false;
        }
        // The old form: unit normals, normalised in f64 (its slack is ε² for a unit normal).
        for (i, m) in normals.iter().enumerate() {
            let unit_normal = m.normalize_or_zero();
            polygon.edge_normals[i] = unit_normal.as_vec3();
            polygon.edge_slack[i] =
                (f64::from(EDGE_TOLERANCE).powi(2) * unit_normal.length_squared()) as f32;
        }
        let kept = if solid_angle < SMALL_SOLID_ANGLE {
            &offsets
        } else {
            &unit
        };
        for (i, r) in kept.iter().enumerate() {
            polygon.points[i] = r.as_vec3();
        }
        polygon.len = n;
        polygon.origin = x;
        polygon.apex = apex.as_vec3();
        polygon.half_solid_angle = half_solid_angle;
        polygon.solid_angle = solid_angle;
        polygon.plane = Plane {
            n: -away.as_vec3(),
            d: -away.dot(xd + mean_offset) as f32,
        };
        polygon.height = height as f32;
        polygon.area = (0.5 * twice_area_length) as f32;
        true
    }

    #[test]
    fn set_up_matches_the_old_form() {
        // Same polygon and point, the old set-up against the new one: solid angle, area,
        // plane, apex, the fan's cumulative angles, the pdf of random directions (away from
        // the edges, where a rounding may flip the inside test) and the samples for equal u.
        let mut rng = Rng::new(41, 0);
        let (mut compared, mut inside) = (0, 0);
        for _ in 0..3000 {
            let (x, vertices) = random_polygon(&mut rng);
            let mut new = SphericalPolygon::empty();
            let mut old = SphericalPolygon::empty();
            let built = new.set(x, &vertices);
            assert_eq!(built, set_by_old_form(&mut old, x, &vertices));
            if !built {
                continue;
            }
            let omega = old.solid_angle();
            assert!(
                (new.solid_angle() - omega).abs() <= 1e-6 * omega,
                "{} vs {omega}",
                new.solid_angle()
            );
            assert!((new.area() - old.area()).abs() <= 1e-6 * old.area());
            assert!(new.plane().n.abs_diff_eq(old.plane().n, 1e-6));
            assert!((new.height - old.height).abs() <= 1e-6 * old.height);
            assert!(new.apex.abs_diff_eq(old.apex, 1e-6));
            assert_eq!(new.len, old.len);
            assert_eq!(new.fan_usable, old.fan_usable);
            for (a, b) in new.fan[..new.len].iter().zip(&old.fan[..old.len]) {
                let (a, b) = (a.y.atan2(a.x), b.y.atan2(b.x));
                assert!((a - b).abs() <= 1e-7 * (1.0 + b.abs()), "{a} vs {b}");
            }
            for _ in 0..20 {
                let w = random_unit(&mut rng);
                let near_edge = old.edge_normals[..old.len]
                    .iter()
                    .any(|m| m.dot(w).abs() < 1e-5);
                if !near_edge {
                    assert_eq!(new.pdf(w) > 0.0, old.pdf(w) > 0.0, "{w}");
                    inside += (old.pdf(w) > 0.0) as usize;
                    let (p, q) = (new.pdf(w), old.pdf(w));
                    assert!((p - q).abs() <= 1e-5 * q, "{p} vs {q}");
                }
                let u = rng.uniform2();
                match (new.sample(u), old.sample(u)) {
                    (Some((a, pa)), Some((b, pb))) => {
                        let size = if old.is_area_sampled() {
                            1e-2
                        } else {
                            omega.sqrt()
                        };
                        assert!((a - b).length() <= 1e-4 * size, "{a} vs {b} (Ω = {omega})");
                        assert!((pa - pb).abs() <= 1e-5 * pb);
                        // Each form's sample is inside its own cone.
                        assert!(new.pdf(a) > 0.0 && old.pdf(b) > 0.0);
                    }
                    (None, None) => {}
                    (a, b) => panic!("{a:?} vs {b:?}"),
                }
                compared += 1;
            }
        }
        assert!(compared > 20_000 && inside > 1000, "{compared} {inside}");
    }

    #[test]
    fn polygon_rejects_bad_input() {
        let square = [
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
        ];
        assert!(SphericalPolygon::new(Vec3::new(0.3, 0.2, 0.0), &square).is_none());
        assert!(SphericalPolygon::new(Vec3::new(5.0, 0.2, 0.0), &square).is_none());
        assert!(SphericalPolygon::new(Vec3::Z, &square[..2]).is_none());
        // Either winding, either side: the same solid angle.
        let mut reversed = square;
        reversed.reverse();
        let above = SphericalPolygon::new(Vec3::Z, &square).unwrap();
        let below = SphericalPolygon::new(-Vec3::Z, &reversed).unwrap();
        // A face of the cube [-1, 1]³ seen from its centre: 4π/6.
        assert!((above.solid_angle() - 4.0 * PI / 6.0).abs() < 1e-5);
        assert!((below.solid_angle() - above.solid_angle()).abs() < 1e-6);
        assert!(above.pdf(-Vec3::Z) > 0.0 && above.pdf(Vec3::Z) == 0.0);
        assert!(below.pdf(Vec3::Z) > 0.0 && below.pdf(-Vec3::Z) == 0.0);
    }
}
