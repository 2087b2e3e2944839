//! The antishadow of a (portal, light) pair: which of the regions of `docs/method.md` (§2) a shading point
//! `x` lies in, decided by precomputed planes through an edge of one polygon and a vertex of the
//! other ([`AntishadowPlanes`]), and by an independent brute-force classifier that projects the
//! light through the portal ([`classify_brute_force`]) to test it against.
//!
//! Conventions: the portal's normal is its front (pointing away from the light); the light's
//! normal is its emitting side, facing the portal. `C(x)` are the directions from `x` that hit
//! the part of the light behind the portal plane, `D(x)` those through the portal.
//!
//! The planes are built in f64 from the f32 vertices and rounded once: planes through a short
//! edge, or through a vertex that rounding left a hair off the other polygon's plane, would
//! otherwise tilt by up to 1e-3 rad.

use glam::{DVec3, Vec3, Vec4};

use super::hull::{self, HalfSpace, HullKind};
use crate::sampling::polygon::{ConvexPolygon, MAX_CLIP_VERTICES, Plane, Verts, merge_close_by};

/// Where `x` lies relative to one portal of a light.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Region {
    /// Not strictly in front of the portal plane: the portal is irrelevant to `x`.
    Behind,
    /// `C ∩ D` is empty (or `x` is not on the light's emitting side).
    Outside,
    /// `C ⊆ D`: every path to the light goes through the portal.
    Antiumbra,
    /// `C ∩ D` non-empty, neither contains the other.
    Antipenumbra,
    /// `D ⊆ C`: every direction through the portal hits the light.
    Antiantumbra,
}

impl Region {
    pub const ALL: [Region; 5] = [
        Region::Behind,
        Region::Outside,
        Region::Antiumbra,
        Region::Antipenumbra,
        Region::Antiantumbra,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Region::Behind => "behind",
            Region::Outside => "outside",
            Region::Antiumbra => "antiumbra",
            Region::Antipenumbra => "antipenumbra",
            Region::Antiantumbra => "antiantumbra",
        }
    }
}

/// Why no antishadow planes exist for a (portal, light) pair; the caller names the nodes.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AntishadowError {
    #[error(
        "no part of the light lies behind the portal's plane (the portal's front must face away from the light)"
    )]
    LightInFrontOfPortal,
    #[error("the portal is not wholly on the light's emitting side")]
    PortalBehindLight,
    #[error("degenerate portal and light: no {0} plane could be built")]
    Degenerate(&'static str),
}

/// Relative to the scene's diameter: how far a vertex must be behind (in front of) a plane to
/// count as strictly behind (in front), and how close clipped light vertices are merged.
const STRICT_TOLERANCE: f64 = 1e-5;
/// Relative to the scene's diameter: a vertex this close to an edge's line spans no plane.
const COLLINEAR_TOLERANCE: f64 = 1e-6;
/// Relative to the scene's diameter: slack when checking (in f64) that each chosen plane has
/// every vertex of the other polygon on its required side. Violations are ~1e-15 in practice.
const SIDE_TOLERANCE: f64 = 1e-6;
/// Relative to the scene's diameter: how close (in f32) a vertex must be to a plane to count as
/// lying on it in [`AntishadowPlanes::volume_edges`].
const ON_PLANE_TOLERANCE: f32 = 1e-4;

/// One plane per edge; a clipped light has at most `MAX_POLYGON_VERTICES + 1` edges.
type Planes = arrayvec::ArrayVec<Plane, MAX_CLIP_VERTICES>;

/// The planes that bound the antishadow volumes of one (portal, light) pair, computed once;
/// [`AntishadowPlanes::classify`] then costs at most `2(|P| + |L|) + 2` dot products, `|L|`
/// counting the vertices of the light clipped behind the portal plane (at most one more than
/// the light's), the 2 for the portal and light planes.
#[derive(Clone, Debug)]
pub struct AntishadowPlanes {
    portal: ConvexPolygon,
    /// The light clipped to behind the portal plane, counter-clockwise around the light normal.
    light_behind: Verts,
    /// Positive in front of the portal.
    portal_plane: Plane,
    /// Positive on the light's emitting side.
    light_plane: Plane,
    /// One per portal edge `(p_i, p_{i+1})`; positive on the portal's side.
    antiumbra: Planes,
    portal_overlap: Planes,
    /// One per edge `(l_j, l_{j+1})` of `light_behind`; the light is on their negative side.
    antiantumbra: Planes,
    light_overlap: Planes,
    /// Diameter of portal and light together: the scale of every tolerance.
    scale: f32,
    /// For a light that is not one planar convex polygon: the planes through its bounding
    /// solid that replace the light-plane, light-overlap and antiantumbra planes (§3.6).
    hull: Option<Box<HullPlanes>>,
    /// Every plane above in lanes of four, tested at once by [`Self::classify`]; `None` for a
    /// solid with more than [`PlaneLanes::MAX`] planes, which is classified plane by plane.
    lanes: Option<PlaneLanes>,
}

/// The planes of [`AntishadowPlanes::classify`] in structure-of-arrays lanes of four: one
/// multiply-add chain per four planes, and the signs of all of them as one bit mask, instead
/// of a branch per plane (the per-point cost that light sampling does not pay). Each lane
/// computes `(n.x·x + n.y·y) + n.z·z − d` in the order of [`Plane::signed_distance`], so every
/// sign, and with it every region, is the plane-by-plane one exactly.
#[derive(Clone, Debug)]
struct PlaneLanes {
    /// Plane `i` is lane `i % 4` of chunk `i / 4`, and bit `i` of the masks; plane 0 is the
    /// portal's (`x` not strictly in front of it is behind).
    chunks: Vec<PlaneChunk>,
    /// The planes `x` must be strictly positive on not to be outside.
    overlap: u64,
    antiumbra: u64,
    antiantumbra: u64,
}

/// Four planes, coordinate by coordinate (the bits of unused lanes are in no group).
#[derive(Clone, Copy, Debug)]
struct PlaneChunk {
    nx: Vec4,
    ny: Vec4,
    nz: Vec4,
    d: Vec4,
}

impl PlaneLanes {
    /// The most planes one bit mask holds.
    const MAX: usize = 64;

