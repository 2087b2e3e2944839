//! Window portals: convex polygons through which the environment lights a room
//! (`docs/method.md` §9). A window's front, where shading points are, is the side its normal
//! points to (the winding's, counter-clockwise); directions through it from a point in front
//! reach the sky unless geometry outside blocks them.
//!
//! Three techniques sample directions through a window: uniform on its area
//! ([`Window::sample_area`]), uniform in its solid angle (the spherical-polygon sampler), and
//! proportional to the environment within it ([`Window::sample_guided`]), whose table lives in a
//! parameterisation that does not depend on the shading point (after Bitterli et al. 2015).

use super::environment::Environment;
pub use super::guided::GuidedBox;
use super::guided::{GuidedTable, coordinate, gnomonic, jacobian};
use crate::asset::desc::PortalDesc;
use crate::sampling::cyclic_pairs;
use crate::sampling::polygon::{ConvexPolygon, PolygonError};
use crate::sampling::spherical::SphericalPolygon;
use glam::{DVec3, Vec2, Vec3};
use std::sync::Arc;

/// Why a window portal cannot be used; every message names the node.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WindowError {
    #[error("window portal node '{portal}': its mesh {error}")]
    BadPolygon { portal: String, error: PolygonError },
    #[error("window portal node '{portal}': portal_light_probability {alpha} is not in [0, 1]")]
    BadAlpha { portal: String, alpha: f32 },
}

/// A validated window portal.
#[derive(Clone, Debug)]
pub struct Window {
    pub name: String,
    /// Index of the `PortalDesc` it was built from in the scene's description.
    pub desc_index: usize,
    /// Probability of sampling the environment itself instead of the window.
    pub alpha: f32,
    /// Whether `alpha` is still to be measured (`portal_light_probability: "auto"`, see
    /// `scene::portals::SourceCheck::auto_alpha`); until then it is the default.
    pub alpha_pending: bool,
    /// The window, its normal pointing to its front (into the room).
    pub polygon: ConvexPolygon,
    /// The largest distance of a vertex from the first: scales the inside test's slack.
    frame: WindowFrame,
    /// The environment's weight over the window's directions, when there is an image to follow;
    /// shared with the window it was built for when an edit only moves or scales the window.
    guided: Option<Arc<GuidedTable>>,
    /// The same for the environment without its sun (`docs/method.md` §9.4), when it has one:
    /// used where the whole sun shows through the window, the sun then drawn on its own.
    sunless: Option<Arc<GuidedTable>>,
    /// The environment's sun as the window's frame sees it, when it has one that can show
    /// through the window's side.
    sun: Option<SunView>,
}

/// The environment's sun in a window's frame (`docs/method.md` §9.4): its cap, and the
/// bounding box of the cap's directions in `(α, β)`, which does not depend on the point. Seen
/// from `x`, the window is the box `B(x)` in these coordinates (a rectangle exactly, any other
/// window within it), so a sun box inside `B(x)` is the first test of whether the whole sun
/// shows, and for a rectangle the only one.
#[derive(Clone, Copy, Debug)]
struct SunView {
    centre: Vec3,
    sin_radius: f32,
    /// `[α_0, α_1, β_0, β_1]`.
    bounds: [f64; 4],
}

/// The sun box's widening for rounding, relative to its extent: its sides are computed
/// exactly ([`gnomonic_range`]).
const SUN_BOX_MARGIN: f64 = 1e-9;

/// Axes of the window's parameterisation: `s`, `t` in its plane, `out = −normal` through it.
#[derive(Clone, Copy, Debug)]
struct WindowFrame {
    centre: DVec3,
    s: DVec3,
    t: DVec3,
    out: DVec3,
    /// The window's bounding box in `(s, t)` about `centre`: `[s_min, s_max, t_min, t_max]`.
    bounds: [f64; 4],
    /// Whether the window fills its bounding box (a rectangle, to [`FILLS_BOX`] of its area):
    /// then the guided technique's support is the box itself, and neither its draw nor its pdf
    /// needs the inside test.
    fills_box: bool,
}

/// A window whose area is at least this share of its bounding box's is taken as filling it.
/// Any share keeps the guided technique exact (its draw and its pdf then both take the box as
/// its support); a sliver of the box outside the window costs only the draws that land in it.
const FILLS_BOX: f64 = 1.0 - 1e-4;

