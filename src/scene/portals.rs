//! Portals that place themselves (`docs/method.md` §11): the openings through which a light's
//! light (or the sky's) leaves the geometry around it, found from a panorama of depths; a check
//! of where a scene's portals let that light out; and the alpha the check implies.
//!
//! **Finding.** From the light's centre (just in front of it), one ray per 1° cell of a
//! panorama gives the depths of what surrounds it. Neighbouring cells whose depths differ by
//! less than [`SAME_SURFACE`] see one surface; at an edge between two surfaces the nearer one
//! occludes the farther. The enclosure is made of the surfaces that are mostly the near side of
//! their edges; the others, and the sky, are where the light leaves. Adjacent leaving surfaces
//! are one opening; the cell pairs across its edge with the enclosure, bisected to the exact
//! edge, are points of its rim; a plane fitted through them is the opening's plane and the
//! rim's hull in that plane its polygon. For the sky, panoramas are taken from the camera and
//! from points the camera sees, and only the sky's own cells leave.
//!
//! **Checking.** Rays drawn as the light emits them (uniform on its area, cosine-distributed)
//! either stop inside the enclosure, pass one of its portals on the way out (the right way), or
//! leave through a found opening without a portal: a leak. For the sky, rays from the surfaces
//! the camera sees that escape are weighted by the sky's luminance, and those that pass no
//! window leak.

use glam::{DMat3, DVec2, DVec3, Vec2, Vec3};
use rayon::prelude::*;

use super::Scene;
use super::opening::wall_axes;
use crate::asset::desc::{DEFAULT_PORTAL_ALPHA, PortalDesc};
use crate::asset::environment::ENVIRONMENT_TARGET;
use crate::light::area::luminance;
use crate::sampling::polygon::{ConvexPolygon, MAX_POLYGON_VERTICES, convex_hull_2d};
use crate::sampling::{Frame, Rng, sample_cosine_hemisphere};

/// The panorama's cells: 1° in longitude and in colatitude.
const COLUMNS: usize = 360;
const ROWS: usize = 180;
/// Neighbouring cells see one surface when their depths differ by less than this factor (a
/// plane stays one surface out to 85° from its normal at 1° cells).
const SAME_SURFACE: f32 = 1.25;
/// Bisection steps that move a rim point from its cell to the edge itself.
const RIM_BISECTIONS: usize = 14;
/// An opening that carries less of the light than this gets no portal.
pub const MIN_OPENING_SHARE: f32 = 0.01;
/// A check draws rays until this many get out (through a portal or past them), so that its
/// resolution of the leak does not depend on how much of the light is stopped...
pub const CHECK_LEAVING_RAYS: usize = 1 << 15;
/// ... or until it has drawn this many.
const CHECK_MAX_RAYS: usize = 1 << 21;
/// The sky check's points: a grid of camera rays, and rays per point and pass.
const SKY_GRID: (usize, usize) = (24, 18);
const SKY_RAYS_PER_POINT: usize = 32;
/// The smallest alpha `auto` gives (`docs/method.md` §11.3).
pub const MIN_AUTO_ALPHA: f32 = 0.02;

/// Whose light a portal or an opening passes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// An area light, by index in the scene's lights.
    Light(usize),
    Environment,
}

/// A planar opening through which light leaves.
#[derive(Clone, Debug)]
pub struct Opening {
    /// A convex polygon, counter-clockwise about `normal`.
    pub corners: Vec<Vec3>,
    /// The side a portal over it faces: away from its light, or, for a window, into the room.
    pub normal: Vec3,
    /// The share of the light (or, for the sky, of the light the panoramas saw) it carries.
    pub share: f32,
}

/// What finding saw around one light or the sky.
#[derive(Clone, Debug)]
pub struct Openings {
    pub source: Source,
    pub name: String,
    pub openings: Vec<Opening>,
    /// The share of the light stopped by what surrounds it.
    pub stopped: f32,
    /// Why an opening got no portal, or why the light has none.
    pub notes: Vec<String>,
    /// Whether every way the light leaves was measured (no opening set aside as not planar or
    /// open to the light's horizon): only then may `auto` take alpha below the default.
    pub complete: bool,
    /// The directions, seen from the light, in which its light leaves without a found opening
    /// (past the edge of what surrounds it, through an opening whose rim is not planar, or
    /// everywhere for a light in the open): light that goes that way without passing a portal
    /// is a leak as much as light through an opening without one.
    pub unfitted: Option<Directions>,
}

/// A set of directions from a point: the cells of a panorama.
#[derive(Clone)]
pub struct Directions {
    origin: Vec3,
    frame: Frame,
    cells: Vec<bool>,
}

impl std::fmt::Debug for Directions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let n = self.cells.iter().filter(|&&c| c).count();
        write!(
            f,
            "Directions({n} of {} cells from {})",
            self.cells.len(),
            self.origin
        )
    }
}

impl Directions {
    /// Whether the point `p` is seen from the origin in one of the directions.
    pub fn sees(&self, p: Vec3) -> bool {
        let Some(d) = (p - self.origin).try_normalize() else {
            return false;
        };
        let local = self.frame.to_local(d);
        let theta = local.z.clamp(-1.0, 1.0).acos();
        let phi = local.y.atan2(local.x).rem_euclid(std::f32::consts::TAU);
        let row = ((theta / std::f32::consts::PI * ROWS as f32) as usize).min(ROWS - 1);
        let column = ((phi / std::f32::consts::TAU * COLUMNS as f32) as usize).min(COLUMNS - 1);
        self.cells[row * COLUMNS + column]
    }
}

/// Found portals: a portal per opening, and what was seen.
#[derive(Clone, Debug)]
pub struct Found {
    pub portals: Vec<PortalDesc>,
    pub sources: Vec<Openings>,
}

/// The openings of every light and of the sky (when the scene has an environment), with a
/// portal for each; their alpha is `auto`.
pub fn find(scene: &Scene) -> Found {
    let lights = scene.geometry.lights.len();
    let mut sources: Vec<Openings> = (0..lights)
        .into_par_iter()
        .map(|i| light_openings(scene, i))
        .collect();
    if scene.environment.is_some() {
        sources.push(sky_openings(scene));
    }
    let mut portals = Vec::new();
    for source in &sources {
        let target = match source.source {
            Source::Light(_) => source.name.clone(),
            Source::Environment => ENVIRONMENT_TARGET.to_owned(),
        };
        let stem = match source.source {
            Source::Light(_) => format!("{}_portal", source.name),
            Source::Environment => "window".to_owned(),
        };
        for (k, opening) in source.openings.iter().enumerate() {
            let name = if source.openings.len() == 1 {
                stem.clone()
            } else {
                format!("{stem}{}", k + 1)
            };
            let mut portal = PortalDesc::from_polygon(name, target.clone(), &opening.corners);
            portal.auto_alpha = true;
            portals.push(portal);
        }
    }
    Found { portals, sources }
}