    /// Lanes for the portal plane followed by the groups `overlap`, `antiumbra` and
    /// `antiantumbra`; `None` past [`Self::MAX`] planes.
    fn new(
        portal: Plane,
        overlap: &[&[Plane]],
        antiumbra: &[Plane],
        antiantumbra: &[Plane],
    ) -> Option<Self> {
        let mut planes = vec![portal];
        let group = |planes: &mut Vec<Plane>, members: &[Plane]| {
            let start = planes.len();
            planes.extend_from_slice(members);
            (start..planes.len()).fold(0u64, |mask, i| {
                mask | 1u64.checked_shl(i as u32).unwrap_or(0)
            })
        };
        let mut overlap_mask = 0;
        for members in overlap {
            overlap_mask |= group(&mut planes, members);
        }
        let antiumbra = group(&mut planes, antiumbra);
        let antiantumbra = group(&mut planes, antiantumbra);
        if planes.len() > Self::MAX {
            return None;
        }
        let chunks = planes
            .chunks(4)
            .map(|four| {
                let lane = |f: &dyn Fn(&Plane) -> f32| {
                    Vec4::from_array(std::array::from_fn(|k| four.get(k).map_or(0.0, f)))
                };
                PlaneChunk {
                    nx: lane(&|q| q.n.x),
                    ny: lane(&|q| q.n.y),
                    nz: lane(&|q| q.n.z),
                    d: lane(&|q| q.d),
                }
            })
            .collect();
        Some(PlaneLanes {
            chunks,
            overlap: overlap_mask,
            antiumbra,
            antiantumbra,
        })
    }

    /// The region from the signs of all planes at `x` (as [`AntishadowPlanes::classify`]).
    #[inline(always)]
    fn classify(&self, x: Vec3) -> Region {
        let (px, py, pz) = (Vec4::splat(x.x), Vec4::splat(x.y), Vec4::splat(x.z));
        let mut positive = 0u64;
        for (k, c) in self.chunks.iter().enumerate() {
            let s = c.nx * px + c.ny * py + c.nz * pz - c.d;
            positive |= u64::from(s.cmpgt(Vec4::ZERO).bitmask()) << (4 * k);
            // Most points behind a portal are known from its plane alone.
            if k == 0 && positive & 1 == 0 {
                return Region::Behind;
            }
        }
        let all = |mask: u64| positive & mask == mask;
        if !all(self.overlap) {
            Region::Outside
        } else if all(self.antiumbra) {
            Region::Antiumbra
        } else if all(self.antiantumbra) {
            Region::Antiantumbra
        } else {
            Region::Antipenumbra
        }
    }
}

/// The planes of a (portal, solid light) pair beyond those of the portal's edges.
#[derive(Clone, Debug)]
struct HullPlanes {
    /// Planes with the portal on their positive side and the solid on their negative side:
    /// faces of the solid, and planes through a portal vertex and two solid vertices. `x` on
    /// the negative side of one of them sees no part of the solid through the portal.
    outside: Vec<Plane>,
    /// Planes through a portal vertex and two solid vertices, the solid on their negative
    /// side: `x` positive on all of them sees the solid through every portal vertex.
    antiantumbra: Vec<Plane>,
}

/// An edge of the antiumbra or antiantumbra volume: the segment from a portal vertex to a light
/// vertex that lies on both planes of that volume meeting at the portal (light) vertex. Extended
/// beyond the portal it bounds the volume in front of the portal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumeEdge {
    pub portal_vertex: Vec3,
    pub light_vertex: Vec3,
    /// [`Region::Antiumbra`] or [`Region::Antiantumbra`].
    pub region: Region,
}