/// Slack of the pdf's box test per unit of the hit's distance over the cosine plus the box's
/// size (directions are `f32`, as for [`ConvexPolygon::ray_through`]): a direction drawn near
/// the box's edge that rounding moves a hair outside still counts as in it.
const BOX_SLACK: f64 = 8.0 * f32::EPSILON as f64;

impl Window {
    /// Validates `desc`, the `desc_index`-th portal of its scene. Its front is its winding's
    /// side. With an image environment, builds the table the guided technique follows.
    pub fn new(
        desc: &PortalDesc,
        desc_index: usize,
        environment: Option<&Environment>,
    ) -> Result<Window, WindowError> {
        let mut window = Self::new_deferred(desc, desc_index, environment, &[])?;
        window.build_table(environment);
        Ok(window)
    }

    /// [`Self::new`] without building its guided table, taking instead the table of a window
    /// in `built` (made for the same environment) whose axes are this one's to within 1e-9 in
    /// their cosines (4.5e-5 rad, a five-hundredth of the table's finest cell): the table
    /// depends on the axes only, not on the window's position or size, so a move or a resize
    /// in the viewer costs no rebuild (0.3 s of both cores). Any table keeps the technique
    /// unbiased, since the draw and its pdf both read it through this window's axes; one for
    /// nearly the same axes samples nearly as well. Without such a window it has no table until
    /// [`Self::build_table`] (the viewer builds it off the UI thread), and the antishadow
    /// strategy samples it uniformly in its solid angle, an exact technique of its own
    /// ([`SkyTechnique::of`](super::sky::SkyTechnique::of)).
    pub fn new_deferred(
        desc: &PortalDesc,
        desc_index: usize,
        environment: Option<&Environment>,
        built: &[Window],
    ) -> Result<Window, WindowError> {
        if !(0.0..=1.0).contains(&desc.alpha) {
            return Err(WindowError::BadAlpha {
                portal: desc.name.clone(),
                alpha: desc.alpha,
            });
        }
        let polygon = ConvexPolygon::from_triangles(&desc.world_triangles()).map_err(|error| {
            WindowError::BadPolygon {
                portal: desc.name.clone(),
                error,
            }
        })?;
        let frame = WindowFrame::new(&polygon);
        let same_axes = |w: &&Window| {
            let close = |a: DVec3, b: DVec3| a.dot(b) > 1.0 - 1e-9;
            close(w.frame.s, frame.s) && close(w.frame.t, frame.t) && close(w.frame.out, frame.out)
        };
        let same = environment
            .filter(|e| !e.is_constant())
            .and_then(|_| built.iter().filter(same_axes).find(|w| w.guided.is_some()));
        let (guided, sunless) = match same {
            Some(w) => (w.guided.clone(), w.sunless.clone()),
            None => (None, None),
        };
        let sun = environment
            .and_then(|e| e.hot_spot())
            .and_then(|(_, centre, sin_radius)| SunView::new(&frame, centre, sin_radius));
        Ok(Window {
            name: desc.name.clone(),
            desc_index,
            alpha: desc.alpha,
            alpha_pending: desc.auto_alpha,
            polygon,
            frame,
            guided,
            sunless,
            sun,
        })
    }

    /// Whether the window has no guided table yet under `environment`, its own (an image to
    /// follow: a constant sky needs none).
    pub fn lacks_table(&self, environment: Option<&Environment>) -> bool {
        self.guided.is_none() && environment.is_some_and(|e| !e.is_constant())
    }

    /// Builds the guided table the window lacks under `environment`, its own (0.3 s of two
    /// cores for the built-in sky).
    pub fn build_table(&mut self, environment: Option<&Environment>) {
        let Some(e) = environment.filter(|_| self.lacks_table(environment)) else {
            return;
        };
        let frame = self.frame;
        let direction = |a, b| frame.direction(a, b).as_vec3();
        self.guided = Some(Arc::new(GuidedTable::new(direction, |w| {
            e.sampling_weight(w)
        })));
        self.sunless = e
            .hot_spot()
            .map(|_| Arc::new(GuidedTable::new(direction, |w| e.sky_weight(w))));
    }

    /// Whether `x` is strictly in front of the window (on the room's side).
    pub fn in_front(&self, x: Vec3) -> bool {
        self.polygon.plane().signed_distance(x) > 0.0
    }

