//! Planar convex polygons: the shape of lights and portals, and the clipping that the antishadow
//! classifier and the projection strategy need. Vertices are stored inline (no allocation), so
//! clipping per shading point is cheap.

use arrayvec::ArrayVec;
use glam::{Vec2, Vec3};

use super::lanes::{F32s, Mask, Vec3s};

/// The most vertices a light or portal polygon may have.
pub const MAX_POLYGON_VERTICES: usize = 12;
/// Room for a clipped polygon: clipping a convex polygon by `k` planes adds at most `k` vertices.
pub const MAX_CLIP_VERTICES: usize = 2 * MAX_POLYGON_VERTICES + 8;
/// Inline vertex storage for polygons and clipping results.
pub type Verts = ArrayVec<Vec3, MAX_CLIP_VERTICES>;

/// The plane `n · p = d`, with `n` of unit length; `signed_distance > 0` is its positive side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    pub n: Vec3,
    pub d: f32,
}

impl Plane {
    pub fn from_point_normal(p: Vec3, n: Vec3) -> Self {
        let n = n.normalize();
        Plane { n, d: n.dot(p) }
    }

    /// The plane through three points, oriented by their winding; `None` if they are collinear.
    pub fn through(a: Vec3, b: Vec3, c: Vec3) -> Option<Self> {
        let n = (b - a).cross(c - a);
        let len = n.length();
        // Relative to the edge lengths, so that tiny and huge scenes behave alike.
        let scale = (b - a).length() * (c - a).length();
        if len.is_nan() || len <= 1e-7 * scale {
            return None;
        }
        Some(Plane::from_point_normal(a, n / len))
    }

    pub fn signed_distance(&self, p: Vec3) -> f32 {
        self.n.dot(p) - self.d
    }

    pub fn flipped(self) -> Self {
        Plane {
            n: -self.n,
            d: -self.d,
        }
    }

    /// The ray parameter where `o + t·dir` crosses the plane, if it does so at `t > 0`.
    #[inline(always)]
    pub fn intersect(&self, o: Vec3, dir: Vec3) -> Option<f32> {
        let denom = self.n.dot(dir);
        if denom == 0.0 {
            return None;
        }
        let t = (self.d - self.n.dot(o)) / denom;
        (t > 0.0 && t.is_finite()).then_some(t)
    }
}

/// Why a set of points is not a usable convex polygon.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PolygonError {
    #[error("has {0} distinct vertices; a polygon needs at least 3")]
    TooFewVertices(usize),
    #[error("has {0} vertices; at most {MAX_POLYGON_VERTICES} are supported")]
    TooManyVertices(usize),
    #[error("has zero area")]
    ZeroArea,
    #[error("is not planar (a vertex lies {0:.3e} off its plane)")]
    NonPlanar(f32),
    #[error("is not convex")]
    NonConvex,
    #[error("has non-finite coordinates")]
    NonFinite,
}

/// A planar convex polygon with counter-clockwise vertices around `normal`.
#[derive(Clone, Debug, PartialEq)]
pub struct ConvexPolygon {
    vertices: Verts,
    normal: Vec3,
    area: f32,
    centroid: Vec3,
    /// The supporting plane, oriented by `normal` (ray tests use it per sample).
    plane: Plane,
    /// Cumulative areas of the fan triangles `(v0, v_i, v_{i+1})`, for area sampling.
    fan_cdf: ArrayVec<f32, MAX_POLYGON_VERTICES>,
    /// The largest distance of a vertex from the first: scales the slack of
    /// [`Self::ray_through`] (fixed per polygon, so not recomputed per evaluation).
    reach: f64,
    /// Per edge `(v_i, v_{i+1})`, the plane through it perpendicular to the polygon, positive
    /// inside: [`clip_convex_in`]'s half-spaces, fixed per polygon (a clip runs per shading
    /// point).
    edge_planes: ArrayVec<Plane, MAX_POLYGON_VERTICES>,
}

/// Slack of [`ConvexPolygon::ray_through`]'s inside test, as a distance on the polygon's plane
/// per unit of `t + reach` (`t` the distance along the ray). [`ConvexPolygon::sample_direction`]'s
/// offset `(v_0 − x) + b_1·e_1 + b_2·e_2` is rounded by a few ulps of those lengths, and its
/// normalisation by one more ulp of `t`: 8 ulps cover both. A band this wide around the
/// polygon gets a pdf that no sample reaches; its share of the area is
/// `perimeter · slack / area`, 1e-4 for a 4 cm portal 2 m away.
const EDGE_SLACK: f64 = 8.0 * f32::EPSILON as f64;

/// The inward planes of a convex polygon's edges: for counter-clockwise vertices around
/// `normal`, `normal × edge` points into the polygon.
fn edge_planes(vertices: &[Vec3], normal: Vec3) -> ArrayVec<Plane, MAX_POLYGON_VERTICES> {
    super::cyclic_pairs(vertices)
        .map(|(a, b)| {
            let inward = normal.cross(b - a);
            Plane {
                n: inward,
                d: inward.dot(a),
            }
        })
        .collect()
}

/// The largest distance of a vertex from the first.
fn reach(vertices: &[Vec3]) -> f64 {
    let v0 = vertices.first().map_or(glam::DVec3::ZERO, |v| v.as_dvec3());
    vertices
        .iter()
        .map(|v| v.as_dvec3().distance(v0))
        .fold(0.0, f64::max)
}

