//! The viewer on scenes lit by the sky through window portals (egui_kittest, software
//! Vulkan): the strategies reach the worker, the overlay shows which windows a point sees the
//! sky through, Flip and Add window portal work from their buttons, the Environment panel turns
//! the sky off and on, and a moved window and a changed environment are saved into the glTF.

use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use glam::Vec3;
use portalview::app::PortalViewApp;
use portalview::light::Strategy;
use portalview::light::antishadow::Region;
mod ui_common;

use ui_common::{serial, step_until};

/// The viewer on `scene` in a window tall enough that the side panel's Portals and
/// Environment sections are on screen without scrolling (clicks reach only what is shown).
fn harness(scene: &str) -> Harness<'static, PortalViewApp> {
    let scene = scene.to_owned();
    let mut h = Harness::builder()
        .with_size(egui::vec2(1100.0, 1500.0))
        .wgpu()
        .build_eframe(move |cc| PortalViewApp::new(&cc.egui_ctx, None, Some(scene)).unwrap());
    step_until(&mut h, "the first scene", |a| {
        a.scene().is_some() && !a.is_busy()
    });
    h
}

fn has_full_frame(app: &PortalViewApp) -> bool {
    app.frame()
        .is_some_and(|f| !f.preview && f.primary.is_some() && f.spp >= 2)
}

fn newer_full_frame(app: &PortalViewApp, generation: u64) -> bool {
    has_full_frame(app) && app.frame().is_some_and(|f| f.generation > generation)
}

fn share(shares: [f32; 5], region: Region) -> f32 {
    shares[Region::ALL.iter().position(|&r| r == region).unwrap()]
}

#[test]
fn window_strategies_overlay_flip_and_add() {
    let _serial = serial();
    let mut h = harness("windows2");
    step_until(&mut h, "first frame", has_full_frame);
    // Antishadow samples the environment within the windows (counted as projection).
    let frame = h.state().frame().unwrap().clone();
    assert!(frame.stats.techniques[2] > 0, "{:?}", frame.stats);
    // Every lit point of the room is in front of a window: the overlay says so.
    let shares = frame.primary.as_ref().unwrap().shares(None);
    assert!(share(shares, Region::Antiantumbra) > 0.9, "{shares:?}");
    // Portal strategy: window-area samples.
    h.get_by_label("portal").click();
    h.step();
    assert_eq!(h.state().settings.strategy, Strategy::Portal);
    step_until(&mut h, "portal frame", |a| {
        newer_full_frame(a, frame.generation)
    });
    let stats = h.state().frame().unwrap().stats;
    assert!(stats.techniques[1] > 0, "{stats:?}");

    // Select the north window in the list and flip it: the room is now behind it.
    h.get_by_label("window_north (window)").click();
    h.step();
    assert_eq!(h.state().editor.selected, Some(0));
    let generation = h.state().frame().unwrap().generation;
    let before = h.state().editor.portals[0].clone();
    h.get_by_label("Flip").click();
    h.run_steps(2);
    assert_eq!(h.state().editor.portals[0], before.flipped());
    step_until(&mut h, "frame after flipping", |a| {
        newer_full_frame(a, generation)
    });
    let primary = h.state().frame().unwrap().primary.clone().unwrap();
    // Regions of the north window alone (portal index 0 of the overlay): behind everywhere.
    let behind = share(primary.shares(Some(0)), Region::Behind);
    assert!(behind > 0.99, "after Flip: {:?}", primary.shares(Some(0)));

    // Add window portal: a new window, selected, valid.
    h.get_by_label("Add window portal").click();
    h.run_steps(2);
    let app = h.state();
    assert_eq!(app.editor.portals.len(), 3);
    assert!(app.editor.portals[2].is_window());
    assert_eq!(app.editor.selected, Some(2));
}

#[test]
fn environment_panel_turns_the_sky_off_and_on_and_saves() {
    let _serial = serial();
    let dir = std::env::temp_dir().join(format!("portalview-ui-env-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for file in ["window.glb", "window_environment.hdr"] {
        std::fs::copy(
            format!("{}/assets/{file}", env!("CARGO_MANIFEST_DIR")),
            dir.join(file),
        )
        .unwrap();
    }
    let path = dir.join("window.glb");
    let mut h = harness(path.to_str().unwrap());
    step_until(&mut h, "first frame", has_full_frame);
    let lit = h.state().frame().unwrap().clone();
    let mean = |f: &portalview::render::worker::Frame| {
        f.pixels
            .iter()
            .map(|p| (p.x + p.y + p.z) as f64)
            .sum::<f64>()
            / f.pixels.len() as f64
    };
    assert!(mean(&lit) > 0.0);

    // Off: the room goes black.
    h.get_by_label("Off").click();
    h.run_steps(2);
    assert!(h.state().scene().unwrap().environment.is_none());
    step_until(&mut h, "dark frame", |a| {
        newer_full_frame(a, lit.generation)
    });
    assert_eq!(mean(h.state().frame().unwrap()), 0.0);

    // A constant sky, then a stronger one: brighter.
    h.get_by_label("Constant").click();
    h.run_steps(2);
    let generation = h.state().frame().unwrap().generation;
    step_until(&mut h, "constant frame", |a| {
        newer_full_frame(a, generation)
    });
    let constant = mean(h.state().frame().unwrap());
    assert!(constant > 0.0);

    // Move the window a little, and save portals and environment through the File menu.
    let app = h.state_mut();
    let mut pose = app.editor.pose(0).unwrap();
    app.editor.checkpoint();
    pose.center += Vec3::new(0.1, 0.0, 0.0);
    app.editor.set_pose(0, pose);
    app.apply_portal_edit();
    h.get_by_label("File").click();
    h.run_steps(2);
    h.get_by_label("Save portals").click();
    h.run_steps(2);
    step_until(&mut h, "saved", |a| !a.is_busy());
    assert_eq!(
        h.state().message(),
        Some(&*format!("saved {}", path.display()))
    );
    let reloaded = portalview::scene::Scene::load(&path).unwrap();
    let environment = reloaded.desc.environment.clone().unwrap();
    assert_eq!(
        environment.map,
        portalview::asset::environment::EnvMap::Constant(Vec3::ONE)
    );
    assert!(reloaded.desc.portals[0].is_window());
    let moved = reloaded.desc.portals[0].world_triangles();
    let original = portalview::scene::Scene::open("window")
        .unwrap()
        .desc
        .portals[0]
        .world_triangles();
    assert!(moved[0][0].abs_diff_eq(original[0][0] + Vec3::new(0.1, 0.0, 0.0), 1e-4));
    let _ = std::fs::remove_dir_all(&dir);
}
