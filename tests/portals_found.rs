//! Portals that place themselves: on every built-in with its portals removed, finding
//! recovers the hand-placed openings; checking flags what is wrong with a scene's portals; the
//! `auto` alpha comes out at its minimum where the portals cover every opening.

use glam::Vec3;
use portalview::asset::builtin;
use portalview::asset::desc::PortalDesc;
use portalview::sampling::polygon::{ConvexPolygon, clip_convex, polygon_area};
use portalview::scene::Scene;
use portalview::scene::portals::{self, MIN_AUTO_ALPHA};

/// The area of the overlap of `found` with `hand`, over the area of their union (`found`
/// projected onto `hand`'s plane first: the two are a few millimetres apart at most).
fn iou(found: &PortalDesc, hand: &PortalDesc) -> f32 {
    let hand = ConvexPolygon::from_triangles(&hand.world_triangles()).unwrap();
    let found = ConvexPolygon::from_triangles(&found.world_triangles()).unwrap();
    // A portal onto an area light faces away from it whatever its winding (`Portal::new`).
    if found.normal().dot(hand.normal()).abs() < 0.99 {
        return 0.0;
    }
    let plane = hand.plane();
    let projected: Vec<Vec3> = found
        .vertices()
        .iter()
        .map(|&p| p - hand.normal() * plane.signed_distance(p))
        .collect();
    let overlap = polygon_area(&clip_convex(&projected, &hand));
    overlap / (found.area() + hand.area() - overlap)
}

#[test]
fn find_recovers_the_hand_placed_portals() {
    for name in builtin::NAMES {
        let scene = Scene::open(name).unwrap();
        let bare = scene.with_portals(Vec::new()).unwrap();
        let found = portals::find(&bare);
        for source in &found.sources {
            for note in &source.notes {
                println!("{name}: {}: {note}", source.name);
            }
        }
        for hand in &scene.desc.portals {
            let best = found
                .portals
                .iter()
                .filter(|f| f.target == hand.target)
                .map(|f| (iou(f, hand), f))
                .max_by(|a, b| a.0.total_cmp(&b.0));
            let (score, f) =
                best.unwrap_or_else(|| panic!("{name}: nothing found for {}", hand.name));
            println!("{name}: {} -> {}: IoU {score:.4}", hand.name, f.name);
            assert!(score >= 0.9, "{name}: {} found with IoU {score}", hand.name);
        }
        // Every found portal is one of the hand-placed openings: finding keeps no opening
        // that carries less than 1% of its light, so an extra one would carry more.
        for f in &found.portals {
            let matched = scene
                .desc
                .portals
                .iter()
                .any(|hand| hand.target == f.target && iou(f, hand) >= 0.9);
            assert!(matched, "{name}: an extra portal {} was found", f.name);
        }
    }
}