/// The most surfaces a ray passes in [`depth`] (its own light's triangles, panes) before it is
/// taken to go on past them all.
const MAX_PASSED_SURFACES: usize = 1024;

/// Traces from `origin` along `dir`, through the triangles of light `skip` (a light is not its
/// own enclosure) and through thin glass (a glazed window or lamp opening is an opening, as
/// the renderer's rays cross it): the distance to the first other surface, or infinity.
pub(super) fn depth(scene: &Scene, skip: Option<usize>, origin: Vec3, dir: Vec3) -> f32 {
    let geometry = &scene.geometry;
    let mut tmin = 0.0;
    // A ray may pass through a light's surface more than once (a bulb's near and far sides, a
    // filament's coils): each pass moves `tmin` on, so this ends; the bound only guards
    // against a pathological mesh.
    for _ in 0..MAX_PASSED_SURFACES {
        let Some(hit) = geometry.bvh.closest_hit(origin, dir, tmin, f32::INFINITY) else {
            return f32::INFINITY;
        };
        let own = skip.is_some_and(|light| {
            geometry
                .triangles
                .get(hit.triangle as usize)
                .is_some_and(|t| t.light as usize == light)
        });
        if !own && !geometry.is_pane(hit.triangle) {
            return hit.t;
        }
        tmin = hit.t * (1.0 + 1e-5) + 1e-7 * geometry.scale();
    }
    // Past that many, the ray is taken to go on: were it taken as stopped, light that leaks
    // would be missed (and `auto` alpha come out low); taken as going on, a leak is at worst
    // overcounted, which errs towards a larger alpha.
    f32::INFINITY
}

/// The depths around a point, one ray per cell.
struct Panorama {
    origin: Vec3,
    frame: Frame,
    /// Whether the source sends light along the cell's direction.
    lit: Vec<bool>,
    /// Distance to the first surface; infinite where the ray escapes.
    depth: Vec<f32>,
    /// The light the cell carries: the emission's weight times the cell's solid angle.
    weight: Vec<f32>,
    skip: Option<usize>,
}

impl Panorama {
    fn direction(frame: &Frame, row: f32, column: f32) -> Vec3 {
        let theta = row / ROWS as f32 * std::f32::consts::PI;
        let phi = column / COLUMNS as f32 * std::f32::consts::TAU;
        let (s, c) = theta.sin_cos();
        frame.to_world(Vec3::new(s * phi.cos(), s * phi.sin(), c))
    }

    fn cell_direction(&self, cell: usize) -> Vec3 {
        let (row, column) = (cell / COLUMNS, cell % COLUMNS);
        Self::direction(&self.frame, row as f32 + 0.5, column as f32 + 0.5)
    }

    /// The panorama from `origin` around `axis`; `emits` weighs a direction (0: not lit).
    fn take(
        scene: &Scene,
        origin: Vec3,
        axis: Vec3,
        skip: Option<usize>,
        emits: &(dyn Fn(Vec3) -> f32 + Sync),
    ) -> Panorama {
        let frame = Frame::from_normal(axis);
        let cell_angle = std::f32::consts::PI / ROWS as f32;
        let rows: Vec<Vec<(bool, f32, f32)>> = (0..ROWS)
            .into_par_iter()
            .map(|row| {
                let solid = cell_angle * cell_angle * ((row as f32 + 0.5) * cell_angle).sin();
                (0..COLUMNS)
                    .map(|column| {
                        let d = Self::direction(&frame, row as f32 + 0.5, column as f32 + 0.5);
                        let w = emits(d);
                        if w > 0.0 {
                            (true, depth(scene, skip, origin, d), w * solid)
                        } else {
                            (false, f32::INFINITY, 0.0)
                        }
                    })
                    .collect()
            })
            .collect();
        let cells = rows.into_iter().flatten();
        let (mut lit, mut depths, mut weight) = (Vec::new(), Vec::new(), Vec::new());
        for (l, d, w) in cells {
            lit.push(l);
            depths.push(d);
            weight.push(w);
        }
        Panorama {
            origin,
            frame,
            lit,
            depth: depths,
            weight,
            skip,
        }
    }

    /// Each cell's right and lower neighbours (longitude wraps).
    fn neighbours() -> impl Iterator<Item = (usize, usize)> {
        (0..ROWS).flat_map(|row| {
            (0..COLUMNS).flat_map(move |column| {
                let cell = row * COLUMNS + column;
                let right = row * COLUMNS + (column + 1) % COLUMNS;
                let down = (row + 1 < ROWS).then_some(cell + COLUMNS);
                std::iter::once((cell, right)).chain(down.map(|d| (cell, d)))
            })
        })
    }

    fn same_surface(&self, a: usize, b: usize) -> bool {
        let (da, db) = (self.depth[a], self.depth[b]);
        match (da.is_finite(), db.is_finite()) {
            (false, false) => true,
            (true, true) => da.max(db) <= da.min(db) * SAME_SURFACE,
            _ => false,
        }
    }

    /// The point on the edge between cell `near` (enclosure) and cell `far` (leaving): the
    /// last direction from `near` towards `far` that still meets the near surface.
    fn rim_point(&self, scene: &Scene, near: usize, far: usize) -> Vec3 {
        let t_near = self.depth[near];
        let t_far = self.depth[far];
        // Between the two surfaces' depths: a hit closer than this is on the near one.
        let threshold = if t_far.is_finite() {
            (t_near * t_far).sqrt()
        } else {
            4.0 * t_near
        };
        let (mut a, mut b) = (self.cell_direction(near), self.cell_direction(far));
        let mut point = self.origin + a * t_near;
        for _ in 0..RIM_BISECTIONS {
            let mid = (a + b).normalize();
            let t = depth(scene, self.skip, self.origin, mid);
            if t <= threshold {
                a = mid;
                point = self.origin + mid * t;
            } else {
                b = mid;
            }
        }
        point
    }
}

