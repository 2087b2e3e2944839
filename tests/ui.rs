//! The real viewer driven by egui_kittest with software Vulkan (Mesa llvmpipe): strategy,
//! sampler, mixture and light selection switching reach the worker, overlays change pixels (the
//! light selection's with its legend and inspector line), portal edits restart accumulation and
//! change the overlay, saving round-trips, and snapshots of the main panels.

use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use glam::Vec3;
use portalview::app::PortalViewApp;
use portalview::app::overlay::{OverlayKind, spread_colour};
use portalview::light::antishadow::Region;
use portalview::light::{Mixture, Selection, Strategy};
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

/// The guide-bounces buttons restart the render with the chosen setting, and back: with the
/// bounces guided through the lampshade's portals, more of the second vertices lie inside the
/// shade, behind both portals, than with the BSDF alone.
#[test]
fn switching_guide_bounces_restarts_the_render_with_it() {
    use portalview::render::integrator::GuideBounces;
    let _serial = serial();
    let mut h = harness("lampshade");
    step_until(&mut h, "first frame", has_full_frame);
    assert_eq!(h.state().settings.max_depth, 2);
    let behind_share = |a: &PortalViewApp| {
        let s = a.frame().unwrap().stats;
        s.regions[0] as f64 / s.regions.iter().sum::<u64>() as f64
    };
    let mut shares = Vec::new();
    // On is the default: off first, then back.
    for (label, bounces) in [("off", GuideBounces::Off), ("on", GuideBounces::On)] {
        click_until_restarted(&mut h, label);
        assert_eq!(h.state().settings.bounces, bounces);
        assert_eq!(h.state().render_settings().bounces, bounces);
        shares.push(behind_share(h.state()));
    }
    assert!(
        shares[1] > 1.2 * shares[0],
        "shading points behind the portals {shares:?}"
    );
}

/// The light selection buttons restart the render with the chosen selection, and back;
/// `view --light-selection` sets the one it starts with.
#[test]
fn switching_the_light_selection_restarts_the_render_with_it() {
    use clap::Parser;
    use portalview::cli::{Cli, Command};
    let cli = Cli::try_parse_from(["portalview", "view", "--light-selection", "power"]).unwrap();
    let Some(Command::View(view)) = cli.command else {
        panic!("not a view command");
    };
    let options: portalview::app::ViewOptions = view.into();
    assert_eq!(options.selection, Some(Selection::Power));
    let _serial = serial();
    let mut h = harness("desklamp");
    step_until(&mut h, "first frame", has_full_frame);
    assert_eq!(h.state().render_settings().selection, Selection::Tree);
    // The tree is the default: power first, then back.
    for (label, selection) in [("power", Selection::Power), ("tree", Selection::Tree)] {
        click_until_restarted(&mut h, label);
        assert_eq!(h.state().settings.selection, selection);
        assert_eq!(h.state().render_settings().selection, selection);
    }
}

/// The *light selection* overlay colours each pixel by how many lights carry most of the
/// tree's picks there, with its legend, and the inspector gives the count under the mouse.
/// Snapshot: the overlay opaque over an image darkened to black (exposure −8), paused, the
/// status bar (spp and time) blanked, so that what is compared does not depend on timing.
#[test]
fn the_light_selection_overlay_draws_with_its_legend() {
    let _serial = serial();
    let mut h = harness_with("desklamp", |app| {
        app.settings.overlay = OverlayKind::LightSelection;
        app.settings.overlay_opacity = 1.0;
        app.settings.exposure = -8.0;
    });
    step_until(&mut h, "first frame", has_full_frame);
    h.state_mut().set_paused(true);
    h.run_steps(3);
    let primary = h.state().frame().unwrap().primary.clone().unwrap();
    let mut counts = std::collections::BTreeMap::new();
    for &n in primary.spread.iter().flatten() {
        *counts.entry(n).or_insert(0usize) += 1;
    }
    // Most pixels see a surface some light reaches; under the shade the lamp in it takes
    // nearly every pick, elsewhere the ceiling's lamp shares them.
    assert!(
        primary.spread.iter().flatten().count() > primary.spread.len() / 2
            && counts.contains_key(&1)
            && counts.keys().any(|&n| n >= 2),
        "pixels per count of lights {counts:?}"
    );
    // The legend names the buckets and says what is counted, and for which tree.
    assert!(h.query_by_label("1 light").is_some());
    assert!(h.query_by_label("16 or more lights").is_some());
    assert!(h.query_by_label("lights carrying 90% of picks").is_some());
    assert!(
        h.query_by_label("(the light tree, as under antishadow)")
            .is_some()
    );
    // The overlay is opaque: where a pixel's hit projects on screen, the buckets' colour of
    // its count shows (but for a few pixels under outlines and the gizmo).
    let image = h.render().unwrap();
    let (w, ht) = (primary.width as usize, primary.height as usize);
    let (mut seen, mut matched, mut inspected) = (0, 0, None);
    for (px, py) in (1..10).flat_map(|i| (1..10).map(move |j| (i * w / 10, j * ht / 10))) {
        let i = py * w + px;
        let (Some(lights), Some(hit)) = (primary.spread[i], primary.points[i]) else {
            continue;
        };
        let Some(pos) = h.state().image_point(hit) else {
            continue;
        };
        seen += 1;
        let pixel = image.get_pixel(pos.x as u32, pos.y as u32).0;
        let colour = spread_colour(lights);
        if pixel[..3] == [colour.r(), colour.g(), colour.b()] {
            matched += 1;
            inspected = Some((pos, lights, hit));
        }
    }
    assert!(seen > 40 && matched * 10 >= seen * 9, "{matched} of {seen}");
    let mut image = image;
    let status = h.get_by_label_contains(" spp").rect();
    for y in (status.min.y as u32).saturating_sub(3)..image.height() {
        for x in 0..image.width() {
            image.put_pixel(x, y, image::Rgba([0, 0, 0, 255]));
        }
    }
    egui_kittest::image_snapshot(&image, "light_selection_overlay");
    // Its legend is as wide as the regions': switching overlays leaves the image where it
    // is (a resized image restarts the render).
    let (pos, lights, hit) = inspected.unwrap();
    for kind in [OverlayKind::Regions, OverlayKind::LightSelection] {
        h.state_mut().settings.overlay = kind;
        h.run_steps(3);
        assert_eq!(h.state().image_point(hit), Some(pos), "{kind:?}");
    }
    // The inspector gives the count of the pixel under the mouse.
    h.hover_at(pos);
    h.run_steps(2);
    let line = format!("lights carrying 90% of picks: {lights}");
    assert!(
        h.query_by_label_contains(&line).is_some(),
        "no inspector line {line:?}"
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