impl AntishadowPlanes {
    /// Builds the planes of `docs/method.md` §3 for `portal`
    /// (normal = front, away from the light) and `light` (normal = emitting side, toward the
    /// portal).
    pub fn new(portal: &ConvexPolygon, light: &ConvexPolygon) -> Result<Self, AntishadowError> {
        let scale = f64::from(diameter(portal.vertices().iter().chain(light.vertices())));
        let strict = STRICT_TOLERANCE * scale;
        let (portal_plane, light_plane) = (PlaneF64::of(portal), PlaneF64::of(light));
        // The portal is a window in its plane (the brute force clips with prisms perpendicular
        // to it), so its vertices are put exactly on it.
        let portal_vertices: Vec<DVec3> = portal
            .vertices()
            .iter()
            .map(|v| portal_plane.project(v.as_dvec3()))
            .collect();
        let light_vertices: Vec<DVec3> = light.vertices().iter().map(|v| v.as_dvec3()).collect();

        // The method's precondition: only the light behind the portal plane is seen through it.
        let deepest = light_vertices
            .iter()
            .map(|&l| -portal_plane.signed_distance(l))
            .fold(f64::NEG_INFINITY, f64::max);
        // Vertices are finite (`ConvexPolygon` checks), so no NaN reaches these comparisons.
        if deepest <= strict {
            return Err(AntishadowError::LightInFrontOfPortal);
        }
        let light_behind = merge_close(&clip_f64(&light_vertices, portal_plane.flipped()), strict);
        if light_behind.len() < 3 {
            return Err(AntishadowError::LightInFrontOfPortal);
        }
        if light_behind.len() > MAX_CLIP_VERTICES {
            return Err(AntishadowError::Degenerate("clipped light"));
        }

        let (lowest, highest) = portal_vertices
            .iter()
            .map(|&p| light_plane.signed_distance(p))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), h| {
                (lo.min(h), hi.max(h))
            });
        if lowest < -strict || highest <= strict {
            return Err(AntishadowError::PortalBehindLight);
        }

        let (antiumbra, portal_overlap) = edge_planes(
            &portal_vertices,
            portal_plane.n,
            -1.0,
            &light_behind,
            scale,
            "antiumbra",
        )?;
        let (light_overlap, antiantumbra) = edge_planes(
            &light_behind,
            light_plane.n,
            1.0,
            &portal_vertices,
            scale,
            "antiantumbra",
        )?;
        // By the construction the antiumbra planes keep the light on their positive side and
        // the antiantumbra planes keep the portal on their negative side; overlap planes the
        // reverse. Check it, so that a numerical surprise is an error and not a wrong region.
        let tol = SIDE_TOLERANCE * scale;
        let all = |planes: &[PlaneF64], vertices: &[DVec3], sign: f64| {
            planes.iter().all(|q| {
                vertices
                    .iter()
                    .all(|&v| sign * q.signed_distance(v) >= -tol)
            })
        };
        if !all(&antiumbra, &light_behind, 1.0) || !all(&antiantumbra, &portal_vertices, -1.0) {
            return Err(AntishadowError::Degenerate("antiumbra or antiantumbra"));
        }
        if !all(&portal_overlap, &light_behind, -1.0) || !all(&light_overlap, &portal_vertices, 1.0)
        {
            return Err(AntishadowError::Degenerate("overlap"));
        }

        let to_f32 = |planes: &[PlaneF64]| planes.iter().map(|q| q.to_f32()).collect::<Planes>();
        Ok(AntishadowPlanes {
            portal: portal.clone(),
            light_behind: light_behind.iter().map(|v| v.as_vec3()).collect(),
            portal_plane: portal_plane.to_f32(),
            light_plane: light_plane.to_f32(),
            antiumbra: to_f32(&antiumbra),
            portal_overlap: to_f32(&portal_overlap),
            antiantumbra: to_f32(&antiantumbra),
            light_overlap: to_f32(&light_overlap),
            scale: scale as f32,
            hull: None,
            lanes: None,
        }
        .with_lanes())
    }

    /// The planes for a light of any shape (`docs/method.md` §3.6): `light_points` are its
    /// vertices; the solid that stands in for it is their convex hull, or a prism holding them
    /// when the hull seen from a point would have too many vertices to project and clip. The
    /// solid is cut behind the portal plane; the portal-edge planes are those of §3.2 against
    /// its vertices; the others come from the solid's faces and from the planes through a
    /// portal vertex and two of its vertices that leave it on one side.
    pub fn new_hull(
        portal: &ConvexPolygon,
        light_points: &[Vec3],
    ) -> Result<Self, AntishadowError> {
        let scale = f64::from(diameter(portal.vertices().iter().chain(light_points)));
        let strict = STRICT_TOLERANCE * scale;
        let tol = SIDE_TOLERANCE * scale;
        let portal_plane = PlaneF64::of(portal);
        let portal_vertices: Vec<DVec3> = portal
            .vertices()
            .iter()
            .map(|v| portal_plane.project(v.as_dvec3()))
            .collect();
        let points = hull::distinct_points(light_points.iter().map(|v| v.as_dvec3()));
        let deepest = points
            .iter()
            .map(|&l| -portal_plane.signed_distance(l))
            .fold(f64::NEG_INFINITY, f64::max);
        if deepest.is_nan() || deepest <= strict {
            return Err(AntishadowError::LightInFrontOfPortal);
        }
        // Behind the portal plane: `n · p <= d` for the plane's front normal.
        let cut = HalfSpace {
            n: portal_plane.n,
            d: portal_plane.d,
        };
        // Room for the solid's silhouette and the portal's edges in one clipped projection.
        let room = MAX_CLIP_VERTICES - portal_vertices.len();
        let mut behind = None;
        for kind in [HullKind::Exact, HullKind::Prism] {
            let planes = hull::bounding_half_spaces(&points, kind)
                .ok_or(AntishadowError::Degenerate("light hull"))?;
            let clipped = hull::clip(&planes, cut, hull::diameter(&points));
            if clipped.vertices.len() <= room {
                behind = Some(clipped);
                break;
            }
        }
        let Some(clipped) = behind else {
            return Err(AntishadowError::Degenerate("light hull"));
        };
        let solid = clipped.vertices;
        if solid.len() < 3 {
            return Err(AntishadowError::LightInFrontOfPortal);
        }
        let (antiumbra, portal_overlap) = edge_planes(
            &portal_vertices,
            portal_plane.n,
            -1.0,
            &solid,
            scale,
            "antiumbra",
        )?;
        let portal_side = |q: &PlaneF64| {
            portal_vertices
                .iter()
                .all(|&p| q.signed_distance(p) >= -tol)
        };
        let mut outside: Vec<PlaneF64> = clipped
            .faces
            .iter()
            .map(|h| PlaneF64 { n: h.n, d: h.d })
            .filter(|q| portal_side(q))
            .collect();
        let mut antiantumbra: Vec<PlaneF64> = Vec::new();
        let add = |list: &mut Vec<PlaneF64>, q: PlaneF64| {
            if !list
                .iter()
                .any(|o| o.n.dot(q.n) > 1.0 - 1e-10 && (o.d - q.d).abs() <= tol)
            {
                list.push(q);
            }
        };
        for &p in &portal_vertices {
            for i in 0..solid.len() {
                for k in i + 1..solid.len() {
                    let (a, b) = (solid[i] - p, solid[k] - p);
                    let m = a.cross(b);
                    if m.length() <= COLLINEAR_TOLERANCE * a.length() * b.length() {
                        continue;
                    }
                    let m = m.normalize();
                    let (lo, hi) = solid
                        .iter()
                        .map(|&v| m.dot(v - p))
                        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), h| {
                            (lo.min(h), hi.max(h))
                        });
                    // Oriented with the solid on the negative side; planes through it skipped.
                    let n = if hi <= tol {
                        m
                    } else if lo >= -tol {
                        -m
                    } else {
                        continue;
                    };
                    let q = PlaneF64 { n, d: n.dot(p) };
                    if portal_side(&q) {
                        add(&mut outside, q);
                    }
                    add(&mut antiantumbra, q);
                }
            }
        }
        let to_f32 = |planes: &[PlaneF64]| planes.iter().map(|q| q.to_f32()).collect::<Planes>();
        let to_vec = |planes: &[PlaneF64]| planes.iter().map(|q| q.to_f32()).collect::<Vec<_>>();
        Ok(AntishadowPlanes {
            portal: portal.clone(),
            light_behind: solid.iter().map(|v| v.as_vec3()).collect(),
            portal_plane: portal_plane.to_f32(),
            // Unused for a solid (its faces are among the outside planes).
            light_plane: portal_plane.flipped().to_f32(),
            antiumbra: to_f32(&antiumbra),
            portal_overlap: to_f32(&portal_overlap),
            antiantumbra: Planes::new(),
            light_overlap: Planes::new(),
            scale: scale as f32,
            hull: Some(Box::new(HullPlanes {
                outside: to_vec(&outside),
                antiantumbra: to_vec(&antiantumbra),
            })),
            lanes: None,
        }
        .with_lanes())
    }

    /// The planes in lanes for [`Self::classify`], in the groups of its tests.
    fn with_lanes(mut self) -> Self {
        self.lanes = match &self.hull {
            None => PlaneLanes::new(
                self.portal_plane,
                &[
                    &[self.light_plane],
                    &self.portal_overlap,
                    &self.light_overlap,
                ],
                &self.antiumbra,
                &self.antiantumbra,
            ),
            Some(hull) => PlaneLanes::new(
                self.portal_plane,
                &[&self.portal_overlap, &hull.outside],
                &self.antiumbra,
                &hull.antiantumbra,
            ),
        };
        self
    }

    /// Whether the light is a solid (§3.6) rather than one planar convex polygon: its clipped
    /// vertices are then a point set whose projection must be hulled.
    pub fn is_hull(&self) -> bool {
        self.hull.is_some()
    }

    /// The region of `x`, in the order of `docs/method.md` §3.3. Points on a plane count as outside the
    /// volume it bounds; a NaN `x` is [`Region::Behind`]. No allocation. The planes' signs are
    /// taken four at a time; the region is exactly [`Self::classify_plane_by_plane`]'s.
    #[inline(always)]
    pub fn classify(&self, x: Vec3) -> Region {
        match &self.lanes {
            Some(lanes) => lanes.classify(x),
            None => self.classify_plane_by_plane(x),
        }
    }

    /// [`Self::classify`] one plane at a time, leaving as soon as the region is known: for a
    /// solid with too many planes for the lanes, and the unit test's oracle.
    #[inline(always)]
    pub fn classify_plane_by_plane(&self, x: Vec3) -> Region {
        let positive = |q: &Plane| q.signed_distance(x) > 0.0;
        if !positive(&self.portal_plane) {
            return Region::Behind;
        }
        if let Some(hull) = &self.hull {
            return if !self.portal_overlap.iter().all(positive)
                || !hull.outside.iter().all(positive)
            {
                Region::Outside
            } else if self.antiumbra.iter().all(positive) {
                Region::Antiumbra
            } else if hull.antiantumbra.iter().all(positive) {
                Region::Antiantumbra
            } else {
                Region::Antipenumbra
            };
        }
        // The pencil arguments behind the light-edge planes need x on the emitting side.
        if !positive(&self.light_plane) {
            return Region::Outside;
        }
        if !self.portal_overlap.iter().all(positive) || !self.light_overlap.iter().all(positive) {
            return Region::Outside;
        }
        if self.antiumbra.iter().all(positive) {
            Region::Antiumbra
        } else if self.antiantumbra.iter().all(positive) {
            Region::Antiantumbra
        } else {
            Region::Antipenumbra
        }
    }

    /// The light clipped to behind the portal plane (counter-clockwise around the light normal);
    /// for a solid light ([`Self::is_hull`]), the vertices of its solid behind that plane.
    pub fn light_behind_portal(&self) -> &[Vec3] {
        &self.light_behind
    }

    /// Whether the light behind the portal, projected from `x` (in front of the portal) onto
    /// the portal's plane, winds counter-clockwise as seen from `x`: a projection from `x`
    /// keeps the winding seen from `x`, so a polygon light's (counter-clockwise around its
    /// normal) does where `x` is on its emitting side, and a solid's outline is hulled
    /// counter-clockwise around the portal's normal, which points towards `x`.
    #[inline(always)]
    pub fn projection_winds_counter_clockwise(&self, x: Vec3) -> bool {
        self.hull.is_some() || self.light_plane.signed_distance(x) > 0.0
    }

    /// The diameter of portal and light together, which every tolerance is relative to.
    pub fn scale(&self) -> f32 {
        self.scale
    }

    /// Positive in front of the portal.
    pub fn portal_plane(&self) -> Plane {
        self.portal_plane
    }

    /// Positive on the light's emitting side.
    pub fn light_plane(&self) -> Plane {
        self.light_plane
    }

    /// The smallest `|signed distance|` from `x` to any plane [`Self::classify`] tests: near 0,
    /// a tiny error in `x` or in the planes may change the region.
    pub fn planes_distance(&self, x: Vec3) -> f32 {
        [self.portal_plane, self.light_plane]
            .iter()
            .chain(&self.antiumbra)
            .chain(&self.portal_overlap)
            .chain(&self.antiantumbra)
            .chain(&self.light_overlap)
            .chain(
                self.hull
                    .iter()
                    .flat_map(|h| h.outside.iter().chain(&h.antiantumbra)),
            )
            .map(|q| q.signed_distance(x).abs())
            .fold(f32::INFINITY, f32::min)
    }

    /// Edges of the antiumbra and antiantumbra volumes, for drawing (best effort): a segment
    /// `portal vertex → light vertex` is returned for a volume when the light (portal) vertex
    /// lies, within tolerance, on both of that volume's planes through the portal (light)
    /// vertex. When those two planes pass through different vertices of the other polygon,
    /// they meet in a line through neither, and nothing is returned for that corner. A segment
    /// may be returned for both volumes (aligned polygons, where their planes coincide).
    pub fn volume_edges(&self) -> impl Iterator<Item = VolumeEdge> + '_ {
        let tol = ON_PLANE_TOLERANCE * self.scale;
        let on_both = move |a: &Plane, b: &Plane, v: Vec3| {
            a.signed_distance(v).abs() <= tol && b.signed_distance(v).abs() <= tol
        };
        let portal = self.portal.vertices();
        let light = &self.light_behind[..];
        // A solid's antiantumbra planes are not one per light edge: only antiumbra edges.
        let (np, nl) = (portal.len(), light.len());
        let nl_edges = if self.hull.is_some() { 0 } else { nl };
        // Vertex i is shared by edges i - 1 and i, whose planes are stored at those indices.
        let antiumbra = (0..np).flat_map(move |i| {
            let (a, b) = (&self.antiumbra[(i + np - 1) % np], &self.antiumbra[i]);
            light
                .iter()
                .filter(move |&&l| on_both(a, b, l))
                .map(move |&l| VolumeEdge {
                    portal_vertex: portal[i],
                    light_vertex: l,
                    region: Region::Antiumbra,
                })
        });
        let antiantumbra = (0..nl_edges).flat_map(move |j| {
            let (a, b) = (&self.antiantumbra[(j + nl - 1) % nl], &self.antiantumbra[j]);
            portal
                .iter()
                .filter(move |&&p| on_both(a, b, p))
                .map(move |&p| VolumeEdge {
                    portal_vertex: p,
                    light_vertex: light[j],
                    region: Region::Antiantumbra,
                })
        });
        antiumbra.chain(antiantumbra)
    }
}