/// A minimal union-find.
struct Sets(Vec<u32>);

impl Sets {
    fn new(n: usize) -> Self {
        Sets((0..n as u32).collect())
    }

    fn root(&mut self, mut x: usize) -> usize {
        while self.0[x] as usize != x {
            self.0[x] = self.0[self.0[x] as usize];
            x = self.0[x] as usize;
        }
        x
    }

    fn join(&mut self, a: usize, b: usize) {
        let (a, b) = (self.root(a), self.root(b));
        if a != b {
            self.0[a.max(b)] = a.min(b) as u32;
        }
    }
}

/// How the panorama's surfaces divide into enclosure and leaving.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Leaving {
    /// A light: surfaces occluded by the enclosure's edges, and the sky.
    Occluded,
    /// The sky only (a room's own furniture occludes its walls).
    Sky,
}

/// A candidate opening seen in one panorama: its rim points and the light through it.
struct Seen {
    rim: Vec<Vec3>,
    weight: f32,
    /// It touches a direction the light does not send light along (the light stands in the
    /// open past the edge of what surrounds it), or covers more than a hemisphere.
    open: bool,
    /// Its cells.
    cells: Vec<usize>,
}

/// The panorama's openings, and the weight of the lit cells and of the enclosure's.
fn openings_seen(scene: &Scene, pano: &Panorama, leaving: Leaving) -> (Vec<Seen>, f32, f32) {
    let cells = pano.depth.len();
    let mut surfaces = Sets::new(cells);
    for (a, b) in Panorama::neighbours() {
        if pano.lit[a] && pano.lit[b] && pano.same_surface(a, b) {
            surfaces.join(a, b);
        }
    }
    let surface: Vec<usize> = (0..cells).map(|c| surfaces.root(c)).collect();
    // Votes at the edges between surfaces: the nearer side occludes the farther.
    let (mut near, mut far) = (vec![0u32; cells], vec![0u32; cells]);
    for (a, b) in Panorama::neighbours() {
        if pano.lit[a] && pano.lit[b] && surface[a] != surface[b] {
            let (n, f) = if pano.depth[a] < pano.depth[b] {
                (a, b)
            } else {
                (b, a)
            };
            near[surface[n]] += 1;
            far[surface[f]] += 1;
        }
    }
    let cell_angle = std::f32::consts::PI / ROWS as f32;
    let solid_angle =
        |c: usize| cell_angle * cell_angle * (((c / COLUMNS) as f32 + 0.5) * cell_angle).sin();
    let mut extent = vec![0f32; cells];
    for c in (0..cells).filter(|&c| pano.lit[c]) {
        extent[surface[c]] += solid_angle(c);
    }
    // A light's enclosure is the largest surface that occludes more than it is occluded: a
    // shade, a can's box, a ceiling with a hole. Whatever is seen past its edges (a stem, a
    // table, a picture on the wall) is where the light goes once out.
    let enclosure = (0..cells)
        .filter(|&s| surface[s] == s && pano.lit[s] && near[s] > far[s])
        .max_by(|&a, &b| extent[a].total_cmp(&extent[b]).then(b.cmp(&a)));
    let leaves = |c: usize| match leaving {
        Leaving::Occluded => Some(surface[c]) != enclosure || !pano.depth[c].is_finite(),
        Leaving::Sky => !pano.depth[c].is_finite(),
    };
    // Adjacent leaving surfaces are one opening.
    let mut groups = Sets::new(cells);
    for (a, b) in Panorama::neighbours() {
        if pano.lit[a] && pano.lit[b] && leaves(a) && leaves(b) {
            groups.join(a, b);
        }
    }
    let total: f32 = pano.weight.iter().sum();
    let mut stopped = 0.0;
    let mut index = std::collections::HashMap::new();
    let mut seen: Vec<Seen> = Vec::new();
    let mut solid: Vec<f32> = Vec::new();
    for c in 0..cells {
        if !pano.lit[c] {
            continue;
        }
        if !leaves(c) {
            stopped += pano.weight[c];
            continue;
        }
        let g = groups.root(c);
        let k = *index.entry(g).or_insert_with(|| {
            seen.push(Seen {
                rim: Vec::new(),
                weight: 0.0,
                open: false,
                cells: Vec::new(),
            });
            solid.push(0.0);
            seen.len() - 1
        });
        seen[k].weight += pano.weight[c];
        seen[k].cells.push(c);
        solid[k] += solid_angle(c);
    }
    // The rim: pairs across the edge between an opening and the largest surface around it (for
    // the sky, the wall rather than a curtain rod in the window).
    let mut pairs: Vec<Vec<(usize, usize)>> = vec![Vec::new(); seen.len()];
    for (a, b) in Panorama::neighbours() {
        match (pano.lit[a], pano.lit[b]) {
            (true, true) => {}
            (true, false) | (false, true) => {
                let lit = if pano.lit[a] { a } else { b };
                if leaves(lit)
                    && let Some(&k) = index.get(&groups.root(lit))
                {
                    seen[k].open = true;
                }
                continue;
            }
            (false, false) => continue,
        }
        let (e, l) = match (leaves(a), leaves(b)) {
            (false, true) => (a, b),
            (true, false) => (b, a),
            _ => continue,
        };
        if let Some(&k) = index.get(&groups.root(l)) {
            pairs[k].push((e, l));
        }
    }
    for (k, opening) in seen.iter_mut().enumerate() {
        if solid[k] > std::f32::consts::TAU {
            opening.open = true;
        }
        let Some(main) = pairs[k]
            .iter()
            .map(|&(e, _)| surface[e])
            .max_by(|&a, &b| extent[a].total_cmp(&extent[b]).then(b.cmp(&a)))
        else {
            continue;
        };
        opening.rim = pairs[k]
            .par_iter()
            .filter(|&&(e, _)| surface[e] == main)
            .map(|&(e, l)| pano.rim_point(scene, e, l))
            .collect();
    }
    (seen, total, stopped)
}

