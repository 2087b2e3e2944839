//! The viewer's comparison mode driven by egui_kittest with software Vulkan (Mesa llvmpipe), on
//! a tiny comparison (32 px wide, a reference of a fraction of a second): entering it renders a
//! reference and every strategy at equal time, the plot and table list them, the wipe slider
//! moves the split view's line, leaving stops the comparison and resumes the render, and a
//! snapshot of the mode's panels. Run in release: `cargo test --release --test ui_compare`.

use egui::accesskit::Role;
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use portalview::app::compare_view::{CompareLayout, Side};
use portalview::app::{PortalViewApp, ViewMode};
use portalview::compare::ReferenceOrigin;
use portalview::compare::worker::{CompareFrame, ReferenceStatus};
use portalview::light::Strategy;
use std::path::PathBuf;

mod ui_common;

use ui_common::{harness_with, serial, step_until};

/// A fresh, empty folder for the reference cache.
fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "portalview-ui-compare-{}-{name}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The viewer on `scene` with a tiny comparison whose references go to `cache`.
fn harness(scene: &str, cache: Option<PathBuf>) -> Harness<'static, PortalViewApp> {
    harness_with(scene, move |app| {
        let compare = &mut app.settings.compare;
        compare.width = 32;
        compare.reference_seconds = 0.3;
        app.compare_view_mut().cache_dir = cache;
    })
}

fn comparison(app: &PortalViewApp) -> Option<&CompareFrame> {
    app.compare_view().frame()
}

/// A ready reference and at least `spp` passes of every strategy.
fn has_runs(app: &PortalViewApp, spp: u32) -> bool {
    comparison(app).is_some_and(|f| {
        f.reference().is_some() && f.runs.len() == 4 && f.runs.iter().all(|r| r.spp >= spp)
    })
}

/// The seconds of the runs: least and most.
fn seconds_range(f: &CompareFrame) -> (f64, f64) {
    let s = f.runs.iter().map(|r| r.seconds);
    (
        s.clone().fold(f64::INFINITY, f64::min),
        s.fold(0.0, f64::max),
    )
}

#[test]
fn comparison_renders_a_reference_and_every_strategy_for_equal_time() {
    let _serial = serial();
    let cache = temp_dir("equal");
    let mut h = harness("fig8c", Some(cache.clone()));
    h.step();
    h.get_by_role_and_label(Role::Button, "Compare").click();
    h.run_steps(2);
    assert_eq!(h.state().mode(), ViewMode::Compare);
    assert!(h.state().compare_view().is_running());
    step_until(&mut h, "comparison runs", |a| {
        has_runs(a, 8) && comparison(a).is_some_and(|f| f.min_seconds() > 0.05)
    });
    let frame = comparison(h.state()).unwrap().clone();
    // The reference: rendered now, cached, with its convergence.
    let reference = frame.reference().unwrap();
    assert!(matches!(
        reference.origin,
        ReferenceOrigin::Rendered(Some(_))
    ));
    let info = reference.info.as_ref().unwrap();
    assert!(info.spp >= 2 && info.seconds >= 0.3, "{info:?}");
    assert!(info.convergence.mean_relative_standard_error > 0.0);
    assert_eq!(
        reference.pixels.len(),
        (frame.width * frame.height) as usize
    );
    assert_eq!(frame.width, 32);
    // Equal time: the scheduler keeps the runs within one pass of each other.
    let (lo, hi) = seconds_range(&frame);
    let pass = hi / frame.runs.iter().map(|r| r.spp).min().unwrap() as f64;
    assert!(hi - lo <= 3.0 * pass + 0.01, "seconds {lo} to {hi}");
    for run in &frame.runs {
        assert_eq!(run.pixels.len(), reference.pixels.len());
        assert!(run.mse.is_finite() && run.mse > 0.0, "{:?}", run.strategy);
        assert!(!run.history.is_empty());
        let last = run.history.last().unwrap();
        assert_eq!(last.spp, run.spp);
        assert!(run.history.windows(2).all(|w| w[0].seconds < w[1].seconds));
    }
    // Every strategy in the table (a label) and in both plots' legends (beside its checkbox).
    h.run_steps(2);
    for s in Strategy::ALL {
        let labels = h.query_all_by_role_and_label(Role::Label, s.name()).count();
        assert!(labels >= 1, "{} not in the table", s.name());
        let boxes = h
            .query_all_by_role_and_label(Role::CheckBox, s.name())
            .count();
        assert!(boxes >= 3, "{} in {boxes} legends and controls", s.name());
    }
    assert!(h.query_by_label("eff. vs light").is_some());
    // Subtracting the reference's noise floor relabels the error columns.
    assert!(h.query_by_label("MSE − floor").is_none());
    h.get_by_role_and_label(Role::CheckBox, "subtract the reference's noise floor")
        .click();
    h.run_steps(2);
    assert!(h.query_by_label("MSE − floor").is_some());
    assert!(h.query_by_label("relMSE − floor").is_some());
    // A second visit to the same scene, camera and size has its reference at once.
    let pixels = reference.pixels.clone();
    h.get_by_role_and_label(Role::Button, "Render").click();
    h.run_steps(2);
    h.get_by_role_and_label(Role::Button, "Compare").click();
    h.run_steps(2);
    step_until(&mut h, "second visit", |a| has_runs(a, 1));
    assert_eq!(
        comparison(h.state()).unwrap().reference().unwrap().pixels,
        pixels
    );
    // So does a new viewer, from the cache.
    drop(h);
    let mut h = harness("fig8c", Some(cache.clone()));
    h.state_mut().set_mode(ViewMode::Compare);
    step_until(&mut h, "cached reference", |a| has_runs(a, 1));
    let reference = comparison(h.state()).unwrap().reference().unwrap();
    assert!(
        matches!(reference.origin, ReferenceOrigin::Cached(_)),
        "{:?}",
        reference.origin
    );
    assert_eq!(reference.pixels, pixels);
    let _ = std::fs::remove_dir_all(&cache);
}

