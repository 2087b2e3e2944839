//! The viewer: an eframe window showing the progressive render of a scene, the antishadow
//! overlays, and portal editing. The app owns UI state only; rendering happens on the worker,
//! reached through one [`RenderHandle`] that the UI never waits on.

pub mod compare_view;
pub mod edit;
pub mod overlay;
mod viewport;

use anyhow::Result;
use egui::{Color32, ColorImage, TextureHandle, TextureOptions};
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, TryRecvError};
use std::time::{Duration, Instant};

use crate::asset::{builtin, gltf};
use crate::camera::Camera;
use crate::light::antishadow::Region;
use crate::light::{Strategy, Technique};
use crate::render::integrator::RenderSettings;
use crate::render::tonemap;
use crate::render::worker::{Frame, RenderHandle, RenderRequest};
use crate::scene::Scene;
use compare_view::{CompareView, CompareViewSettings};
use edit::PortalEditor;
use overlay::OverlayKind;

/// What persists between runs (eframe storage).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ViewerSettings {
    pub strategy: Strategy,
    /// Overrides every portal's alpha when set.
    pub alpha: Option<f32>,
    pub max_depth: u32,
    /// Exposure in stops.
    pub exposure: f32,
    /// Show log-luminance in false colour instead of the tone-mapped image.
    pub false_colour: bool,
    /// Render resolution relative to the viewport's physical pixels.
    pub resolution_scale: f32,
    /// The scene opened last: a built-in name or a file path.
    pub scene: String,
    /// Files opened recently, newest first.
    pub recent: Vec<String>,
    pub overlay: OverlayKind,
    pub overlay_opacity: f32,
    /// Portal and light outlines over the image.
    pub show_outlines: bool,
    /// Edges of the antishadow volumes over the image.
    pub show_volumes: bool,
    /// Classify the overlay's regions with the brute-force classifier (debug).
    pub brute_force_regions: bool,
    /// The comparison mode's settings.
    pub compare: CompareViewSettings,
}

impl Default for ViewerSettings {
    fn default() -> Self {
        ViewerSettings {
            strategy: Strategy::Antishadow,
            alpha: None,
            // One bounce more than the thesis's direct-only experiments, so that surfaces lit
            // only indirectly (the outside of a lampshade) are visible in the viewer.
            max_depth: 2,
            exposure: 0.0,
            false_colour: false,
            resolution_scale: 0.5,
            scene: "lampshade".into(),
            recent: Vec::new(),
            overlay: OverlayKind::None,
            overlay_opacity: 0.5,
            show_outlines: true,
            show_volumes: false,
            brute_force_regions: false,
            compare: CompareViewSettings::default(),
        }
    }
}

/// What the window shows: the progressive render of one strategy, or the equal-time
/// comparison of the strategies against a reference.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ViewMode {
    #[default]
    Render,
    Compare,
}

/// Actions collected while drawing a frame, applied at its end.
#[must_use]
enum Command {
    /// Switch between the render and the comparison.
    SetMode(ViewMode),
    Open(String),
    Restart,
    Undo,
    Redo,
    Save,
    SaveAs,
    AddPortal(usize),
    DeletePortal(usize),
    /// A portal's fields changed (the editor holds the new value).
    PortalEdited,
}

/// What the legend's shares were computed for: (frame generation, portal or all).
type LegendKey = (u64, Option<usize>);

/// How many recent files are remembered.
const RECENT: usize = 8;

