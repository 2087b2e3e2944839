//! The viewer on scenes lit by the sky through window portals (egui_kittest, software
//! Vulkan): the strategies reach the worker, the overlay shows which windows a point sees the
//! sky through, Flip and Add window portal work from their buttons, the Environment panel turns
//! the sky off and on, and a moved window and a changed environment are saved into the glTF.

use clap::Parser;
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use glam::Vec3;
use portalview::app::PortalViewApp;
use portalview::cli::{Cli, Command};
use portalview::light::Strategy;
use portalview::light::antishadow::Region;
use portalview::sampling::polygon::ConvexPolygon;
mod ui_common;

use ui_common::{
    click_save_portals, has_full_frame, newer_full_frame, save_portals, serial, step_until,
};

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
    // The legend says what antishadow samples in front of a window: projection, not portal.
    h.get_by_label("antiantumbra: projection");
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

    // Add window portal, then a click on the north window's opening: a window fitted to it,
    // selected, facing into the room; undone by Ctrl+Z.
    h.get_by_label("Add window portal").click();
    h.run_steps(2);
    assert!(h.state().is_placing_window());
    let north = polygon(&h.state().scene().unwrap().desc.portals[0]);
    let at = h.state().image_point(north.centroid()).unwrap();
    click_at(&mut h, at, egui::PointerButton::Primary);
    let app = h.state();
    assert!(!app.is_placing_window());
    assert_eq!(app.editor.portals.len(), 3);
    assert!(app.editor.portals[2].is_window());
    assert_eq!(app.editor.selected, Some(2));
    assert!(
        app.message().unwrap().starts_with("window portal fitted"),
        "{:?}",
        app.message()
    );
    let fitted = polygon(&app.editor.portals[2]);
    for v in north.vertices() {
        let d = fitted
            .vertices()
            .iter()
            .map(|f| f.distance(*v))
            .fold(f32::MAX, f32::min);
        assert!(d < 2e-3, "corner {v} is {d} m away");
    }
    // The opening's own window was flipped above; the fitted one faces the room again.
    assert!(fitted.normal().abs_diff_eq(Vec3::Z, 1e-4));
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.run_steps(2);
    assert_eq!(h.state().editor.portals.len(), 2);

    // Right-click on a plain wall, Add window portal here: no opening, so the default square
    // at the camera's target, and a message that says so.
    // (Below the north window: the tall window's image is narrow.)
    let wall = h.state().image_point(Vec3::new(0.0, 0.4, -2.0)).unwrap();
    click_at(&mut h, wall, egui::PointerButton::Secondary);
    h.get_by_label("Add window portal here").click();
    h.run_steps(2);
    let app = h.state();
    assert_eq!(app.editor.portals.len(), 3);
    assert!(app.editor.portals[2].is_window());
    assert!(
        app.message()
            .unwrap()
            .starts_with("no window opening there"),
        "{:?}",
        app.message()
    );
    let square = polygon(&app.editor.portals[2]);
    assert!((square.area() - 1.0).abs() < 1e-4);
    assert!(
        square
            .centroid()
            .abs_diff_eq(app.scene().unwrap().camera.target, 1e-4)
    );
}

fn polygon(portal: &portalview::asset::desc::PortalDesc) -> ConvexPolygon {
    ConvexPolygon::from_triangles(&portal.world_triangles()).unwrap()
}

/// A press and release of `button` at `pos`, with the pointer moved there first.
fn click_at(h: &mut Harness<'static, PortalViewApp>, pos: egui::Pos2, button: egui::PointerButton) {
    h.hover_at(pos);
    h.step();
    for pressed in [true, false] {
        h.event(egui::Event::PointerButton {
            pos,
            button,
            pressed,
            modifiers: egui::Modifiers::NONE,
        });
        h.step();
    }
    h.run_steps(2);
}