/// A plane in f64, `n · p = d` with `n` of unit length.
#[derive(Clone, Copy, Debug)]
struct PlaneF64 {
    n: DVec3,
    d: f64,
}

impl PlaneF64 {
    /// A polygon's plane, through its vertices' mean, with `n` from Newell's formula around the
    /// first vertex. ([`ConvexPolygon::normal`] sums cross products of absolute positions, which
    /// for a polygon far from the origin relative to its size costs digits: 5e-6 rad was seen.)
    fn of(polygon: &ConvexPolygon) -> Self {
        let vertices = polygon.vertices();
        let v0 = vertices[0].as_dvec3();
        let twice_area: DVec3 = vertices
            .windows(2)
            .skip(1)
            .map(|w| (w[0].as_dvec3() - v0).cross(w[1].as_dvec3() - v0))
            .sum();
        // The winding fixes the orientation; `ConvexPolygon` guarantees a non-zero area.
        let n = twice_area
            .try_normalize()
            .unwrap_or(polygon.normal().as_dvec3());
        let mean = vertices.iter().map(|v| v.as_dvec3()).sum::<DVec3>() / vertices.len() as f64;
        PlaneF64 { n, d: n.dot(mean) }
    }

    fn signed_distance(&self, p: DVec3) -> f64 {
        self.n.dot(p) - self.d
    }