pub struct PortalViewApp {
    pub settings: ViewerSettings,
    /// The scene as loaded or last saved.
    scene: Scene,
    /// The scene with the editor's valid portals: what the worker renders.
    rendered: Scene,
    pub editor: PortalEditor,
    /// Portals the editor holds that break a precondition: (index, message).
    portal_errors: Vec<(usize, String)>,
    /// The camera as the user moved it (starts as the scene's).
    camera: Camera,
    renderer: RenderHandle,
    texture: Option<TextureHandle>,
    overlay_texture: Option<TextureHandle>,
    /// What the overlay texture shows: (generation, kind, portal, opacity).
    overlay_key: Option<(u64, OverlayKind, Option<usize>, u32)>,
    /// The legend's pixel shares per region, and the (generation, portal) they are for.
    legend: Option<(LegendKey, [f32; 5])>,
    /// The frame on screen, kept to re-tone-map when exposure changes.
    frame: Option<Frame>,
    /// Which portal the region overlay shows (`None`: all).
    overlay_portal: Option<usize>,
    /// Render size last requested, in pixels.
    requested_size: (u32, u32),
    paused: bool,
    /// An error or notice to show.
    message: Option<String>,
    /// A scene loading on a background thread.
    loading: Option<(String, Receiver<Result<Scene, String>>)>,
    /// The "open path" text field.
    path_input: String,
    /// When the newest request was made, to time its first frame.
    requested_at: Option<(u64, Instant)>,
    /// Time from the last request to its first (preview) frame.
    pub first_frame_latency: Option<Duration>,
    /// Recent UI frame times (time spent in `ui`).
    frame_times: VecDeque<Duration>,
    gizmo: viewport::Gizmo,
    /// Render or compare (not persisted: the viewer starts rendering).
    mode: ViewMode,
    compare: CompareView,
}

impl PortalViewApp {
    /// `scene` overrides the persisted one. A scene that fails to load is reported in the
    /// window, and the built-in lampshade is shown instead.
    pub fn new(
        ctx: &egui::Context,
        storage: Option<&dyn eframe::Storage>,
        scene: Option<String>,
    ) -> Result<Self> {
        let mut settings: ViewerSettings = storage
            .and_then(|s| eframe::get_value(s, eframe::APP_KEY))
            .unwrap_or_default();
        if let Some(scene) = scene {
            settings.scene = scene;
        }
        let (scene, message) = match Scene::open(&settings.scene) {
            Ok(scene) => (scene, None),
            Err(e) => {
                settings.scene = "lampshade".into();
                (Scene::open("lampshade")?, Some(e.to_string()))
            }
        };
        let repaint = ctx.clone();
        let renderer = RenderHandle::spawn(0, Box::new(move || repaint.request_repaint()))?;
        Ok(PortalViewApp {
            camera: scene.camera,
            editor: PortalEditor::new(&scene),
            rendered: scene.clone(),
            scene,
            settings,
            portal_errors: Vec::new(),
            renderer,
            texture: None,
            overlay_texture: None,
            overlay_key: None,
            legend: None,
            frame: None,
            overlay_portal: None,
            requested_size: (0, 0),
            paused: false,
            message,
            loading: None,
            path_input: String::new(),
            requested_at: None,
            first_frame_latency: None,
            frame_times: VecDeque::new(),
            gizmo: viewport::Gizmo::default(),
            mode: ViewMode::Render,
            compare: CompareView::default(),
        })
    }

    /// The scene being rendered (with the editor's valid portals).
    pub fn rendered_scene(&self) -> &Scene {
        &self.rendered
    }

    /// The newest frame shown.
    pub fn frame(&self) -> Option<&Frame> {
        self.frame.as_ref()
    }

    /// Pauses or resumes rendering (a paused request keeps its image and renders nothing).
    pub fn set_paused(&mut self, paused: bool) {
        self.paused = paused;
        self.restart();
    }

    pub fn camera_mut(&mut self) -> &mut Camera {
        &mut self.camera
    }

    pub fn mode(&self) -> ViewMode {
        self.mode
    }

    /// Switches mode. Comparing pauses the render and compares at the current scene and camera;
    /// leaving stops the comparison and restarts the render.
    pub fn set_mode(&mut self, mode: ViewMode) {
        if mode == self.mode {
            return;
        }
        self.mode = mode;
        if mode == ViewMode::Render {
            self.compare.stop();
        }
        self.restart();
    }

    pub fn compare_view(&self) -> &CompareView {
        &self.compare
    }

    /// The comparison's state (tests set its cache folder, or pause it).
    pub fn compare_view_mut(&mut self) -> &mut CompareView {
        &mut self.compare
    }

