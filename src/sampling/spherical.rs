//! Spherical triangles and polygons: solid angles (Van Oosterom–Strackee), uniform sampling by
//! solid angle (Arvo 1995), and the spherical polygon that the projection strategy samples.

use arrayvec::ArrayVec;
use glam::{DVec3, Vec2, Vec3};

use super::polygon::{MAX_CLIP_VERTICES, Plane, Verts, sample_polygon_area};

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

const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// The solid angle of the spherical triangle with unit vertices `a`, `b`, `c` (Van Oosterom and
/// Strackee 1983): `2·atan2(|a·(b×c)|, 1 + a·b + b·c + c·a)`, either winding.
pub fn spherical_triangle_solid_angle(a: Vec3, b: Vec3, c: Vec3) -> f32 {
    solid_angle_f64(a.as_dvec3(), b.as_dvec3(), c.as_dvec3()) as f32
}

/// Van Oosterom–Strackee in f64: products of f32 inputs are exact there, so neither the triple
/// product of a small triangle nor the denominator of a near-hemisphere one (where `1 + c·a` and
/// `a·b` are tiny differences of O(1) products) loses the digits that f32 would.
fn solid_angle_f64(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let volume = a.dot((b - a).cross(c - a)).abs();
    let denominator = 1.0 + a.dot(b) + b.dot(c) + c.dot(a);
    2.0 * volume.atan2(denominator)
}

