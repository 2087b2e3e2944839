//! The comparison mode: the chosen strategies at equal render time against a converged
//! reference, shown as a split view with a wipe line or as a grid, as images or per-pixel error
//! maps, with a live log-log plot of their error against time and a table of numbers. The work
//! happens on a [`CompareHandle`]'s thread; this module owns UI state only.

use egui::{
    Color32, ColorImage, FontId, Pos2, Rect, RichText, Sense, Stroke, TextureHandle,
    TextureOptions, Ui,
};
use egui_plot::{Corner, GridMark, HLine, HoverPosition, Legend, Line, LineStyle, Plot};
use glam::Vec3;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use crate::compare::report::{sci, strategy_rgb, tick_label};
use crate::compare::worker::{
    CompareFrame, CompareHandle, CompareRequest, ReferenceSource, ReferenceStatus, RunFrame,
};
use crate::compare::{
    ConvergencePoint, ImageSpec, REFERENCE_STRATEGY, RELMSE_EPSILON, Reference, ReferenceBudget,
    ReferenceOrigin, default_cache_dir, scene_hash,
};
use crate::light::Strategy;
use crate::render::tonemap;
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
pub const COMPARE_SEED: u64 = 0;

/// Error maps show log10 of the relative squared error over [LO, HI].
const ERROR_LOG_LO: f64 = -6.0;
const ERROR_LOG_HI: f64 = 0.0;

/// What a comparison depends on: a change starts a new one.
#[derive(Clone, Debug, PartialEq)]
struct RequestKey {
    scene: u64,
    strategies: Vec<Strategy>,
    width: u32,
    max_depth: u32,
    alpha: Option<u32>,
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

/// The comparison mode's state. The app hands it the scene ([`Self::set_scene`]), calls
/// [`Self::sync`] every frame while the mode is on and [`Self::stop`] when it ends.
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
    /// Render threads of the comparison (0: every core).
    pub threads: usize,
    /// A reference EXR chosen by the user, instead of rendering one.
    reference_file: Option<PathBuf>,
    path_input: String,
    textures: HashMap<Side, (TextureKey, TextureHandle)>,
    message: Option<String>,
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
            threads: 0,
            reference_file: None,
            path_input: String::new(),
            textures: HashMap::new(),
            message: None,
        }
    }
}

/// Plot and label colours by strategy (those of `portalview compare`'s SVG plots).
pub fn strategy_colour(strategy: Strategy) -> Color32 {
    let [r, g, b] = strategy_rgb(strategy);
    Color32::from_rgb(r, g, b)
}

/// Per-pixel relative squared error, `mean over channels of (x - r)^2 / (r^2 + eps)` (the
/// terms of relMSE), log-scaled over [`ERROR_LOG_LO`, `ERROR_LOG_HI`] in false colour.
pub fn error_map(image: &[Vec3], reference: &[Vec3]) -> Vec<Color32> {
    image
        .iter()
        .zip(reference)
        .map(|(&x, &r)| {
            let (x, r) = (x.as_dvec3(), r.as_dvec3());
            let d = x - r;
            let e = d * d / (r * r + RELMSE_EPSILON);
            let e = (e.x + e.y + e.z) / 3.0;
            let t = if e > 0.0 {
                ((e.log10() - ERROR_LOG_LO) / (ERROR_LOG_HI - ERROR_LOG_LO)) as f32
            } else {
                0.0
            };
            let [r, g, b] = tonemap::false_colour(t);
            Color32::from_rgb(r, g, b)
        })
        .collect()
}

/// Scientific notation with three decimals, or a dash for a missing value.
fn log_tick(mark: GridMark, _range: &std::ops::RangeInclusive<f64>) -> String {
    tick_label(10f64.powf(mark.value))
}

/// The largest rect of aspect ratio `aspect` (width / height) centred in `area`.
fn fit(area: Rect, aspect: f32) -> Rect {
    let aspect = aspect.max(1e-3);
    let size = if area.width() / area.height().max(1.0) > aspect {
        egui::vec2(area.height() * aspect, area.height())
    } else {
        egui::vec2(area.width(), area.width() / aspect)
    };
    Rect::from_center_size(area.center(), size)
}