    fn render_settings(&self) -> RenderSettings {
        RenderSettings {
            strategy: self.settings.strategy,
            alpha: self.settings.alpha,
            max_depth: self.settings.max_depth,
            seed: 0,
        }
    }

    /// Restarts accumulation with the current scene, camera and settings (while comparing:
    /// hands them to the comparison, which restarts if they changed, and keeps the render paused).
    pub fn restart(&mut self) {
        let mut scene = self.rendered.clone();
        scene.camera = self.camera;
        if self.mode == ViewMode::Compare {
            self.compare.set_scene(scene.clone());
        }
        let (width, height) = self.requested_size;
        if width == 0 || height == 0 {
            return;
        }
        let generation = self.renderer.request(RenderRequest {
            scene,
            settings: self.render_settings(),
            width,
            height,
            paused: self.paused || self.mode == ViewMode::Compare,
            brute_force_regions: self.settings.brute_force_regions,
        });
        self.requested_at = Some((generation, Instant::now()));
    }

    /// Rebuilds the rendered scene from the editor's portals and restarts.
    pub fn apply_portal_edit(&mut self) {
        let (rendered, errors) = self.scene.with_portals_lenient(self.editor.portals.clone());
        self.rendered = rendered;
        self.portal_errors = errors
            .into_iter()
            .map(|(i, e)| (i, e.to_string()))
            .collect();
        self.restart();
    }

    /// Starts loading a built-in scene or a file on a background thread.
    pub fn open(&mut self, name_or_path: String) {
        let (tx, rx) = std::sync::mpsc::channel();
        let name = name_or_path.clone();
        std::thread::spawn(move || {
            let _ = tx.send(Scene::open(&name).map_err(|e| e.to_string()));
        });
        self.loading = Some((name_or_path, rx));
    }

    /// Takes a loaded scene, or reports its error and keeps the current one.
    fn poll_loading(&mut self) {
        let Some((name, rx)) = &self.loading else {
            return;
        };
        let result = match rx.try_recv() {
            Ok(result) => result,
            Err(TryRecvError::Empty) => return,
            Err(TryRecvError::Disconnected) => Err(format!("{name}: loading stopped")),
        };
        let name = name.clone();
        self.loading = None;
        match result {
            Ok(scene) => self.set_scene(scene, name),
            Err(e) => self.message = Some(e),
        }
    }

    /// Replaces the scene (loaded, or reloaded after saving).
    pub fn set_scene(&mut self, scene: Scene, name: String) {
        if scene.source.is_some() {
            self.settings.recent.retain(|r| *r != name);
            self.settings.recent.insert(0, name.clone());
            self.settings.recent.truncate(RECENT);
        }
        self.settings.scene = name;
        self.camera = scene.camera;
        self.editor = PortalEditor::new(&scene);
        self.rendered = scene.clone();
        self.scene = scene;
        self.portal_errors.clear();
        self.overlay_portal = None;
        self.message = None;
        self.restart();
    }

    /// Saves the edited portals: into the glTF file the scene came from (only portal nodes
    /// change), or, for a built-in scene, as a new `.glb` at `path`.
    pub fn save(&mut self, path: Option<&Path>) -> Result<PathBuf, String> {
        let target = match (path, &self.scene.source) {
            (Some(p), _) => p.to_owned(),
            (None, Some(p)) => p.clone(),
            (None, None) => return Err("a built-in scene needs Save as…".into()),
        };
        let to_same_file = self.scene.source.as_deref() == Some(target.as_path());
        let written = if to_same_file {
            gltf::save_portals(&target, &self.editor.portals)
        } else {
            let mut desc = (*self.scene.desc).clone();
            desc.portals = self.editor.portals.clone();
            desc.camera = Some(self.camera);
            gltf::export_glb(&desc, &target)
        };
        written.map_err(|e| e.to_string())?;
        // Reload so that new portals know their nodes; keep the view as it is.
        let reloaded = Scene::load(&target).map_err(|e| e.to_string())?;
        let (camera, selected) = (self.camera, self.editor.selected);
        self.set_scene(reloaded, target.display().to_string());
        self.camera = camera;
        self.editor.selected = selected.filter(|&s| s < self.editor.portals.len());
        self.editor.mark_saved();
        self.restart();
        Ok(target)
    }