/// A uniformly distributed direction in the spherical triangle with unit vertices `a`, `b`, `c`
/// (pdf [`spherical_triangle_pdf`]); `None` for a degenerate triangle.
///
/// Arvo's (1995) map, structured as pbrt-v4's `SampleSphericalTriangle`: `u.x` picks the point `c'`
/// on the arc `a → c` that cuts off the sub-triangle `(a, b, c')` of area `u.x · Ω`, and `u.y`
/// picks a point on the arc `b → c'` with `1 − cos θ` uniform. Arvo's and pbrt's closed forms go
/// through the vertex angles and `cos β'`, which cancel catastrophically in f32 for small or thin
/// triangles; here `c'` is solved from the Van Oosterom–Strackee formula instead (same map), with
/// every quantity formed from vertex differences.
pub fn sample_spherical_triangle(a: Vec3, b: Vec3, c: Vec3, u: Vec2) -> Option<Vec3> {
    let area = spherical_triangle_solid_angle(a, b, c);
    if area.is_nan() || area <= MIN_TRIANGLE_SOLID_ANGLE {
        return None;
    }
    // The arc a → c: unit tangent `t` at `a`, and its length.
    let ac = c - a;
    let t = (ac - ac.dot(a) * a).try_normalize()?;
    let arc_ac = angle_between(a, c);
    // With c'(s) = cos s·a + sin s·t, the area of (a, b, c') is
    //   2·atan2(sin s·k, (1 + a·b)(1 + cos s) + sin s·(b·t)),   k = |a·(b×t)|,
    // and setting it to `area_sub` gives tan(s/2) in closed form (half-angle substitution).
    let ab = b - a;
    let k = ab.dot(t.cross(a)).abs();
    let b_t = ab.dot(t);
    // 1 + a·b = |a + b|²/2, accurate also when b is nearly opposite a.
    let one_plus_cos_ab = 0.5 * (a + b).length_squared();
    let area_sub = u.x * area;
    let (sin_half, cos_half) = (0.5 * area_sub).sin_cos();
    let half_s = (sin_half * one_plus_cos_ab).atan2(cos_half * k - sin_half * b_t);
    let s = (2.0 * half_s).min(arc_ac);
    // c' − a = (cos s − 1)·a + sin s·t, without cancelling cos s − 1.
    let sin_quarter = (0.5 * s).sin();
    let cp_minus_a = -2.0 * sin_quarter * sin_quarter * a + s.sin() * t;
    // The arc b → c': cos θ uniform in [b·c', 1], with 1 − b·c' = |c' − b|²/2.
    let bcp = cp_minus_a - ab;
    let one_minus_cos = u.y * 0.5 * bcp.length_squared();
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
/// points inside) nearest x, given the foot of x on its plane.
fn nearest_point(vertices: &[DVec3], foot: DVec3) -> DVec3 {
    let edges = super::cyclic_pairs(vertices);
    if edges.clone().all(|(a, b)| foot.dot(a.cross(b - a)) >= 0.0) {
        return foot;
    }
    // Outside: the nearest point is on an edge.
    edges
        .map(|(a, b)| {
            let e = b - a;
            a + (-a.dot(e) / e.length_squared()).clamp(0.0, 1.0) * e
        })
        .filter(|p| p.is_finite())
        .min_by(|p, q| p.length_squared().total_cmp(&q.length_squared()))
        .unwrap_or(foot)
}

/// The angle between unit vectors, accurate near 0 and π (unlike `acos` of the dot product).
fn angle_between(a: Vec3, b: Vec3) -> f32 {
    if a.dot(b) < 0.0 {
        std::f32::consts::PI - 2.0 * (0.5 * (a + b).length()).min(1.0).asin()
    } else {
        2.0 * (0.5 * (b - a).length()).min(1.0).asin()
    }
}

/// A planar convex polygon seen from a point `x`: the directions through it, sampled uniformly by
/// solid angle (or by area when it subtends less than [`SMALL_SOLID_ANGLE`]).
///
/// Sampling picks a triangle of a fan by solid angle, then samples it with
/// [`sample_spherical_triangle`]. The fan's apex is the polygon's point nearest `x` rather than a
/// vertex, so that no fan triangle joins nearly opposite directions when `x` is close to a large
/// polygon.
///
/// Built once per shading point, so everything is stored inline.
#[derive(Clone, Debug)]
pub struct SphericalPolygon {
    origin: Vec3,
    /// Vertices minus `origin`, wound clockwise as seen from `origin`.
    offsets: Verts,
    /// Unit directions from `origin` to the vertices.
    directions: Verts,
    /// Unit direction to the polygon's point nearest `origin`: the apex of the fan.
    apex: Vec3,
    /// Unit normals of the planes through `origin` and each edge `(v_i, v_{i+1})`, pointing inside.
    edge_normals: Verts,
    /// Cumulative solid angles of the fan triangles `(apex, v_i, v_{i+1})`, `i = 0..n`.
    fan_cdf: ArrayVec<f32, MAX_CLIP_VERTICES>,
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
        let n = vertices.len();
        if !(3..=MAX_CLIP_VERTICES).contains(&n)
            || !x.is_finite()
            || vertices.iter().any(|v| !v.is_finite())
        {
            return None;
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
        let area = 0.5 * twice_area.length();
        let winding_normal = twice_area.try_normalize()?;
        // Arrays are filled in place (`extend`, not `collect`): a collected array is copied
        // whole, all of its capacity, when it is moved into place.
        let mut offsets: ArrayVec<DVec3, MAX_CLIP_VERTICES> = ArrayVec::new();
        offsets.extend(vertices.iter().map(|v| v.as_dvec3() - xd));
        let mean_offset = offsets.iter().copied().sum::<DVec3>() / n as f64;
        let scale = offsets.iter().map(|r| r.length()).fold(0.0, f64::max);
        // Orient the polygon so that its winding normal points away from x: then `r_i × r_{i+1}`
        // points inside for every edge.
        let mut away = winding_normal;
        if away.dot(mean_offset) < 0.0 {
            away = -away;
            offsets.reverse();
        }
        let height = away.dot(mean_offset);
        if height.is_nan() || height <= PLANE_TOLERANCE * scale {
            return None;
        }
        let mut unit: ArrayVec<DVec3, MAX_CLIP_VERTICES> = ArrayVec::new();
        unit.extend(offsets.iter().map(|r| r.normalize()));
        let mut edge_normals = Verts::new();
        edge_normals.extend(
            super::cyclic_pairs(&offsets)
                .map(|(r, r_next)| r.cross(r_next - r).normalize_or_zero().as_vec3()),
        );
        // The fan's apex is the polygon's point nearest x, not a vertex: every polygon point is
        // then less than 90° from it, whereas from x close to a large polygon the diagonals of
        // a vertex fan join nearly opposite directions, whose great circles f32 cannot pin down.
        let apex = nearest_point(&offsets, height * away).normalize();
        let mut fan_cdf = ArrayVec::new();
        let mut total = 0.0;
        for (a, b) in super::cyclic_pairs(&unit) {
            total += solid_angle_f64(apex, a, b);
            fan_cdf.push(total as f32);
        }
        let solid_angle = total as f32;
        if !(solid_angle > 0.0 && solid_angle.is_finite()) {
            return None;
        }
        let plane = Plane {
            n: -away.as_vec3(),
            d: -away.dot(xd + mean_offset) as f32,
        };
        let mut polygon = SphericalPolygon {
            origin: x,
            offsets: Verts::new(),
            directions: Verts::new(),
            apex: apex.as_vec3(),
            edge_normals,
            fan_cdf,
            solid_angle,
            plane,
            height: height as f32,
            area: area as f32,
        };
        polygon.offsets.extend(offsets.iter().map(|r| r.as_vec3()));
        polygon.directions.extend(unit.iter().map(|d| d.as_vec3()));
        Some(polygon)
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
    pub fn solid_angle(&self) -> f32 {
        self.solid_angle
    }

    /// Whether the polygon is too small to sample by solid angle (see [`SMALL_SOLID_ANGLE`]);
    /// depends on the origin only, so [`Self::sample`] and [`Self::pdf`] always agree.
    pub fn is_area_sampled(&self) -> bool {
        self.solid_angle < SMALL_SOLID_ANGLE
    }

    /// A unit direction `wi` through the polygon and its pdf in solid angle.
    pub fn sample(&self, u: Vec2) -> Option<(Vec3, f32)> {
        if self.is_area_sampled() {
            let wi = sample_polygon_area(&self.offsets, u).try_normalize()?;
            return Some((wi, self.area_pdf(wi)));
        }
        let (i, ux) = self.pick_fan_triangle(u.x)?;
        let d = &self.directions;
        let next = (i + 1) % d.len();
        let wi = sample_spherical_triangle(self.apex, d[i], d[next], Vec2::new(ux, u.y))?;
        Some((wi, 1.0 / self.solid_angle))
    }

    /// The pdf in solid angle of [`Self::sample`] for the unit direction `wi`: 0 unless the ray
    /// `origin + t·wi`, `t > 0`, passes through the polygon (boundary included).
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
    fn contains(&self, wi: Vec3) -> bool {
        // The edge planes alone bound the cone; the first test rejects the opposite hemisphere
        // early and keeps `area_pdf` away from grazing directions.
        self.plane.n.dot(wi) < 0.0
            && self
                .edge_normals
                .iter()
                .all(|m| m.dot(wi) >= -EDGE_TOLERANCE)
    }

    /// Area sampling's pdf in solid angle, `d² / (A·|cos θ|)`: here `d = h / |cos θ|` with `h`
    /// the origin's distance to the plane, so sample and pdf use the same expression.
    fn area_pdf(&self, wi: Vec3) -> f32 {
        let cos_theta = self.plane.n.dot(wi).abs();
        self.height * self.height / (self.area * cos_theta * cos_theta * cos_theta)
    }

    /// The fan triangle `(apex, v_i, v_{i+1})` for `u`, picked by solid angle, and `u` rescaled
    /// to [0, 1) within its bin (so that stratification carries over to the triangle).
    fn pick_fan_triangle(&self, u: f32) -> Option<(usize, f32)> {
        let cdf = &self.fan_cdf;
        let lower = |i: usize| if i == 0 { 0.0 } else { cdf[i - 1] };
        let target = u * self.solid_angle;
        let mut i = cdf.partition_point(|&c| c <= target).min(cdf.len() - 1);
        // `u·Ω` can round up to Ω and land on trailing empty triangles.
        while i > 0 && cdf[i] <= lower(i) {
            i -= 1;
        }
        let width = cdf[i] - lower(i);
        if width.is_nan() || width <= 0.0 {
            return None;
        }
        Some((
            i,
            ((target - lower(i)) / width).clamp(0.0, ONE_MINUS_EPSILON),
        ))
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
