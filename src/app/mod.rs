//! The viewer: an eframe window showing the progressive render of a scene, the antishadow
//! overlays, portal editing and the comparison mode. The app owns UI state only: rendering
//! happens on the worker, reached through one [`RenderHandle`], scenes are opened and saved
//! by background `loader::Job`s, and what an edit needs that takes long (window tables, an
//! environment) is made by the `builder::Builder`; the UI never waits on any of them.
//!
//! This file holds the app, its frame loop and the commands a frame collects; each panel,
//! the viewport, the gizmo and the file dialogs live in their own files.

mod builder;
pub mod compare_view;
pub mod edit;
mod environment_panel;
mod files;
mod frame_view;
mod gizmo;
mod loader;
mod menu;
pub mod overlay;
mod portal_panel;
mod settings;
mod side_panel;
mod viewport;

use anyhow::Result;
use std::collections::VecDeque;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use crate::asset::desc::PortalDesc;
use crate::asset::environment::{EnvironmentDesc, EnvironmentOverrides};
use crate::camera::Camera;
use crate::light::{Mixture, Selection, Strategy};
use crate::render::integrator::{GlassShadows, GuideBounces, RenderSettings};
use crate::render::worker::{Frame, RenderHandle, RenderRequest};
use crate::sampling::SamplerKind;
use crate::scene::Scene;
use crate::scene::opening::fit_opening;
use crate::scene::portals::SourceCheck;
use builder::{Builder, Built};
use compare_view::CompareView;
use edit::PortalEditor;
use environment_panel::EnvironmentEdit;
use files::{FilePicker, Purpose};
use frame_view::FrameView;
use loader::{Done, Job, SaveRequest};
use overlay::OverlayKind;
use settings::DEFAULT_SCENE;
pub use settings::{ViewMode, ViewerSettings};

/// Actions collected while drawing a frame, applied at its end.
#[must_use]
enum Command {
    /// Switch between the render and the comparison.
    SetMode(ViewMode),
    /// Open a built-in scene by name or a file by path.
    Open(String),
    /// Show the file dialog for a purpose.
    ShowDialog(Purpose),
    Restart,
    ResetCamera,
    Undo,
    Redo,
    /// Save the portals into the scene's file.
    Save,
    /// Save the scene and its portals as a new `.glb`.
    SaveAs(PathBuf),
    AddPortal(usize),
    /// Wait for a click on the image, then add a window portal in the opening there.
    AddWindow,
    /// Add a window portal fitted to the opening under the image point `ndc` (normalised
    /// coordinates of an image of aspect `aspect`), or a default one if there is none.
    AddWindowAt {
        ndc: glam::Vec2,
        aspect: f32,
    },
    /// Turn a window portal's front over.
    FlipPortal(usize),
    /// Change the environment.
    Environment(EnvironmentEdit),
    DeletePortal(usize),
    /// A portal's fields changed (the editor holds the new value).
    PortalEdited,
    /// Find the openings of the lights and the sky and propose a portal for each.
    FindPortals,
    /// Check the editor's portals: leaks and portals no light passes.
    CheckPortals,
}

/// The scene on screen.
struct Current {
    /// The scene as loaded or last saved.
    scene: Scene,
    /// The scene with the editor's valid portals: what the worker renders. Its windows may
    /// lack their guided tables while the builder makes them (they are then sampled by solid
    /// angle, which is exact).
    rendered: Scene,
    /// An environment edit the builder is making (`Some(None)`: off); until it is done the
    /// scenes keep the old one.
    environment: Option<Option<EnvironmentDesc>>,
    /// The camera as the user moved it (starts as the scene's).
    camera: Camera,
    /// Portals the editor holds that break a precondition: (index, message).
    portal_errors: Vec<(usize, String)>,
    /// The last check, and the portals it checked (stale once they are edited).
    checks: Option<(Vec<PortalDesc>, Vec<SourceCheck>)>,
    /// What the last *Find portals* noted (lights in the open, openings left without a portal).
    found_notes: Vec<String>,
}