    /// Uploads the newest frame from the worker, if it is new.
    fn poll_frame(&mut self, ctx: &egui::Context) {
        if let Some(error) = self.renderer.error() {
            self.message = Some(error);
        }
        let Some(frame) = self.renderer.latest() else {
            return;
        };
        let is_new = self.frame.as_ref().is_none_or(|f| {
            (f.generation, f.spp, f.preview) != (frame.generation, frame.spp, frame.preview)
        });
        if is_new && frame.generation == self.renderer.generation() {
            if let Some((generation, at)) = self.requested_at
                && generation == frame.generation
            {
                self.first_frame_latency = Some(at.elapsed());
                self.requested_at = None;
            }
            self.frame = Some(frame);
            self.upload(ctx);
        }
    }

    /// Tone-maps the frame on screen into the render texture.
    fn upload(&mut self, ctx: &egui::Context) {
        let Some(frame) = &self.frame else {
            return;
        };
        let pixels: Vec<Color32> = if self.settings.false_colour {
            false_colour_pixels(&frame.pixels)
        } else {
            frame
                .pixels
                .iter()
                .map(|&c| {
                    let [r, g, b] = tonemap::to_srgb8(c, self.settings.exposure);
                    Color32::from_rgb(r, g, b)
                })
                .collect()
        };
        let image = ColorImage::new([frame.width as usize, frame.height as usize], pixels);
        match &mut self.texture {
            Some(t) => t.set(image, TextureOptions::LINEAR),
            None => self.texture = Some(ctx.load_texture("render", image, TextureOptions::LINEAR)),
        }
    }

    /// Rebuilds the overlay texture when what it shows changed.
    fn update_overlay(&mut self, ctx: &egui::Context) {
        let Some(frame) = &self.frame else {
            return;
        };
        let Some(primary) = &frame.primary else {
            return;
        };
        let opacity_key = (self.settings.overlay_opacity * 1000.0) as u32;
        let key = (
            frame.generation,
            self.settings.overlay,
            self.overlay_portal,
            opacity_key,
        );
        if self.overlay_key == Some(key) {
            return;
        }
        self.overlay_key = Some(key);
        let image = overlay::overlay_image(
            primary,
            self.settings.overlay,
            self.overlay_portal,
            self.settings.overlay_opacity,
        );
        match &mut self.overlay_texture {
            Some(t) => t.set(image, TextureOptions::NEAREST),
            None => {
                self.overlay_texture =
                    Some(ctx.load_texture("overlay", image, TextureOptions::NEAREST))
            }
        }
    }

