//! The convex solid that stands in for a light of any shape (a bulb, a tube, a curved or
//! non-convex panel) when a portal targets it (`docs/method.md` §1, §3.6): the convex hull of
//! its vertices, or, when that has too many vertices for the per-point projection, an octagonal
//! prism around the light's longest extent that contains it. Both are kept as half-spaces
//! `n · p <= d` (outward unit normals), cut behind the portal plane, and turned back into
//! vertices by intersecting the planes three at a time. All in f64, once per portal.
//!
//! Any convex solid containing the light keeps the estimator unbiased: the projection technique
//! samples directions towards it and evaluates its density exactly, and directions that miss the
//! light itself contribute zero. A tighter solid only wastes fewer samples.

use glam::DVec3;

/// A half-space `n · p <= d`, `n` of unit length (pointing out of the solid).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HalfSpace {
    pub n: DVec3,
    pub d: f64,
}

impl HalfSpace {
    /// Positive outside the solid.
    pub fn signed_distance(&self, p: DVec3) -> f64 {
        self.n.dot(p) - self.d
    }

    fn same_as(&self, other: &HalfSpace, tol: f64) -> bool {
        self.n.dot(other.n) > 1.0 - 1e-10 && (self.d - other.d).abs() <= tol
    }
}

/// At most this many distinct light vertices are hulled exactly (the facet search visits every
/// triple of them); lights with more get the bounding prism.
const MAX_EXACT_POINTS: usize = 24;
/// Relative to the light's diameter: how far off a plane a vertex may be and still lie on it.
const ON_PLANE: f64 = 1e-7;

/// The clipped solid: its vertices and the planes of its faces (those with 3 or more vertices
/// on them), excluding the cutting plane.
#[derive(Clone, Debug)]
pub struct ClippedHull {
    pub vertices: Vec<DVec3>,
    pub faces: Vec<HalfSpace>,
}

/// Which bounding solid [`bounding_half_spaces`] builds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HullKind {
    /// The convex hull of the vertices (for at most `MAX_EXACT_POINTS` of them).
    Exact,
    /// An octagonal prism around the longest extent, holding every vertex.
    Prism,
}

/// The light's distinct vertices, in f64.
pub fn distinct_points(points: impl IntoIterator<Item = DVec3>) -> Vec<DVec3> {
    let mut out: Vec<DVec3> = points.into_iter().collect();
    out.sort_by(|a, b| {
        a.x.total_cmp(&b.x)
            .then(a.y.total_cmp(&b.y))
            .then(a.z.total_cmp(&b.z))
    });
    out.dedup();
    out
}

/// The half-spaces of a convex solid holding `points` (distinct, finite): the exact hull when
/// `kind` is [`HullKind::Exact`] and there are few enough points, else the prism. `None` when the
/// points are all on one line (no solid or polygon holds them with a positive area).
pub fn bounding_half_spaces(points: &[DVec3], kind: HullKind) -> Option<Vec<HalfSpace>> {
    let scale = diameter(points);
    if !(scale > 0.0 && scale.is_finite()) {
        return None;
    }
    let planes = if kind == HullKind::Exact && points.len() <= MAX_EXACT_POINTS {
        exact_faces(points, scale)
    } else {
        prism(points)
    };
    (planes.len() >= 4).then_some(planes)
}

/// Every plane through three of the points with all of them on one side, each side once for a
/// flat set; for a flat set also the planes through two points along its normal that have all
/// on one side (the outline's edges).
fn exact_faces(points: &[DVec3], scale: f64) -> Vec<HalfSpace> {
    let tol = ON_PLANE * scale;
    let n = points.len();
    let mut faces: Vec<HalfSpace> = Vec::new();
    let push = |faces: &mut Vec<HalfSpace>, normal: DVec3, through: DVec3| {
        let side = |s: f64| {
            let (lo, hi) = points
                .iter()
                .map(|&p| s * normal.dot(p - through))
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), h| {
                    (lo.min(h), hi.max(h))
                });
            (lo, hi)
        };
        for s in [1.0, -1.0] {
            let (_, hi) = side(s);
            if hi <= tol {
                let h = HalfSpace {
                    n: s * normal,
                    d: s * normal.dot(through),
                };
                if !faces.iter().any(|f| f.same_as(&h, tol)) {
                    faces.push(h);
                }
            }
        }
    };
    let mut flat_normal = None;
    for i in 0..n {
        for j in i + 1..n {
            for k in j + 1..n {
                let (a, b, c) = (points[i], points[j], points[k]);
                let m = (b - a).cross(c - a);
                if m.length() <= 1e-9 * scale * scale {
                    continue;
                }
                let m = m.normalize();
                let before = faces.len();
                push(&mut faces, m, a);
                // Both sides at once: every point lies on this plane.
                if faces.len() == before + 2 {
                    flat_normal = Some(m);
                }
            }
        }
    }
    if let Some(normal) = flat_normal {
        for i in 0..n {
            for j in i + 1..n {
                let m = (points[j] - points[i]).cross(normal);
                if m.length() <= 1e-9 * scale {
                    continue;
                }
                push(&mut faces, m.normalize(), points[i]);
            }
        }
    }
    faces
}

