//! Where a light behind portals lights its own enclosure directly (`docs/method.md` §10): the
//! box around the points its rays first meet behind every one of its portals. There the
//! estimator samples the light itself (no portal applies), and the light tree gives the light
//! its enclosure's share; a shade that bulges beyond its rims (a bell, a globe) is inside that
//! box, where the box around the light and its portals alone would leave its bulge out.

use glam::Vec3;

use super::Scene;
use super::portals::depth;
use crate::light::MAX_TERMS;
use crate::sampling::{Frame, Rng, sample_cosine_hemisphere};

/// Rays drawn from each light.
const RAYS: usize = 1024;
/// The farthest share of the points met is left out: a small leak (a gap between a shade and
/// its bulb's cap) ends on the room's walls, and would stretch the box over the room.
const FARTHEST_DROPPED: f32 = 0.02;
/// Fixes the rays: the box is part of the scene, the same in every render.
const SEED: u64 = 0x454e_434c;

/// The box (lo, hi) where light `index` lights its enclosure: around the light, its portals,
/// and the points its rays first meet behind all its portals (those the estimator uses, the
/// first [`MAX_TERMS`]) without crossing one. `None` for a light without portals.
pub fn enclosure_box(scene: &Scene, index: usize) -> Option<(Vec3, Vec3)> {
    let light = scene.geometry.lights.get(index)?;
    let portals: Vec<_> = scene
        .portals
        .iter()
        .filter(|p| p.light == index)
        .take(MAX_TERMS)
        .collect();
    if portals.is_empty() {
        return None;
    }
    let eps = 1e-4 * scene.geometry.scale();
    let mut rng = Rng::keyed(SEED, &[index as u64]);
    let mut met: Vec<(f32, Vec3)> = Vec::new();
    for _ in 0..RAYS {
        let u = rng.uniform2();
        let side = rng.uniform();
        let direction = sample_cosine_hemisphere(rng.uniform2());
        let Some(point) = light.sample_point(u) else {
            continue;
        };
        let n = if light.double_sided && side < 0.5 {
            -point.n
        } else {
            point.n
        };
        let d = Frame::from_normal(n).to_world(direction);
        let o = point.p + n * eps;
        let t = depth(scene, Some(index), o, d);
        if !t.is_finite() {
            continue;
        }
        let crosses = portals
            .iter()
            .any(|p| p.polygon.intersect(o, d).is_some_and(|s| s < t));
        let x = o + d * t;
        // In front of a portal the estimator samples through it: not the enclosure.
        let behind_all = portals
            .iter()
            .all(|p| p.planes.portal_plane().signed_distance(x) <= 0.0);
        if !crosses && behind_all {
            met.push((x.distance(light.centroid()), x));
        }
    }
    met.sort_by(|a, b| a.0.total_cmp(&b.0));
    let kept = met.len() - (FARTHEST_DROPPED * met.len() as f32) as usize;
    let box_of = light
        .corners()
        .chain(
            portals
                .iter()
                .flat_map(|p| p.polygon.vertices().iter().copied()),
        )
        .chain(met[..kept].iter().map(|&(_, x)| x))
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    Some(box_of)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The lampshade's enclosure reaches its shade and no farther: the room's walls and
    /// floor, met by the light that leaves through the openings, are not in it.
    #[test]
    fn the_lampshade_box_holds_its_shade_and_not_the_room() {
        let scene = Scene::open("lampshade").expect("built-in");
        let index = scene.portals[0].light;
        let (lo, hi) = enclosure_box(&scene, index).expect("the light has portals");
        let (room_lo, room_hi) = scene.geometry.bounds;
        let size = (hi - lo).length();
        assert!(size > 0.0);
        assert!(size < 0.5 * (room_hi - room_lo).length(), "{lo} {hi}");
        assert!(enclosure_box(&scene, usize::MAX).is_none());
    }
}
