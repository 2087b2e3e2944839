//! What the viewer's UI test suites share: one lock, one app factory, and a way to wait for
//! the background workers.
#![allow(dead_code)]

use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use portalview::app::PortalViewApp;
use std::time::{Duration, Instant};

/// UI tests run one at a time: each harness renders through llvmpipe and runs its own render
/// worker, and on a small machine several at once starve each other's workers.
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

pub fn serial() -> std::sync::MutexGuard<'static, ()> {
    SERIAL.lock().unwrap_or_else(|e| e.into_inner())
}

/// One factory for the app under test: `scene` opened in a 1100×700 window, then `setup`;
/// returned once the scene (which loads in the background) is on screen.
pub fn harness_with(
    scene: &str,
    setup: impl FnOnce(&mut PortalViewApp) + 'static,
) -> Harness<'static, PortalViewApp> {
    let scene = scene.to_owned();
    let mut h = Harness::builder()
        .with_size(egui::vec2(1100.0, 700.0))
        .wgpu()
        .build_eframe(move |cc| {
            let mut app = PortalViewApp::new(&cc.egui_ctx, None, Some(scene)).unwrap();
            setup(&mut app);
            app
        });
    step_until(&mut h, "the first scene", |a| {
        a.scene().is_some() && !a.is_busy()
    });
    h
}

/// Steps the UI until `done` holds (the workers run on their own threads), or fails with a
/// screenshot of what the window showed.
pub fn step_until(
    h: &mut Harness<'static, PortalViewApp>,
    what: &str,
    done: impl Fn(&PortalViewApp) -> bool,
) {
    let start = Instant::now();
    while !done(h.state()) {
        if start.elapsed() > Duration::from_secs(60) {
            if let Ok(image) = h.render() {
                let _ = image.save(format!("target/ui-timeout-{}.png", what.replace(' ', "_")));
            }
            panic!("timed out waiting for {what}");
        }
        std::thread::sleep(Duration::from_millis(30));
        h.step();
    }
}

/// A full-resolution frame of the newest request, with its per-pixel classification.
pub fn has_full_frame(app: &PortalViewApp) -> bool {
    app.frame()
        .is_some_and(|f| !f.preview && f.primary.is_some() && f.spp >= 2)
}

/// A full frame of a request made after the frame of `generation`.
pub fn newer_full_frame(app: &PortalViewApp, generation: u64) -> bool {
    has_full_frame(app) && app.frame().is_some_and(|f| f.generation > generation)
}

/// Clicks the widget labelled `label` and steps until a full frame of the render it restarted
/// arrives.
pub fn click_until_restarted(h: &mut Harness<'static, PortalViewApp>, label: &str) {
    let generation = h
        .state()
        .frame()
        .expect("a frame before the click")
        .generation;
    h.get_by_label(label).click();
    step_until(h, "restarted frame", |a| newer_full_frame(a, generation));
}

/// Clicks *File → Save portals*.
pub fn click_save_portals(h: &mut Harness<'static, PortalViewApp>) {
    h.get_by_label("File").click();
    h.run_steps(2);
    h.get_by_label("Save portals").click();
    h.run_steps(2);
}

/// Saves through *File → Save portals* and waits until the viewer reports the save to `path`.
pub fn save_portals(h: &mut Harness<'static, PortalViewApp>, path: &std::path::Path) {
    click_save_portals(h);
    step_until(h, "saved", |a| !a.is_busy());
    assert_eq!(
        h.state().message(),
        Some(&*format!("saved {}", path.display()))
    );
}
