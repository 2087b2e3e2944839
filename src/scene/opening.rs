//! Fitting a window portal to the opening under the mouse: the hole in a wall that a camera
//! ray passes through. Only the scene's own rays are used, so any mesh works (zero-thickness
//! walls as the built-ins have, or thick walls with reveals).
//!
//! 1. Rays around the mouse's (in growing rings on the image) hit the surfaces around the
//!    opening; each hit gives a candidate plane (its triangle's plane, facing the camera).
//! 2. A plane is the wall of an opening if the mouse ray crosses it before hitting anything,
//!    at a point where a short probe perpendicular to the plane finds no surface (a hole), and
//!    the plane's surface encloses that point on all four sides.
//! 3. In the nearest such plane, the probe marches outward from the crossing along the wall's
//!    two axes (up, projected into the plane, and across), stopping where it meets the wall,
//!    refined by bisection; scans at several levels widen the rectangle to the opening's
//!    bounding box, so a non-rectangular (convex) opening is covered.

use glam::{Vec2, Vec3};

use super::Scene;
use crate::camera::Camera;

/// A rectangle fitted to an opening, in the wall's plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Opening {
    /// Counter-clockwise about `normal`, so that a portal made from them faces it.
    pub corners: [Vec3; 4],
    /// The wall's normal on the camera's side: into the room.
    pub normal: Vec3,
    /// Width (along the wall, horizontal where the wall is not) and height.
    pub size: Vec2,
}

/// Rings of rays around the mouse's, as offsets in normalised image coordinates.
const RING_RADII: [f32; 7] = [0.01, 0.03, 0.06, 0.1, 0.18, 0.3, 0.5];
const RING_RAYS: usize = 16;
/// Marching steps per scene size, and bisection steps after a step meets the wall.
const STEPS_PER_SCALE: f32 = 400.0;
const BISECTIONS: usize = 24;
/// Levels scanned across the rectangle when widening it to the opening's bounding box.
const SCAN_LEVELS: usize = 15;

/// A plane `{x : normal · x = offset}`.
#[derive(Clone, Copy, Debug)]
struct WallPlane {
    normal: Vec3,
    offset: f32,
}

/// The ray queries of one fit.
struct Probe<'a> {
    scene: &'a Scene,
    /// Length tolerance: probe offsets and plane matching.
    eps: f32,
    step: f32,
    /// How far an opening may extend from the mouse's point.
    reach: f32,
}

impl Probe<'_> {
    /// Whether the wall's surface is at `q` (a probe from just in front of the plane, along
    /// its normal, meets something within a hair behind it).
    fn wall_at(&self, q: Vec3, normal: Vec3) -> bool {
        let origin = q + normal * self.eps;
        self.scene
            .geometry
            .bvh
            .occluded(origin, -normal, 0.0, 2.0 * self.eps)
    }

    /// Distance from `start` (in the opening) along `dir` to the wall, if within reach.
    fn march(&self, start: Vec3, dir: Vec3, normal: Vec3) -> Option<f32> {
        let mut inside = 0.0;
        let mut s = self.step;
        while s <= self.reach {
            if self.wall_at(start + dir * s, normal) {
                let mut wall = s;
                for _ in 0..BISECTIONS {
                    let mid = 0.5 * (inside + wall);
                    if self.wall_at(start + dir * mid, normal) {
                        wall = mid;
                    } else {
                        inside = mid;
                    }
                }
                return Some(0.5 * (inside + wall));
            }
            inside = s;
            s += self.step;
        }
        None
    }
}

/// The rectangle of the opening that the camera ray through `ndc` (normalised image
/// coordinates, origin top-left, for an image of aspect `aspect`) passes through, if there is
/// one; `None` where the ray meets a wall, or passes no enclosed hole in a plane.
pub fn fit_opening(scene: &Scene, camera: &Camera, ndc: Vec2, aspect: f32) -> Option<Opening> {
    let scale = scene.geometry.scale();
    let probe = Probe {
        scene,
        eps: 1e-4 * scale,
        step: scale / STEPS_PER_SCALE,
        reach: scale,
    };
    let (o, d) = camera.ray(ndc, aspect);
    // A glazed opening is an opening: the panes are looked through.
    let t_mouse = scene
        .geometry
        .closest_hit_through_panes(o, d, 0.0, f32::INFINITY)
        .map_or(f32::INFINITY, |h| h.t);
    // Where the mouse ray crosses each candidate plane, nearest first.
    let mut crossings: Vec<(f32, Vec3)> = candidate_planes(scene, camera, ndc, aspect, probe.eps)
        .into_iter()
        .filter_map(|plane| {
            let along = d.dot(plane.normal);
            (along < -1e-3).then(|| ((plane.offset - plane.normal.dot(o)) / along, plane.normal))
        })
        // The mouse ray must reach the plane before anything else: through a hole in it.
        .filter(|&(t, _)| t > 0.0 && t < t_mouse - probe.eps)
        .collect();
    crossings.sort_by(|a, b| a.0.total_cmp(&b.0));
    crossings.into_iter().find_map(|(t, normal)| {
        let crossing = o + d * t;
        if probe.wall_at(crossing, normal) {
            return None;
        }
        fit_in_plane(&probe, crossing, normal)
    })
}