    /// Whether this window and `other` share one guided table (see [`Self::new_deferred`]).
    pub fn shares_table(&self, other: &Window) -> bool {
        match (&self.guided, &other.guided) {
            (Some(a), Some(b)) => Arc::ptr_eq(a, b),
            _ => false,
        }
    }

    /// Whether the window fills its bounding box in its frame (a rectangle), so that the guided
    /// technique's support is the box and its draw and pdf skip the inside test.
    pub fn fills_box(&self) -> bool {
        self.frame.fills_box
    }

    /// Whether the guided technique has a table (an image environment, once it is built).
    pub fn is_guided(&self) -> bool {
        self.guided.is_some()
    }

    /// A direction through a uniform point of the window, with its solid-angle pdf.
    pub fn sample_area(&self, x: Vec3, u: Vec2) -> Option<(Vec3, f32)> {
        self.polygon.sample_direction(x, u)
    }

    /// The solid-angle pdf of [`Self::sample_area`]: `d² / (A |cos θ|)` through the window.
    pub fn area_pdf(&self, x: Vec3, wi: Vec3) -> f32 {
        self.polygon.direction_pdf(x, wi)
    }

    /// If the ray `x + t·wi` (`t > 0`) passes through the window: `t` and the cosine with its
    /// normal ([`ConvexPolygon::ray_through`]).
    pub fn through(&self, x: Vec3, wi: Vec3) -> Option<(f64, f64)> {
        self.polygon.ray_through(x, wi)
    }

    /// The window seen from `x`, for sampling by solid angle (`None` edge-on).
    pub fn solid_angle(&self, x: Vec3) -> Option<SphericalPolygon> {
        SphericalPolygon::new(x, self.polygon.vertices())
    }

    /// Whether the whole cap about the unit `centre` with radius `asin(sin_radius)` (below 90°)
    /// passes through the window from `x` (in front): it lies inside every plane through `x`
    /// and an edge, which bound the window's directions. For a counter-clockwise polygon seen
    /// from its front, `(b − x) × (a − x)` is edge `ab`'s plane's normal towards the inside;
    /// the cap is inside when `centre · n ≥ sin_radius · |n|`.
    fn holds_cap(&self, x: Vec3, centre: Vec3, sin_radius: f32) -> bool {
        let sin2 = sin_radius * sin_radius;
        cyclic_pairs(self.polygon.vertices()).all(|(a, b)| {
            let n = (b - x).cross(a - x);
            let d = centre.dot(n);
            d >= 0.0 && d * d >= sin2 * n.length_squared()
        })
    }

    /// The box of the window's directions from `x` in `(α, β)` and the table's integral over
    /// it; `None` without a table, or for `x` not in front.
    #[inline(always)]
    pub fn guided_box(&self, x: Vec3) -> Option<GuidedBox> {
        self.box_in(self.guided.as_deref()?, x)
    }

    /// [`Self::guided_box`], but where the environment's whole sun shows through the window
    /// from `x`, in the table of the environment without it, marked `sunless` (the sun is then
    /// drawn on its own). Whether it shows only changes the variance: either table gives an
    /// exact technique. The sun's box inside the window's decides it for a rectangle; another
    /// window also tests the sun's cap against its edges.
    #[inline(always)]
    pub fn guided_box_split(&self, x: Vec3) -> Option<GuidedBox> {
        let (alpha, beta) = self.box_coordinates(x)?;
        let shows_sun = self.sun.as_ref().is_some_and(|sun| {
            let [a0, a1, b0, b1] = sun.bounds;
            alpha[0] <= a0
                && a1 <= alpha[1]
                && beta[0] <= b0
                && b1 <= beta[1]
                && (self.frame.fills_box || self.holds_cap(x, sun.centre, sun.sin_radius))
        });
        match (shows_sun, self.sunless.as_deref()) {
            (true, Some(table)) => {
                let mut b = table.guided_box(alpha, beta)?;
                b.sunless = true;
                Some(b)
            }
            _ => self.guided.as_deref()?.guided_box(alpha, beta),
        }
    }

    /// The table a box reads.
    #[inline(always)]
    fn table_of(&self, b: &GuidedBox) -> Option<&GuidedTable> {
        if b.sunless {
            self.sunless.as_deref()
        } else {
            self.guided.as_deref()
        }
    }