    fn menu_bar(&mut self, ui: &mut egui::Ui, commands: &mut Vec<Command>) {
        egui::MenuBar::new().ui(ui, |ui| {
            ui.menu_button("File", |ui| {
                if ui.button("Open glTF…").clicked() {
                    if let Some(path) = rfd::FileDialog::new()
                        .add_filter("glTF", &["gltf", "glb"])
                        .pick_file()
                    {
                        commands.push(Command::Open(path.display().to_string()));
                    }
                    ui.close();
                }
                ui.horizontal(|ui| {
                    ui.add(
                        egui::TextEdit::singleline(&mut self.path_input)
                            .hint_text("path to .gltf/.glb")
                            .desired_width(180.0),
                    );
                    if ui.button("Open path").clicked() && !self.path_input.trim().is_empty() {
                        commands.push(Command::Open(self.path_input.trim().to_owned()));
                        ui.close();
                    }
                });
                ui.menu_button("Open recent", |ui| {
                    if self.settings.recent.is_empty() {
                        ui.label("(none)");
                    }
                    for r in self.settings.recent.clone() {
                        if ui.button(&r).clicked() {
                            commands.push(Command::Open(r));
                            ui.close();
                        }
                    }
                });
                ui.separator();
                let can_save = self.scene.source.is_some();
                if ui
                    .add_enabled(can_save, egui::Button::new("Save portals"))
                    .clicked()
                {
                    commands.push(Command::Save);
                    ui.close();
                }
                if ui.button("Save as .glb…").clicked() {
                    commands.push(Command::SaveAs);
                    ui.close();
                }
            });
            ui.menu_button("Scenes", |ui| {
                for name in builtin::NAMES {
                    if ui.button(name).clicked() {
                        commands.push(Command::Open(name.to_owned()));
                        ui.close();
                    }
                }
            });
            ui.menu_button("Edit", |ui| {
                if ui
                    .add_enabled(self.editor.can_undo(), egui::Button::new("Undo  (Ctrl+Z)"))
                    .clicked()
                {
                    commands.push(Command::Undo);
                    ui.close();
                }
                if ui
                    .add_enabled(self.editor.can_redo(), egui::Button::new("Redo  (Ctrl+Y)"))
                    .clicked()
                {
                    commands.push(Command::Redo);
                    ui.close();
                }
            });
            ui.separator();
            let mut mode = self.mode;
            ui.selectable_value(&mut mode, ViewMode::Render, "Render");
            ui.selectable_value(&mut mode, ViewMode::Compare, "Compare");
            if mode != self.mode {
                commands.push(Command::SetMode(mode));
            }
            if let Some((name, _)) = &self.loading {
                ui.spinner();
                ui.label(format!("loading {name}…"));
            }
        });
    }

    fn render_controls(&mut self, ui: &mut egui::Ui, commands: &mut Vec<Command>) {
        let ViewerSettings {
            strategy,
            alpha,
            max_depth,
            exposure,
            false_colour,
            resolution_scale,
            ..
        } = &mut self.settings;
        ui.label(egui::RichText::new(format!("Scene: {}", self.scene.name)).strong());
        ui.label("Strategy (keys 1–4)");
        ui.horizontal_wrapped(|ui| {
            for s in Strategy::ALL {
                if ui.selectable_value(strategy, s, s.name()).changed() {
                    commands.push(Command::Restart);
                }
            }
        });
        let mut override_alpha = alpha.is_some();
        if ui.checkbox(&mut override_alpha, "override alpha").changed() {
            *alpha = override_alpha.then_some(0.1);
            commands.push(Command::Restart);
        }
        if let Some(a) = alpha
            && ui
                .add(egui::Slider::new(a, 0.0..=1.0).text("alpha"))
                .changed()
        {
            commands.push(Command::Restart);
        }
        if ui
            .add(egui::Slider::new(max_depth, 1..=8).text("max depth"))
            .changed()
        {
            commands.push(Command::Restart);
        }
        if ui
            .add(egui::Slider::new(resolution_scale, 0.125..=1.0).text("resolution"))
            .changed()
        {
            // The size change restarts the render.
            self.requested_size = (0, 0);
        }
        let mut retone = ui
            .add(egui::Slider::new(exposure, -8.0..=8.0).text("exposure"))
            .changed();
        retone |= ui
            .checkbox(false_colour, "false-colour luminance")
            .changed();
        ui.horizontal(|ui| {
            if ui
                .button(if self.paused { "Resume" } else { "Pause" })
                .clicked()
            {
                self.paused = !self.paused;
                commands.push(Command::Restart);
            }
            if ui.button("Reset camera").clicked() {
                self.camera = self.scene.camera;
                commands.push(Command::Restart);
            }
        });
        if retone {
            self.upload(ui.ctx());
        }
    }

