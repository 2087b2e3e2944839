//! Numerical robustness of the portal techniques (issue #9, item 7): a sampled direction's
//! density is never lost to rounding, near a portal's edge or an antishadow plane. Run in
//! release.

mod common;

use common::*;
use glam::Vec3;
use portalview::asset::builtin;
use portalview::light::estimator::{portal_pdf, projected_light, projection, sample_portal};
use portalview::light::portal::Portal;
use portalview::sampling::polygon::clip_convex;
use portalview::sampling::spherical::SphericalPolygon;
use portalview::sampling::{Frame, Rng, cyclic_pairs};
use portalview::scene::Scene;

/// Every built-in scene, then [`far_small_portal`].
fn builtin_scenes_and_far_small_portal() -> Vec<Scene> {
    let mut scenes: Vec<Scene> = builtin::NAMES
        .iter()
        .map(|name| Scene::open(name).unwrap())
        .collect();
    scenes.push(far_small_portal());
    scenes
}

/// A 4 cm portal tilted off the vertical, far from the world origin, under a 60 cm light.
fn far_small_portal() -> Scene {
    let centre = Vec3::new(100.0, 2.5, 50.0);
    let light = square(centre + Vec3::new(0.05, 0.4, -0.03), -Vec3::Y, 0.3);
    let mut desc = floor_and_light(0.5, light, 10.0);
    let normal = Vec3::new(0.35, -1.0, 0.2);
    desc.portals
        .push(portal("small", "light", 0.1, &square(centre, normal, 0.02)));
    Scene::from_desc(desc, "test").unwrap()
}

/// 10^6 portal samples from 100 points 2 m from a 4 cm portal at (100, 2.5, 50): every drawn
/// direction gets a positive portal pdf, equal to the density its draw reported. Negative case:
/// the same directions judged by intersecting the portal in absolute f32 coordinates with an
/// exact edge test (the renderer's former `portal_pdf`) fall outside their own portal about a
/// hundred times, so these points do probe the edges' rounding. (Such a sample's mixture pdf
/// lacked the portal term, `0.9 · p_portal`, about 2000 times `0.1 · p_light` here.)
#[test]
fn far_small_portal_samples_keep_their_pdf() {
    let scene = far_small_portal();
    let portal = &scene.portals[0];
    let frame = Frame::from_normal(portal.polygon.normal());
    let mut rng = Rng::new(17, 3);
    let (mut lost, mut judged_outside_before) = (0usize, 0usize);
    for _ in 0..100 {
        // A direction within 60° of the portal's front normal.
        let cos = 1.0 - 0.5 * rng.uniform();
        let sin = (1.0 - cos * cos).sqrt();
        let phi = std::f32::consts::TAU * rng.uniform();
        let d = frame.to_world(Vec3::new(sin * phi.cos(), sin * phi.sin(), cos));
        let x = portal.polygon.centroid() + 2.0 * d;
        for _ in 0..10_000 {
            let Some((wi, sampled)) = sample_portal(portal, x, rng.uniform2()) else {
                lost += 1;
                continue;
            };
            let evaluated = portal_pdf(portal, x, wi);
            if !(evaluated > 0.0 && (evaluated - sampled).abs() <= 1e-3 * sampled) {
                lost += 1;
            }
            if portal.polygon.intersect(x, wi).is_none() {
                judged_outside_before += 1;
            }
        }
    }
    assert_eq!(lost, 0, "samples whose evaluated pdf is not their own");
    assert!(
        judged_outside_before > 20,
        "only {judged_outside_before} samples fall outside by the absolute test"
    );
}

/// The portal pdf still vanishes a little way outside the portal: the slack is a rounding
/// margin, not a widening. Directions through points 1e-3 of the portal's size outside each
/// edge get 0, those as far inside get the pdf.
#[test]
fn portal_pdf_slack_stays_within_rounding() {
    let scene = far_small_portal();
    let portal = &scene.portals[0];
    let x = portal.polygon.centroid() + 2.0 * (-Vec3::Y + Vec3::new(0.3, 0.0, 0.1)).normalize();
    let c = portal.polygon.centroid();
    for (a, b) in portal.polygon.edges() {
        let mid = 0.5 * (a + b);
        let out = (mid - c).normalize() * 0.04 * 1e-3;
        let inside = (mid - out - x).normalize();
        let outside = (mid + out - x).normalize();
        assert!(portal_pdf(portal, x, inside) > 0.0, "inside edge {a} {b}");
        assert_eq!(portal_pdf(portal, x, outside), 0.0, "outside edge {a} {b}");
    }
}