/// `portalview view window --environment 0.3,0.5,0.7 --environment-strength 2
/// --environment-rotation -30`: the start-up scene's environment is the command line's (over
/// the scene's built-in sky), and the Environment panel says it is not the file's.
fn app_from_command_line(args: &[&str]) -> Harness<'static, PortalViewApp> {
    let cli = Cli::try_parse_from(args).unwrap();
    let Some(Command::View(view)) = cli.command else {
        panic!("not a view command");
    };
    let options: portalview::app::ViewOptions = view.into();
    let mut h = Harness::builder()
        .with_size(egui::vec2(1100.0, 1500.0))
        .wgpu()
        .build_eframe(move |cc| PortalViewApp::with_options(&cc.egui_ctx, None, options).unwrap());
    step_until(&mut h, "the first scene", |a| {
        a.scene().is_some() && !a.is_busy()
    });
    h
}

const VIEW_WITH_SKY: [&str; 9] = [
    "portalview",
    "view",
    "window",
    "--environment",
    "0.3,0.5,0.7",
    "--environment-strength",
    "2",
    "--environment-rotation",
    "-30",
];

#[test]
fn view_takes_the_environment_flags() {
    let _serial = serial();
    let mut h = app_from_command_line(&VIEW_WITH_SKY);
    let environment = h.state().scene().unwrap().desc.environment.clone().unwrap();
    assert_eq!(
        environment.map,
        portalview::asset::environment::EnvMap::Constant(Vec3::new(0.3, 0.5, 0.7))
    );
    assert_eq!(environment.strength, 2.0);
    assert_eq!(environment.rotation_degrees, -30.0);
    assert!(h.state().scene().unwrap().environment.is_some());
    h.run_steps(2);
    h.get_by_label("unsaved environment (File > Save as .glb…)");
    // Only a strength: the scene's own sky, stronger.
    let h = app_from_command_line(&[
        "portalview",
        "view",
        "window",
        "--environment-strength",
        "3",
    ]);
    let environment = h.state().scene().unwrap().desc.environment.clone().unwrap();
    assert!(matches!(
        environment.map,
        portalview::asset::environment::EnvMap::Image { file: None, .. }
    ));
    assert_eq!(environment.strength, 3.0);
    // A broken one: the error names the file, and the viewer falls back to the default scene.
    let h = app_from_command_line(&[
        "portalview",
        "view",
        "window",
        "--environment",
        "/nonexistent/sky.hdr",
    ]);
    assert!(
        h.state()
            .message()
            .unwrap()
            .contains("/nonexistent/sky.hdr")
    );
}

/// Holding the pointer over the image with the Statistics open (and a constant sky, whose
/// colour button is drawn every frame) must not restart the render: its numbers change every
/// frame, and a line wider than the panel used to widen it, resize the image and restart
/// accumulation, so spp never grew.
#[test]
fn hovering_the_image_keeps_accumulating() {
    let _serial = serial();
    let mut h = app_from_command_line(&VIEW_WITH_SKY);
    h.get_by_label("Statistics").click();
    h.run_steps(2);
    let window = polygon(&h.state().scene().unwrap().desc.portals[0]);
    let over = h
        .state()
        .image_point(window.centroid() - Vec3::new(0.0, 1.0, 0.0))
        .unwrap();
    h.hover_at(over);
    step_until(&mut h, "first frame", has_full_frame);
    let first = h.state().frame().unwrap().clone();
    // A statistic far wider than the panel (a slow first frame).
    h.state_mut().first_frame_latency = Some(std::time::Duration::from_secs(1_000_000_000));
    step_until(&mut h, "four more passes", |a| {
        let f = a.frame().unwrap();
        assert_eq!(f.generation, first.generation, "the render restarted");
        f.spp >= first.spp + 4
    });
    // The pointer is still over the image: the inspector shows.
    h.get_by_label_contains("antishadow uses");
}