impl ConvexPolygon {
    /// Validates `points` (in order, either winding; the normal follows the winding).
    pub fn new(points: &[Vec3]) -> Result<Self, PolygonError> {
        if points.iter().any(|p| !p.is_finite()) {
            return Err(PolygonError::NonFinite);
        }
        let scale = diameter(points);
        let mut vertices = Verts::new();
        for &p in points {
            let is_repeat = vertices
                .last()
                .is_some_and(|&q: &Vec3| q.distance(p) <= 1e-6 * scale);
            if !is_repeat {
                if vertices.is_full() {
                    return Err(PolygonError::TooManyVertices(points.len()));
                }
                vertices.push(p);
            }
        }
        while vertices.len() > 1
            && vertices[0].distance(vertices[vertices.len() - 1]) <= 1e-6 * scale
        {
            vertices.pop();
        }
        // Drop collinear vertices: they carry no shape and would make degenerate planes.
        let mut i = 0;
        while vertices.len() >= 3 && i < vertices.len() {
            let n = vertices.len();
            let (a, b, c) = (
                vertices[(i + n - 1) % n],
                vertices[i],
                vertices[(i + 1) % n],
            );
            if (b - a).cross(c - b).length() <= 1e-6 * (b - a).length() * (c - b).length() {
                vertices.remove(i);
            } else {
                i += 1;
            }
        }
        if vertices.len() < 3 {
            return Err(PolygonError::TooFewVertices(vertices.len()));
        }
        if vertices.len() > MAX_POLYGON_VERTICES {
            return Err(PolygonError::TooManyVertices(vertices.len()));
        }
        let newell = newell_normal(&vertices);
        let area = 0.5 * newell.length();
        if area.is_nan() || area <= 1e-10 * scale * scale {
            return Err(PolygonError::ZeroArea);
        }
        let normal = newell.normalize();
        let mean = vertices.iter().copied().sum::<Vec3>() / vertices.len() as f32;
        let off_plane = vertices
            .iter()
            .map(|&v| normal.dot(v - mean).abs())
            .fold(0.0, f32::max);
        if off_plane > 1e-4 * scale {
            return Err(PolygonError::NonPlanar(off_plane));
        }
        let n = vertices.len();
        for i in 0..n {
            let (a, b, c) = (vertices[i], vertices[(i + 1) % n], vertices[(i + 2) % n]);
            if (b - a).cross(c - b).dot(normal) < 0.0 {
                return Err(PolygonError::NonConvex);
            }
        }
        let centroid = area_centroid(&vertices, normal);
        let fan_cdf = fan_cdf(&vertices);
        Ok(ConvexPolygon {
            reach: reach(&vertices),
            edge_planes: edge_planes(&vertices, normal),
            vertices,
            normal,
            area,
            centroid,
            plane: Plane::from_point_normal(centroid, normal),
            fan_cdf,
        })
    }

    /// Merges triangles (a quad's two, or any coplanar fan) into the one convex polygon they
    /// tile, oriented like the triangles. Fails if they are not coplanar or do not tile a
    /// convex polygon exactly.
    pub fn from_triangles(triangles: &[[Vec3; 3]]) -> Result<Self, PolygonError> {
        if triangles.len() == 1 {
            return ConvexPolygon::new(&triangles[0]);
        }
        let points: Vec<Vec3> = triangles.iter().flatten().copied().collect();
        if points.iter().any(|p| !p.is_finite()) {
            return Err(PolygonError::NonFinite);
        }
        let scale = diameter(&points);
        let summed: Vec3 = triangles
            .iter()
            .map(|[a, b, c]| (*b - *a).cross(*c - *a))
            .sum();
        let triangle_area: f32 = triangles
            .iter()
            .map(|[a, b, c]| 0.5 * (*b - *a).cross(*c - *a).length())
            .sum();
        if summed.is_nan() || summed.length() <= 1e-10 * scale * scale {
            return Err(PolygonError::ZeroArea);
        }
        let normal = summed.normalize();
        let origin = points[0];
        let off_plane = points
            .iter()
            .map(|&p| normal.dot(p - origin).abs())
            .fold(0.0, f32::max);
        if off_plane > 1e-4 * scale {
            return Err(PolygonError::NonPlanar(off_plane));
        }
        let frame = super::Frame::from_normal(normal);
        let flat: Vec<Vec2> = points
            .iter()
            .map(|&p| {
                let l = frame.to_local(p - origin);
                Vec2::new(l.x, l.y)
            })
            .collect();
        let hull = convex_hull_2d(flat);
        let hull_3d: Vec<Vec3> = hull
            .iter()
            .map(|h| origin + frame.t * h.x + frame.b * h.y)
            .collect();
        let polygon = ConvexPolygon::new(&hull_3d)?;
        // Overlapping or flipped triangles, or a non-convex outline, change the area sum; its
        // rounding is at most a few ulps per triangle, so anything beyond that is a notch the
        // hull would wrongly sample (a light emitting where it has no surface).
        let rounding = (8.0 * f32::EPSILON * triangles.len() as f32).max(1e-6);
        if (polygon.area - triangle_area).abs() > rounding * polygon.area {
            return Err(PolygonError::NonConvex);
        }
        Ok(polygon)
    }

    pub fn vertices(&self) -> &[Vec3] {
        &self.vertices
    }
    pub fn normal(&self) -> Vec3 {
        self.normal
    }
    pub fn area(&self) -> f32 {
        self.area
    }
    pub fn centroid(&self) -> Vec3 {
        self.centroid
    }
    pub fn plane(&self) -> Plane {
        self.plane
    }