/// The planes of the surfaces hit by rays in rings around the mouse's, each facing the
/// camera, without repeats.
fn candidate_planes(
    scene: &Scene,
    camera: &Camera,
    ndc: Vec2,
    aspect: f32,
    eps: f32,
) -> Vec<WallPlane> {
    let geometry = &scene.geometry;
    let mut planes: Vec<WallPlane> = Vec::new();
    for r in RING_RADII {
        for k in 0..RING_RAYS {
            let a = std::f32::consts::TAU * (k as f32 + 0.5) / RING_RAYS as f32;
            // Rings are round on screen: the horizontal offset is divided by the aspect.
            let p = ndc + Vec2::new(r * a.cos() / aspect.max(1e-3), r * a.sin());
            let (o, d) = camera.ray(p, aspect);
            let Some(hit) = geometry.closest_hit_through_panes(o, d, 0.0, f32::INFINITY) else {
                continue;
            };
            let Some(triangle) = geometry.triangles.get(hit.triangle as usize) else {
                continue;
            };
            let [p0, p1, p2] = triangle.p;
            let Some(mut normal) = (p1 - p0).cross(p2 - p0).try_normalize() else {
                continue;
            };
            if normal.dot(d) > 0.0 {
                normal = -normal;
            }
            let point = o + d * hit.t;
            let plane = WallPlane {
                normal,
                offset: normal.dot(point),
            };
            let known = planes.iter().any(|q| {
                q.normal.dot(plane.normal) > 0.9999 && (q.offset - plane.offset).abs() < 10.0 * eps
            });
            if !known {
                planes.push(plane);
            }
        }
    }
    planes
}

/// The wall's axes: `v` up (world +Y projected into the plane; for a floor or ceiling, world
/// −Z), `u = v × n` across, so that `u × v = n`.
pub(super) fn wall_axes(normal: Vec3) -> (Vec3, Vec3) {
    let up = if normal.y.abs() < 0.95 {
        Vec3::Y
    } else {
        Vec3::NEG_Z
    };
    let v = (up - normal * normal.dot(up)).normalize();
    (v.cross(normal), v)
}

/// The bounding rectangle of the hole around `crossing` in the plane through it with normal
/// `normal`, if the wall encloses it on every side.
fn fit_in_plane(probe: &Probe, crossing: Vec3, normal: Vec3) -> Option<Opening> {
    let (u, v) = wall_axes(normal);
    let at = |x: f32, y: f32| crossing + u * x + v * y;
    // The cross through the mouse's point: the wall must be met on all four sides.
    let mut lo = Vec2::new(
        -probe.march(crossing, -u, normal)?,
        -probe.march(crossing, -v, normal)?,
    );
    let mut hi = Vec2::new(
        probe.march(crossing, u, normal)?,
        probe.march(crossing, v, normal)?,
    );
    // Scans across at several levels widen it to the bounding box of a convex opening.
    for _ in 0..2 {
        let (mut new_lo, mut new_hi) = (lo, hi);
        for k in 0..SCAN_LEVELS {
            let f = (k as f32 + 0.5) / SCAN_LEVELS as f32;
            let centre = 0.5 * (lo + hi);
            // A row at height y, from the middle outward along u; a column likewise.
            let y = lo.y + f * (hi.y - lo.y);
            let start = at(centre.x, y);
            if !probe.wall_at(start, normal) {
                if let Some(l) = probe.march(start, -u, normal) {
                    new_lo.x = new_lo.x.min(centre.x - l);
                }
                if let Some(r) = probe.march(start, u, normal) {
                    new_hi.x = new_hi.x.max(centre.x + r);
                }
            }
            let x = lo.x + f * (hi.x - lo.x);
            let start = at(x, centre.y);
            if !probe.wall_at(start, normal) {
                if let Some(b) = probe.march(start, -v, normal) {
                    new_lo.y = new_lo.y.min(centre.y - b);
                }
                if let Some(t) = probe.march(start, v, normal) {
                    new_hi.y = new_hi.y.max(centre.y + t);
                }
            }
        }
        if new_lo == lo && new_hi == hi {
            break;
        }
        (lo, hi) = (new_lo, new_hi);
    }
    let size = hi - lo;
    (size.min_element() > 0.0).then(|| Opening {
        corners: [
            at(lo.x, lo.y),
            at(hi.x, lo.y),
            at(hi.x, hi.y),
            at(lo.x, hi.y),
        ],
        normal,
        size,
    })
}