    fn flipped(self) -> Self {
        PlaneF64 {
            n: -self.n,
            d: -self.d,
        }
    }

    fn project(&self, p: DVec3) -> DVec3 {
        p - self.n * self.signed_distance(p)
    }

    fn to_f32(self) -> Plane {
        let n = self.n.as_vec3();
        // Offset through the plane's point nearest the origin, for the rounded normal.
        let d = n.as_dvec3().dot(self.n * self.d);
        Plane { n, d: d as f32 }
    }
}

/// For each edge `(a, b)` of the polygon `vertices` (counter-clockwise around `normal`), the two
/// extreme planes of the pencil through `a`, `b` and each vertex of `other`: first the one with
/// all of `other` on its positive side, then the one with all of `other` on its negative side.
/// `other` lies on the side `side · normal` (within rounding): -1 for the portal, whose light is
/// behind it, giving (antiumbra, overlap) planes positive on the portal's side; +1 for the light,
/// whose portal is on its emitting side, giving (overlap, antiantumbra) planes with the light on
/// their negative side.
///
/// In the cross-section across the edge, with `u = normal × e` pointing into the polygon and
/// `v = normal`, a candidate through `o` at angle θ (from `u` toward `v`) has the normal
/// `e × (o − a) ∝ −sin θ·u + cos θ·v`, which is the orientation `docs/method.md` §3.2 asks for, and `o'` is
/// on its positive side iff `sin(θ' − θ) > 0`. As all of `other` lies in one half-plane, the
/// planes sought are the candidates of smallest and largest θ. Choosing by angle rather than by
/// testing each candidate's sides also handles vertices on the polygon's own plane (a light
/// clipped by the portal plane), where the candidate is that plane and orienting it by the
/// centroid is undefined. The angle is measured from the middle of the half-plane, `side · v`,
/// with `atan2`: `cos θ` would be flat at the half-plane's edges, exactly where such vertices are.
fn edge_planes(
    vertices: &[DVec3],
    normal: DVec3,
    side: f64,
    other: &[DVec3],
    scale: f64,
    what: &'static str,
) -> Result<(Vec<PlaneF64>, Vec<PlaneF64>), AntishadowError> {
    let n = vertices.len();
    let mut first = Vec::with_capacity(n);
    let mut second = Vec::with_capacity(n);
    for i in 0..n {
        let (a, b) = (vertices[i], vertices[(i + 1) % n]);
        let e = (b - a).normalize_or_zero();
        let u = normal.cross(e);
        let mut lowest: Option<(f64, DVec3)> = None;
        let mut highest: Option<(f64, DVec3)> = None;
        for &o in other {
            let w = o - a;
            let w_perp = w - e * w.dot(e);
            let len = w_perp.length();
            // `o` on the edge's line spans no plane; the other vertices decide.
            if len <= COLLINEAR_TOLERANCE * scale {
                continue;
            }
            // θ minus the angle of `side · v`, in (-π, π]; it wraps only straight opposite.
            let theta = (-side * w_perp.dot(u)).atan2(side * w_perp.dot(normal));
            let m = e.cross(w_perp) / len;
            if lowest.is_none_or(|(t, _)| theta < t) {
                lowest = Some((theta, m));
            }
            if highest.is_none_or(|(t, _)| theta > t) {
                highest = Some((theta, m));
            }
        }
        let (Some((_, lo)), Some((_, hi))) = (lowest, highest) else {
            return Err(AntishadowError::Degenerate(what));
        };
        first.push(PlaneF64 {
            n: lo,
            d: lo.dot(a),
        });
        second.push(PlaneF64 {
            n: hi,
            d: hi.dot(a),
        });
    }
    Ok((first, second))
}

/// Sutherland–Hodgman in f64: keeps the part of `vertices` on the positive side of `plane`.
/// Cut points land on the plane to f64 precision, which the plane construction relies on.
fn clip_f64(vertices: &[DVec3], plane: PlaneF64) -> Vec<DVec3> {
    let mut out = Vec::with_capacity(vertices.len() + 1);
    let k = vertices.len();
    for i in 0..k {
        let (a, b) = (vertices[i], vertices[(i + 1) % k]);
        let (da, db) = (plane.signed_distance(a), plane.signed_distance(b));
        if da >= 0.0 {
            out.push(a);
        }
        if (da >= 0.0) != (db >= 0.0) {
            out.push(a + da / (da - db) * (b - a));
        }
    }
    out
}

/// Drops vertices within `tol` of their predecessor: clipping repeats a vertex that lies on
/// the plane, and a very short edge would give planes with an ill-defined direction.
fn merge_close(vertices: &[DVec3], tol: f64) -> Vec<DVec3> {
    let mut out = vertices.to_vec();
    let kept = merge_close_by(&mut out, |a, b| a.distance(b) <= tol);
    out.truncate(kept);
    out
}

fn diameter<'a>(points: impl Iterator<Item = &'a Vec3>) -> f32 {
    let (lo, hi) = points.fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| {
        (lo.min(p), hi.max(p))
    });
    (hi - lo).length().max(f32::MIN_POSITIVE)
}

/// Relative area tolerance of [`classify_brute_force`]: the overlap counts as empty below
/// `BRUTE_FORCE_AREA_TOLERANCE` times the smaller of the two areas, and as the whole of the
/// projected light (the portal) within that fraction of its area. Near a plane the overlap grows
/// with the square of the distance from it, scaled down by the ratio of the light's depth to
/// x's height, so relative areas of 1e-9 occur a thousandth of the scene size from a plane;
/// f64 rounding (about 1e-15 here) stays far below.
pub const BRUTE_FORCE_AREA_TOLERANCE: f64 = 1e-12;