/// An octagonal prism holding the points: its axis along their (approximate) longest extent,
/// its first side direction towards the point farthest from that axis, so that a flat light
/// gets two of the sides in its own plane.
fn prism(points: &[DVec3]) -> Vec<HalfSpace> {
    let farthest = |from: DVec3| {
        points
            .iter()
            .copied()
            .max_by(|a, b| {
                a.distance_squared(from)
                    .total_cmp(&b.distance_squared(from))
            })
            .unwrap_or(from)
    };
    let p1 = farthest(points[0]);
    let p2 = farthest(p1);
    let axis = (p2 - p1).normalize_or(DVec3::Z);
    let off_axis = |p: DVec3| {
        let r = p - p1;
        r - axis * r.dot(axis)
    };
    let u = points
        .iter()
        .map(|&p| off_axis(p))
        .max_by(|a, b| a.length_squared().total_cmp(&b.length_squared()))
        .and_then(|r| r.try_normalize())
        .unwrap_or_else(|| axis.any_orthonormal_vector());
    let v = axis.cross(u);
    let mut directions = vec![axis, -axis];
    for k in 0..8 {
        let (s, c) = (f64::from(k) * std::f64::consts::FRAC_PI_4).sin_cos();
        directions.push(c * u + s * v);
    }
    directions
        .into_iter()
        .map(|n| HalfSpace {
            n,
            d: points
                .iter()
                .map(|&p| n.dot(p))
                .fold(f64::NEG_INFINITY, f64::max),
        })
        .collect()
}

/// The solid `planes` cut by the half-space `cut`: its vertices (each plane triple's meeting
/// point inside all the others, merged within rounding) and its faces other than `cut`.
pub fn clip(planes: &[HalfSpace], cut: HalfSpace, scale: f64) -> ClippedHull {
    let tol = ON_PLANE * scale;
    let all: Vec<HalfSpace> = planes.iter().copied().chain([cut]).collect();
    let mut vertices: Vec<DVec3> = Vec::new();
    let k = all.len();
    for i in 0..k {
        for j in i + 1..k {
            for l in j + 1..k {
                let (a, b, c) = (all[i], all[j], all[l]);
                let bc = b.n.cross(c.n);
                let det = a.n.dot(bc);
                if det.abs() <= 1e-9 {
                    continue;
                }
                let p = (a.d * bc + b.d * c.n.cross(a.n) + c.d * a.n.cross(b.n)) / det;
                if !p.is_finite() || all.iter().any(|h| h.signed_distance(p) > 10.0 * tol) {
                    continue;
                }
                if !vertices.iter().any(|q| q.distance(p) <= 100.0 * tol) {
                    vertices.push(p);
                }
            }
        }
    }
    let faces = planes
        .iter()
        .filter(|h| {
            vertices
                .iter()
                .filter(|&&p| h.signed_distance(p).abs() <= 10.0 * tol)
                .count()
                >= 3
        })
        .copied()
        .collect();
    ClippedHull { vertices, faces }
}

/// The diagonal of the points' bounding box.
pub fn diameter(points: &[DVec3]) -> f64 {
    let (lo, hi) = points.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    (hi - lo).length()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube() -> Vec<DVec3> {
        let mut points = vec![];
        for i in 0..8 {
            points.push(DVec3::new(
                f64::from(i & 1),
                f64::from((i >> 1) & 1),
                f64::from((i >> 2) & 1),
            ));
        }
        // An inner point, which is no vertex of the hull.
        points.push(DVec3::splat(0.5));
        points
    }

    #[test]
    fn cube_hull_has_six_faces_and_eight_vertices() {
        let points = cube();
        let faces = bounding_half_spaces(&points, HullKind::Exact).unwrap();
        assert_eq!(faces.len(), 6, "{faces:?}");
        // Cut at z <= 0.25: eight vertices, five faces besides the cut.
        let cut = HalfSpace {
            n: DVec3::Z,
            d: 0.25,
        };
        let clipped = clip(&faces, cut, 1.0);
        assert_eq!(clipped.vertices.len(), 8);
        assert!(clipped.vertices.iter().all(|v| v.z <= 0.25 + 1e-12));
        assert_eq!(clipped.faces.len(), 5);
    }

    #[test]
    fn flat_points_get_their_outline() {
        // A flat L shape: its hull is a pentagon with two faces (both sides) and five sides.
        let points: Vec<DVec3> = [
            (0.0, 0.0),
            (2.0, 0.0),
            (2.0, 1.0),
            (1.0, 1.0),
            (1.0, 2.0),
            (0.0, 2.0),
        ]
        .iter()
        .map(|&(x, y)| DVec3::new(x, y, 3.0))
        .collect();
        let faces = bounding_half_spaces(&points, HullKind::Exact).unwrap();
        assert_eq!(faces.len(), 2 + 5, "{faces:?}");
        let cut = HalfSpace {
            n: DVec3::Z,
            d: 10.0,
        };
        let clipped = clip(&faces, cut, 2.0);
        assert_eq!(clipped.vertices.len(), 5);
    }

    #[test]
    fn prism_holds_every_point() {
        let points: Vec<DVec3> = (0..200)
            .map(|i| {
                let t = f64::from(i) * 0.37;
                DVec3::new(4.0 * t.sin(), 0.3 * (3.0 * t).cos(), 0.2 * (5.0 * t).sin())
            })
            .collect();
        let planes = bounding_half_spaces(&points, HullKind::Exact).unwrap();
        assert_eq!(planes.len(), 10);
        let scale = diameter(&points);
        let clipped = clip(
            &planes,
            HalfSpace {
                n: DVec3::Y,
                d: 100.0,
            },
            scale,
        );
        assert_eq!(clipped.vertices.len(), 16);
        for p in &points {
            assert!(planes.iter().all(|h| h.signed_distance(*p) <= 1e-12));
        }
    }

    #[test]
    fn collinear_points_have_no_solid() {
        let points: Vec<DVec3> = (0..5).map(|i| DVec3::X * f64::from(i)).collect();
        assert!(bounding_half_spaces(&points, HullKind::Exact).is_none());
    }
}