    fn overlay_controls(&mut self, ui: &mut egui::Ui) {
        let settings = &mut self.settings;
        egui::ComboBox::from_label("overlay")
            .selected_text(settings.overlay.name())
            .show_ui(ui, |ui| {
                for k in OverlayKind::ALL {
                    ui.selectable_value(&mut settings.overlay, k, k.name());
                }
            });
        let portal_name = |i: Option<usize>| match i {
            None => "all portals".to_owned(),
            Some(i) => self
                .rendered
                .portals
                .get(i)
                .map_or("?".into(), |p| p.name.clone()),
        };
        egui::ComboBox::from_label("regions of")
            .selected_text(portal_name(self.overlay_portal))
            .show_ui(ui, |ui| {
                ui.selectable_value(&mut self.overlay_portal, None, portal_name(None));
                for i in 0..self.rendered.portals.len() {
                    ui.selectable_value(&mut self.overlay_portal, Some(i), portal_name(Some(i)));
                }
            });
        ui.add(egui::Slider::new(&mut settings.overlay_opacity, 0.0..=1.0).text("opacity"));
        ui.checkbox(&mut settings.show_outlines, "portal and light outlines");
        ui.checkbox(&mut settings.show_volumes, "antishadow volume edges");
        if ui
            .checkbox(&mut settings.brute_force_regions, "brute-force classifier (debug)")
            .on_hover_text("Regions from projecting the light through each point onto the portal plane, instead of the precomputed planes")
            .changed()
        {
            self.requested_size = (0, 0);
        }
        // The legend: colours and the share of pixels in each region.
        let shares = self.frame.as_ref().and_then(|f| {
            let key = (f.generation, self.overlay_portal);
            match self.legend {
                Some((k, shares)) if k == key => Some(shares),
                _ => {
                    let shares = f.primary.as_ref()?.shares(self.overlay_portal);
                    self.legend = Some((key, shares));
                    Some(shares)
                }
            }
        });
        egui::Grid::new("legend").num_columns(3).show(ui, |ui| {
            for (k, region) in Region::ALL.into_iter().enumerate() {
                let (rect, _) =
                    ui.allocate_exact_size(egui::vec2(14.0, 14.0), egui::Sense::hover());
                ui.painter()
                    .rect_filled(rect, 2.0, overlay::region_colour(region));
                let technique = Strategy::Antishadow.technique(region);
                ui.label(format!(
                    "{}: {}",
                    region.name(),
                    technique.map_or("light alone", Technique::name)
                ));
                ui.label(shares.map_or("–".into(), |s| format!("{:.1}%", 100.0 * s[k])));
                ui.end_row();
            }
        });
    }

    fn statistics(&self, ui: &mut egui::Ui) {
        let Some(f) = &self.frame else {
            ui.label("waiting for the first frame…");
            return;
        };
        let s = &f.stats;
        let secs = f.elapsed.as_secs_f64().max(1e-9);
        egui::Grid::new("stats").num_columns(2).show(ui, |ui| {
            ui.label("samples/s");
            ui.label(format!("{:.2} M", f.samples_per_second() / 1e6));
            ui.end_row();
            ui.label("rays/s");
            ui.label(format!("{:.2} M", s.rays() as f64 / secs / 1e6));
            ui.end_row();
            ui.label("shadow rays");
            ui.label(format!("{}", s.shadow_rays));
            ui.end_row();
            ui.label("sampling time");
            ui.label(format!(
                "{:.0} ns / sample",
                s.sampling_ns as f64 / s.light_samples().max(1) as f64
            ));
            ui.end_row();
            for (k, r) in Region::ALL.into_iter().enumerate() {
                let share = s.regions[k] as f64 / s.shading_points().max(1) as f64;
                ui.label(format!("points in {}", r.name()));
                ui.label(format!("{:.1}%", 100.0 * share));
                ui.end_row();
            }
            for (k, t) in Technique::ALL.into_iter().enumerate() {
                ui.label(format!("{} samples", t.name()));
                ui.label(format!("{}", s.techniques[k]));
                ui.end_row();
            }
            ui.label("empty samples");
            ui.label(format!("{}", s.empty_samples));
            ui.end_row();
            if let Some(l) = self.first_frame_latency {
                ui.label("first frame after a change");
                ui.label(format!("{:.0} ms", l.as_secs_f64() * 1e3));
                ui.end_row();
            }
            if let Some(t) = self.mean_frame_time() {
                ui.label("UI frame time");
                ui.label(format!("{:.1} ms", t.as_secs_f64() * 1e3));
                ui.end_row();
            }
        });
    }