    #[inline(always)]
    fn box_in(&self, table: &GuidedTable, x: Vec3) -> Option<GuidedBox> {
        let (alpha, beta) = self.box_coordinates(x)?;
        table.guided_box(alpha, beta)
    }

    /// The window's box from `x` in `(α, β)`: `([α_0, α_1], [β_0, β_1])`; `None` for `x` not in
    /// front.
    #[inline(always)]
    fn box_coordinates(&self, x: Vec3) -> Option<([f64; 2], [f64; 2])> {
        let f = &self.frame;
        let rel = x.as_dvec3() - f.centre;
        let h = -rel.dot(f.out);
        if !(h > 0.0 && h.is_finite()) {
            return None;
        }
        let (xs, xt) = (rel.dot(f.s), rel.dot(f.t));
        let [s0, s1, t0, t1] = f.bounds;
        let alpha = [coordinate((s0 - xs) / h), coordinate((s1 - xs) / h)];
        let beta = [coordinate((t0 - xt) / h), coordinate((t1 - xt) / h)];
        Some((alpha, beta))
    }

    /// A direction through the window drawn proportional to the table within the box, with its
    /// solid-angle pdf `T(α, β) / (Z · J(α, β))`. The box bounds the window; a draw that falls
    /// in the box but outside the window is no sample (`None`), so the density is that of the
    /// box restricted to the window (it integrates to the window's share of `Z`). A window that
    /// fills its box ([`Self::fills_box`]) skips the inside test: its support is the box.
    #[inline(always)]
    pub fn sample_guided(&self, b: &GuidedBox, x: Vec3, u: Vec2) -> Option<(Vec3, f32)> {
        let table = self.table_of(b)?;
        let (alpha, beta, weight) = table.sample(b, [f64::from(u.x), f64::from(u.y)])?;
        let (ta, tb) = (gnomonic(alpha), gnomonic(beta));
        let f = &self.frame;
        let wi = (ta * f.s + tb * f.t + f.out).normalize().as_vec3();
        if !f.fills_box {
            self.through(x, wi)?;
        }
        let pdf = weight / (b.integral() * jacobian(ta, tb));
        (pdf > 0.0 && pdf.is_finite()).then_some((wi, pdf as f32))
    }

    /// The solid-angle pdf of [`Self::sample_guided`] for `wi`: 0 unless it passes through the
    /// window (through the box, for a window that fills it).
    pub fn guided_pdf(&self, b: &GuidedBox, x: Vec3, wi: Vec3) -> f32 {
        let Some(table) = self.table_of(b) else {
            return 0.0;
        };
        let f = &self.frame;
        if !f.fills_box && self.through(x, wi).is_none() {
            return 0.0;
        }
        let w = wi.as_dvec3();
        let dz = w.dot(f.out);
        if dz <= 0.0 {
            return 0.0;
        }
        let (ta, tb) = (w.dot(f.s) / dz, w.dot(f.t) / dz);
        if f.fills_box && !f.box_holds(x, ta, tb) {
            return 0.0;
        }
        let (alpha, beta) = (coordinate(ta), coordinate(tb));
        // The window lies inside the box: a direction through it that rounding puts a hair
        // outside takes the box's edge cell.
        let alpha = alpha.clamp(b.alpha[0], b.alpha[1]);
        let beta = beta.clamp(b.beta[0], b.beta[1]);
        (table.density(alpha, beta) / (b.integral() * jacobian(ta, tb))) as f32
    }
}

/// `[a_min, a_max, b_min, b_max]` of the points `(a, b)`.
fn bounding_box(points: impl Iterator<Item = (f64, f64)>) -> [f64; 4] {
    let empty = [
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    ];
    points.fold(empty, |[a0, a1, b0, b1], (a, b)| {
        [a0.min(a), a1.max(a), b0.min(b), b1.max(b)]
    })
}