/// A plane through `points`: unit normal, a point on it, and the points within tolerance.
fn fit_plane(points: &[Vec3]) -> Option<(DVec3, DVec3, Vec<Vec3>)> {
    let fit = |points: &[Vec3]| -> Option<(DVec3, DVec3)> {
        if points.len() < 3 {
            return None;
        }
        let c = points.iter().map(|p| p.as_dvec3()).sum::<DVec3>() / points.len() as f64;
        let mut m = DMat3::ZERO;
        for p in points {
            let d = p.as_dvec3() - c;
            m += DMat3::from_cols(d * d.x, d * d.y, d * d.z);
        }
        // The normal is the covariance's least eigenvector: inverse iteration, with a
        // regularisation that keeps a perfectly flat rim's matrix invertible.
        let trace = m.x_axis.x + m.y_axis.y + m.z_axis.z;
        if trace.is_nan() || trace <= 0.0 {
            return None;
        }
        let inverse = (m + DMat3::from_diagonal(DVec3::splat(1e-9 * trace))).inverse();
        let mut n = DVec3::new(0.577, 0.577, 0.578);
        for _ in 0..40 {
            n = (inverse * n).try_normalize()?;
        }
        Some((n, c))
    };
    let (n, c) = fit(points)?;
    let size = points
        .iter()
        .map(|p| p.as_dvec3().distance(c))
        .fold(0.0, f64::max);
    let mut residuals: Vec<f64> = points
        .iter()
        .map(|p| n.dot(p.as_dvec3() - c).abs())
        .collect();
    residuals.sort_by(f64::total_cmp);
    let median = residuals[residuals.len() / 2];
    let tolerance = (3.0 * median).max(1e-4 * size);
    let kept: Vec<Vec3> = points
        .iter()
        .copied()
        .filter(|p| n.dot(p.as_dvec3() - c).abs() <= tolerance)
        .collect();
    let (n, c) = fit(&kept)?;
    let rms = (kept
        .iter()
        .map(|p| n.dot(p.as_dvec3() - c).powi(2))
        .sum::<f64>()
        / kept.len() as f64)
        .sqrt();
    // A rim is planar when nearly all of it lies in the plane, to 2% of its size.
    (kept.len() * 10 >= points.len() * 8 && rms <= 0.02 * size).then_some((n, c, kept))
}

/// Where the lines through `a0, a1` and through `b0, b1` meet, if they are not parallel.
fn meet(a0: DVec2, a1: DVec2, b0: DVec2, b1: DVec2) -> Option<DVec2> {
    let (da, db) = (a1 - a0, b1 - b0);
    let denominator = da.perp_dot(db);
    if denominator.abs() <= 1e-12 * da.length() * db.length() {
        return None;
    }
    Some(a0 + da * ((b0 - a0).perp_dot(db) / denominator))
}

/// A convex polygon of at most `max` vertices holding the convex polygon `hull` (counter-
/// clockwise): edges are removed where extending their neighbours adds the least area, so a
/// polygonal rim sampled along its sides gets its own corners back.
fn enclosing_polygon(mut hull: Vec<DVec2>, max: usize) -> Vec<DVec2> {
    let area = |h: &[DVec2]| {
        (0..h.len())
            .map(|i| 0.5 * h[i].perp_dot(h[(i + 1) % h.len()]))
            .sum::<f64>()
    };
    // Removals that add little go on below `max` too, up to 1% of the area in all: a corner
    // the rim's samples cut off is put back (an uncovered corner leaks, and a leak reached only
    // by the alpha share is costly), and a vertex on a straight side (collinear to rounding)
    // would make the polygon's edges ill-defined.
    let (small, mut budget) = (2e-3 * area(&hull), 1e-2 * area(&hull));
    while hull.len() > 3 {
        let n = hull.len();
        let best = (0..n)
            .filter_map(|i| {
                // Remove edge (i, i+1): the edges before and after it meet at x.
                let (p, a, b, q) = (
                    hull[(i + n - 1) % n],
                    hull[i],
                    hull[(i + 1) % n],
                    hull[(i + 2) % n],
                );
                let x = meet(p, a, q, b)?;
                // x must lie beyond the edge, on the outside, for the result to be convex; to
                // rounding, so that a vertex on a straight side (x = a) goes too.
                let added = 0.5 * (b - a).perp_dot(x - a);
                let rounding = 1e-9 * (b - a).length_squared().max((a - p).length_squared());
                (added <= rounding && (x - a).dot(a - p) >= -rounding).then_some((
                    added.min(0.0).abs(),
                    i,
                    x,
                ))
            })
            .min_by(|a, b| a.0.total_cmp(&b.0));
        match best {
            Some((added, i, x)) if n > max || (added <= small && added <= budget) => {
                budget -= added;
                hull[i] = x;
                hull.remove((i + 1) % n);
            }
            _ => break,
        }
    }
    hull
}

/// Each edge moved out by `margin`.
fn grown(polygon: &[DVec2], margin: f64) -> Vec<DVec2> {
    let n = polygon.len();
    let edge = |i: usize| {
        let (a, b) = (polygon[i], polygon[(i + 1) % n]);
        let out = -(b - a).perp().normalize_or_zero() * margin;
        (a + out, b + out)
    };
    (0..n)
        .map(|i| {
            let (a0, a1) = edge((i + n - 1) % n);
            let (b0, b1) = edge(i);
            meet(a0, a1, b0, b1).unwrap_or(b0)
        })
        .collect()
}

/// The opening a light's rim points describe, facing away from `from`: in the plane through
/// the rim's outermost point, so that the portal covers the whole opening.
fn light_opening(rim: &[Vec3], from: Vec3) -> Option<Vec<Vec3>> {
    let (mut n, c, kept) = fit_plane(rim)?;
    if n.dot(c - from.as_dvec3()) < 0.0 {
        n = -n;
    }
    let offset = kept
        .iter()
        .map(|p| n.dot(p.as_dvec3()))
        .fold(f64::NEG_INFINITY, f64::max);
    polygon_in_plane(&kept, n, offset)
}

/// A convex polygon of at most [`MAX_POLYGON_VERTICES`] holding the rim points projected
/// into the plane `n · x = offset`, counter-clockwise about `n`, a hair larger than them.
fn polygon_in_plane(rim: &[Vec3], n: DVec3, offset: f64) -> Option<Vec<Vec3>> {
    let frame = Frame::from_normal(n.as_vec3());
    let (t, b) = (frame.t.as_dvec3(), frame.b.as_dvec3());
    let c = rim.iter().map(|p| p.as_dvec3()).sum::<DVec3>() / rim.len().max(1) as f64;
    let flat: Vec<DVec2> = rim
        .iter()
        .map(|p| DVec2::new(t.dot(p.as_dvec3() - c), b.dot(p.as_dvec3() - c)))
        .collect();
    // The hull in f32: coordinates about the rim's centroid keep it to a micrometre.
    let hull: Vec<DVec2> = convex_hull_2d(flat.iter().map(|p| p.as_vec2()).collect())
        .into_iter()
        .map(|p| p.as_dvec2())
        .collect();
    if hull.len() < 3 {
        return None;
    }
    let size = hull.iter().map(|p| p.length()).fold(0.0, f64::max);
    let polygon = grown(&enclosing_polygon(hull, MAX_POLYGON_VERTICES), 1e-3 * size);
    let origin = c + n * (offset - n.dot(c));
    let corners: Vec<Vec3> = polygon
        .iter()
        .map(|p| (origin + t * p.x + b * p.y).as_vec3())
        .collect();
    ConvexPolygon::new(&corners).ok().map(|_| corners)
}