    fn status_bar(&self, ui: &mut egui::Ui) {
        if self.mode == ViewMode::Compare {
            ui.horizontal(|ui| self.compare.status(ui));
            return;
        }
        ui.horizontal(|ui| {
            match &self.frame {
                Some(f) => {
                    ui.label(format!(
                        "{} spp{}  {}×{}  {:.1} s  {:.2} M samples/s",
                        f.spp,
                        if f.preview { " (preview)" } else { "" },
                        f.width,
                        f.height,
                        f.elapsed.as_secs_f32(),
                        f.samples_per_second() / 1e6
                    ));
                }
                None => {
                    ui.label("starting…");
                }
            }
            if self.paused {
                ui.label("paused");
            }
        });
    }

    /// The mean UI frame time over recent frames.
    pub fn mean_frame_time(&self) -> Option<Duration> {
        let n = self.frame_times.len() as u32;
        (n > 0).then(|| self.frame_times.iter().sum::<Duration>() / n)
    }

    fn handle_keys(&mut self, ctx: &egui::Context, commands: &mut Vec<Command>) {
        if ctx.egui_wants_keyboard_input() {
            return;
        }
        ctx.input(|i| {
            for (key, s) in [
                egui::Key::Num1,
                egui::Key::Num2,
                egui::Key::Num3,
                egui::Key::Num4,
            ]
            .into_iter()
            .zip(Strategy::ALL)
            {
                if i.key_pressed(key) && self.settings.strategy != s {
                    self.settings.strategy = s;
                    commands.push(Command::Restart);
                }
            }
            if i.modifiers.command && i.key_pressed(egui::Key::Z) {
                commands.push(if i.modifiers.shift {
                    Command::Redo
                } else {
                    Command::Undo
                });
            }
            if i.modifiers.command && i.key_pressed(egui::Key::Y) {
                commands.push(Command::Redo);
            }
            if i.key_pressed(egui::Key::Delete)
                && let Some(s) = self.editor.selected
            {
                commands.push(Command::DeletePortal(s));
            }
            for file in &i.raw.dropped_files {
                commands.push(Command::Open(file.path().display().to_string()));
            }
        });
    }

    fn apply(&mut self, commands: Vec<Command>) {
        let mut restart = false;
        let mut edited = false;
        for command in commands {
            match command {
                Command::SetMode(mode) => self.set_mode(mode),
                Command::Open(name) => self.open(name),
                Command::Restart => restart = true,
                Command::Undo => edited |= self.editor.undo(),
                Command::Redo => edited |= self.editor.redo(),
                Command::Save => match self.save(None) {
                    Ok(path) => self.message = Some(format!("saved {}", path.display())),
                    Err(e) => self.message = Some(e),
                },
                Command::SaveAs => {
                    let name = format!("{}.glb", self.scene.name);
                    if let Some(path) = rfd::FileDialog::new()
                        .add_filter("glTF binary", &["glb"])
                        .set_file_name(name)
                        .save_file()
                    {
                        match self.save(Some(&path)) {
                            Ok(path) => self.message = Some(format!("saved {}", path.display())),
                            Err(e) => self.message = Some(e),
                        }
                    }
                }
                Command::AddPortal(light) => {
                    edited |= self.editor.add_for_light(&self.scene, light).is_some()
                }
                Command::DeletePortal(i) => {
                    self.editor.delete(i);
                    edited = true;
                }
                Command::PortalEdited => edited = true,
            }
        }
        if edited {
            self.apply_portal_edit();
        } else if restart {
            self.restart();
        }
    }