    /// The same polygon seen from the other side (reversed winding, negated normal).
    pub fn flipped(&self) -> Self {
        let mut vertices = self.vertices.clone();
        vertices.reverse();
        ConvexPolygon {
            fan_cdf: fan_cdf(&vertices),
            reach: reach(&vertices),
            edge_planes: edge_planes(&vertices, -self.normal),
            vertices,
            normal: -self.normal,
            plane: self.plane.flipped(),
            area: self.area,
            centroid: self.centroid,
        }
    }

    /// Edges `(v_i, v_{i+1})`, closing back to the first vertex.
    pub fn edges(&self) -> impl Iterator<Item = (Vec3, Vec3)> + '_ {
        super::cyclic_pairs(&self.vertices)
    }

    /// A uniformly distributed point on the polygon (pdf `1 / area`): a fan triangle by area
    /// from the precomputed table, `u.x` reused inside it.
    pub fn sample_uniform(&self, u: Vec2) -> Vec3 {
        let (i, b) = self.pick_fan_point(u);
        let v = &self.vertices;
        b.x * v[0] + b.y * v[i + 1] + (1.0 - b.x - b.y) * v[i + 2]
    }

    /// The same point as [`Self::sample_uniform`] less `origin`, formed from `v_0 − origin` and
    /// edge vectors: each is rounded relative to its own length, so the offset is good to a few
    /// ulps of its length even when the polygon and `origin` are far from the world origin
    /// (where an absolute point is only good to an ulp of its coordinates).
    #[inline(always)]
    pub fn sample_uniform_offset(&self, origin: Vec3, u: Vec2) -> Vec3 {
        let (i, b) = self.pick_fan_point(u);
        let v = &self.vertices;
        (v[0] - origin) + b.y * (v[i + 1] - v[0]) + (1.0 - b.x - b.y) * (v[i + 2] - v[0])
    }

    /// A direction from `x` through a uniform point of the polygon, with its solid-angle pdf
    /// `d² / (A |cos θ|)`. The point is drawn as an offset from `x`
    /// ([`Self::sample_uniform_offset`]), so the direction is good to a few ulps of the angle
    /// even for a small polygon far from the world origin.
    pub fn sample_direction(&self, x: Vec3, u: Vec2) -> Option<(Vec3, f32)> {
        let v = self.sample_uniform_offset(x, u);
        let dist = v.length();
        let wi = v / dist;
        let cos = self.normal.dot(wi).abs();
        (dist > 0.0 && cos > 0.0).then(|| (wi, dist * dist / (self.area * cos)))
    }

    /// The solid-angle pdf of [`Self::sample_direction`]: `d² / (A |cos θ|)` through the
    /// polygon, 0 for a direction that misses it.
    pub fn direction_pdf(&self, x: Vec3, wi: Vec3) -> f32 {
        match self.ray_through(x, wi) {
            Some((t, cos)) => (t * t / (f64::from(self.area) * cos.abs())) as f32,
            None => 0.0,
        }
    }

    /// If the ray `x + t·wi` (`t > 0`) passes through the polygon: `t` and the cosine of `wi`
    /// with the normal. Computed in f64 relative to `x` (differences of f32 positions are exact
    /// there), with the inside test against the planes through `x` and each edge, allowing
    /// `EDGE_SLACK`: a direction [`Self::sample_direction`] drew near an edge must never be
    /// judged outside, or its sample would be weighted by a mixture pdf without its own term.
    #[inline(always)]
    pub fn ray_through(&self, x: Vec3, wi: Vec3) -> Option<(f64, f64)> {
        let vertices = self.vertices();
        let (xd, w, n) = (x.as_dvec3(), wi.as_dvec3(), self.normal.as_dvec3());
        let v0 = vertices.first()?.as_dvec3();
        // The plane's signed distance from x along n, and the ray's distance to it.
        let height = n.dot(v0 - xd);
        let cos = n.dot(w);
        let t = height / cos;
        if !(t > 0.0 && t.is_finite()) {
            return None;
        }
        let slack = EDGE_SLACK * (t + self.reach);
        // With counter-clockwise vertices around n, `(a − x) × (b − a)` has `sign(height) · w`
        // on its positive side for w through the polygon; `t · m̂ · w` is the hit's distance to
        // the plane through x and the edge.
        let inside = super::cyclic_pairs(vertices).all(|(a, b)| {
            let (a, b) = (a.as_dvec3(), b.as_dvec3());
            let m = (a - xd).cross(b - a);
            height.signum() * m.dot(w) * t >= -slack * m.length()
        });
        inside.then_some((t, cos))
    }

    /// The fan triangle `(v_0, v_{i+1}, v_{i+2})` for `u.x` and barycentrics in it.
    fn pick_fan_point(&self, u: Vec2) -> (usize, Vec2) {
        let total = self.fan_cdf.last().copied().unwrap_or(0.0);
        let target = u.x * total;
        let i = self
            .fan_cdf
            .partition_point(|&c| c <= target)
            .min(self.fan_cdf.len().saturating_sub(1));
        let lo = if i == 0 { 0.0 } else { self.fan_cdf[i - 1] };
        let a = self.fan_cdf[i] - lo;
        let ux = if a > 0.0 {
            ((target - lo) / a).clamp(0.0, 1.0)
        } else {
            0.5
        };
        (i, super::sample_uniform_triangle(Vec2::new(ux, u.y)))
    }

    /// Where the ray `o + t·dir` (any side) hits the polygon, if at `t > 0`.
    #[inline(always)]
    pub fn intersect(&self, o: Vec3, dir: Vec3) -> Option<f32> {
        let t = self.plane().intersect(o, dir)?;
        self.contains_coplanar(o + t * dir).then_some(t)
    }

    /// Whether the rays `o + t·dir` of each lane hit the polygon ([`Self::intersect`] lane by
    /// lane, its answer's `is_some`).
    #[inline(always)]
    pub fn hits_lanes(&self, o: Vec3s, dir: Vec3s) -> Mask {
        let plane = self.plane();
        let n = Vec3s::splat(plane.n);
        // `Plane::intersect`: a zero `denom` makes `t` infinite or NaN, which the test refuses.
        let t = (plane.d - n.dot(o)) / n.dot(dir);
        let mut hit = t.test(F32s::splat(0.0), |t, zero| t > zero && t < f32::INFINITY);
        let p = o + dir.scale(t);
        for (edge, &a) in self.edge_planes.iter().zip(&self.vertices) {
            let inside = Vec3s::splat(edge.n).dot(p - Vec3s::splat(a));
            for (hit, &inside) in hit.iter_mut().zip(&inside.0) {
                *hit &= inside >= 0.0;
            }
        }
        hit
    }

    /// Whether `p`, assumed on the polygon's plane, is inside it (boundary included).
    #[inline(always)]
    pub fn contains_coplanar(&self, p: Vec3) -> bool {
        // `(b − a) × (p − a) · n = (n × (b − a)) · (p − a)`: the stored inward edge normal, one
        // dot product per edge (the light hit of every projection or portal sample, and of
        // BSDF samples, takes it).
        self.edge_planes
            .iter()
            .zip(&self.vertices)
            .all(|(plane, &a)| plane.n.dot(p - a) >= 0.0)
    }
}