impl SunView {
    /// The cap about the unit world `centre` with radius `asin(sin_radius)` in `frame`; `None`
    /// if part of it faces away from the window's outside (`ω · out ≤ 0`), where no point in
    /// front sees it through the window.
    fn new(frame: &WindowFrame, centre: Vec3, sin_radius: f32) -> Option<SunView> {
        let c = centre.as_dvec3();
        let sin_r = f64::from(sin_radius);
        let cos_r = (1.0 - sin_r * sin_r).max(0.0).sqrt();
        // The cap lies on the outside when its centre is more than its radius from the plane.
        if c.dot(frame.out) <= sin_r + 1e-6 {
            return None;
        }
        let u = c.any_orthonormal_vector();
        let v = c.cross(u);
        let rim = [cos_r * c, sin_r * u, sin_r * v];
        let (a0, a1) = gnomonic_range(rim, frame.s, frame.out)?;
        let (b0, b1) = gnomonic_range(rim, frame.t, frame.out)?;
        let (wa, wb) = (a1 - a0, b1 - b0);
        let margin = |w: f64| SUN_BOX_MARGIN * w + 1e-12;
        Some(SunView {
            centre,
            sin_radius,
            bounds: [
                coordinate(a0 - margin(wa)),
                coordinate(a1 + margin(wa)),
                coordinate(b0 - margin(wb)),
                coordinate(b1 + margin(wb)),
            ],
        })
    }
}

/// The least and greatest of `(d · axis) / (d · out)` over the circle `d(φ) = p + cos φ · q +
/// sin φ · r` (`[p, q, r]`, a cap's rim), where `d · out > 0` all round: exactly, not from
/// points on the rim (between which the rim bulges, most when the cap nears the window's
/// plane). With `A + B cos φ + C sin φ` over `D + E cos φ + F sin φ`, the value `k` is taken
/// somewhere on the rim where `|A − kD| ≤ |(B − kE, C − kF)|`, and its extremes are the roots of
/// `(A − kD)² = (B − kE)² + (C − kF)²`.
fn gnomonic_range([p, q, r]: [DVec3; 3], axis: DVec3, out: DVec3) -> Option<(f64, f64)> {
    let (a, b, c) = (p.dot(axis), q.dot(axis), r.dot(axis));
    let (d, e, f) = (p.dot(out), q.dot(out), r.dot(out));
    let k2 = d * d - e * e - f * f;
    let k1 = a * d - b * e - c * f;
    let k0 = a * a - b * b - c * c;
    // d · out > 0 on the whole rim exactly when D > |(E, F)|, that is k2 > 0 with D > 0.
    if !(d > 0.0 && k2 > 0.0) {
        return None;
    }
    let root = (k1 * k1 - k2 * k0).max(0.0).sqrt();
    Some(((k1 - root) / k2, (k1 + root) / k2))
}

impl WindowFrame {
    /// `s` along the edge whose direction gives the smallest bounding box (for a convex
    /// polygon, the smallest enclosing rectangle has a side on an edge): a rectangle's box is
    /// the rectangle itself.
    fn new(polygon: &ConvexPolygon) -> Self {
        let n = polygon.normal().as_dvec3();
        let centre = polygon.centroid().as_dvec3();
        let out = -n;
        let vertices: Vec<DVec3> = polygon.vertices().iter().map(|v| v.as_dvec3()).collect();
        let mut best: Option<(f64, WindowFrame)> = None;
        for (a, b) in cyclic_pairs(&vertices) {
            let Some(s) = (b - a).try_normalize() else {
                continue;
            };
            let t = out.cross(s);
            let bounds = bounding_box(
                vertices
                    .iter()
                    .map(|v| ((v - centre).dot(s), (v - centre).dot(t))),
            );
            let area = (bounds[1] - bounds[0]) * (bounds[3] - bounds[2]);
            if best.as_ref().is_none_or(|(a, _)| area < *a) {
                best = Some((
                    area,
                    WindowFrame {
                        centre,
                        s,
                        t,
                        out,
                        bounds,
                        fills_box: f64::from(polygon.area()) >= FILLS_BOX * area,
                    },
                ));
            }
        }
        // A validated polygon has edges, so `best` is set; the fallback keeps this total.
        best.map(|(_, f)| f).unwrap_or_else(|| {
            let s = n.any_orthonormal_vector();
            WindowFrame {
                centre,
                s,
                t: out.cross(s),
                out,
                bounds: [0.0; 4],
                fills_box: false,
            }
        })
    }