impl Current {
    fn new(scene: Scene) -> Self {
        Current {
            camera: scene.camera,
            rendered: scene.clone(),
            scene,
            environment: None,
            portal_errors: Vec::new(),
            checks: None,
            found_notes: Vec::new(),
        }
    }

    /// The last check, if it checked the portals `editor` holds now.
    fn fresh_checks(&self, editor: &[PortalDesc]) -> Option<&[SourceCheck]> {
        self.checks
            .as_ref()
            .filter(|(checked, _)| checked.as_slice() == editor)
            .map(|(_, checks)| checks.as_slice())
    }

    /// The environment as last edited (what the panel shows and saving writes).
    fn edited_environment(&self) -> Option<EnvironmentDesc> {
        match &self.environment {
            Some(edited) => edited.clone(),
            None => self.scene.desc.environment.clone(),
        }
    }

    /// The index among the rendered portals, then windows (as the overlay counts them), of
    /// the editor's portal `i` (if it is valid).
    fn rendered_index(&self, i: usize) -> Option<usize> {
        let portals = &self.rendered.portals;
        portals.iter().position(|p| p.desc_index == i).or_else(|| {
            let w = self
                .rendered
                .windows
                .iter()
                .position(|w| w.desc_index == i)?;
            Some(portals.len() + w)
        })
    }
}

pub struct PortalViewApp {
    pub settings: ViewerSettings,
    /// The scene on screen (`None` until the first one has loaded).
    current: Option<Current>,
    pub editor: PortalEditor,
    renderer: RenderHandle,
    /// Builds window tables and environments for edits.
    builder: Builder<Built>,
    /// The newest frame and its textures.
    view: FrameView,
    /// Which portal the region overlay shows (`None`: all).
    overlay_portal: Option<usize>,
    /// The environment was changed since loading or saving.
    environment_dirty: bool,
    /// Render size last requested, in pixels.
    requested_size: (u32, u32),
    paused: bool,
    /// An error or notice to show in the side panel.
    message: Option<String>,
    /// A scene opening or saving on a background thread.
    job: Option<Job>,
    /// Portals being found or checked on a background thread.
    portal_job: Option<Job>,
    /// The file dialog, while it is open.
    picker: Option<FilePicker>,
    /// The "open path" field of the menu bar.
    path_input: String,
    /// When the newest request was made, to time its first frame.
    requested_at: Option<(u64, Instant)>,
    /// Time from the last request to its first (preview) frame.
    pub first_frame_latency: Option<Duration>,
    /// Recent UI frame times (time spent in `show`).
    frame_times: VecDeque<Duration>,
    gizmo: gizmo::Gizmo,
    /// *Add window portal* was pressed: the next click on the image says where the opening is.
    placing_window: bool,
    /// Where the image was last right-clicked (its context menu's point).
    context_point: Option<egui::Pos2>,
    /// Where the image was last drawn.
    image_rect: Option<egui::Rect>,
    /// Render or compare (not persisted: the viewer starts rendering).
    mode: ViewMode,
    compare: CompareView,
    /// Wakes the UI from background jobs.
    ctx: egui::Context,
}

impl PortalViewApp {
    /// `scene` overrides the persisted one. It loads in the background; one that fails is
    /// reported in the window, and the built-in lampshade is opened instead.
    pub fn new(
        ctx: &egui::Context,
        storage: Option<&dyn eframe::Storage>,
        scene: Option<String>,
    ) -> Result<Self> {
        Self::with_options(
            ctx,
            storage,
            ViewOptions {
                scene,
                ..ViewOptions::default()
            },
        )
    }