/// The region of `x` found without the planes: project the part of `light` behind the portal
/// plane from `x` onto that plane, clip it against the portal and compare the areas of the
/// projection, the portal and their intersection. A slow reference for tests, computed in f64
/// from the f32 inputs: in f32 the areas of thin overlaps drown in rounding.
pub fn classify_brute_force(portal: &ConvexPolygon, light: &ConvexPolygon, x: Vec3) -> Region {
    let x = x.as_dvec3();
    let (portal_plane, light_plane) = (PlaneF64::of(portal), PlaneF64::of(light));
    let height = portal_plane.signed_distance(x);
    // Written as "in front" tests so that a NaN x is behind, as in `classify`.
    let in_front_of_portal = height > 0.0;
    if !in_front_of_portal {
        return Region::Behind;
    }
    let on_emitting_side = light_plane.signed_distance(x) > 0.0;
    if !on_emitting_side {
        return Region::Outside;
    }
    let light_vertices: Vec<DVec3> = light.vertices().iter().map(|v| v.as_dvec3()).collect();
    let behind = clip_f64(&light_vertices, portal_plane.flipped());
    if behind.len() < 3 {
        return Region::Outside;
    }
    overlap_region(portal, portal_plane, x, &behind, false)
}

/// [`classify_brute_force`] for a solid light (§3.6): `solid` are the vertices of its solid
/// behind the portal plane ([`AntishadowPlanes::light_behind_portal`]); their projection from
/// `x` is hulled before it is clipped.
pub fn classify_brute_force_hull(portal: &ConvexPolygon, solid: &[Vec3], x: Vec3) -> Region {
    let x = x.as_dvec3();
    let portal_plane = PlaneF64::of(portal);
    // Written as an "in front" test so that a NaN x is behind, as in `classify`.
    let in_front_of_portal = portal_plane.signed_distance(x) > 0.0;
    if !in_front_of_portal {
        return Region::Behind;
    }
    let solid: Vec<DVec3> = solid.iter().map(|v| v.as_dvec3()).collect();
    overlap_region(portal, portal_plane, x, &solid, true)
}

/// The region from the areas of the projection of `behind` (points behind the portal plane,
/// a convex polygon in order unless `hull`), the portal and their intersection.
fn overlap_region(
    portal: &ConvexPolygon,
    portal_plane: PlaneF64,
    x: DVec3,
    behind: &[DVec3],
    hull: bool,
) -> Region {
    let height = portal_plane.signed_distance(x);
    // Central projection from x: each v is behind or on the plane and x strictly in front, so
    // the segment x→v crosses the plane once, at 0 < t <= 1.
    let projected: Vec<DVec3> = behind
        .iter()
        .map(|&v| x + height / (height - portal_plane.signed_distance(v)) * (v - x))
        .collect();
    let projected = if hull {
        hull_in_plane(&projected, portal_plane.n)
    } else {
        projected
    };
    if projected.len() < 3 {
        return Region::Outside;
    }
    // Sutherland–Hodgman against the prism over each portal edge: with counter-clockwise
    // vertices around the portal normal, `n × edge` points inward. The subject's winding does
    // not matter (it comes out either way, depending on x), as areas are taken unsigned.
    let portal_vertices: Vec<DVec3> = portal
        .vertices()
        .iter()
        .map(|v| portal_plane.project(v.as_dvec3()))
        .collect();
    let n = portal_vertices.len();
    let mut overlap = projected.clone();
    for i in 0..n {
        if overlap.len() < 3 {
            break;
        }
        let (a, b) = (portal_vertices[i], portal_vertices[(i + 1) % n]);
        let inward = portal_plane.n.cross(b - a).normalize_or_zero();
        overlap = clip_f64(
            &overlap,
            PlaneF64 {
                n: inward,
                d: inward.dot(a),
            },
        );
    }
    let area_c = fan_area(&projected);
    let area_d = fan_area(&portal_vertices);
    let area_cd = if overlap.len() < 3 {
        0.0
    } else {
        fan_area(&overlap)
    };
    let tol = BRUTE_FORCE_AREA_TOLERANCE;
    if area_cd <= tol * area_c.min(area_d) {
        Region::Outside
    } else if area_c - area_cd <= tol * area_c {
        Region::Antiumbra
    } else if area_d - area_cd <= tol * area_d {
        Region::Antiantumbra
    } else {
        Region::Antipenumbra
    }
}