/// Cumulative fan-triangle areas of a convex polygon (one entry per triangle).
fn fan_cdf(vertices: &[Vec3]) -> ArrayVec<f32, MAX_POLYGON_VERTICES> {
    let v0 = vertices[0];
    let mut total = 0.0;
    vertices[1..]
        .windows(2)
        .map(|w| {
            total += 0.5 * (w[0] - v0).cross(w[1] - v0).length();
            total
        })
        .collect()
}

/// The largest distance between two of `points` (a scale for tolerances).
fn diameter(points: &[Vec3]) -> f32 {
    let (lo, hi) = points
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| {
            (lo.min(p), hi.max(p))
        });
    (hi - lo).length().max(f32::MIN_POSITIVE)
}

/// Twice the vector area of a closed polygon (Newell's method), relative to its first vertex
/// so that polygons far from the origin keep their precision. Always inlined: the ordered
/// light draw takes it per piece, per sample.
#[inline(always)]
pub fn newell_normal(vertices: &[Vec3]) -> Vec3 {
    let Some(&v0) = vertices.first() else {
        return Vec3::ZERO;
    };
    let n = vertices.len();
    let mut sum = Vec3::ZERO;
    for i in 0..n {
        let next = if i + 1 == n { 0 } else { i + 1 };
        sum += (vertices[i] - v0).cross(vertices[next] - v0);
    }
    sum
}

/// The area-weighted centroid of a convex polygon.
fn area_centroid(vertices: &[Vec3], normal: Vec3) -> Vec3 {
    let v0 = vertices[0];
    let (mut sum, mut weight) = (Vec3::ZERO, 0.0);
    for w in vertices[1..].windows(2) {
        let a = 0.5 * (w[0] - v0).cross(w[1] - v0).dot(normal);
        sum += a * (v0 + w[0] + w[1]) / 3.0;
        weight += a;
    }
    if weight > 0.0 {
        sum / weight
    } else {
        vertices.iter().copied().sum::<Vec3>() / vertices.len() as f32
    }
}

/// A uniform point on a convex polygon: pick a fan triangle by area, reusing `u.x`.
#[inline(always)]
pub fn sample_polygon_area(vertices: &[Vec3], u: Vec2) -> Vec3 {
    let v0 = vertices[0];
    let fan_area = |w: &[Vec3]| (w[0] - v0).cross(w[1] - v0).length();
    let total: f32 = vertices[1..].windows(2).map(fan_area).sum();
    let mut target = u.x * total;
    let triangles = vertices[1..].windows(2);
    let count = triangles.len();
    for (i, w) in triangles.enumerate() {
        let a = fan_area(w);
        if target < a || i + 1 == count {
            let ux = if a > 0.0 {
                (target / a).clamp(0.0, 1.0)
            } else {
                0.5
            };
            let b = super::sample_uniform_triangle(Vec2::new(ux, u.y));
            return b.x * v0 + b.y * w[0] + (1.0 - b.x - b.y) * w[1];
        }
        target -= a;
    }
    v0
}

/// Half-spaces whose intersection [`sample_polygon_area_ordered`] draws from last.
pub type Cut = ArrayVec<Plane, { MAX_POLYGON_VERTICES + 1 }>;

