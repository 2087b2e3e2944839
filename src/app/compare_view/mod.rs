//! The comparison mode: the chosen strategies at equal render time against a converged
//! reference, shown as a split view with a wipe line or as a grid, as images or per-pixel error
//! maps, with a live log-log plot of their error against time and a table of numbers. The work
//! happens on a [`CompareHandle`]'s thread; this module owns UI state only.
//!
//! This file holds the mode's settings and state, its link to the worker, and the panels'
//! layout; the side panel's sections, the images and the plots have their own files.

mod images;
mod panels;
mod plots;

use egui::{Color32, TextureHandle, Ui};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use super::files::FilePicker;
use super::side_panel::notice;
use crate::compare::report::strategy_rgb;
use crate::compare::worker::{
    CompareFrame, CompareHandle, CompareRequest, ReferenceSource, ReferenceStatus,
};
use crate::compare::{ImageSpec, Reference, ReferenceBudget, default_cache_dir, scene_hash};
use crate::light::{Mixture, Selection, Strategy};
use crate::render::integrator::{GlassShadows, GuideBounces};
use crate::sampling::SamplerKind;
use crate::scene::Scene;

/// How the images are laid out.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum CompareLayout {
    /// Two images, one each side of a wipe line.
    Split,
    /// Every compared strategy, two to a row.
    #[default]
    Grid,
}

/// What one side of the split view shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Side {
    Strategy(Strategy),
    Reference,
}

impl Side {
    pub fn name(self) -> &'static str {
        match self {
            Side::Strategy(s) => s.name(),
            Side::Reference => "reference",
        }
    }
}

/// The comparison's persisted settings (part of the viewer's).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct CompareViewSettings {
    /// The strategies compared (each gets an equal share of the time).
    pub strategies: Vec<Strategy>,
    pub layout: CompareLayout,
    /// Per-pixel relative squared error instead of the images.
    pub error_maps: bool,
    /// The split view's sides.
    pub left: Side,
    pub right: Side,
    /// Where the wipe line is, as a fraction of the image's width.
    pub wipe: f32,
    /// Comparison width in pixels; the height follows the camera's aspect ratio (as in
    /// `portalview compare --width`, so that the two share cached references).
    pub width: u32,
    /// Render time of the reference.
    pub reference_seconds: f64,
}

impl Default for CompareViewSettings {
    fn default() -> Self {
        CompareViewSettings {
            strategies: Strategy::ALL.to_vec(),
            layout: CompareLayout::Grid,
            error_maps: false,
            left: Side::Strategy(Strategy::Light),
            right: Side::Strategy(Strategy::Antishadow),
            wipe: 0.5,
            width: 256,
            reference_seconds: 30.0,
        }
    }
}

/// The seed of the compared renders (the reference's is derived from it).
const COMPARE_SEED: u64 = 0;

/// What a comparison depends on: a change starts a new one.
#[derive(Clone, Debug, PartialEq)]
struct RequestKey {
    scene: u64,
    strategies: Vec<Strategy>,
    width: u32,
    max_depth: u32,
    alpha: Option<u32>,
    sampler: SamplerKind,
    mixture: Mixture,
    selection: Selection,
    glass: GlassShadows,
    bounces: GuideBounces,
    reference: ReferenceSource,
}

/// What a texture shows.
#[derive(Clone, Copy, Debug, PartialEq)]
struct TextureKey {
    generation: u64,
    spp: u32,
    exposure: u32,
    error_map: bool,
}