/// The openings through which light `index` leaves what surrounds it.
pub fn light_openings(scene: &Scene, index: usize) -> Openings {
    let light = &scene.geometry.lights[index];
    let eps = 1e-4 * scene.geometry.scale();
    let flat = light.polygon.as_ref().map(|p| p.normal());
    let (axis, origin) = match flat {
        Some(n) if !light.double_sided => (n, light.centroid() + n * eps),
        Some(n) => (n, light.centroid()),
        None => (Vec3::Y, light.centroid()),
    };
    let double_sided = light.double_sided;
    let emits = move |d: Vec3| match flat {
        Some(n) if double_sided => d.dot(n).abs(),
        Some(n) => d.dot(n).max(0.0),
        None => 1.0,
    };
    let pano = Panorama::take(scene, origin, axis, Some(index), &emits);
    let (seen, total, stopped) = openings_seen(scene, &pano, Leaving::Occluded);
    let mut unfitted = Directions {
        origin: pano.origin,
        frame: pano.frame,
        cells: vec![false; pano.depth.len()],
    };
    let mut result = Openings {
        source: Source::Light(index),
        name: light.name.clone(),
        openings: Vec::new(),
        stopped: stopped / total.max(f32::MIN_POSITIVE),
        notes: Vec::new(),
        complete: true,
        unfitted: None,
    };
    if result.stopped < MIN_OPENING_SHARE {
        result
            .notes
            .push("in the open: nothing near it stops its light, so no portal helps".to_owned());
        unfitted.cells = pano.lit.clone();
        result.unfitted = Some(unfitted);
        return result;
    }
    for s in seen {
        let share = s.weight / total.max(f32::MIN_POSITIVE);
        if s.open {
            for &c in &s.cells {
                unfitted.cells[c] = true;
            }
            result.complete = false;
            result.notes.push(format!(
                "{:.0}% of its light leaves past the edge of what surrounds it (it stands in the \
                 open on that side): no portal there",
                100.0 * share
            ));
            continue;
        }
        // Too small for a portal of its own (and, at the panorama's resolution, often a sliver
        // of the enclosure's own rim seen edge-on): not counted as a leak.
        if share < MIN_OPENING_SHARE {
            continue;
        }
        match light_opening(&s.rim, origin) {
            Some(corners) => result.openings.push(Opening {
                normal: ConvexPolygon::new(&corners).map_or(axis, |p| p.normal()),
                corners,
                share,
            }),
            None => {
                for &c in &s.cells {
                    unfitted.cells[c] = true;
                }
                result.complete = false;
                result.notes.push(format!(
                    "{:.0}% of its light leaves through an opening whose rim is not planar: no \
                     portal fitted",
                    100.0 * share
                ));
            }
        }
    }
    if unfitted.cells.contains(&true) {
        result.unfitted = Some(unfitted);
    }
    if result.openings.is_empty() && result.notes.is_empty() {
        result
            .notes
            .push("closed: none of its light leaves what surrounds it".to_owned());
    }
    result
}

/// Points the camera sees on the scene's surfaces, lifted off them towards the camera, with
/// their normals on the camera's side.
fn camera_points(scene: &Scene) -> Vec<(Vec3, Vec3)> {
    let geometry = &scene.geometry;
    let eps = 1e-4 * geometry.scale();
    let aspect = scene.camera.aspect;
    let (columns, rows) = SKY_GRID;
    let mut points = Vec::new();
    for row in 0..rows {
        for column in 0..columns {
            let ndc = Vec2::new(
                (column as f32 + 0.5) / columns as f32,
                (row as f32 + 0.5) / rows as f32,
            );
            let (o, d) = scene.camera.ray(ndc, aspect);
            let Some(hit) = geometry.closest_hit_through_panes(o, d, 0.0, f32::INFINITY) else {
                continue;
            };
            let Some(triangle) = geometry.triangles.get(hit.triangle as usize) else {
                continue;
            };
            let mut n = triangle.geometric_normal();
            if n.dot(d) > 0.0 {
                n = -n;
            }
            points.push((o + d * hit.t + n * eps, n));
        }
    }
    points
}