    /// The viewer as `portalview view` starts it: the options override what was used last,
    /// and the start-up scene's environment is replaced as they say.
    pub fn with_options(
        ctx: &egui::Context,
        storage: Option<&dyn eframe::Storage>,
        options: ViewOptions,
    ) -> Result<Self> {
        let mut settings: ViewerSettings = storage
            .and_then(|s| eframe::get_value(s, eframe::APP_KEY))
            .unwrap_or_default();
        if let Some(scene) = options.scene {
            settings.scene = scene;
        }
        settings.strategy = options.strategy.unwrap_or(settings.strategy);
        settings.overlay = options.overlay.unwrap_or(settings.overlay);
        settings.max_depth = options.max_depth.unwrap_or(settings.max_depth).max(1);
        settings.sampler = options.sampler.unwrap_or(settings.sampler);
        settings.mixture = options.mixture.unwrap_or(settings.mixture);
        settings.selection = options.selection.unwrap_or(settings.selection);
        settings.glass = options.glass.unwrap_or(settings.glass);
        settings.bounces = options.bounces.unwrap_or(settings.bounces);
        settings.show_volumes |= options.volumes;
        let repaint = ctx.clone();
        let renderer = RenderHandle::spawn(0, Box::new(move || repaint.request_repaint()))?;
        let repaint = ctx.clone();
        let builder = Builder::spawn(Box::new(move || repaint.request_repaint()))?;
        let job = Job::open_with_environment(settings.scene.clone(), options.environment, ctx);
        Ok(PortalViewApp {
            job: Some(job),
            portal_job: None,
            settings,
            current: None,
            editor: PortalEditor::default(),
            renderer,
            builder,
            view: FrameView::default(),
            overlay_portal: None,
            environment_dirty: false,
            requested_size: (0, 0),
            paused: false,
            message: None,
            picker: None,
            path_input: String::new(),
            requested_at: None,
            first_frame_latency: None,
            frame_times: VecDeque::new(),
            gizmo: gizmo::Gizmo::default(),
            placing_window: false,
            context_point: None,
            image_rect: None,
            mode: ViewMode::Render,
            compare: CompareView::default(),
            ctx: ctx.clone(),
        })
    }

    /// The scene as loaded or last saved (`None` until the first one has loaded).
    pub fn scene(&self) -> Option<&Scene> {
        self.current.as_ref().map(|c| &c.scene)
    }

    /// Whether a scene is opening or saving in the background.
    pub fn is_busy(&self) -> bool {
        self.job.is_some()
    }

    /// The scene the worker renders: the editor's valid portals, its windows perhaps still
    /// without their tables (`None` until the first scene has loaded).
    pub fn rendered(&self) -> Option<&Scene> {
        self.current.as_ref().map(|c| &c.rendered)
    }

    /// Whether portals are being found or checked in the background.
    pub fn is_checking_portals(&self) -> bool {
        self.portal_job.is_some()
    }

    /// The last check of the portals, if it checked those the editor holds now.
    pub fn portal_checks(&self) -> Option<&[SourceCheck]> {
        self.current
            .as_ref()
            .and_then(|c| c.fresh_checks(&self.editor.portals))
    }

    /// Whether an edit's window tables or environment are building in the background.
    pub fn is_building(&self) -> bool {
        self.builder.is_building()
    }