/// The comparison mode's state. The app hands it the scene (`set_scene`), calls
/// `sync` every frame while the mode is on and `stop` when it ends.
pub struct CompareView {
    worker: Option<CompareHandle>,
    frame: Option<Arc<CompareFrame>>,
    /// The scene, with the camera to compare at, and its hash.
    scene: Option<(Scene, u64)>,
    /// What the running comparison was started for.
    running: Option<RequestKey>,
    /// The newest reference seen, offered to later comparisons that it fits.
    last_reference: Option<Arc<Reference>>,
    paused: bool,
    /// Where references are cached (`None`: not cached). Defaults to
    /// `compare::default_cache_dir()`.
    pub cache_dir: Option<PathBuf>,
    /// A reference EXR chosen by the user, instead of rendering one.
    reference_file: Option<PathBuf>,
    path_input: String,
    /// The file dialog for a reference EXR, while it is open.
    picker: Option<FilePicker>,
    textures: HashMap<Side, (TextureKey, TextureHandle)>,
    message: Option<String>,
    /// Whether the numbers subtract the reference's noise floor from each error.
    subtract_floor: bool,
}

impl Default for CompareView {
    fn default() -> Self {
        CompareView {
            worker: None,
            frame: None,
            scene: None,
            running: None,
            last_reference: None,
            paused: false,
            cache_dir: default_cache_dir(),
            reference_file: None,
            path_input: String::new(),
            picker: None,
            textures: HashMap::new(),
            message: None,
            subtract_floor: false,
        }
    }
}

/// Plot and label colours by strategy (those of `portalview compare`'s SVG plots).
fn strategy_colour(strategy: Strategy) -> Color32 {
    let [r, g, b] = strategy_rgb(strategy);
    Color32::from_rgb(r, g, b)
}

impl CompareView {
    /// The scene and camera to compare at; a change restarts a running comparison.
    pub(super) fn set_scene(&mut self, scene: Scene) {
        let hash = scene_hash(
            &scene,
            ImageSpec {
                width: 0,
                height: 0,
                max_depth: 0,
            },
        );
        self.scene = Some((scene, hash));
    }

    /// Whether the comparison worker exists (between the first `sync` and
    /// `stop`).
    pub fn is_running(&self) -> bool {
        self.worker.is_some()
    }

    /// The newest frame of the comparison (kept after `stop` until the next start).
    pub fn frame(&self) -> Option<&CompareFrame> {
        self.frame.as_deref()
    }

    /// Pauses (the running pass is abandoned) or resumes the comparison.
    pub fn set_paused(&mut self, paused: bool) {
        self.paused = paused;
        if let Some(worker) = &self.worker {
            worker.set_paused(paused);
        }
    }

    /// Stops the comparison: its worker ends (this waits for its current pass to abandon).
    pub(super) fn stop(&mut self) {
        self.worker = None;
        self.running = None;
    }

    /// Takes the newest frame of the running comparison.
    fn poll(&mut self) {
        let Some(worker) = &self.worker else {
            return;
        };
        let Some(frame) = worker.latest() else {
            return;
        };
        if frame.generation != worker.generation()
            || self.frame.as_ref().is_some_and(|f| Arc::ptr_eq(f, &frame))
        {
            return;
        }
        if let Some(reference) = frame.reference() {
            self.last_reference = Some(reference.clone());
        }
        self.frame = Some(frame);
    }

    /// The comparison's size for `settings`, before a reference file overrides it.
    fn image(&self, settings: &CompareViewSettings, max_depth: u32) -> Option<ImageSpec> {
        let (scene, _) = self.scene.as_ref()?;
        let width = settings.width.max(1);
        Some(ImageSpec {
            width,
            height: scene.camera.height_for_width(width),
            max_depth,
        })
    }