/// Points `1e-7 · scale` to either side of every candidate antishadow plane of `portal`: planes
/// through a portal edge and a light vertex, and through a light edge and a portal vertex
/// (`docs/method.md` §3), at several places on each plane in front of the portal.
fn points_off_planes(portal: &Portal) -> Vec<Vec3> {
    let p = portal.polygon.vertices();
    let l = portal.planes.light_behind_portal();
    let scale = portal.planes.scale();
    let mut planes: Vec<(Vec3, Vec3, Vec3)> = vec![];
    for (a, b) in portal.polygon.edges() {
        planes.extend(l.iter().map(|&v| (a, b - a, a - v)));
    }
    for (a, b) in cyclic_pairs(l) {
        planes.extend(p.iter().map(|&v| (v, b - a, v - a)));
    }
    let mut points = vec![];
    for (origin, along, away) in planes {
        let Some(n) = along.cross(away).try_normalize() else {
            continue;
        };
        for s in [-0.5, 0.2, 0.5, 0.8, 1.5] {
            for k in [0.3, 1.0, 3.0] {
                let on = origin + s * along + k * scale * away.normalize();
                for side in [-1.0, 1.0] {
                    points.push(on + side * 1e-7 * scale * n);
                }
            }
        }
    }
    points
}

/// Whether every one of `n` samples of `q` gets, evaluated, the positive density it was drawn
/// with: a plane of the inside test cutting through the polygon would zero some of them.
fn samples_keep_their_pdf(q: &SphericalPolygon, n: usize, rng: &mut Rng) -> bool {
    (0..n).all(|_| match q.sample(rng.uniform2()) {
        Some((wi, pdf)) => {
            let evaluated = q.pdf(wi);
            pdf > 0.0 && (evaluated - pdf).abs() <= 1e-3 * pdf
        }
        None => true,
    })
}

/// From points 1e-7·scale off an antishadow plane, a projection's samples all keep their pdf,
/// on every built-in scene, the far small portal, and a tilted pair. Negative case: the same
/// projections built from the unmerged clip (the light's vertices projected from x and clipped
/// to the portal, as before the merge) lose samples at some of these points, so the points do
/// produce the edges of a few ulps that the merge removes.
#[test]
fn projections_near_antishadow_planes_keep_their_pdf() {
    let scenes = builtin_scenes_and_far_small_portal();
    let mut rng = Rng::new(5, 5);
    let (mut checked, mut broken, mut broken_unmerged) = (0usize, vec![], 0usize);
    for scene in &scenes {
        for portal in &scene.portals {
            for x in points_off_planes(portal) {
                let Some(q) = projection(portal, x) else {
                    continue;
                };
                checked += 1;
                if !samples_keep_their_pdf(&q, 200, &mut rng) {
                    broken.push((portal.name.clone(), x));
                }
                let unmerged = unmerged_projection(portal, x);
                if let Some(q) = unmerged.and_then(|v| SphericalPolygon::new(x, &v))
                    && !samples_keep_their_pdf(&q, 200, &mut rng)
                {
                    broken_unmerged += 1;
                }
            }
        }
    }
    assert!(checked > 1000, "only {checked} projections");
    assert!(
        broken.is_empty(),
        "{} of {checked}: {broken:?}",
        broken.len()
    );
    assert!(broken_unmerged > 0, "the unmerged clip never broke");
}

/// `Q(x)` as the renderer built it before merging close vertices.
fn unmerged_projection(portal: &Portal, x: Vec3) -> Option<Vec<Vec3>> {
    let plane = portal.polygon.plane();
    let dx = plane.signed_distance(x);
    let projected: Vec<Vec3> = portal
        .planes
        .light_behind_portal()
        .iter()
        .map(|&v| x + (v - x) * (dx / (dx - plane.signed_distance(v))))
        .collect();
    let q = clip_convex(&projected, &portal.polygon);
    (q.len() >= 3).then(|| q.to_vec())
}

/// `Q(x)` comes wound clockwise as seen from `x` (its Newell normal about `x` pointing away
/// from it), the winding `SphericalPolygon::set` takes without reversing it in f64: the
/// projection keeps the winding of the light seen from `x`, which the portal's planes know
/// (`AntishadowPlanes::projection_winds_counter_clockwise`). Checked from random points in
/// front of every portal of every built-in scene, and the far small portal.
#[test]
fn projections_come_wound_clockwise_from_x() {
    let scenes = builtin_scenes_and_far_small_portal();
    let mut rng = Rng::new(7, 7);
    let mut checked = 0usize;
    for scene in &scenes {
        for portal in &scene.portals {
            let frame = Frame::from_normal(portal.polygon.normal());
            let scale = portal.planes.scale();
            for _ in 0..400 {
                let u = rng.uniform2();
                let (a, b) = (4.0 * u.x - 2.0, 4.0 * u.y - 2.0);
                let x = portal.polygon.centroid()
                    + scale * (a * frame.t + b * frame.b + (0.05 + 2.0 * rng.uniform()) * frame.n);
                let q = projected_light(portal, x);
                if q.len() < 3 {
                    continue;
                }
                let xd = x.as_dvec3();
                let offsets: Vec<_> = q.iter().map(|v| v.as_dvec3() - xd).collect();
                let twice_area: glam::DVec3 = cyclic_pairs(&offsets)
                    .map(|(r, r_next)| r.cross(r_next - r))
                    .sum();
                let mean: glam::DVec3 = offsets.iter().sum();
                assert!(
                    twice_area.dot(mean) > 0.0,
                    "{}: Q({x}) winds counter-clockwise from x",
                    portal.name
                );
                checked += 1;
            }
        }
    }
    assert!(checked > 1000, "only {checked} projections");
}