/// A uniform point on the convex polygon `vertices`, of density `1 / area` like
/// [`sample_polygon_area`], drawn in an order: the part outside the intersection of the
/// half-spaces `cut` (`signed_distance ≥ 0` inside), in convex pieces, from the lowest `u.x`,
/// the intersection from the highest. So under stratified `u` the count of points drawn
/// outside varies as little as the count of `u.x` below a threshold: where the outside is
/// occluded, its zeros are stratified instead of scattered over the unit square. Piece `k` is
/// inside planes `0..k` and outside plane `k`; the last piece is inside all of them.
#[inline(always)]
pub fn sample_polygon_area_ordered(vertices: &[Vec3], cut: &[Plane], u: Vec2) -> Vec3 {
    // Walk the pieces in order, each one's area the difference of the inside's before and
    // after its plane, and stop at the one `u.x` falls in (most draws stop early). The inside
    // is clipped into two buffers in turn (it is `vertices` before the first plane), and a
    // piece is clipped with the negated distances of its plane (what the flipped plane gives,
    // to the bit), each vertex's distance computed once.
    let mut area = polygon_area(vertices);
    let mut target = u.x * area;
    let (mut first, mut second) = (Verts::new(), Verts::new());
    // Which holds the inside: `vertices` (0), `first` (1) or `second` (2).
    let mut holder = 0u8;
    for plane in cut {
        let (inside, next): (&[Vec3], &mut Verts) = match holder {
            0 => (vertices, &mut first),
            1 => (&first, &mut second),
            _ => (&second, &mut first),
        };
        let mut distances = [0.0f32; MAX_CLIP_VERTICES];
        for (d, &p) in distances.iter_mut().zip(inside.iter()) {
            *d = plane.signed_distance(p);
        }
        let distances = &distances[..inside.len()];
        clip_by_distances_into(inside, distances, next);
        let next_area = polygon_area(next);
        let a = area - next_area;
        if a > 0.0 && target < a {
            let mut outside = [0.0f32; MAX_CLIP_VERTICES];
            for (o, &d) in outside.iter_mut().zip(distances) {
                *o = -d;
            }
            let mut piece = Verts::new();
            clip_by_distances_into(inside, &outside[..distances.len()], &mut piece);
            let ux = (target / a).clamp(0.0, super::ONE_BELOW);
            return sample_polygon_area(&piece, Vec2::new(ux, u.y));
        }
        target -= a.max(0.0);
        area = next_area;
        holder = if holder == 1 { 2 } else { 1 };
    }
    let inside: &[Vec3] = match holder {
        0 => vertices,
        1 => &first,
        _ => &second,
    };
    if area <= 0.0 {
        // Rounding ran past the last piece with area: the plain draw, same density.
        return sample_polygon_area(vertices, u);
    }
    let ux = (target / area).clamp(0.0, super::ONE_BELOW);
    sample_polygon_area(inside, Vec2::new(ux, u.y))
}

/// The area of a (possibly degenerate) convex polygon.
#[inline(always)]
pub fn polygon_area(vertices: &[Vec3]) -> f32 {
    0.5 * newell_normal(vertices).length()
}

/// Sutherland–Hodgman against one plane: keeps the part with `signed_distance >= 0`.
pub fn clip_by_plane(vertices: &[Vec3], plane: Plane) -> Verts {
    let mut out = Verts::new();
    clip_by_plane_into(vertices, plane, &mut out);
    out
}

/// [`clip_by_plane`] into a reused buffer.
fn clip_by_plane_into(vertices: &[Vec3], plane: Plane, out: &mut Verts) {
    let mut distances: ArrayVec<f32, MAX_CLIP_VERTICES> = ArrayVec::new();
    distances.extend(vertices.iter().map(|&p| plane.signed_distance(p)));
    clip_by_distances_into(vertices, &distances, out);
}

/// Sutherland–Hodgman given each vertex's signed distance to the plane (each computed once).
#[inline(always)]
fn clip_by_distances_into(vertices: &[Vec3], distances: &[f32], out: &mut Verts) {
    out.clear();
    // Plain index loops on this path (per shading point): the iterator adapters were left
    // out of line, compiled without the renderer's instruction-set features.
    let n = vertices.len().min(distances.len());
    for i in 0..n {
        let next = if i + 1 == n { 0 } else { i + 1 };
        let (a, b, da, db) = (vertices[i], vertices[next], distances[i], distances[next]);
        if da >= 0.0 {
            push(out, a);
        }
        if (da >= 0.0) != (db >= 0.0) {
            let t = da / (da - db);
            push(out, a + t * (b - a));
        }
    }
}

#[inline(always)]
fn push(out: &mut Verts, p: Vec3) {
    // Capacity covers every clip this crate performs; a full buffer would mean a logic error.
    debug_assert!(!out.is_full());
    let _ = out.try_push(p);
}

/// Clips `subject` (coplanar with `clip`) to the inside of the convex polygon `clip`.
pub fn clip_convex(subject: &[Vec3], clip: &ConvexPolygon) -> Verts {
    let (mut first, mut second) = (Verts::new(), Verts::new());
    clip_convex_in(subject, clip, &mut first, &mut second)
        .iter()
        .copied()
        .collect()
}

