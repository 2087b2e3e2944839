//! The real viewer driven by egui_kittest with software Vulkan (Mesa llvmpipe): strategy
//! switching reaches the worker, overlays change pixels, portal edits restart accumulation and
//! change the overlay, saving round-trips, and snapshots of the main panels.

use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use glam::Vec3;
use portalview::app::PortalViewApp;
use portalview::app::overlay::OverlayKind;
use portalview::light::antishadow::Region;
use portalview::light::{Mixture, Strategy};
use portalview::sampling::SamplerKind;
mod ui_common;

use ui_common::{
    click_until_restarted, harness_with, has_full_frame, newer_full_frame, save_portals, serial,
    step_until,
};

/// The viewer on `scene`, as built for every test here.
fn harness(scene: &str) -> Harness<'static, PortalViewApp> {
    harness_with(scene, |_| {})
}

#[test]
fn switching_strategy_changes_what_the_worker_renders() {
    let _serial = serial();
    let mut h = harness("fig8a");
    step_until(&mut h, "first frame", has_full_frame);
    // fig8a's object is in the antiantumbra: antishadow samples the portal there.
    let stats = h.state().frame().unwrap().stats;
    assert!(stats.techniques[1] > 0, "no portal samples: {stats:?}");
    h.get_by_label("light").click();
    h.step();
    assert_eq!(h.state().settings.strategy, Strategy::Light);
    let generation = h.state().frame().unwrap().generation;
    step_until(&mut h, "light frame", |a| newer_full_frame(a, generation));
    let stats = h.state().frame().unwrap().stats;
    assert_eq!(
        stats.techniques[1] + stats.techniques[2],
        0,
        "light sampling drew portal samples"
    );
    assert!(stats.techniques[0] > 0);
    // Key 3 selects projection.
    h.key_press(egui::Key::Num3);
    h.step();
    assert_eq!(h.state().settings.strategy, Strategy::Projection);
}

/// The sampler buttons restart the render with the chosen random numbers.
#[test]
fn switching_sampler_restarts_the_render_with_it() {
    let _serial = serial();
    let mut h = harness("fig8b");
    step_until(&mut h, "first frame", has_full_frame);
    for (label, kind) in [
        ("independent", SamplerKind::Independent),
        ("sobol", SamplerKind::Sobol),
    ] {
        click_until_restarted(&mut h, label);
        assert_eq!(h.state().settings.sampler, kind);
        assert_eq!(h.state().render_settings().sampler, kind);
    }
}

/// The mixture buttons restart the render with the chosen estimator: in fig8c, where most
/// shading points draw from both shares, one sample from each traces more shadow rays per
/// camera ray than one sample of the mixture.
#[test]
fn switching_the_mixture_restarts_the_render_with_it() {
    let _serial = serial();
    let mut h = harness("fig8c");
    step_until(&mut h, "first frame", has_full_frame);
    let shadow_rays_per_path = |a: &PortalViewApp| {
        let s = a.frame().unwrap().stats;
        s.shadow_rays as f64 / s.camera_rays as f64
    };
    let mut ratios = Vec::new();
    // One sample is the default: each share first, then back.
    for (label, mixture) in [
        ("each-share", Mixture::EachShare),
        ("one-sample", Mixture::OneSample),
    ] {
        click_until_restarted(&mut h, label);
        assert_eq!(h.state().settings.mixture, mixture);
        assert_eq!(h.state().render_settings().mixture, mixture);
        ratios.push(shadow_rays_per_path(h.state()));
    }
    assert!(
        ratios[0] > 1.2 * ratios[1],
        "shadow rays per path {ratios:?}"
    );
}

#[test]
fn toggling_the_overlay_changes_the_pixels() {
    let _serial = serial();
    let mut h = harness("fig8c");
    step_until(&mut h, "first frame", has_full_frame);
    h.state_mut().set_paused(true);
    h.step();
    let before = h.render().unwrap();
    h.state_mut().settings.overlay = OverlayKind::Regions;
    h.step();
    h.step();
    let after = h.render().unwrap();
    let changed = before
        .pixels()
        .zip(after.pixels())
        .filter(|(a, b)| a != b)
        .count();
    assert!(changed > 10_000, "only {changed} pixels changed");
}