    /// Takes the worker's newest frame, and starts the worker, or a new comparison, when what
    /// is compared changed. Called every frame while the mode is on.
    pub(super) fn sync(
        &mut self,
        ctx: &egui::Context,
        settings: &CompareViewSettings,
        max_depth: u32,
        alpha: Option<f32>,
        (sampler, mixture, selection, glass, bounces): (
            SamplerKind,
            Mixture,
            Selection,
            GlassShadows,
            GuideBounces,
        ),
    ) {
        self.poll();
        if let Some(frame) = &self.frame
            && matches!(frame.reference, ReferenceStatus::Rendering(_))
            && !self.paused
        {
            // The reference's progress bar advances without frames.
            ctx.request_repaint_after(Duration::from_millis(100));
        }
        let Some(image) = self.image(settings, max_depth) else {
            return;
        };
        let Some((scene, hash)) = &self.scene else {
            return;
        };
        let strategies: Vec<Strategy> = Strategy::ALL
            .into_iter()
            .filter(|s| settings.strategies.contains(s))
            .collect();
        let reference = match &self.reference_file {
            Some(path) => ReferenceSource::File(path.clone()),
            None => ReferenceSource::Render {
                budget: ReferenceBudget::Seconds(settings.reference_seconds),
                cache_dir: self.cache_dir.clone(),
            },
        };
        let key = RequestKey {
            scene: *hash,
            strategies,
            width: image.width,
            max_depth,
            alpha: alpha.map(f32::to_bits),
            sampler,
            mixture,
            selection,
            glass,
            bounces,
            reference,
        };
        if self.worker.is_some() && self.running.as_ref() == Some(&key) {
            return;
        }
        if self.worker.is_none() {
            let repaint = ctx.clone();
            // Every core renders the comparison.
            match CompareHandle::spawn(0, Box::new(move || repaint.request_repaint())) {
                Ok(worker) => self.worker = Some(worker),
                Err(e) => {
                    self.message = Some(format!("cannot start the comparison: {e}"));
                    return;
                }
            }
        }
        let Some(worker) = self.worker.as_mut() else {
            return;
        };
        let request = CompareRequest {
            scene: scene.clone(),
            strategies: key.strategies.clone(),
            image,
            alpha,
            seed: COMPARE_SEED,
            sampler,
            mixture,
            selection,
            glass,
            bounces,
            reference: key.reference.clone(),
            known_reference: self.last_reference.clone(),
            paused: self.paused,
        };
        worker.start(request);
        self.running = Some(key);
        self.frame = None;
        self.message = None;
    }

    /// The mode's panels: controls, reference and numbers on the left, the plot at the bottom,
    /// the images in the middle. `message` is the app's notice, shown above the controls.
    pub(super) fn show(
        &mut self,
        ui: &mut Ui,
        settings: &mut CompareViewSettings,
        exposure: &mut f32,
        message: &mut Option<String>,
    ) {
        egui::Panel::left("controls")
            .resizable(true)
            .default_size(330.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| {
                    notice(ui, message);
                    notice(ui, &mut self.message);
                    egui::CollapsingHeader::new("Comparison")
                        .default_open(true)
                        .show(ui, |ui| self.controls(ui, settings, exposure));
                    egui::CollapsingHeader::new("Reference")
                        .default_open(true)
                        .show(ui, |ui| self.reference_panel(ui, settings));
                    egui::CollapsingHeader::new("Numbers")
                        .default_open(true)
                        .show(ui, |ui| self.numbers(ui));
                });
            });
        egui::Panel::bottom("compare plot")
            .resizable(true)
            .default_size(230.0)
            .show(ui, |ui| self.plots(ui));
        egui::CentralPanel::default().show(ui, |ui| self.view(ui, settings, *exposure));
        if let Some(picker) = &mut self.picker
            && let Some(chosen) = picker.show(ui.ctx())
        {
            self.picker = None;
            if chosen.is_some() {
                self.reference_file = chosen;
            }
        }
    }

    /// One line for the status bar.
    pub(super) fn status(&self, ui: &mut Ui) {
        match &self.frame {
            Some(f) => {
                ui.label(format!(
                    "comparison {}×{} px  {} passes  {:.2} s per strategy",
                    f.width,
                    f.height,
                    f.passes,
                    f.min_seconds()
                ));
            }
            None if self.paused => {
                ui.label("comparison paused before it started");
                return;
            }
            None => {
                ui.label("comparison starting...");
            }
        }
        if self.paused {
            ui.label("paused");
        }
    }
}