    /// Whether the ray from `x` with tangents `(a, b)` (`a = ω·s / ω·out`, likewise `b`) meets
    /// the window's plane inside the bounding box, to [`BOX_SLACK`]: the inside test of a box.
    fn box_holds(&self, x: Vec3, a: f64, b: f64) -> bool {
        let rel = x.as_dvec3() - self.centre;
        let h = -rel.dot(self.out);
        let (ps, pt) = (rel.dot(self.s) + h * a, rel.dot(self.t) + h * b);
        let [s0, s1, t0, t1] = self.bounds;
        let size = (s1 - s0).max(t1 - t0);
        // An error δ in the direction moves the hit by about its distance `h·|(a, b, 1)|` times
        // δ over the cosine `1 / |(a, b, 1)|`: grazing rays need the wider slack.
        let slack = BOX_SLACK * (h * (1.0 + a * a + b * b) + size);
        (s0 - slack..=s1 + slack).contains(&ps) && (t0 - slack..=t1 + slack).contains(&pt)
    }

    /// The unit direction at gnomonic coordinates `(a, b)` (`a = ω·s / ω·out`, likewise `b`).
    fn direction(&self, a: f64, b: f64) -> DVec3 {
        (a * self.s + b * self.t + self.out).normalize()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Caps of radius 0.2 whose rims pass 1e-2 to 1e-4 rad in front of the window's plane, at
    /// several azimuths: every point of a dense rim lies within [`gnomonic_range`]'s extremes,
    /// which the dense rim reaches (so they are tight). The box of 256 rim points widened by
    /// 1e-3 of its extent, the earlier rule, misses part of some of these caps: the case the
    /// exact range is for.
    #[test]
    fn the_sun_box_holds_a_cap_near_the_window_plane() {
        let (s, t, out) = (DVec3::X, DVec3::Y, DVec3::Z);
        let radius = 0.2f64;
        let mut old_rule_failed = 0;
        for gap in [1e-2, 1e-3, 1e-4] {
            for azimuth in [0.1f64, 0.7, 1.9, 2.6] {
                let elevation = radius + gap;
                let horizontal = DVec3::new(azimuth.cos(), azimuth.sin(), 0.0);
                let c = horizontal * elevation.cos() + out * elevation.sin();
                let u = c.any_orthonormal_vector();
                let v = c.cross(u);
                let rim = [radius.cos() * c, radius.sin() * u, radius.sin() * v];
                let (a0, a1) = gnomonic_range(rim, s, out).unwrap();
                let (b0, b1) = gnomonic_range(rim, t, out).unwrap();
                let point = |phi: f64| {
                    let d = rim[0] + phi.cos() * rim[1] + phi.sin() * rim[2];
                    (d.dot(s) / d.dot(out), d.dot(t) / d.dot(out))
                };
                let dense = 1_000_000;
                let mut seen = [f64::MAX, f64::MIN, f64::MAX, f64::MIN];
                for k in 0..dense {
                    let (a, b) = point(std::f64::consts::TAU * k as f64 / dense as f64);
                    let slack = 1e-9 * (a1 - a0).max(b1 - b0);
                    assert!(
                        a >= a0 - slack && a <= a1 + slack,
                        "α {a} outside [{a0}, {a1}]"
                    );
                    assert!(
                        b >= b0 - slack && b <= b1 + slack,
                        "β {b} outside [{b0}, {b1}]"
                    );
                    seen = [
                        seen[0].min(a),
                        seen[1].max(a),
                        seen[2].min(b),
                        seen[3].max(b),
                    ];
                }
                let exact = [a0, a1, b0, b1];
                let extent = (a1 - a0).max(b1 - b0);
                for (x, e) in seen.iter().zip(exact) {
                    assert!(
                        (x - e).abs() <= 1e-6 * extent,
                        "gap {gap}: {seen:?} vs {exact:?}"
                    );
                }
                // The earlier rule: the box of 256 rim points, widened by 1e-3 of its extent.
                let old =
                    bounding_box((0..256).map(|k| point(std::f64::consts::TAU * k as f64 / 256.0)));
                let widen = |lo: f64, hi: f64| (lo - 1e-3 * (hi - lo), hi + 1e-3 * (hi - lo));
                let (oa0, oa1) = widen(old[0], old[1]);
                let (ob0, ob1) = widen(old[2], old[3]);
                old_rule_failed += usize::from(a1 > oa1 || a0 < oa0 || b1 > ob1 || b0 < ob0);
            }
        }
        assert!(old_rule_failed > 0, "the 256-point boxes held every cap");
        let (u, v) = (DVec3::Y, DVec3::Z);
        // A cap that reaches behind the plane has no box.
        let low = [radius.cos() * DVec3::X, radius.sin() * u, radius.sin() * v];
        assert!(gnomonic_range(low, s, out).is_none());
    }
}