/// [`clip_convex`] with two buffers to clip into in turn: the clipped polygon, which is
/// `subject` itself when no edge of `clip` cuts it, else one of the buffers (a clip per
/// shading point: no vertex array is copied that need not be).
#[inline(always)]
pub fn clip_convex_in<'a>(
    subject: &'a [Vec3],
    clip: &ConvexPolygon,
    first: &'a mut Verts,
    second: &'a mut Verts,
) -> &'a [Vec3] {
    // Which holds the polygon so far: `subject` (0), `first` (1) or `second` (2). (The
    // ordered light draw alternates the same way; a shared helper for the two cost 0.6% of
    // every render's instructions through code generation, so each spells it out.)
    let mut holder = 0u8;
    for plane in &clip.edge_planes {
        let src: &[Vec3] = match holder {
            0 => subject,
            1 => first,
            _ => second,
        };
        if src.len() < 3 {
            return &[];
        }
        let mut distances = [0.0f32; MAX_CLIP_VERTICES];
        let mut all_inside = true;
        for (d, &p) in distances.iter_mut().zip(src.iter()) {
            *d = plane.signed_distance(p);
            all_inside &= *d >= 0.0;
        }
        // An edge that keeps every vertex leaves the polygon as it is: no copy.
        if all_inside {
            continue;
        }
        let distances = &distances[..src.len()];
        holder = match holder {
            0 => {
                clip_by_distances_into(subject, distances, first);
                1
            }
            1 => {
                clip_by_distances_into(first, distances, second);
                2
            }
            _ => {
                clip_by_distances_into(second, distances, first);
                1
            }
        };
    }
    match holder {
        0 => subject,
        1 => first,
        _ => second,
    }
}

/// Copies `vertices` into `out`, dropping each vertex within `tol` of the previous one kept,
/// and trailing ones within `tol` of the first: a clip repeats, a few ulps apart, a vertex that
/// lies on a clipping plane, and the edge between the copies has a direction made by
/// rounding. What is kept is a subsequence of the vertices, so a convex polygon stays convex.
#[inline(always)]
pub fn merge_close_into(vertices: &[Vec3], tol: f32, out: &mut Verts) {
    // `merge_close_by` written out: its closure was left out of line on the renderer's path.
    let tol2 = tol * tol;
    out.clear();
    for &v in vertices {
        if out
            .last()
            .is_none_or(|kept| kept.distance_squared(v) > tol2)
        {
            push(out, v);
        }
    }
    while out.len() > 1 && out[0].distance_squared(out[out.len() - 1]) <= tol2 {
        out.pop();
    }
}

/// [`merge_close_into`] in place, for any vertex type and closeness: moves the kept vertices
/// to the front of `vertices` and returns how many there are.
#[inline(always)]
pub fn merge_close_by<T: Copy>(vertices: &mut [T], close: impl Fn(T, T) -> bool) -> usize {
    let mut kept = 0;
    for i in 0..vertices.len() {
        if kept == 0 || !close(vertices[kept - 1], vertices[i]) {
            vertices[kept] = vertices[i];
            kept += 1;
        }
    }
    while kept > 1 && close(vertices[0], vertices[kept - 1]) {
        kept -= 1;
    }
    kept
}

/// The convex hull of `points`, which lie in a plane with normal `n`, counter-clockwise around
/// `n` (Andrew's monotone chain, without allocation: it runs per shading point).
pub fn convex_hull_in_plane(points: &[Vec3], n: Vec3) -> Verts {
    let mut hull = Verts::new();
    let Some(&origin) = points.first() else {
        return hull;
    };
    let frame = super::Frame::from_normal(n);
    let mut flat: ArrayVec<(Vec2, Vec3), MAX_CLIP_VERTICES> = ArrayVec::new();
    for &p in points.iter().take(MAX_CLIP_VERTICES) {
        let l = frame.to_local(p - origin);
        flat.push((Vec2::new(l.x, l.y), p));
    }
    flat.sort_unstable_by(|a, b| a.0.x.total_cmp(&b.0.x).then(a.0.y.total_cmp(&b.0.y)));
    let cross = |o: Vec2, a: Vec2, b: Vec2| (a - o).perp_dot(b - o);
    // The chain holds at most n + 1 points before its last pop.
    let mut chain: ArrayVec<(Vec2, Vec3), { MAX_CLIP_VERTICES + 1 }> = ArrayVec::new();
    for pass in 0..2 {
        let start = chain.len();
        for k in 0..flat.len() {
            let p = if pass == 0 {
                flat[k]
            } else {
                flat[flat.len() - 1 - k]
            };
            while chain.len() >= start + 2
                && cross(chain[chain.len() - 2].0, chain[chain.len() - 1].0, p.0) <= 0.0
            {
                chain.pop();
            }
            if chain.try_push(p).is_err() {
                return Verts::new();
            }
        }
        chain.pop();
    }
    hull.extend(chain.iter().map(|c| c.1));
    hull
}