/// The windows through which the sky reaches the surfaces the camera sees: panoramas from the
/// camera and from some of those surfaces, merged by plane.
pub fn sky_openings(scene: &Scene) -> Openings {
    let mut viewpoints = vec![scene.camera.eye];
    let points = camera_points(scene);
    // Every 27th point of the grid: 16 of them, spread over the image.
    viewpoints.extend(points.iter().step_by(27).map(|&(p, _)| p));
    let mut rims: Vec<(DVec3, f64, Vec<Vec3>, f32)> = Vec::new();
    // The sky's light seen in all panoramas, and the part of it through planar windows.
    let (mut sky, mut through_windows) = (0.0, 0.0);
    // Cells are weighed by the sky's luminance (a tiny floor keeps every cell lit): the sun's
    // window matters more than a dark skylight.
    let emits = |d: Vec3| luminance(sky_radiance(scene, d)).max(0.0) + 1e-6;
    for &origin in &viewpoints {
        let pano = Panorama::take(scene, origin, Vec3::Y, None, &emits);
        sky += (0..pano.depth.len())
            .filter(|&c| !pano.depth[c].is_finite())
            .map(|c| pano.weight[c])
            .sum::<f32>();
        let (seen, _, _) = openings_seen(scene, &pano, Leaving::Sky);
        for s in seen {
            if s.open {
                continue;
            }
            let Some((mut n, c, kept)) = fit_plane(&s.rim) else {
                continue;
            };
            // Into the room: towards the viewpoint.
            if n.dot(origin.as_dvec3() - c) < 0.0 {
                n = -n;
            }
            let offset = n.dot(c);
            through_windows += s.weight;
            let tolerance = 1e-3 * f64::from(scene.geometry.scale());
            match rims.iter_mut().find(|(m, o, rim, _)| {
                m.dot(n) > 0.999 && (o - offset).abs() < tolerance && overlaps(rim, &kept, n)
            }) {
                Some((_, _, rim, weight)) => {
                    rim.extend(kept);
                    *weight += s.weight;
                }
                None => rims.push((n, offset, kept, s.weight)),
            }
        }
    }
    let mut notes = Vec::new();
    let mut openings = Vec::new();
    let total_weight: f32 = rims.iter().map(|r| r.3).sum::<f32>().max(f32::MIN_POSITIVE);
    for (n, offset, rim, weight) in rims {
        let share = weight / total_weight;
        if share < MIN_OPENING_SHARE {
            continue;
        }
        // The window's polygon, as a light's opening, facing into the room.
        let Some(corners) = polygon_in_plane(&rim, n, offset) else {
            continue;
        };
        openings.push(Opening {
            corners,
            normal: n.as_vec3(),
            share,
        });
    }
    let elsewhere = (sky - through_windows).max(0.0) / sky.max(f32::MIN_POSITIVE);
    let complete = elsewhere <= MIN_OPENING_SHARE;
    if !complete {
        notes.push(format!(
            "{:.0}% of the sky the panoramas saw comes through no planar window: no portal there",
            100.0 * elsewhere
        ));
    }
    if openings.is_empty() && notes.is_empty() {
        notes.push("the sky reaches no surface the camera sees".to_owned());
    }
    Openings {
        source: Source::Environment,
        name: ENVIRONMENT_TARGET.to_owned(),
        openings,
        stopped: 0.0,
        notes,
        complete,
        unfitted: None,
    }
}

/// Whether two rims in one plane (normal `n`) have overlapping bounding boxes.
fn overlaps(a: &[Vec3], b: &[Vec3], n: DVec3) -> bool {
    let (u, v) = wall_axes(n.as_vec3());
    let bounds = |points: &[Vec3]| {
        points.iter().fold(
            (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY)),
            |(lo, hi), p| {
                let q = Vec2::new(u.dot(*p), v.dot(*p));
                (lo.min(q), hi.max(q))
            },
        )
    };
    let ((alo, ahi), (blo, bhi)) = (bounds(a), bounds(b));
    alo.cmple(bhi).all() && blo.cmple(ahi).all()
}

/// The environment's radiance along `d` (black without one).
fn sky_radiance(scene: &Scene, d: Vec3) -> Vec3 {
    scene
        .environment
        .as_deref()
        .map_or(Vec3::ZERO, |e| e.radiance(d))
}

/// How one portal is used.
#[derive(Clone, Debug)]
pub struct PortalUse {
    /// Index of its `PortalDesc` in the scene's description.
    pub desc_index: usize,
    pub name: String,
    /// The share of the source's light it lets out the right way.
    pub share: f32,
    /// The share that crosses it from its front (the portal faces the light).
    pub wrong_way: f32,
}

/// Where one light's (or the sky's) light goes past its portals.
#[derive(Clone, Debug)]
pub struct SourceCheck {
    pub source: Source,
    pub name: String,
    /// Shares of the light emitted (for the sky: of the sky's light reaching the surfaces the
    /// camera sees): through its portals, and leaving without passing one.
    pub through: f32,
    pub leak: f32,
    /// The standard error of `leak`.
    pub leak_error: f32,
    /// Rays drawn.
    pub rays: usize,
    /// The share of the light that gets out at all (for a light, `through + leak`; for the
    /// sky, the cosine-weighted share of directions from the points seen that escape): how
    /// much of what light sampling draws is of use.
    pub reach: f32,
    pub portals: Vec<PortalUse>,
    /// The openings the leak passes, each carrying more than the check's noise and 1% of the
    /// light that leaves (corners, counter-clockwise about the side the light leaves to).
    pub leaking: Vec<Vec<Vec3>>,
    /// What finding the openings noted (for the leak's completeness).
    pub notes: Vec<String>,
    pub complete: bool,
}

impl SourceCheck {
    /// The share of the light that leaves which passes no portal.
    pub fn leak_fraction(&self) -> f32 {
        let leaving = self.through + self.leak;
        if leaving > 0.0 {
            self.leak / leaving
        } else {
            0.0
        }
    }

    /// Whether the leak is more than the check's noise and more than 1% of the leaving light.
    pub fn leaks(&self) -> bool {
        self.leak > 3.0 * self.leak_error && self.leak_fraction() > MIN_OPENING_SHARE
    }

    /// The portals that let none of the light out the right way.
    pub fn useless(&self) -> impl Iterator<Item = &PortalUse> {
        self.portals.iter().filter(|p| p.share == 0.0)
    }

    /// What is wrong, one line each (empty when nothing is).
    pub fn problems(&self) -> Vec<String> {
        let mut problems = Vec::new();
        if self.leaks() {
            problems.push(format!(
                "{:.1}% ± {:.1}% of its light leaves without passing a portal ({:.0}% of the \
                 light that leaves): an opening without a portal, or a portal over part of one",
                100.0 * self.leak,
                100.0 * self.leak_error,
                100.0 * self.leak_fraction()
            ));
        }
        for p in &self.portals {
            if p.wrong_way > 0.0 && p.share == 0.0 {
                problems.push(format!(
                    "portal '{}' faces the wrong way: {:.1}% of the light crosses it from its \
                     front",
                    p.name,
                    100.0 * p.wrong_way
                ));
            } else if p.share == 0.0 {
                problems.push(format!(
                    "portal '{}': none of the light passes through it (misplaced, or in the \
                     wrong wall)",
                    p.name
                ));
            }
        }
        problems
    }
}

/// Checks every light that has portals, and the sky when it has windows.
pub fn check(scene: &Scene, seed: u64) -> Vec<SourceCheck> {
    let lights: Vec<usize> = (0..scene.geometry.lights.len())
        .filter(|&i| scene.portals.iter().any(|p| p.light == i))
        .collect();
    let mut checks: Vec<SourceCheck> = lights
        .into_par_iter()
        .map(|i| check_light(scene, i, &light_openings(scene, i), seed))
        .collect();
    if !scene.windows.is_empty() && scene.environment.is_some() {
        checks.push(check_sky(scene, &sky_openings(scene).openings, seed));
    }
    checks
}