/// A caption on a dark background, anchored at `pos` by its top-left or top-right corner.
fn caption(painter: &egui::Painter, pos: Pos2, text: String, right: bool, colour: Color32) {
    let galley = painter.layout_no_wrap(text, FontId::proportional(13.0), Color32::WHITE);
    let origin = if right {
        pos - egui::vec2(galley.size().x, 0.0)
    } else {
        pos
    };
    let background = Rect::from_min_size(origin, galley.size()).expand(3.0);
    painter.rect_filled(background, 3.0, Color32::from_black_alpha(180));
    painter.rect_filled(
        Rect::from_min_size(background.left_top(), egui::vec2(3.0, background.height())),
        0.0,
        colour,
    );
    painter.galley(origin, galley, Color32::WHITE);
}

/// One line on a strategy: name, spp, seconds, MSE.
fn run_caption(run: &RunFrame) -> String {
    format!(
        "{}  {} spp  {:.2} s  MSE {}",
        run.strategy.name(),
        run.spp,
        run.seconds,
        sci(run.mse)
    )
}

/// Where a reference came from, in a few words.
fn origin_text(origin: &ReferenceOrigin) -> String {
    match origin {
        ReferenceOrigin::Rendered(Some(p)) => format!("rendered now, cached as {}", p.display()),
        ReferenceOrigin::Rendered(None) => "rendered now (not cached)".to_owned(),
        ReferenceOrigin::Cached(p) => format!("from the cache, {}", p.display()),
        ReferenceOrigin::File(p) => format!("from {}", p.display()),
    }
}

/// Efficiency `1 / (MSE × seconds)` of `run` over light sampling's, when both are known.
fn efficiency_vs_light(run: &RunFrame, light: Option<&RunFrame>) -> Option<f64> {
    let light = light?;
    let e = light.mse * light.seconds / (run.mse * run.seconds);
    e.is_finite().then_some(e)
}