/// Andrew's monotone chain; counter-clockwise, without collinear points.
pub fn convex_hull_2d(mut points: Vec<Vec2>) -> Vec<Vec2> {
    points.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    points.dedup();
    if points.len() < 3 {
        return points;
    }
    let cross = |o: Vec2, a: Vec2, b: Vec2| (a - o).perp_dot(b - o);
    let mut hull: Vec<Vec2> = Vec::with_capacity(points.len() * 2);
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &Vec2>> = if pass == 0 {
            Box::new(points.iter())
        } else {
            Box::new(points.iter().rev())
        };
        for &p in iter {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> Vec<Vec3> {
        vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ]
    }

    #[test]
    fn lane_hits_match_intersect() {
        use crate::sampling::lanes::LANES;
        let tilted: Vec<Vec3> = square()
            .iter()
            .map(|&v| Vec3::new(v.x, v.y, 0.3 * v.x - 0.2 * v.y) + Vec3::new(-0.5, 0.2, 1.0))
            .collect();
        let mut rng = crate::sampling::Rng::new(3, 4);
        for polygon in [square(), tilted].map(|v| ConvexPolygon::new(&v).unwrap()) {
            let mut hits = 0;
            for round in 0..512 {
                let o: [Vec3; LANES] = std::array::from_fn(|_| {
                    Vec3::new(rng.uniform(), rng.uniform(), rng.uniform() - 0.5) * 3.0 - 1.0
                });
                // Toward points around the polygon (its box, grown by half), some backwards.
                let mut dir: [Vec3; LANES] = std::array::from_fn(|i| {
                    let target = Vec3::new(rng.uniform(), rng.uniform(), 0.0) * 2.0 - 0.5;
                    let target = polygon.vertices()[0] + target.x * Vec3::X + target.y * Vec3::Y;
                    let d = (target - o[i]).normalize();
                    if rng.uniform() < 0.2 { -d } else { d }
                });
                // Parallel to the plane, and through a vertex and an edge.
                if round == 0 {
                    dir[0] = Vec3::X;
                    dir[1] = (polygon.vertices()[0] - o[1]).normalize();
                    dir[2] = (polygon.vertices()[1] + polygon.vertices()[2]) * 0.5 - o[2];
                }
                let lanes =
                    polygon.hits_lanes(Vec3s::from_fn(|i| o[i]), Vec3s::from_fn(|i| dir[i]));
                for i in 0..LANES {
                    let scalar = polygon.intersect(o[i], dir[i]).is_some();
                    assert_eq!(lanes[i], scalar, "{:?} {:?}", o[i], dir[i]);
                    hits += scalar as u32;
                }
            }
            // Both answers were met many times.
            assert!(hits > 200 && hits < 512 * 8 - 200, "{hits}");
        }
    }

    #[test]
    fn square_properties() {
        let p = ConvexPolygon::new(&square()).unwrap();
        assert!((p.area() - 1.0).abs() < 1e-6);
        assert!(p.normal().abs_diff_eq(Vec3::Z, 1e-6));
        assert!(p.centroid().abs_diff_eq(Vec3::new(0.5, 0.5, 0.0), 1e-6));
        assert_eq!(p.flipped().normal(), -Vec3::Z);
    }

    #[test]
    fn rejects_bad_polygons() {
        let mut s = square();
        s[2].z = 0.5;
        assert!(matches!(
            ConvexPolygon::new(&s),
            Err(PolygonError::NonPlanar(_))
        ));
        let dart = [
            Vec3::ZERO,
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(1.0, 0.3, 0.0),
            Vec3::new(1.0, 2.0, 0.0),
        ];
        // A dart (reflex vertex) in one orientation or the other.
        assert_eq!(ConvexPolygon::new(&dart), Err(PolygonError::NonConvex));
        let line = [Vec3::ZERO, Vec3::X, 2.0 * Vec3::X];
        assert!(ConvexPolygon::new(&line).is_err());
    }

    #[test]
    fn merges_quad_triangles() {
        let s = square();
        let tris = [[s[0], s[1], s[2]], [s[0], s[2], s[3]]];
        let p = ConvexPolygon::from_triangles(&tris).unwrap();
        assert_eq!(p.vertices().len(), 4);
        assert!((p.area() - 1.0).abs() < 1e-5);
        assert!(p.normal().abs_diff_eq(Vec3::Z, 1e-5));
        // Overlapping triangles do not tile one polygon.
        let overlap = [[s[0], s[1], s[2]], [s[0], s[1], s[2]]];
        assert_eq!(
            ConvexPolygon::from_triangles(&overlap),
            Err(PolygonError::NonConvex)
        );
        // A unit square with a triangular notch of 0.025% of its area (its tip 0.0005 in from
        // the right side): within the earlier 0.1% tolerance, but not within rounding, so the
        // hull would emit where there is no light.
        let e = 0.0005;
        let notched = [
            [Vec3::ZERO, Vec3::X, Vec3::new(1.0 - e, 0.5, 0.0)],
            [
                Vec3::ZERO,
                Vec3::new(1.0 - e, 0.5, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
            ],
            [Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), Vec3::Y],
        ];
        assert_eq!(
            ConvexPolygon::from_triangles(&notched),
            Err(PolygonError::NonConvex)
        );
        // A fan of 12 triangles tiling a 12-gon (the most vertices a polygon light has) off
        // the origin merges, its rounding allowed.
        let ring: Vec<Vec3> = (0..12)
            .map(|k| {
                let a = std::f32::consts::TAU * k as f32 / 12.0;
                Vec3::new(3.0 * a.cos(), 3.0 * a.sin(), 0.0) + Vec3::new(10.0, -7.0, 0.0)
            })
            .collect();
        let centre = Vec3::new(10.0, -7.0, 0.0);
        let fan: Vec<[Vec3; 3]> = (0..12)
            .map(|k| [centre, ring[k], ring[(k + 1) % 12]])
            .collect();
        let merged = ConvexPolygon::from_triangles(&fan);
        assert!(merged.is_ok(), "{merged:?}");
    }

    #[test]
    fn clipping() {
        let p = ConvexPolygon::new(&square()).unwrap();
        let half = clip_by_plane(
            p.vertices(),
            Plane::from_point_normal(Vec3::splat(0.5), Vec3::X),
        );
        assert!((polygon_area(&half) - 0.5).abs() < 1e-6);
        let shifted: Vec<Vec3> = square()
            .iter()
            .map(|v| *v + Vec3::new(0.5, 0.5, 0.0))
            .collect();
        let overlap = clip_convex(&shifted, &p);
        assert!((polygon_area(&overlap) - 0.25).abs() < 1e-6);
    }

    /// A pentagon in `z = 0` and the half-spaces of what a point above it sees through a
    /// smaller square (a light, and a portal seen from a shading point): about half of it.
    fn pentagon_and_cut() -> (Vec<Vec3>, Vec<Plane>) {
        let pentagon = (0..5)
            .map(|i| {
                let a = i as f32 * std::f32::consts::TAU / 5.0;
                Vec3::new(a.cos(), a.sin(), 0.0)
            })
            .collect();
        let apex = Vec3::new(0.6, 0.3, 2.0);
        let portal = [
            Vec3::new(0.2, -0.1, 1.0),
            Vec3::new(0.9, -0.1, 1.0),
            Vec3::new(0.9, 0.6, 1.0),
            Vec3::new(0.2, 0.6, 1.0),
        ];
        let c = portal.iter().copied().sum::<Vec3>() / 4.0;
        let mut cut: Vec<Plane> = (0..4)
            .map(|i| {
                let p = Plane::through(apex, portal[i], portal[(i + 1) % 4]).unwrap();
                if p.signed_distance(c) < 0.0 {
                    p.flipped()
                } else {
                    p
                }
            })
            .collect();
        cut.push(Plane::from_point_normal(c, -Vec3::Z));
        (pentagon, cut)
    }

    fn inside(cut: &[Plane], p: Vec3) -> bool {
        cut.iter().all(|plane| plane.signed_distance(p) >= -1e-5)
    }

    /// `sample_polygon_area_ordered` keeps the density `1 / area`: the share of its points on
    /// the positive side of each of a few planes (the cut's own among them) matches the area
    /// there. Tolerance: 4.5 binomial standard errors `sqrt(p(1 − p)/n)` per plane (a false
    /// alarm in 1e-5 per plane). A draw whose `u.x` is skewed, as a wrong weighting of the
    /// pieces would be, fails the same check.
    #[test]
    fn ordered_area_draws_are_uniform_on_the_polygon() {
        let (pentagon, cut) = pentagon_and_cut();
        let mut planes = cut.clone();
        for k in 0..8 {
            let a = k as f32 * 0.7;
            let n = Vec3::new(a.cos(), a.sin(), 0.0);
            planes.push(Plane::from_point_normal(n * (0.1 * k as f32 - 0.4), n));
        }
        let total = polygon_area(&pentagon);
        let worst_z = |skew: f32| {
            let mut rng = crate::sampling::Rng::new(7, 3);
            let n = 40_000;
            let points: Vec<Vec3> = (0..n)
                .map(|_| {
                    let u = rng.uniform2();
                    let u = Vec2::new(u.x.powf(skew), u.y);
                    sample_polygon_area_ordered(&pentagon, &cut, u)
                })
                .collect();
            assert!(points.iter().all(|p| p.z.abs() < 1e-6));
            planes
                .iter()
                .map(|plane| {
                    let p = (polygon_area(&clip_by_plane(&pentagon, *plane)) / total) as f64;
                    let hits = points
                        .iter()
                        .filter(|q| plane.signed_distance(**q) >= 0.0)
                        .count();
                    let share = hits as f64 / n as f64;
                    (share - p).abs() / (p * (1.0 - p) / n as f64).sqrt()
                })
                .fold(0.0, f64::max)
        };
        let z = worst_z(1.0);
        assert!(z < 4.5, "worst z {z}");
        let skewed = worst_z(1.2);
        assert!(skewed > 4.5, "a skewed draw passes: worst z {skewed}");
    }

    /// The point of the order: with `u.x` stratified in `n` intervals, the count of points
    /// drawn outside the cut is one of the two integers around `n · share`, as for `u.x` below
    /// a threshold (variance at most 1/4), where the plain draw scatters the outside over
    /// the unit square and its count varies several times more.
    #[test]
    fn ordered_draws_count_the_outside_as_evenly_as_stratified_numbers_allow() {
        let (pentagon, cut) = pentagon_and_cut();
        let n = 16;
        let variance = |ordered: bool| {
            let mut rng = crate::sampling::Rng::new(11, 5);
            let counts: Vec<f64> = (0..400)
                .map(|_| {
                    (0..n)
                        .filter(|&i| {
                            let u = Vec2::new((i as f32 + rng.uniform()) / n as f32, rng.uniform());
                            let p = if ordered {
                                sample_polygon_area_ordered(&pentagon, &cut, u)
                            } else {
                                sample_polygon_area(&pentagon, u)
                            };
                            !inside(&cut, p)
                        })
                        .count() as f64
                })
                .collect();
            let mean = counts.iter().sum::<f64>() / counts.len() as f64;
            counts.iter().map(|c| (c - mean).powi(2)).sum::<f64>() / counts.len() as f64
        };
        let (ordered, plain) = (variance(true), variance(false));
        assert!(ordered <= 0.3, "ordered count variance {ordered}");
        assert!(
            plain > 2.0 * ordered.max(0.25),
            "plain {plain}, ordered {ordered}"
        );
    }

    #[test]
    fn ray_intersection() {
        let p = ConvexPolygon::new(&square()).unwrap();
        let t = p.intersect(Vec3::new(0.5, 0.5, 2.0), -Vec3::Z).unwrap();
        assert!((t - 2.0).abs() < 1e-6);
        assert!(p.intersect(Vec3::new(1.5, 0.5, 2.0), -Vec3::Z).is_none());
        assert!(p.intersect(Vec3::new(0.5, 0.5, 2.0), Vec3::Z).is_none());
    }
}