    /// The whole UI, for eframe and for headless tests and benchmarks.
    pub fn show(&mut self, ui: &mut egui::Ui) {
        let start = Instant::now();
        let ctx = ui.ctx().clone();
        self.poll_loading();
        self.poll_frame(&ctx);
        self.update_overlay(&ctx);
        let mut commands = Vec::new();
        self.handle_keys(&ctx, &mut commands);
        egui::Panel::top("menu").show(ui, |ui| self.menu_bar(ui, &mut commands));
        egui::Panel::bottom("status").show(ui, |ui| self.status_bar(ui));
        if self.mode == ViewMode::Compare {
            let settings = &mut self.settings;
            self.compare
                .sync(&ctx, &settings.compare, settings.max_depth, settings.alpha);
            self.compare.show(
                ui,
                &mut settings.compare,
                &mut settings.exposure,
                &mut self.message,
            );
        } else {
            self.render_panels(ui, &mut commands);
        }
        self.apply(commands);
        // Frames wake the UI through the worker's notify; this is only a slow heartbeat.
        ctx.request_repaint_after(Duration::from_millis(500));
        self.frame_times.push_back(start.elapsed());
        if self.frame_times.len() > 120 {
            self.frame_times.pop_front();
        }
    }

    /// The render mode's panels: controls on the left, the image in the middle.
    fn render_panels(&mut self, ui: &mut egui::Ui, commands: &mut Vec<Command>) {
        egui::Panel::left("controls")
            .resizable(true)
            .default_size(330.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| {
                    if let Some(m) = self.message.clone() {
                        ui.horizontal(|ui| {
                            ui.colored_label(Color32::LIGHT_RED, m);
                            if ui.small_button("x").clicked() {
                                self.message = None;
                            }
                        });
                    }
                    egui::CollapsingHeader::new("Render")
                        .default_open(true)
                        .show(ui, |ui| self.render_controls(ui, commands));
                    egui::CollapsingHeader::new("Antishadow overlay")
                        .default_open(true)
                        .show(ui, |ui| self.overlay_controls(ui));
                    egui::CollapsingHeader::new("Portals")
                        .default_open(true)
                        .show(ui, |ui| self.portal_panel(ui, commands));
                    egui::CollapsingHeader::new("Statistics")
                        .default_open(false)
                        .show(ui, |ui| self.statistics(ui));
                });
            });
        egui::CentralPanel::default().show(ui, |ui| self.viewport(ui, commands));
    }
}

/// log10 luminance over four decades below the brightest pixel, in false colour.
fn false_colour_pixels(pixels: &[glam::Vec3]) -> Vec<Color32> {
    let lum: Vec<f32> = pixels
        .iter()
        .map(|&c| crate::light::area::luminance(c))
        .collect();
    let max = lum.iter().copied().fold(0.0, f32::max).max(1e-12);
    lum.iter()
        .map(|&l| {
            let t = if l > 0.0 {
                1.0 + (l / max).log10() / 4.0
            } else {
                0.0
            };
            let [r, g, b] = tonemap::false_colour(t);
            Color32::from_rgb(r, g, b)
        })
        .collect()
}

impl eframe::App for PortalViewApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.show(ui);
    }

    fn save(&mut self, storage: &mut dyn eframe::Storage) {
        eframe::set_value(storage, eframe::APP_KEY, &self.settings);
    }
}

/// How the viewer starts; `None` keeps what was used last.
#[derive(Clone, Debug, Default)]
pub struct ViewOptions {
    /// Built-in name or a `.gltf`/`.glb` path.
    pub scene: Option<String>,
    pub strategy: Option<Strategy>,
    pub overlay: Option<OverlayKind>,
    /// Draw the edges of the antishadow volumes.
    pub volumes: bool,
    pub max_depth: Option<u32>,
}

/// Opens the viewer window (blocks until it closes).
pub fn run_viewer(args: ViewOptions) -> Result<()> {
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title("portalview")
            .with_inner_size([1280.0, 800.0])
            .with_drag_and_drop(true),
        ..Default::default()
    };
    eframe::run_native(
        "portalview",
        options,
        Box::new(move |cc| {
            let mut app = PortalViewApp::new(&cc.egui_ctx, cc.storage, args.scene)?;
            let s = &mut app.settings;
            s.strategy = args.strategy.unwrap_or(s.strategy);
            s.overlay = args.overlay.unwrap_or(s.overlay);
            s.max_depth = args.max_depth.unwrap_or(s.max_depth).max(1);
            s.show_volumes |= args.volumes;
            Ok(Box::new(app))
        }),
    )
    .map_err(|e| anyhow::anyhow!("cannot open the viewer window: {e}"))
}