impl CompareView {
    /// The scene and camera to compare at; a change restarts a running comparison.
    pub fn set_scene(&mut self, scene: Scene) {
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

    /// Whether the comparison worker exists (between the first [`Self::sync`] and
    /// [`Self::stop`]).
    pub fn is_running(&self) -> bool {
        self.worker.is_some()
    }

    /// The newest frame of the comparison (kept after [`Self::stop`] until the next start).
    pub fn frame(&self) -> Option<&CompareFrame> {
        self.frame.as_deref()
    }

    pub fn paused(&self) -> bool {
        self.paused
    }

    /// Pauses (the running pass is abandoned) or resumes the comparison.
    pub fn set_paused(&mut self, paused: bool) {
        self.paused = paused;
        if let Some(worker) = &self.worker {
            worker.set_paused(paused);
        }
    }

    /// Uses a reference EXR (`None`: render one) from the next [`Self::sync`] on.
    pub fn set_reference_file(&mut self, path: Option<PathBuf>) {
        self.reference_file = path;
    }

    /// Stops the comparison: its worker ends (this waits for its current pass to abandon).
    pub fn stop(&mut self) {
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
    pub fn sync(
        &mut self,
        ctx: &egui::Context,
        settings: &CompareViewSettings,
        max_depth: u32,
        alpha: Option<f32>,
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
            reference,
        };
        if self.worker.is_some() && self.running.as_ref() == Some(&key) {
            return;
        }
        if self.worker.is_none() {
            let repaint = ctx.clone();
            match CompareHandle::spawn(self.threads, Box::new(move || repaint.request_repaint())) {
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
    pub fn show(
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
                    for m in [&mut *message, &mut self.message] {
                        if let Some(text) = m.clone() {
                            ui.horizontal(|ui| {
                                ui.colored_label(Color32::LIGHT_RED, text);
                                if ui.small_button("x").clicked() {
                                    *m = None;
                                }
                            });
                        }
                    }
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
    }

    fn controls(&mut self, ui: &mut Ui, settings: &mut CompareViewSettings, exposure: &mut f32) {
        let CompareViewSettings {
            strategies, width, ..
        } = settings;
        if let Some((scene, _)) = &self.scene {
            ui.label(RichText::new(format!("Scene: {}", scene.name)).strong());
        }
        ui.label(
            "Every strategy gets the same render time; errors are measured against the reference.",
        );
        ui.label("Strategies");
        ui.horizontal_wrapped(|ui| {
            for s in Strategy::ALL {
                let mut on = strategies.contains(&s);
                if ui.checkbox(&mut on, s.name()).changed() {
                    strategies.retain(|&t| t != s);
                    if on {
                        strategies.push(s);
                    }
                }
            }
        });
        ui.add(
            egui::Slider::new(width, 16..=640)
                .logarithmic(true)
                .text("width (px)"),
        );
        let size = match (&self.frame, self.reference_file.is_some()) {
            (Some(f), _) => Some((f.width, f.height)),
            (None, false) => self
                .scene
                .as_ref()
                .map(|(s, _)| (*width, s.camera.height_for_width((*width).max(1)))),
            (None, true) => None,
        };
        if let Some((w, h)) = size {
            ui.label(format!("comparison size {w}×{h} px"));
        }
        ui.add(egui::Slider::new(exposure, -8.0..=8.0).text("exposure"));
        ui.horizontal(|ui| {
            if ui
                .button(if self.paused { "Resume" } else { "Pause" })
                .clicked()
            {
                self.set_paused(!self.paused);
            }
            if ui.button("Restart comparison").clicked() {
                // The next sync starts it again (the reference is kept).
                self.running = None;
            }
        });
    }

    fn reference_panel(&mut self, ui: &mut Ui, settings: &mut CompareViewSettings) {
        ui.label(format!(
            "Rendered with {} sampling, from another seed than the compared renders.",
            REFERENCE_STRATEGY.name()
        ));
        match self.frame.as_ref().map(|f| &f.reference) {
            None if self.paused => {
                ui.label("paused");
            }
            None => {
                ui.label("starting...");
            }
            Some(ReferenceStatus::Rendering(bar)) => {
                ui.horizontal(|ui| {
                    if !self.paused {
                        ui.spinner();
                    }
                    ui.label(if self.paused {
                        "paused"
                    } else {
                        "rendering the reference"
                    });
                });
                let (done, text) = reference_progress(bar);
                ui.add(egui::ProgressBar::new(done).text(text));
            }
            Some(ReferenceStatus::Ready(reference)) => {
                ui.label(origin_text(&reference.origin));
                match &reference.info {
                    Some(info) => {
                        let c = &info.convergence;
                        egui::Grid::new("reference info")
                            .num_columns(2)
                            .show(ui, |ui| {
                                ui.label("samples");
                                ui.label(format!("{} spp in {:.1} s", info.spp, info.seconds));
                                ui.end_row();
                                ui.label("mean rel. std. error");
                                ui.label(format!("{:.3}%", 100.0 * c.mean_relative_standard_error));
                                ui.end_row();
                                ui.label("noise floor");
                                ui.label(format!(
                                    "MSE {}, relMSE {}",
                                    sci(c.mse_floor),
                                    sci(c.relmse_floor)
                                ));
                                ui.end_row();
                            });
                    }
                    None => {
                        ui.label("its convergence is unknown (no sidecar JSON beside it)");
                    }
                }
            }
            Some(ReferenceStatus::Failed(e)) => {
                ui.colored_label(Color32::LIGHT_RED, e);
            }
        }
        if let Some(frame) = &self.frame {
            for note in &frame.notes {
                ui.colored_label(Color32::from_rgb(255, 160, 60), note);
            }
        }
        if let Some(error) = self.worker.as_ref().and_then(|w| w.error()) {
            ui.colored_label(Color32::LIGHT_RED, error);
        }
        ui.add_enabled(
            self.reference_file.is_none(),
            egui::Slider::new(&mut settings.reference_seconds, 0.1..=600.0)
                .logarithmic(true)
                .text("reference seconds"),
        );
        ui.horizontal(|ui| {
            if ui.button("Load reference EXR...").clicked()
                && let Some(path) = rfd::FileDialog::new()
                    .add_filter("OpenEXR", &["exr"])
                    .pick_file()
            {
                self.reference_file = Some(path);
            }
            if self.reference_file.is_some() && ui.button("Render reference").clicked() {
                self.reference_file = None;
            }
        });
        ui.horizontal(|ui| {
            ui.add(
                egui::TextEdit::singleline(&mut self.path_input)
                    .hint_text("path to a reference .exr")
                    .desired_width(180.0),
            );
            if ui.button("Load path").clicked() && !self.path_input.trim().is_empty() {
                self.reference_file = Some(PathBuf::from(self.path_input.trim()));
            }
        });
        if let Some(path) = &self.reference_file {
            ui.label(format!(
                "using {} (the comparison takes its size)",
                path.display()
            ));
        }
    }

    fn numbers(&self, ui: &mut Ui) {
        let Some(frame) = self.frame.as_ref().filter(|f| !f.runs.is_empty()) else {
            ui.label("no numbers yet");
            return;
        };
        let light = frame.run(Strategy::Light);
        egui::Grid::new("compare numbers")
            .num_columns(6)
            .striped(true)
            .show(ui, |ui| {
                for h in [
                    "strategy",
                    "spp",
                    "seconds",
                    "MSE",
                    "relMSE",
                    "eff. vs light",
                ] {
                    ui.label(RichText::new(h).strong());
                }
                ui.end_row();
                for run in &frame.runs {
                    ui.colored_label(strategy_colour(run.strategy), run.strategy.name());
                    ui.label(format!("{}", run.spp));
                    ui.label(format!("{:.2}", run.seconds));
                    ui.label(sci(run.mse));
                    ui.label(sci(run.relmse));
                    ui.label(
                        efficiency_vs_light(run, light)
                            .map_or("-".to_owned(), |e| format!("{e:.2}")),
                    );
                    ui.end_row();
                }
            });
        ui.label(
            "Efficiency is 1 / (MSE × seconds), relative to light sampling's: above 1 is better.",
        );
    }

    fn plots(&self, ui: &mut Ui) {
        let floor = self
            .frame
            .as_ref()
            .and_then(|f| f.reference())
            .and_then(|r| r.info.as_ref())
            .map(|i| i.convergence);
        ui.columns(2, |columns| {
            self.plot(
                &mut columns[0],
                "MSE",
                |p| p.mse,
                floor.map(|c| c.mse_floor),
            );
            self.plot(
                &mut columns[1],
                "relMSE",
                |p| p.relmse,
                floor.map(|c| c.relmse_floor),
            );
        });
    }

    /// A log-log plot of `value` against seconds, a line per strategy.
    fn plot(
        &self,
        ui: &mut Ui,
        what: &'static str,
        value: fn(&ConvergencePoint) -> f64,
        floor: Option<f64>,
    ) {
        let runs = self.frame.as_ref().map_or(&[][..], |f| &f.runs[..]);
        Plot::new(format!("compare {what}"))
            .legend(
                Legend::default()
                    .position(Corner::LeftBottom)
                    .follow_insertion_order(true),
            )
            .x_axis_label("seconds per strategy")
            .y_axis_label(what)
            .x_axis_formatter(log_tick)
            .y_axis_formatter(log_tick)
            .link_axis(egui::Id::unique("compare plots"), [true, false])
            .allow_scroll(false)
            .label_formatter(move |pos: &HoverPosition<'_>| match pos {
                HoverPosition::NearDataPoint {
                    plot_name,
                    position,
                    ..
                } => Some(format!(
                    "{plot_name}\n{} s\n{what} {}",
                    tick_label(10f64.powf(position.x)),
                    sci(10f64.powf(position.y))
                )),
                HoverPosition::Elsewhere { .. } => None,
            })
            .show(ui, |plot_ui| {
                for run in runs {
                    let points: Vec<[f64; 2]> = run
                        .history
                        .iter()
                        .filter(|p| p.seconds > 0.0 && value(p) > 0.0)
                        .map(|p| [p.seconds.log10(), value(p).log10()])
                        .collect();
                    plot_ui.line(
                        Line::new(run.strategy.name(), points)
                            .color(strategy_colour(run.strategy))
                            .width(2.0),
                    );
                }
                if let Some(f) = floor.filter(|f| *f > 0.0) {
                    plot_ui.hline(
                        HLine::new("reference noise floor", f.log10())
                            .color(Color32::GRAY)
                            .style(LineStyle::dashed_loose()),
                    );
                }
            });
    }

    /// The texture of `side` in `frame` (an image or its error map), uploaded when stale.
    fn texture(
        &mut self,
        ctx: &egui::Context,
        frame: &CompareFrame,
        side: Side,
        error_map: bool,
        exposure: f32,
    ) -> Option<egui::TextureId> {
        let reference = frame.reference();
        let (pixels, spp) = match side {
            Side::Strategy(s) => {
                let run = frame.run(s)?;
                (&run.pixels[..], run.spp)
            }
            Side::Reference => (&reference?.pixels[..], u32::MAX),
        };
        if pixels.is_empty() || pixels.len() != (frame.width * frame.height) as usize {
            return None;
        }
        let key = TextureKey {
            generation: frame.generation,
            spp,
            exposure: exposure.to_bits(),
            error_map,
        };
        if let Some((k, t)) = self.textures.get(&side)
            && *k == key
        {
            return Some(t.id());
        }
        let colours = if error_map {
            let reference = reference.filter(|r| r.pixels.len() == pixels.len())?;
            self::error_map(pixels, &reference.pixels)
        } else {
            pixels
                .iter()
                .map(|&c| {
                    let [r, g, b] = tonemap::to_srgb8(c, exposure);
                    Color32::from_rgb(r, g, b)
                })
                .collect()
        };
        let image = ColorImage::new([frame.width as usize, frame.height as usize], colours);
        match self.textures.get_mut(&side) {
            Some((k, t)) => {
                t.set(image, TextureOptions::NEAREST);
                *k = key;
                Some(t.id())
            }
            None => {
                let t = ctx.load_texture(
                    format!("compare {}", side.name()),
                    image,
                    TextureOptions::NEAREST,
                );
                let id = t.id();
                self.textures.insert(side, (key, t));
                Some(id)
            }
        }
    }

    fn view(&mut self, ui: &mut Ui, settings: &mut CompareViewSettings, exposure: f32) {
        let CompareViewSettings {
            layout,
            error_maps,
            left,
            right,
            wipe,
            ..
        } = settings;
        let frame = self.frame.clone();
        let sides: Vec<Side> = frame
            .as_ref()
            .map(|f| f.runs.iter().map(|r| Side::Strategy(r.strategy)).collect())
            .unwrap_or_else(|| Strategy::ALL.map(Side::Strategy).to_vec())
            .into_iter()
            .chain([Side::Reference])
            .collect();
        ui.horizontal(|ui| {
            ui.selectable_value(layout, CompareLayout::Split, "split");
            ui.selectable_value(layout, CompareLayout::Grid, "grid");
            ui.separator();
            ui.checkbox(error_maps, "error maps");
            if *layout == CompareLayout::Split {
                ui.separator();
                for (side, label) in [(&mut *left, "left"), (&mut *right, "right")] {
                    egui::ComboBox::from_label(label)
                        .selected_text(side.name())
                        .show_ui(ui, |ui| {
                            for &s in &sides {
                                ui.selectable_value(side, s, s.name());
                            }
                        });
                }
                ui.add(egui::Slider::new(wipe, 0.0..=1.0).text("wipe"));
            }
        });
        if *error_maps {
            error_legend(ui);
        }
        let Some(frame) = frame else {
            ui.centered_and_justified(|ui| {
                ui.label(if self.paused { "paused" } else { "starting..." });
            });
            return;
        };
        if frame.runs.is_empty() {
            self.reference_progress_view(ui, &frame);
            return;
        }
        match *layout {
            CompareLayout::Split => self.split(ui, &frame, settings, exposure),
            CompareLayout::Grid => self.grid(ui, &frame, settings.error_maps, exposure),
        }
    }

    /// While the reference renders (or failed): what is happening, in the middle.
    fn reference_progress_view(&self, ui: &mut Ui, frame: &CompareFrame) {
        ui.vertical_centered(|ui| {
            ui.add_space(ui.available_height() / 3.0);
            match &frame.reference {
                ReferenceStatus::Rendering(bar) => {
                    if !self.paused {
                        ui.spinner();
                    }
                    ui.label(format!(
                        "Rendering the reference ({} sampling, {}×{} px){}",
                        REFERENCE_STRATEGY.name(),
                        frame.width,
                        frame.height,
                        if self.paused { ": paused" } else { "" }
                    ));
                    let (done, text) = reference_progress(bar);
                    ui.add(egui::ProgressBar::new(done).desired_width(320.0).text(text));
                }
                ReferenceStatus::Failed(e) => {
                    ui.colored_label(Color32::LIGHT_RED, e);
                    ui.label("Load another reference, or render one.");
                }
                ReferenceStatus::Ready(_) => {
                    ui.label("No strategy is compared: tick some on the left.");
                }
            }
        });
    }

    fn split(
        &mut self,
        ui: &mut Ui,
        frame: &CompareFrame,
        settings: &mut CompareViewSettings,
        exposure: f32,
    ) {
        let (area, response) = ui.allocate_exact_size(ui.available_size(), Sense::click_and_drag());
        let rect = fit(area, frame.width as f32 / frame.height.max(1) as f32);
        let painter = ui.painter_at(area);
        painter.rect_filled(area, 0.0, Color32::BLACK);
        if let Some(pos) = response.interact_pointer_pos()
            && (response.dragged() || response.clicked() || response.is_pointer_button_down_on())
        {
            settings.wipe = ((pos.x - rect.left()) / rect.width().max(1.0)).clamp(0.0, 1.0);
        }
        if response.hovered() {
            ui.ctx().set_cursor_icon(egui::CursorIcon::ResizeHorizontal);
        }
        let wipe = settings.wipe.clamp(0.0, 1.0);
        let x = rect.left() + wipe * rect.width();
        let ctx = ui.ctx().clone();
        let halves = [
            (
                settings.left,
                Rect::from_min_max(rect.min, Pos2::new(x, rect.max.y)),
                Rect::from_min_max(Pos2::ZERO, Pos2::new(wipe, 1.0)),
            ),
            (
                settings.right,
                Rect::from_min_max(Pos2::new(x, rect.min.y), rect.max),
                Rect::from_min_max(Pos2::new(wipe, 0.0), Pos2::new(1.0, 1.0)),
            ),
        ];
        for (side, target, uv) in halves {
            match self.texture(&ctx, frame, side, settings.error_maps, exposure) {
                Some(id) => {
                    painter.image(id, target, uv, Color32::WHITE);
                }
                None if target.width() > 40.0 => {
                    painter.text(
                        target.center(),
                        egui::Align2::CENTER_CENTER,
                        format!("{}: no image", side.name()),
                        FontId::proportional(14.0),
                        Color32::GRAY,
                    );
                }
                None => {}
            }
        }
        painter.line_segment(
            [Pos2::new(x, rect.top()), Pos2::new(x, rect.bottom())],
            Stroke::new(2.0, Color32::WHITE),
        );
        painter.circle_filled(Pos2::new(x, rect.center().y), 6.0, Color32::WHITE);
        let texts = [settings.left, settings.right].map(|side| match side {
            Side::Strategy(s) => (
                frame
                    .run(s)
                    .map_or(format!("{}: not compared", s.name()), run_caption),
                strategy_colour(s),
            ),
            Side::Reference => (
                match frame.reference().and_then(|r| r.info.as_ref()) {
                    Some(info) => format!("reference  {} spp  {:.1} s", info.spp, info.seconds),
                    None => "reference".to_owned(),
                },
                Color32::WHITE,
            ),
        });
        let [(left, left_colour), (right, right_colour)] = texts;
        caption(
            &painter,
            rect.left_top() + egui::vec2(8.0, 8.0),
            left,
            false,
            left_colour,
        );
        caption(
            &painter,
            rect.right_top() + egui::vec2(-8.0, 8.0),
            right,
            true,
            right_colour,
        );
    }

    fn grid(&mut self, ui: &mut Ui, frame: &CompareFrame, error_maps: bool, exposure: f32) {
        let (area, _) = ui.allocate_exact_size(ui.available_size(), Sense::hover());
        let painter = ui.painter_at(area);
        painter.rect_filled(area, 0.0, Color32::BLACK);
        let n = frame.runs.len();
        let columns = if n <= 1 { 1 } else { 2 };
        let rows = n.div_ceil(columns).max(1);
        let cell = egui::vec2(area.width() / columns as f32, area.height() / rows as f32);
        let aspect = frame.width as f32 / frame.height.max(1) as f32;
        let ctx = ui.ctx().clone();
        for (k, run) in frame.runs.iter().enumerate() {
            let min =
                area.min + egui::vec2((k % columns) as f32 * cell.x, (k / columns) as f32 * cell.y);
            let rect = fit(Rect::from_min_size(min, cell).shrink(2.0), aspect);
            let side = Side::Strategy(run.strategy);
            if let Some(id) = self.texture(&ctx, frame, side, error_maps, exposure) {
                let uv = Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0));
                painter.image(id, rect, uv, Color32::WHITE);
            }
            caption(
                &painter,
                rect.left_top() + egui::vec2(8.0, 8.0),
                run_caption(run),
                false,
                strategy_colour(run.strategy),
            );
        }
    }

    /// One line for the status bar.
    pub fn status(&self, ui: &mut Ui) {
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

/// The reference render's progress: the fraction done and a line on it.
fn reference_progress(bar: &indicatif::ProgressBar) -> (f32, String) {
    let (position, length) = (bar.position(), bar.length().unwrap_or(0));
    let done = if length > 0 {
        (position as f64 / length as f64).min(1.0) as f32
    } else {
        0.0
    };
    let message = bar.message();
    let text = if length == 0 {
        "looking for a cached reference".to_owned()
    } else {
        format!(
            "{:.1} of {:.1} s  {}",
            position as f64 / 1e3,
            length as f64 / 1e3,
            message
        )
    };
    (done, text)
}

/// The error maps' colour scale, with its ends labelled.
fn error_legend(ui: &mut Ui) {
    ui.horizontal(|ui| {
        ui.label(format!(
            "relative squared error (x - r)^2 / (r^2 + {RELMSE_EPSILON}):"
        ));
        ui.label(tick_label(10f64.powf(ERROR_LOG_LO)));
        let (rect, _) = ui.allocate_exact_size(egui::vec2(200.0, 14.0), Sense::hover());
        let steps = 50;
        for i in 0..steps {
            let t = (i as f32 + 0.5) / steps as f32;
            let [r, g, b] = tonemap::false_colour(t);
            let x0 = rect.left() + rect.width() * i as f32 / steps as f32;
            let x1 = rect.left() + rect.width() * (i + 1) as f32 / steps as f32;
            ui.painter().rect_filled(
                Rect::from_min_max(Pos2::new(x0, rect.top()), Pos2::new(x1, rect.bottom())),
                0.0,
                Color32::from_rgb(r, g, b),
            );
        }
        ui.label(tick_label(10f64.powf(ERROR_LOG_HI)));
    });
}