/// Light `index`'s rays against its portals and the openings found around it.
pub fn check_light(scene: &Scene, index: usize, found: &Openings, seed: u64) -> SourceCheck {
    let light = &scene.geometry.lights[index];
    let eps = 1e-4 * scene.geometry.scale();
    let portals: Vec<&crate::light::portal::Portal> =
        scene.portals.iter().filter(|p| p.light == index).collect();
    let openings: Vec<(ConvexPolygon, f32, &Opening)> = found
        .openings
        .iter()
        .filter_map(|o| {
            let polygon = ConvexPolygon::new(&o.corners).ok()?;
            let size = o
                .corners
                .iter()
                .map(|c| c.distance(polygon.centroid()))
                .fold(0.0, f32::max);
            Some((polygon, size, o))
        })
        .collect();
    let mut rng = Rng::keyed(seed, &[0x504f_5254, index as u64]);
    let (mut through, mut wrong) = (vec![0u32; portals.len()], vec![0u32; portals.len()]);
    // Per found opening: the rays that leave through it past every portal; and those that
    // leave in a direction with no found opening, past every portal.
    let mut leaks = vec![0u32; openings.len()];
    let mut unfitted_leaks = 0u32;
    let (mut drawn, mut out) = (0usize, 0usize);
    while drawn < CHECK_MAX_RAYS && out < CHECK_LEAVING_RAYS {
        drawn += 1;
        let u = rng.uniform2();
        let Some(point) = light.sample_point(u) else {
            continue;
        };
        let mut n = point.n;
        if light.double_sided && rng.uniform() < 0.5 {
            n = -n;
        }
        let d = Frame::from_normal(n).to_world(sample_cosine_hemisphere(rng.uniform2()));
        let o = point.p + n * eps;
        let t_hit = depth(scene, Some(index), o, d);
        // Where it leaves through a found opening, if it does before it stops.
        let leaves_at = openings
            .iter()
            .enumerate()
            .filter_map(|(k, (polygon, size, _))| {
                let t = polygon.intersect(o, d)?;
                // Out only if it goes on past the opening's plane (a ray that meets the rim
                // itself, in the polygon's hair of margin, stays in).
                (t + 1e-3 * size < t_hit).then_some((t + 0.5 * size, k))
            })
            .min_by(|a, b| a.0.total_cmp(&b.0));
        // A portal counts if it is passed before the light is out of its opening (with half
        // the opening's size to spare: a portal a little outside the rim still serves).
        let limit = leaves_at.map_or(t_hit, |(t, _)| t).min(t_hit);
        let mut first: Option<(f32, usize, bool)> = None;
        for (k, portal) in portals.iter().enumerate() {
            if let Some(t) = portal.polygon.intersect(o, d)
                && t < limit
                && first.is_none_or(|(b, _, _)| t < b)
            {
                first = Some((t, k, d.dot(portal.polygon.normal()) > 0.0));
            }
        }
        if let Some((_, k, true)) = first {
            through[k] += 1;
            out += 1;
            continue;
        }
        if let Some((_, k, false)) = first {
            wrong[k] += 1;
        }
        if let Some((_, k)) = leaves_at {
            leaks[k] += 1;
            out += 1;
        } else if let Some(unfitted) = &found.unfitted {
            // Where it stops (or far along it, if it escapes), as the light's panorama saw it.
            let end = o + d * t_hit.min(1e3 * scene.geometry.scale());
            if unfitted.sees(end) {
                unfitted_leaks += 1;
                out += 1;
            }
        }
    }
    let n = drawn.max(1) as f32;
    let leak = (leaks.iter().sum::<u32>() + unfitted_leaks) as f32 / n;
    let leaking = leaking_openings(
        openings.iter().map(|(_, _, o)| *o),
        leaks.iter().map(|&l| l as f32 / n),
        |s| (s * (1.0 - s) / n).sqrt(),
    );
    SourceCheck {
        source: Source::Light(index),
        name: light.name.clone(),
        rays: drawn,
        reach: out as f32 / n,
        through: through.iter().sum::<u32>() as f32 / n,
        leak,
        leak_error: (leak * (1.0 - leak) / n).sqrt(),
        portals: portals
            .iter()
            .enumerate()
            .map(|(k, p)| PortalUse {
                desc_index: p.desc_index,
                name: p.name.clone(),
                share: through[k] as f32 / n,
                wrong_way: wrong[k] as f32 / n,
            })
            .collect(),
        leaking,
        notes: found.notes.clone(),
        complete: found.complete,
    }
}