    /// What the builder is making, in a few words, while it is.
    fn building(&self) -> Option<&'static str> {
        let current = self.current.as_ref().filter(|_| self.is_building())?;
        let environment = current.rendered.environment.as_deref();
        Some(if current.environment.is_some() {
            "building the environment"
        } else if current
            .rendered
            .windows
            .iter()
            .any(|w| w.lacks_table(environment))
        {
            "building window tables"
        } else {
            // The auto alphas and the enclosures' boxes (`Scene::build_tables`).
            "measuring the portals"
        })
    }

    /// The error or notice the side panel shows.
    pub fn message(&self) -> Option<&str> {
        self.message.as_deref()
    }

    /// The newest frame shown.
    pub fn frame(&self) -> Option<&Frame> {
        self.view.frame.as_ref()
    }

    /// Pauses or resumes rendering (a paused request keeps its image and renders nothing).
    pub fn set_paused(&mut self, paused: bool) {
        self.paused = paused;
        self.restart();
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

    /// What the render worker is asked to render with (the viewer's settings).
    pub fn render_settings(&self) -> RenderSettings {
        RenderSettings {
            strategy: self.settings.strategy,
            alpha: self.settings.alpha,
            max_depth: self.settings.max_depth,
            seed: 0,
            sampler: self.settings.sampler,
            mixture: self.settings.mixture,
            selection: self.settings.selection,
            glass: self.settings.glass,
            bounces: self.settings.bounces,
        }
    }

    /// Restarts accumulation with the current scene, camera and settings (while comparing:
    /// hands them to the comparison, which restarts if they changed, and keeps the render paused).
    fn restart(&mut self) {
        let Some(current) = &self.current else {
            return;
        };
        let mut scene = current.rendered.clone();
        scene.camera = current.camera;
        // The comparison waits for the built scene: it would time the stand-in technique.
        if self.mode == ViewMode::Compare && !self.builder.is_building() {
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

    /// Rebuilds the rendered scene from the editor's portals and restarts, without waiting:
    /// a window keeps its guided table if it kept its axes (a move, a resize); a turned or
    /// new one has none until the builder has made it, and is sampled by solid angle (exact)
    /// meanwhile; the built scene then restarts the render again.
    pub fn apply_portal_edit(&mut self) {
        if let Some(current) = &mut self.current {
            let (rendered, errors) = current
                .scene
                .with_portals_deferred(self.editor.portals.clone(), Some(&current.rendered));
            current.rendered = rendered;
            current.portal_errors = errors
                .into_iter()
                .map(|(i, e)| (i, e.to_string()))
                .collect();
        }
        self.request_build();
        self.restart();
    }

    /// Asks the builder for what the rendered scene lacks (window tables, an edited
    /// environment); if it lacks nothing, forgets any build under way (its state is gone).
    fn request_build(&mut self) {
        let Some(current) = &self.current else {
            return;
        };
        let environment = current.environment.clone();
        if environment.is_none() && !current.rendered.lacks_tables() {
            self.builder.forget();
            return;
        }
        let (scene, rendered) = (current.scene.clone(), current.rendered.clone());
        self.builder.request(Box::new(move || {
            builder::complete(scene, rendered, environment)
        }));
    }

    /// Takes the builder's result: the scene to render (and, after an environment edit, the
    /// saved scene under the new environment); the render restarts.
    fn poll_build(&mut self) {
        let Some(result) = self.builder.poll() else {
            return;
        };
        let Some(current) = &mut self.current else {
            return;
        };
        current.environment = None;
        match result {
            Ok(Built { scene, rendered }) => {
                if let Some(scene) = scene {
                    current.scene = scene;
                }
                current.rendered = rendered;
                self.restart();
            }
            Err(e) => self.message = Some(e),
        }
    }

    /// Starts opening a built-in scene or a file in the background; the current scene stays
    /// until it has loaded, and stays if it fails.
    pub fn open(&mut self, name_or_path: String) {
        self.message = None;
        self.job = Some(Job::open(name_or_path, &self.ctx));
    }

    /// Starts saving the edited portals in the background: into the glTF file the scene came
    /// from (only portal nodes change), or, given `path`, as a new `.glb`.
    fn save(&mut self, path: Option<PathBuf>) {
        let Some(current) = &self.current else {
            return;
        };
        let target = match (path, &current.scene.source) {
            (Some(p), _) => p,
            (None, Some(p)) => p.clone(),
            (None, None) => {
                self.message = Some("a built-in scene is saved with File > Save as .glb…".into());
                return;
            }
        };
        let into_source = current.scene.source.as_deref() == Some(target.as_path());
        self.environment_dirty = false;
        // The latest edits, whether or not their tables or environment are built yet.
        let mut desc = (*current.scene.desc).clone();
        desc.portals = self.editor.portals.clone();
        desc.environment = current.edited_environment();
        desc.camera = Some(current.camera);
        let request = SaveRequest {
            target,
            into_source,
            desc,
        };
        self.message = None;
        self.job = Some(Job::save(request, &self.ctx));
    }

    /// Checks the editor's portals in the background.
    fn check_portals(&mut self) {
        if let Some(current) = &self.current {
            let scene = current.rendered.clone();
            self.portal_job = Some(Job::check_portals(scene, &self.ctx));
        }
    }

    /// Takes the found portals into the editor (an undoable edit; their alpha is `auto`),
    /// then checks them; or a check's result.
    fn poll_portal_job(&mut self) {
        let Some(result) = self.portal_job.as_ref().and_then(Job::poll) else {
            return;
        };
        self.portal_job = None;
        match result {
            Ok(Done::Found(found)) => {
                let Some(current) = &mut self.current else {
                    return;
                };
                current.found_notes = found
                    .sources
                    .iter()
                    .flat_map(|s| s.notes.iter().map(move |n| format!("{}: {n}", s.name)))
                    .collect();
                self.editor.checkpoint();
                self.editor.portals = found.portals;
                self.editor.selected = (!self.editor.portals.is_empty()).then_some(0);
                self.apply_portal_edit();
                self.check_portals();
            }
            Ok(Done::Checked { portals, checks }) => {
                if let Some(current) = &mut self.current {
                    current.checks = Some((portals, checks));
                }
            }
            Ok(_) => {}
            Err(e) => self.message = Some(e),
        }
    }

    /// Takes the background job's result: a scene to show, or an error to report (the current
    /// scene stays). If the first scene fails, the default one is opened instead.
    fn poll_job(&mut self) {
        let Some(result) = self.job.as_ref().and_then(Job::poll) else {
            return;
        };
        self.job = None;
        match result {
            Ok(Done::Opened {
                name,
                scene,
                environment_replaced,
            }) => {
                // What the file holds that is not read is said, not dropped in silence.
                // (Kept apart from an earlier error, such as the one a fallback scene follows.)
                let warnings = &scene.desc.warnings;
                if !warnings.is_empty() {
                    self.message = Some(warnings.join("\n"));
                }
                self.show_scene(scene, name);
                // The command line's sky is not the file's: saving writes it, as the panel says.
                self.environment_dirty = environment_replaced;
                self.restart();
            }
            Ok(Done::Saved {
                path,
                scene,
                portals,
            }) => self.saved(path, scene, portals),
            Ok(Done::Environment { map, warnings }) => {
                let kept = self.current.as_ref().and_then(Current::edited_environment);
                let environment = crate::asset::environment::EnvironmentDesc {
                    map,
                    ..kept.unwrap_or(crate::asset::environment::EnvironmentDesc::constant(
                        glam::Vec3::ONE,
                    ))
                };
                self.apply_environment(EnvironmentEdit::Set(Some(environment)));
                if !warnings.is_empty() {
                    self.message = Some(warnings.join("\n"));
                }
            }
            // Finding and checking run as portal jobs, never as this one.
            Ok(Done::Found(_) | Done::Checked { .. }) => {}
            Err(e) => {
                self.message = Some(e);
                if self.current.is_none() && self.settings.scene != DEFAULT_SCENE {
                    self.settings.scene = DEFAULT_SCENE.into();
                    self.job = Some(Job::open(DEFAULT_SCENE.into(), &self.ctx));
                }
            }
        }
    }

    /// Puts a loaded scene on screen, with its own camera and portals (the caller restarts).
    fn show_scene(&mut self, scene: Scene, name: String) {
        if scene.source.is_some() {
            self.settings.remember(&name);
        }
        self.settings.scene = name;
        self.editor = PortalEditor::new(&scene);
        self.current = Some(Current::new(scene));
        // Portals found or checked for the previous scene are not this one's.
        self.portal_job = None;
        self.builder.forget();
        self.overlay_portal = None;
        self.environment_dirty = false;
    }

    /// After saving: the file read back replaces the scene (so that new portals know their
    /// nodes), and the view stays as it is. Edits made while saving stay, unsaved.
    fn saved(&mut self, path: PathBuf, scene: Scene, portals: Vec<PortalDesc>) {
        let camera = self.current.as_ref().map(|c| c.camera);
        let environment = self.current.as_ref().map(Current::edited_environment);
        let editor = std::mem::take(&mut self.editor);
        let unchanged = editor.portals == portals;
        let saved_environment = scene.desc.environment.clone();
        self.show_scene(scene, path.display().to_string());
        if let Some(environment) = environment.filter(|e| *e != saved_environment) {
            self.apply_environment(EnvironmentEdit::Set(environment));
        }
        if let (Some(current), Some(camera)) = (&mut self.current, camera) {
            current.camera = camera;
        }
        if unchanged {
            self.editor.selected = editor.selected.filter(|&s| s < self.editor.portals.len());
            self.editor.mark_saved();
            self.restart();
        } else {
            self.editor = editor;
            self.apply_portal_edit();
        }
        self.message = Some(format!("saved {}", path.display()));
    }

    /// Uploads the newest frame from the worker, if it is new.
    fn poll_frame(&mut self) {
        if let Some(error) = self.renderer.error() {
            self.message = Some(error);
        }
        let Some(frame) = self.renderer.latest() else {
            return;
        };
        if frame.generation != self.renderer.generation() || !self.view.is_new(&frame) {
            return;
        }
        if let Some((generation, at)) = self.requested_at
            && generation == frame.generation
        {
            self.first_frame_latency = Some(at.elapsed());
            self.requested_at = None;
        }
        self.view.frame = Some(frame);
        self.view.upload(
            &self.ctx,
            self.settings.exposure,
            self.settings.false_colour,
        );
    }

    /// Adds a window portal fitted to the opening under the image point `ndc`; where there is
    /// none, the default square at the camera's target, and says so. Whether one was added.
    fn add_window_at(&mut self, ndc: glam::Vec2, aspect: f32) -> bool {
        let Some(current) = &self.current else {
            return false;
        };
        match fit_opening(&current.scene, &current.camera, ndc, aspect) {
            Some(opening) => {
                self.message = Some(format!(
                    "window portal fitted to the opening: {:.3} × {:.3} m",
                    opening.size.x, opening.size.y
                ));
                self.editor.add_window_in(&opening).is_some()
            }
            None => {
                self.message = Some(
                    "no window opening there (a hole with the wall around it): placed a 1 m \
                     window at the camera's target, facing the camera; move it into the \
                     opening with the gizmo"
                        .into(),
                );
                self.editor.add_window(&current.camera).is_some()
            }
        }
    }

    /// Where the world point `p` is on screen, through the camera, in the image as last drawn.
    pub fn image_point(&self, p: glam::Vec3) -> Option<egui::Pos2> {
        let projector = viewport::Projector {
            camera: self.current.as_ref()?.camera,
            rect: self.image_rect?,
        };
        projector.point(p)
    }

    /// Whether the viewer waits for a click on the image to add a window portal there.
    pub fn is_placing_window(&self) -> bool {
        self.placing_window
    }

    /// The mean UI frame time over recent frames.
    fn mean_frame_time(&self) -> Option<Duration> {
        let n = self.frame_times.len() as u32;
        (n > 0).then(|| self.frame_times.iter().sum::<Duration>() / n)
    }

    fn handle_keys(&mut self, ctx: &egui::Context, commands: &mut Vec<Command>) {
        ctx.input(|i| {
            // Dropped files open whatever has the keyboard.
            for file in &i.raw.dropped_files {
                commands.push(Command::Open(file.path().display().to_string()));
            }
        });
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
            if i.key_pressed(egui::Key::Escape) {
                self.placing_window = false;
            }
            if i.key_pressed(egui::Key::Delete)
                && let Some(s) = self.editor.selected
            {
                commands.push(Command::DeletePortal(s));
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
                Command::ShowDialog(purpose) => self.show_dialog(purpose),
                Command::Restart => restart = true,
                Command::ResetCamera => {
                    if let Some(current) = &mut self.current {
                        current.camera = current.scene.camera;
                        restart = true;
                    }
                }
                Command::Undo => edited |= self.editor.undo(),
                Command::Redo => edited |= self.editor.redo(),
                Command::Save => self.save(None),
                Command::SaveAs(path) => self.save(Some(path)),
                Command::AddPortal(light) => {
                    if let Some(current) = &self.current {
                        edited |= self.editor.add_for_light(&current.scene, light).is_some();
                    }
                }
                Command::AddWindow => self.placing_window = true,
                Command::AddWindowAt { ndc, aspect } => {
                    self.placing_window = false;
                    edited |= self.add_window_at(ndc, aspect);
                }
                Command::FlipPortal(i) => edited |= self.editor.flip(i),
                Command::Environment(edit) => self.apply_environment(edit),
                Command::DeletePortal(i) => {
                    self.editor.delete(i);
                    edited = true;
                }
                Command::PortalEdited => edited = true,
                Command::FindPortals => {
                    if let Some(current) = &self.current {
                        let scene = current.rendered.clone();
                        self.portal_job = Some(Job::find_portals(scene, &self.ctx));
                    }
                }
                Command::CheckPortals => self.check_portals(),
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
        self.poll_job();
        self.poll_portal_job();
        self.poll_build();
        self.poll_frame();
        self.view.update_overlay(
            &ctx,
            self.settings.overlay,
            self.overlay_portal,
            self.settings.overlay_opacity,
        );
        let mut commands = Vec::new();
        self.handle_keys(&ctx, &mut commands);
        egui::Panel::top("menu").show(ui, |ui| self.menu_bar(ui, &mut commands));
        egui::Panel::bottom("status").show(ui, |ui| self.status_bar(ui));
        if self.mode == ViewMode::Compare {
            let settings = &mut self.settings;
            self.compare.sync(
                &ctx,
                &settings.compare,
                settings.max_depth,
                settings.alpha,
                (
                    settings.sampler,
                    settings.mixture,
                    settings.selection,
                    settings.glass,
                    settings.bounces,
                ),
            );
            self.compare.show(
                ui,
                &mut settings.compare,
                &mut settings.exposure,
                &mut self.message,
            );
        } else {
            self.render_panels(ui, &mut commands);
        }
        self.file_dialog(&ctx, &mut commands);
        self.apply(commands);
        // Frames and finished jobs wake the UI; this is only a slow heartbeat.
        ctx.request_repaint_after(Duration::from_millis(500));
        self.frame_times.push_back(start.elapsed());
        if self.frame_times.len() > 120 {
            self.frame_times.pop_front();
        }
    }
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
    pub sampler: Option<SamplerKind>,
    pub mixture: Option<Mixture>,
    pub selection: Option<Selection>,
    pub glass: Option<GlassShadows>,
    pub bounces: Option<GuideBounces>,
    /// Replaces the start-up scene's environment (the command line's `--environment…`).
    pub environment: EnvironmentOverrides,
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
            let app = PortalViewApp::with_options(&cc.egui_ctx, cc.storage, args)?;
            Ok(Box::new(app))
        }),
    )
    .map_err(|e| anyhow::anyhow!("cannot open the viewer window: {e}"))
}