#[test]
fn the_wipe_slider_changes_the_split_view() {
    let _serial = serial();
    let mut h = harness("fig8b", None);
    {
        let compare = &mut h.state_mut().settings.compare;
        compare.layout = CompareLayout::Split;
        compare.left = Side::Strategy(Strategy::Light);
        compare.right = Side::Strategy(Strategy::Antishadow);
        compare.error_maps = true;
        compare.wipe = 0.2;
    }
    h.state_mut().set_mode(ViewMode::Compare);
    step_until(&mut h, "comparison runs", |a| has_runs(a, 4));
    // Freeze the images, then move the line with the slider.
    h.state_mut().compare_view_mut().set_paused(true);
    h.run_steps(3);
    let before = h.render().unwrap();
    h.get_by_role_and_label(Role::Slider, "wipe")
        .set_value_accesskit(0.8);
    h.run_steps(3);
    assert!((h.state().settings.compare.wipe - 0.8).abs() < 1e-3);
    let after = h.render().unwrap();
    let changed = before
        .pixels()
        .zip(after.pixels())
        .filter(|(a, b)| a != b)
        .count();
    assert!(changed > 5_000, "only {changed} pixels changed");
    // A click on the image puts the line there.
    h.get_by_role_and_label(Role::Slider, "wipe")
        .set_value_accesskit(0.5);
    h.run_steps(2);
    let before = h.state().settings.compare.wipe;
    // Right of the middle of the image area (the window is 1100 × 700, the plot below).
    let at = egui::pos2(1000.0, 250.0);
    h.hover_at(at);
    h.step();
    h.drag_at(at);
    h.step();
    h.drop_at(at);
    h.run_steps(2);
    let wipe = h.state().settings.compare.wipe;
    assert!(wipe > before + 0.2, "wipe {before} -> {wipe}");
}

#[test]
fn leaving_the_mode_stops_the_comparison_and_resumes_the_render() {
    let _serial = serial();
    let mut h = harness("fig8a", None);
    step_until(&mut h, "render frame", |a| {
        a.frame().is_some_and(|f| !f.preview)
    });
    h.state_mut().set_mode(ViewMode::Compare);
    h.step();
    let render_spp = h.state().frame().map(|f| f.spp);
    step_until(&mut h, "comparison runs", |a| has_runs(a, 2));
    // The render is paused while comparing.
    assert_eq!(h.state().frame().map(|f| f.spp), render_spp);
    let render_generation = h.state().frame().map_or(0, |f| f.generation);
    h.get_by_role_and_label(Role::Button, "Render").click();
    h.step();
    assert_eq!(h.state().mode(), ViewMode::Render);
    assert!(!h.state().compare_view().is_running());
    let passes = comparison(h.state()).unwrap().passes;
    // The render restarts with a new request and accumulates; the comparison's numbers stay
    // as they were over 8 render passes (counted, not timed: a loaded machine only slows
    // both).
    step_until(&mut h, "render frames", |a| {
        a.frame()
            .is_some_and(|f| f.generation > render_generation && !f.preview && f.spp >= 8)
    });
    h.step();
    assert_eq!(comparison(h.state()).unwrap().passes, passes);
}

/// The reference's progress is shown while it renders; opening another scene abandons it and
/// compares the new scene.
#[test]
fn the_reference_shows_its_progress_and_follows_the_scene() {
    let _serial = serial();
    let mut h = harness("fig8b", None);
    h.state_mut().settings.compare.reference_seconds = 1.5;
    h.state_mut().set_mode(ViewMode::Compare);
    step_until(&mut h, "reference render", |a| {
        comparison(a).is_some_and(|f| matches!(f.reference, ReferenceStatus::Rendering(_)))
    });
    // Shown within a few frames while the reference renders (a frame's layout can lag the
    // worker's first report by a step or two on a loaded machine).
    let mut shown = false;
    for _ in 0..20 {
        h.step();
        shown = h
            .query_all_by(|n| {
                n.role() == Role::ProgressIndicator
                    && n.label().is_some_and(|l| l.contains(" of 1.5 s"))
            })
            .next()
            .is_some();
        let rendering = comparison(h.state())
            .is_some_and(|f| matches!(f.reference, ReferenceStatus::Rendering(_)));
        if shown || !rendering {
            break;
        }
    }
    assert!(shown, "no progress bar of the reference");
    // Another scene: the running reference is abandoned for one of the new scene.
    h.state_mut().open("fig8a".to_owned());
    h.state_mut().settings.compare.reference_seconds = 0.3;
    step_until(&mut h, "reference of the new scene", |a| {
        has_runs(a, 1)
            && comparison(a)
                .and_then(|f| f.reference()?.info.as_ref())
                .is_some_and(|i| i.scene == "fig8a")
    });
    h.run_steps(2);
    assert!(h.query_by_label_contains("mean rel. std. error").is_some());
}

/// A snapshot of the mode's panels, paused before any work so that it is deterministic (the
/// controls, an empty plot and table, the reference waiting).
#[test]
fn snapshot_compare_panel() {
    let _serial = serial();
    let mut h = harness_with("lampshade", |app| {
        app.set_paused(true);
        app.compare_view_mut().cache_dir = None;
        app.compare_view_mut().set_paused(true);
        app.set_mode(ViewMode::Compare);
    });
    h.run_steps(4);
    assert!(comparison(h.state()).is_none());
    h.snapshot("compare_panel");
}