#[test]
fn moving_a_portal_restarts_and_changes_the_overlay() {
    let _serial = serial();
    let mut h = harness("fig8b");
    step_until(&mut h, "first frame", has_full_frame);
    let before = h.state().frame().unwrap().clone();
    let shares = before.primary.as_ref().unwrap().shares(None);
    let antiumbra = |s: [f32; 5]| {
        s[Region::ALL
            .iter()
            .position(|&r| r == Region::Antiumbra)
            .unwrap()]
    };
    // Slide the portal sideways: much of the floor leaves the antiumbra.
    let app = h.state_mut();
    let mut pose = app.editor.pose(0).unwrap();
    app.editor.checkpoint();
    pose.center += Vec3::new(0.9, 0.0, 0.0);
    app.editor.set_pose(0, pose);
    app.apply_portal_edit();
    step_until(&mut h, "frame after the edit", |a| {
        newer_full_frame(a, before.generation)
    });
    let after = h.state().frame().unwrap();
    assert!(
        after.spp < before.spp + 1000,
        "accumulation did not restart"
    );
    let moved = after.primary.as_ref().unwrap().shares(None);
    assert!(
        antiumbra(moved) < antiumbra(shares) - 0.05,
        "{shares:?} -> {moved:?}"
    );
    // Undo from the Edit menu puts it back.
    h.get_by_label("Edit").click();
    h.run_steps(2);
    h.get_by_label("Undo  (Ctrl+Z)").click();
    h.run_steps(2);
    assert_eq!(
        h.state().editor.portals,
        portalview::scene::Scene::open("fig8b")
            .unwrap()
            .desc
            .portals
    );
}

#[test]
fn save_then_load_round_trips_the_portals() {
    let _serial = serial();
    let dir = std::env::temp_dir().join(format!("portalview-ui-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("fig8b.glb");
    std::fs::copy(
        concat!(env!("CARGO_MANIFEST_DIR"), "/assets/fig8b.glb"),
        &path,
    )
    .unwrap();
    let mut h = harness(path.to_str().unwrap());
    h.step();
    let app = h.state_mut();
    let mut pose = app.editor.pose(0).unwrap();
    app.editor.checkpoint();
    pose.center += Vec3::new(0.1, 0.0, -0.05);
    pose.scale *= 1.2;
    app.editor.set_pose(0, pose);
    app.editor.portals[0].alpha = 0.25;
    app.apply_portal_edit();
    let edited = app.editor.portals[0].world_triangles();
    save_portals(&mut h, &path);
    assert!(!h.state().editor.dirty);
    let reloaded = portalview::scene::Scene::load(&path).unwrap();
    let portal = &reloaded.desc.portals[0];
    assert!((portal.alpha - 0.25).abs() < 1e-6);
    for (a, b) in portal
        .world_triangles()
        .iter()
        .flatten()
        .zip(edited.iter().flatten())
    {
        assert!(a.abs_diff_eq(*b, 1e-4), "{a} vs {b}");
    }
    // Everything but the portal is as it was.
    let original = portalview::scene::Scene::load(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/assets/fig8b.glb"
    )))
    .unwrap();
    assert_eq!(reloaded.desc.meshes, original.desc.meshes);
    assert_eq!(reloaded.desc.materials, original.desc.materials);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Snapshots of the main panels, with rendering paused before the first pass so that the
/// image is deterministic (outlines and gizmo over a black viewport; every panel drawn).
#[test]
fn snapshot_main_panels() {
    let _serial = serial();
    let mut h = harness_with("lampshade", |app| app.set_paused(true));
    h.run_steps(4);
    h.snapshot("main_window");
    h.state_mut().settings.overlay = OverlayKind::Techniques;
    h.state_mut().settings.show_volumes = true;
    h.run_steps(2);
    h.snapshot("overlay_controls");
}