/// The convex hull of points lying in the plane with normal `n`, counter-clockwise around it
/// (Andrew's monotone chain in f64).
fn hull_in_plane(points: &[DVec3], n: DVec3) -> Vec<DVec3> {
    let Some(&origin) = points.first() else {
        return Vec::new();
    };
    let u = n.any_orthonormal_vector();
    let v = n.cross(u);
    let mut flat: Vec<(f64, f64, DVec3)> = points
        .iter()
        .map(|&p| ((p - origin).dot(u), (p - origin).dot(v), p))
        .collect();
    flat.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let cross = |o: &(f64, f64, DVec3), a: &(f64, f64, DVec3), b: &(f64, f64, DVec3)| {
        (a.0 - o.0) * (b.1 - o.1) - (a.1 - o.1) * (b.0 - o.0)
    };
    let mut hull: Vec<(f64, f64, DVec3)> = Vec::with_capacity(2 * flat.len());
    for pass in 0..2 {
        let start = hull.len();
        for k in 0..flat.len() {
            let p = if pass == 0 {
                flat[k]
            } else {
                flat[flat.len() - 1 - k]
            };
            while hull.len() >= start + 2
                && cross(&hull[hull.len() - 2], &hull[hull.len() - 1], &p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull.into_iter().map(|h| h.2).collect()
}

/// The area of a convex polygon as a fan around its first vertex: relative coordinates keep
/// the rounding error proportional to the polygon's size, not to its distance from the origin.
fn fan_area(vertices: &[DVec3]) -> f64 {
    let Some(&v0) = vertices.first() else {
        return 0.0;
    };
    let twice: DVec3 = vertices
        .windows(2)
        .skip(1)
        .map(|w| (w[0] - v0).cross(w[1] - v0))
        .sum();
    0.5 * twice.length()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(center: Vec3, half: f32) -> ConvexPolygon {
        let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
        let points: Vec<Vec3> = corners
            .iter()
            .map(|&(a, b)| center + half * Vec3::new(a, b, 0.0))
            .collect();
        ConvexPolygon::new(&points).unwrap()
    }

    /// Portal [-1, 1]² at z = 0 facing +z; light [-2, 2]² at z = -1 facing +z. On the axis the
    /// light projects to half-width 2z / (z + 1): inside the portal below z = 1, around it above.
    fn aligned() -> (ConvexPolygon, ConvexPolygon) {
        (square(Vec3::ZERO, 1.0), square(-Vec3::Z, 2.0))
    }

    #[test]
    fn aligned_squares_hand_placed_points() {
        let (portal, light) = aligned();
        let planes = AntishadowPlanes::new(&portal, &light).unwrap();
        let cases = [
            (Vec3::new(0.0, 0.0, -0.5), Region::Behind),
            (Vec3::new(0.3, -0.2, -0.01), Region::Behind),
            (Vec3::new(0.0, 0.0, 0.5), Region::Antiumbra),
            (Vec3::new(0.2, 0.1, 0.2), Region::Antiumbra),
            (Vec3::new(0.0, 0.0, 3.0), Region::Antiantumbra),
            (Vec3::new(0.1, -0.1, 10.0), Region::Antiantumbra),
            (Vec3::new(1.0, 0.0, 0.5), Region::Antipenumbra),
            (Vec3::new(0.0, 2.0, 1.0), Region::Antipenumbra),
            (Vec3::new(10.0, 0.0, 0.5), Region::Outside),
            (Vec3::new(-5.0, 5.0, 0.2), Region::Outside),
        ];
        for (x, expected) in cases {
            assert_eq!(planes.classify(x), expected, "planes at {x}");
            assert_eq!(
                classify_brute_force(&portal, &light, x),
                expected,
                "brute force at {x}"
            );
        }
        // The on-axis switch from antiumbra to antiantumbra is at z = 1.
        assert_eq!(
            planes.classify(Vec3::new(0.0, 0.0, 0.99)),
            Region::Antiumbra
        );
        assert_eq!(
            planes.classify(Vec3::new(0.0, 0.0, 1.01)),
            Region::Antiantumbra
        );
        assert!(
            (planes.planes_distance(Vec3::new(0.0, 0.0, 0.99)) - 0.01 / 2f32.sqrt()).abs() < 1e-4
        );
    }

    #[test]
    fn outside_when_not_on_the_emitting_side() {
        // A light facing away from the portal's direction except for a sliver: tilt it so that
        // points in front of the portal can be behind the light's plane.
        let portal = square(Vec3::ZERO, 1.0);
        let tilted: Vec<Vec3> = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
            .iter()
            .map(|&(a, b)| Vec3::new(3.0 + 0.5 * a, b, -1.0 + 0.5 * a))
            .collect();
        let light = ConvexPolygon::new(&tilted).unwrap();
        // Normal ∝ (-1, 0, 1): emitting up and toward the portal.
        assert!(light.normal().x < 0.0 && light.normal().z > 0.0);
        let planes = AntishadowPlanes::new(&portal, &light).unwrap();
        let x = Vec3::new(6.0, 0.0, 0.5);
        assert!(planes.light_plane().signed_distance(x) < 0.0);
        assert_eq!(planes.classify(x), Region::Outside);
        assert_eq!(classify_brute_force(&portal, &light, x), Region::Outside);
    }

    #[test]
    fn errors() {
        let (portal, light) = aligned();
        // The portal facing the light: the light is in front of it.
        assert_eq!(
            AntishadowPlanes::new(&portal.flipped(), &light).unwrap_err(),
            AntishadowError::LightInFrontOfPortal
        );
        // The light emitting away from the portal.
        assert_eq!(
            AntishadowPlanes::new(&portal, &light.flipped()).unwrap_err(),
            AntishadowError::PortalBehindLight
        );
        // A light in the portal plane has nothing strictly behind it.
        assert_eq!(
            AntishadowPlanes::new(&portal, &square(Vec3::ZERO, 3.0)).unwrap_err(),
            AntishadowError::LightInFrontOfPortal
        );
        assert!(!AntishadowError::PortalBehindLight.to_string().is_empty());
    }

    #[test]
    fn light_straddling_the_portal_plane_is_clipped() {
        // The light tilted through the portal plane: only z <= 0 (x <= 1.2) of it remains.
        // (Not x <= 1: a clipped edge on a portal edge's line would make "D ⊆ C" hinge on
        // rounding everywhere, far from any plane.)
        let portal = square(Vec3::ZERO, 1.0);
        let points: Vec<Vec3> = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
            .iter()
            .map(|&(a, b)| Vec3::new(1.5 * a, 1.5 * b, -0.48 + 0.6 * a))
            .collect();
        let light = ConvexPolygon::new(&points).unwrap();
        let planes = AntishadowPlanes::new(&portal, &light).unwrap();
        assert!(planes.light_behind_portal().iter().all(|v| v.z <= 1e-6));
        assert!(
            planes
                .light_behind_portal()
                .iter()
                .any(|v| v.z.abs() <= 1e-6)
        );
        let mut seen = [0usize; 5];
        for i in 0..21 {
            for k in 0..21 {
                for z in [0.05, 0.3, 1.0, 3.0, 8.0] {
                    let x = Vec3::new(-5.0 + 0.5 * i as f32, -5.0 + 0.5 * k as f32, z);
                    if planes.planes_distance(x) < 1e-3 {
                        continue;
                    }
                    let region = planes.classify(x);
                    assert_eq!(region, classify_brute_force(&portal, &light, x), "at {x}");
                    seen[region as usize] += 1;
                }
            }
        }
        for region in [Region::Outside, Region::Antipenumbra, Region::Antiantumbra] {
            assert!(seen[region as usize] > 0, "{region:?} never seen: {seen:?}");
        }
    }

    #[test]
    fn aligned_volume_edges_join_corresponding_corners() {
        let (portal, light) = aligned();
        let planes = AntishadowPlanes::new(&portal, &light).unwrap();
        let edges: Vec<VolumeEdge> = planes.volume_edges().collect();
        for region in [Region::Antiumbra, Region::Antiantumbra] {
            let of_region: Vec<_> = edges.iter().filter(|e| e.region == region).collect();
            assert_eq!(of_region.len(), 4, "{region:?}: {edges:?}");
            for e in of_region {
                // Corresponding corners: the light corner is twice the portal corner, 1 below.
                let expected = Vec3::new(2.0 * e.portal_vertex.x, 2.0 * e.portal_vertex.y, -1.0);
                assert!(e.light_vertex.abs_diff_eq(expected, 1e-5), "{e:?}");
            }
        }
    }

    /// Solids of random points (a cloud, 6 to 40 of them, so some take the prism; a third
    /// straddling the portal plane) behind tilted portals: the planes agree with the brute force
    /// outside a thin band, and every region occurs.
    #[test]
    fn solid_planes_match_brute_force() {
        use crate::sampling::Rng;
        let mut rng = Rng::new(41, 42);
        let mut seen = [0usize; 5];
        let (mut compared, mut wrong_differs) = (0, 0);
        for trial in 0..60 {
            let tilt = Vec3::new(rng.uniform() - 0.5, 1.0, rng.uniform() - 0.5).normalize();
            let t = tilt.any_orthonormal_vector();
            let b = tilt.cross(t);
            let half = 0.05 + 0.4 * rng.uniform();
            let portal = ConvexPolygon::new(&[
                -half * t - half * b,
                half * t - half * b,
                half * t + half * b,
                -half * t + half * b,
            ])
            .unwrap();
            // The portal's front is +tilt; the cloud sits below it.
            let depth = if trial % 3 == 0 { 0.1 } else { 0.6 };
            let centre = Vec3::new(
                rng.uniform() - 0.5,
                -depth - 0.2 * rng.uniform(),
                rng.uniform() - 0.5,
            );
            let count = 6 + (rng.uniform() * 35.0) as usize;
            let points: Vec<Vec3> = (0..count)
                .map(|_| {
                    centre
                        + 0.6
                            * Vec3::new(
                                rng.uniform() - 0.5,
                                rng.uniform() - 0.5,
                                rng.uniform() - 0.5,
                            )
                })
                .collect();
            let Ok(planes) = AntishadowPlanes::new_hull(&portal, &points) else {
                continue;
            };
            assert!(planes.is_hull());
            // Negative case: the planes of a solid 3 % larger must disagree somewhere.
            let larger: Vec<Vec3> = points
                .iter()
                .map(|&p| centre + 1.03 * (p - centre))
                .collect();
            let wrong = AntishadowPlanes::new_hull(&portal, &larger).ok();
            for _ in 0..400 {
                let x = Vec3::new(
                    4.0 * (rng.uniform() - 0.5),
                    3.0 * rng.uniform() - 0.5,
                    4.0 * (rng.uniform() - 0.5),
                );
                if planes.planes_distance(x) < 1e-4 {
                    continue;
                }
                let region = planes.classify(x);
                let expected = classify_brute_force_hull(&portal, planes.light_behind_portal(), x);
                assert_eq!(region, expected, "trial {trial} at {x}");
                if wrong.as_ref().is_some_and(|w| w.classify(x) != expected) {
                    wrong_differs += 1;
                }
                seen[region as usize] += 1;
                compared += 1;
            }
        }
        assert!(compared > 15_000, "{compared}");
        assert!(
            wrong_differs > 50,
            "a 3 % larger solid went unnoticed: {wrong_differs}"
        );
        assert!(seen.iter().all(|&c| c > 100), "{seen:?}");
    }

    /// A convex polygon of `n` vertices at sorted random angles on an ellipse about `centre`,
    /// counter-clockwise around the unit `normal`.
    fn random_convex(
        rng: &mut crate::sampling::Rng,
        centre: Vec3,
        normal: Vec3,
        n: usize,
    ) -> Option<ConvexPolygon> {
        let t = normal.any_orthonormal_vector();
        let b = normal.cross(t);
        let (ra, rb) = (0.1 + rng.uniform(), 0.1 + rng.uniform());
        let mut angles: Vec<f32> = (0..n)
            .map(|_| std::f32::consts::TAU * rng.uniform())
            .collect();
        angles.sort_by(f32::total_cmp);
        let points: Vec<Vec3> = angles
            .iter()
            .map(|a| centre + ra * a.cos() * t + rb * a.sin() * b)
            .collect();
        ConvexPolygon::new(&points).ok()
    }

    /// The lanes give exactly the plane-by-plane regions, for random polygon pairs (3 to 8
    /// vertices, tilted, some lights straddling the portal plane) and random solids, at random
    /// points and at points on the volumes' edges, where rounding decides the signs: the lanes
    /// must round every signed distance as `Plane::signed_distance` does.
    #[test]
    fn lanes_match_plane_by_plane() {
        use crate::sampling::Rng;
        let mut rng = Rng::new(17, 18);
        let random_unit_tilt = |rng: &mut Rng, spread: f32| {
            Vec3::new(
                spread * (rng.uniform() - 0.5),
                1.0,
                spread * (rng.uniform() - 0.5),
            )
            .normalize()
        };
        let mut seen = [0usize; 5];
        let (mut pairs, mut on_edges) = (0, 0);
        for trial in 0..300 {
            let portal_normal = random_unit_tilt(&mut rng, 0.8);
            let light_normal = random_unit_tilt(&mut rng, 1.2);
            let (np, nl) = (3 + trial % 6, 3 + (trial / 6) % 6);
            let Some(portal) = random_convex(&mut rng, Vec3::ZERO, portal_normal, np) else {
                continue;
            };
            let depth = if trial % 4 == 0 {
                0.2
            } else {
                0.4 + rng.uniform()
            };
            let centre = Vec3::new(rng.uniform() - 0.5, -depth, rng.uniform() - 0.5);
            let Some(light) = random_convex(&mut rng, centre, light_normal, nl) else {
                continue;
            };
            let solid = trial % 5 == 0;
            let planes = if solid {
                let mut corners: Vec<Vec3> = light.vertices().to_vec();
                corners.extend(light.vertices().iter().map(|&v| v - 0.2 * light_normal));
                AntishadowPlanes::new_hull(&portal, &corners)
            } else {
                AntishadowPlanes::new(&portal, &light)
            };
            let Ok(planes) = planes else {
                continue;
            };
            // A solid may have too many planes for the lanes; a polygon pair never has.
            if planes.lanes.is_none() {
                assert!(solid, "trial {trial}: no lanes");
                continue;
            }
            pairs += 1;
            let mut check = |x: Vec3| {
                let region = planes.classify(x);
                assert_eq!(
                    region,
                    planes.classify_plane_by_plane(x),
                    "trial {trial} at {x}"
                );
                seen[region as usize] += 1;
            };
            for _ in 0..200 {
                check(Vec3::new(
                    6.0 * (rng.uniform() - 0.5),
                    3.0 * rng.uniform() - 0.5,
                    6.0 * (rng.uniform() - 0.5),
                ));
            }
            // Beyond the portal on lines through a portal vertex and a light vertex, and on the
            // portal's edges: points on planes (to rounding).
            for &p in portal.vertices() {
                for &l in planes.light_behind_portal() {
                    check(p + (0.5 + 2.0 * rng.uniform()) * (p - l));
                    on_edges += 1;
                }
            }
            for (a, b) in portal.edges() {
                check(a.lerp(b, rng.uniform()));
            }
            check(Vec3::NAN);
        }
        assert!(pairs > 200 && on_edges > 5_000, "{pairs} pairs, {on_edges}");
        assert!(seen.iter().all(|&c| c > 100), "{seen:?}");
    }

    #[test]
    fn region_names() {
        // Statistics index their counts by `region as usize`.
        for (i, &region) in Region::ALL.iter().enumerate() {
            assert_eq!(region as usize, i, "{region:?}");
        }
        let names: Vec<&str> = Region::ALL.iter().map(|r| r.name()).collect();
        assert_eq!(
            names,
            [
                "behind",
                "outside",
                "antiumbra",
                "antipenumbra",
                "antiantumbra"
            ]
        );
    }
}