#[test]
fn environment_panel_turns_the_sky_off_and_on_and_saves() {
    let _serial = serial();
    let (mut h, path) = harness_on_copy("env");
    let dir = path.parent().unwrap().to_owned();
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

    // Off: the room goes black, once the builder has made the scene without a sky.
    h.get_by_label("Off").click();
    h.run_steps(2);
    step_until(&mut h, "the sky off", |a| {
        !a.is_building() && a.scene().unwrap().environment.is_none()
    });
    step_until(&mut h, "dark frame", |a| {
        newer_full_frame(a, lit.generation)
    });
    assert_eq!(mean(h.state().frame().unwrap()), 0.0);

    // A constant sky, then a stronger one: brighter.
    let generation = h.state().frame().unwrap().generation;
    h.get_by_label("Constant").click();
    h.run_steps(2);
    step_until(&mut h, "constant frame", |a| {
        !a.is_building() && newer_full_frame(a, generation)
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
    save_portals(&mut h, &path);
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

/// `window` copied into a fresh folder (saving writes into it): the harness on it.
fn harness_on_copy(tag: &str) -> (Harness<'static, PortalViewApp>, std::path::PathBuf) {
    let dir = std::env::temp_dir().join(format!("portalview-ui-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for file in ["window.glb", "window_environment.hdr"] {
        std::fs::copy(
            format!("{}/assets/{file}", env!("CARGO_MANIFEST_DIR")),
            dir.join(file),
        )
        .unwrap();
    }
    let path = dir.join("window.glb");
    (harness(path.to_str().unwrap()), path)
}

/// The window turned by `angle` about the vertical through its centre (other axes, so its
/// table cannot be reused), as an undoable edit of the editor.
fn turn_window(app: &mut PortalViewApp, angle: f32) {
    let mut pose = app.editor.pose(0).unwrap();
    app.editor.checkpoint();
    pose.rotation = glam::Quat::from_rotation_y(angle) * pose.rotation;
    app.editor.set_pose(0, pose);
}

/// A turned window needs a new guided table: the edit returns at once with the window in the
/// rendered scene but without its table (sampled by solid angle meanwhile), the render goes on,
/// and the built scene arrives from the background and is rendered. Undo works the same way.
/// A save made while a table builds writes the latest edit.
#[test]
fn a_turned_window_renders_at_once_and_its_table_arrives_later() {
    let _serial = serial();
    let (mut h, path) = harness_on_copy("turn");
    step_until(&mut h, "first frame", has_full_frame);
    let generation = h.state().frame().unwrap().generation;
    assert!(h.state().rendered().unwrap().windows[0].is_guided());

    // No table is built on the UI thread: the edit is rendered without it.
    let app = h.state_mut();
    turn_window(app, 0.1);
    app.apply_portal_edit();
    assert!(app.is_building());
    let rendered = app.rendered().unwrap();
    assert!(rendered.lacks_tables());
    let turned = polygon(&app.editor.portals[0]);
    assert!(
        rendered.windows[0]
            .polygon
            .normal()
            .abs_diff_eq(turned.normal(), 1e-5)
    );
    h.step();
    if h.state().is_building() {
        h.get_by_label_contains("building window tables");
    }
    step_until(&mut h, "the window's table", |a| !a.is_building());
    assert!(!h.state().rendered().unwrap().lacks_tables());
    assert!(h.state().rendered().unwrap().windows[0].is_guided());
    step_until(&mut h, "a frame of the built scene", |a| {
        newer_full_frame(a, generation)
    });

    // Undo: the original axes again, whose table was dropped: built again in the background.
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.run_steps(2);
    step_until(&mut h, "the undone window's table", |a| {
        !a.is_building() && !a.rendered().unwrap().lacks_tables()
    });
    assert_eq!(
        h.state().editor.portals,
        h.state().scene().unwrap().desc.portals
    );

    // Turn it further and save at once, while its table builds: the file has the turn.
    let app = h.state_mut();
    turn_window(app, 0.2);
    app.apply_portal_edit();
    assert!(app.is_building());
    let edited = app.editor.portals[0].world_triangles();
    save_portals(&mut h, &path);
    let saved = portalview::scene::Scene::load(&path).unwrap().desc.portals[0].world_triangles();
    for (a, b) in saved.iter().flatten().zip(edited.iter().flatten()) {
        assert!(a.abs_diff_eq(*b, 1e-4), "saved {a}, edited {b}");
    }
    // The file read back is on screen, with its table.
    assert!(!h.state().is_building());
    assert!(!h.state().rendered().unwrap().lacks_tables());
    if let Some(dir) = path.parent() {
        let _ = std::fs::remove_dir_all(dir);
    }
}

/// An environment edit builds the environment and its windows' tables in the background while
/// the old scene renders; a save made meanwhile writes the new environment.
#[test]
fn an_environment_edit_builds_in_the_background_and_saves() {
    let _serial = serial();
    let (mut h, path) = harness_on_copy("env");
    step_until(&mut h, "first frame", has_full_frame);
    let before = h.state().scene().unwrap().desc.environment.clone().unwrap();
    assert!(matches!(
        before.map,
        portalview::asset::environment::EnvMap::Image { .. }
    ));
    // A constant sky: while it builds, the scene keeps the old one.
    h.get_by_label("Constant").click();
    for _ in 0..2 {
        h.step();
        if h.state().is_building() {
            assert_eq!(
                h.state().scene().unwrap().desc.environment,
                Some(before.clone())
            );
            break;
        }
    }
    step_until(&mut h, "the constant sky", |a| {
        !a.is_building()
            && a.scene().unwrap().desc.environment.as_ref().map(|e| &e.map)
                == Some(&portalview::asset::environment::EnvMap::Constant(Vec3::ONE))
    });
    assert!(h.state().rendered().unwrap().environment.is_some());
    // Off, then save at once (before or after the quick build is taken; saving writes the
    // edited environment either way): the file has no sky.
    h.get_by_label("Off").click();
    h.step();
    click_save_portals(&mut h);
    step_until(&mut h, "saved", |a| !a.is_busy() && !a.is_building());
    let reloaded = portalview::scene::Scene::load(&path).unwrap();
    assert!(reloaded.desc.environment.is_none());
    assert!(h.state().scene().unwrap().environment.is_none());
    if let Some(dir) = path.parent() {
        let _ = std::fs::remove_dir_all(dir);
    }
}

/// *Find portals* on `window` with its portal deleted proposes a window portal over the
/// opening (alpha auto), and the check that follows finds no leak; a flipped window is then
/// flagged by *Check portals*, in red in the panel; Undo brings the deleted portal back.
#[test]
fn find_and_check_portals_from_the_panel() {
    let _serial = serial();
    let mut h = harness("window");
    step_until(&mut h, "first frame", has_full_frame);
    let hand = h.state().editor.portals.clone();
    h.get_by_label("window_north (window)").click();
    h.step();
    h.get_by_label("Delete portal").click();
    h.run_steps(2);
    assert!(h.state().editor.portals.is_empty());

    h.get_by_label("Find portals").click();
    h.run_steps(2);
    step_until(&mut h, "found and checked", |a| {
        !a.is_checking_portals() && a.portal_checks().is_some()
    });
    let found = h.state().editor.portals.clone();
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(found[0].is_window() && found[0].auto_alpha);
    let checks = h.state().portal_checks().unwrap().to_vec();
    assert!(checks.iter().all(|c| c.problems().is_empty()), "{checks:?}");
    h.get_by_label_contains("environment: 100.0% through its portals");

    // Flipped, the window lets no light out the right way: the check says so.
    h.get_by_label("Flip").click();
    h.run_steps(2);
    h.get_by_label("Check portals").click();
    h.run_steps(2);
    step_until(&mut h, "checked", |a| {
        !a.is_checking_portals() && a.portal_checks().is_some()
    });
    h.get_by_label_contains("faces the wrong way");

    // Undo (the flip, the found portals, the deletion) restores the hand-placed window.
    for _ in 0..3 {
        h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
        h.run_steps(2);
    }
    assert_eq!(h.state().editor.portals, hand);
}