/// Rays from the surfaces the camera sees that escape to the sky, weighted by its luminance,
/// against the windows.
pub fn check_sky(scene: &Scene, found: &[Opening], seed: u64) -> SourceCheck {
    let geometry = &scene.geometry;
    let windows = &scene.windows;
    // Points outside (seen through a window) would count their sky as a leak.
    let eye = scene.camera.eye;
    let inside: Vec<(Vec3, Vec3)> = camera_points(scene)
        .into_iter()
        .filter(|&(p, _)| {
            let d = (p - eye).normalize_or_zero();
            let t = p.distance(eye);
            !windows
                .iter()
                .any(|w| w.polygon.intersect(eye, d).is_some_and(|tw| tw < t))
        })
        .collect();
    let openings: Vec<(ConvexPolygon, &Opening)> = found
        .iter()
        .filter_map(|o| Some((ConvexPolygon::new(&o.corners).ok()?, o)))
        .collect();
    let mut leaks = vec![0f64; openings.len()];
    let mut rng = Rng::keyed(seed, &[0x0053_4b59, 0]);
    let (mut through, mut wrong) = (vec![0f64; windows.len()], vec![0f64; windows.len()]);
    let (mut total, mut leak) = (0f64, 0f64);
    let (mut squares, mut leak_squares) = (0f64, 0f64);
    let (mut drawn, mut escaped) = (0usize, 0usize);
    // Whole passes over the points (every point weighs the same), until enough rays escape.
    let pass = inside.len() * SKY_RAYS_PER_POINT;
    while escaped < CHECK_LEAVING_RAYS && pass > 0 && drawn + pass <= CHECK_MAX_RAYS {
        for (p, frame) in inside
            .iter()
            .flat_map(|&(p, n)| std::iter::repeat_n((p, Frame::from_normal(n)), SKY_RAYS_PER_POINT))
        {
            drawn += 1;
            let d = frame.to_world(sample_cosine_hemisphere(rng.uniform2()));
            // Light through thin glass leaves as the renderer's rays do.
            if geometry
                .closest_hit_through_panes(p, d, 0.0, f32::INFINITY)
                .is_some()
            {
                continue;
            }
            escaped += 1;
            let w = f64::from(luminance(sky_radiance(scene, d)));
            total += w;
            squares += w * w;
            let mut first: Option<(f32, usize, bool)> = None;
            for (k, window) in windows.iter().enumerate() {
                if let Some(t) = window.polygon.intersect(p, d)
                    && first.is_none_or(|(b, _, _)| t < b)
                {
                    // A window faces into the room: light going out crosses it from its front.
                    first = Some((t, k, d.dot(window.polygon.normal()) < 0.0));
                }
            }
            match first {
                Some((_, k, true)) => through[k] += w,
                other => {
                    if let Some((_, k, false)) = other {
                        wrong[k] += w;
                    }
                    leak += w;
                    leak_squares += w * w;
                    let out = openings
                        .iter()
                        .enumerate()
                        .filter_map(|(k, (o, _))| Some((o.intersect(p, d)?, k)))
                        .min_by(|a, b| a.0.total_cmp(&b.0));
                    if let Some((_, k)) = out {
                        leaks[k] += w;
                    }
                }
            }
        }
    }
    let total = total.max(f64::MIN_POSITIVE);
    let share = leak / total;
    // A ratio of sums, Σx/Σw with x = w·[leaks]: its variance is Var(x − share·w)/(N·E[w]²),
    // and Σ(x − share·w)² = (1 − 2·share)·Σx² + share²·Σw² since x·w = x².
    let residual = (1.0 - 2.0 * share) * leak_squares + share * share * squares;
    let leak_error = residual.max(0.0).sqrt() / total;
    SourceCheck {
        source: Source::Environment,
        name: ENVIRONMENT_TARGET.to_owned(),
        rays: drawn,
        reach: escaped as f32 / drawn.max(1) as f32,
        through: (through.iter().sum::<f64>() / total) as f32,
        leak: share as f32,
        leak_error: leak_error as f32,
        portals: windows
            .iter()
            .enumerate()
            .map(|(k, w)| PortalUse {
                desc_index: w.desc_index,
                name: w.name.clone(),
                share: (through[k] / total) as f32,
                wrong_way: (wrong[k] / total) as f32,
            })
            .collect(),
        leaking: leaking_openings(
            openings.iter().map(|(_, o)| *o),
            leaks.iter().map(|l| (l / total) as f32),
            |_| leak_error as f32,
        ),
        notes: Vec::new(),
        complete: true,
    }
}

/// The openings whose leak `shares` are above three standard errors (`error` of a share) and
/// 1% of the light.
fn leaking_openings<'a>(
    openings: impl Iterator<Item = &'a Opening>,
    shares: impl Iterator<Item = f32>,
    error: impl Fn(f32) -> f32,
) -> Vec<Vec<Vec3>> {
    openings
        .zip(shares)
        .filter(|&(_, s)| s > 3.0 * error(s) && s > MIN_OPENING_SHARE)
        .map(|(o, _)| o.corners.clone())
        .collect()
}

impl SourceCheck {
    /// The alpha `auto` gives this light's portals (or the windows; `docs/method.md` §11.3):
    /// with `ℓ` the leak's share of the light that gets out and `r` the share of what light
    /// sampling draws that gets out at all, the α minimising `(ℓ/r)/α + (1 − ℓ)/(1 − α)`, at
    /// least [`MIN_AUTO_ALPHA`]; not below the default when some of the light gets out where the
    /// check could not measure it.
    pub fn auto_alpha(&self) -> f32 {
        let leak = self.leak_fraction().clamp(0.0, 1.0);
        let (a, b) = ((leak / self.reach.max(1e-6)).sqrt(), (1.0 - leak).sqrt());
        let best = (a / (a + b)).max(MIN_AUTO_ALPHA);
        if self.complete {
            best
        } else {
            best.max(DEFAULT_PORTAL_ALPHA)
        }
    }
}

impl Scene {
    /// The alpha rendering uses for `source` (a light's is the largest of its portals', the
    /// sky's the largest of its windows'), and whether it was measured (`auto`); `None`
    /// without portals.
    pub fn alpha_of(&self, source: Source) -> Option<(f32, bool)> {
        let auto = |i: usize| self.desc.portals.get(i).is_some_and(|d| d.auto_alpha);
        let alphas: Vec<(f32, bool)> = match source {
            Source::Light(light) => self
                .portals
                .iter()
                .filter(|p| p.light == light)
                .map(|p| (p.alpha, auto(p.desc_index)))
                .collect(),
            Source::Environment => self
                .windows
                .iter()
                .map(|w| (w.alpha, auto(w.desc_index)))
                .collect(),
        };
        alphas
            .into_iter()
            .reduce(|a, b| if b.0 > a.0 { b } else { a })
    }

    /// Whether some portal's alpha is `auto` and not measured yet.
    pub fn alpha_pending(&self) -> bool {
        self.portals.iter().any(|p| p.alpha_pending) || self.windows.iter().any(|w| w.alpha_pending)
    }

    /// Measures the leaks behind `auto` portals and sets their alpha (`seed` fixes the rays).
    pub fn resolve_auto_alpha(&mut self, seed: u64) {
        let lights: Vec<usize> = (0..self.geometry.lights.len())
            .filter(|&i| self.portals.iter().any(|p| p.light == i && p.alpha_pending))
            .collect();
        let scene = &*self;
        let alphas: Vec<(usize, f32)> = lights
            .into_par_iter()
            .map(|i| {
                let check = check_light(scene, i, &light_openings(scene, i), seed);
                (i, check.auto_alpha())
            })
            .collect();
        for (i, alpha) in alphas {
            for p in self
                .portals
                .iter_mut()
                .filter(|p| p.light == i && p.alpha_pending)
            {
                p.alpha = alpha;
                p.alpha_pending = false;
            }
        }
        if self.windows.iter().any(|w| w.alpha_pending) {
            // The sky's leak is measured directly (escaping rays); the windows' openings only
            // say where it leaks, which alpha does not need.
            let alpha = check_sky(self, &[], seed).auto_alpha();
            for w in self.windows.iter_mut().filter(|w| w.alpha_pending) {
                w.alpha = alpha;
                w.alpha_pending = false;
            }
        }
    }
}
