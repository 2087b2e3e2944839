//! The viewer: an eframe window showing the progressive render of a scene. The app owns UI
//! state only; rendering happens on the worker, reached through one [`RenderHandle`].

use anyhow::Result;
use egui::{Color32, ColorImage, TextureHandle, TextureOptions};
use serde::{Deserialize, Serialize};
use std::time::Duration;

use crate::light::Strategy;
use crate::render::integrator::RenderSettings;
use crate::render::tonemap;
use crate::render::worker::{Frame, RenderHandle, RenderRequest};
use crate::scene::Scene;
use crate::scene::camera::Camera;

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
    /// Render resolution relative to the viewport's physical pixels.
    pub resolution_scale: f32,
    /// The scene opened last: a built-in name or a file path.
    pub scene: String,
}

impl Default for ViewerSettings {
    fn default() -> Self {
        ViewerSettings {
            strategy: Strategy::Antishadow,
            alpha: None,
            max_depth: 1,
            exposure: 0.0,
            resolution_scale: 0.5,
            scene: "lampshade".into(),
        }
    }
}

pub struct PortalViewApp {
    settings: ViewerSettings,
    scene: Scene,
    /// The camera as the user moved it (starts as the scene's).
    camera: Camera,
    renderer: RenderHandle,
    texture: Option<TextureHandle>,
    /// The frame on screen, kept to re-tone-map when exposure changes.
    frame: Option<Frame>,
    /// Render size last requested, in pixels.
    requested_size: (u32, u32),
    paused: bool,
    /// An error to show (loading, saving, the worker).
    message: Option<String>,
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
        // One core stays with the UI thread's scheduling on small machines: the pool uses all
        // cores, and the UI repaints only when a frame arrives or the user acts.
        let renderer = RenderHandle::spawn(0, Box::new(move || repaint.request_repaint()))?;
        Ok(PortalViewApp {
            camera: scene.camera,
            settings,
            scene,
            renderer,
            texture: None,
            frame: None,
            requested_size: (0, 0),
            paused: false,
            message,
        })
    }

    fn render_settings(&self) -> RenderSettings {
        RenderSettings {
            strategy: self.settings.strategy,
            alpha: self.settings.alpha,
            max_depth: self.settings.max_depth,
            seed: 0,
        }
    }

    /// Restarts accumulation with the current scene, camera and settings.
    fn restart(&mut self) {
        let mut scene = self.scene.clone();
        scene.camera = self.camera;
        let (width, height) = self.requested_size;
        if width == 0 || height == 0 {
            return;
        }
        self.renderer.request(RenderRequest {
            scene,
            settings: self.render_settings(),
            width,
            height,
            paused: self.paused,
        });
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
            self.frame = Some(frame);
            self.upload(ctx);
        }
    }

    fn upload(&mut self, ctx: &egui::Context) {
        let Some(frame) = &self.frame else {
            return;
        };
        let pixels: Vec<Color32> = frame
            .pixels
            .iter()
            .map(|&c| {
                let [r, g, b] = tonemap::to_srgb8(c, self.settings.exposure);
                Color32::from_rgb(r, g, b)
            })
            .collect();
        let image = ColorImage::new([frame.width as usize, frame.height as usize], pixels);
        match &mut self.texture {
            Some(t) => t.set(image, TextureOptions::LINEAR),
            None => self.texture = Some(ctx.load_texture("render", image, TextureOptions::LINEAR)),
        }
    }

    fn side_panel(&mut self, ui: &mut egui::Ui) -> bool {
        let mut changed = false;
        ui.heading("portalview");
        ui.label(format!("Scene: {}", self.scene.name));
        ui.separator();
        ui.label("Strategy");
        ui.horizontal(|ui| {
            for s in Strategy::ALL {
                changed |= ui
                    .selectable_value(&mut self.settings.strategy, s, s.name())
                    .changed();
            }
        });
        let mut max_depth = self.settings.max_depth;
        changed |= ui
            .add(egui::Slider::new(&mut max_depth, 1..=8).text("max depth"))
            .changed();
        self.settings.max_depth = max_depth;
        ui.add(egui::Slider::new(&mut self.settings.exposure, -8.0..=8.0).text("exposure"))
            .changed()
            .then(|| self.upload(ui.ctx()));
        if ui.button("Reset camera").clicked() {
            self.camera = self.scene.camera;
            changed = true;
        }
        ui.separator();
        if let Some(f) = &self.frame {
            ui.label(format!(
                "{} spp{}  {:.1} s  {:.2} M samples/s",
                f.spp,
                if f.preview { " (preview)" } else { "" },
                f.elapsed.as_secs_f32(),
                f.samples_per_second() / 1e6
            ));
        }
        changed
    }
}

impl eframe::App for PortalViewApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        let ctx = ui.ctx().clone();
        self.poll_frame(&ctx);
        let mut changed = false;
        egui::Panel::left("controls").show(ui, |ui| {
            changed |= self.side_panel(ui);
            if let Some(m) = &self.message {
                ui.colored_label(Color32::LIGHT_RED, m);
            }
        });
        egui::CentralPanel::default().show(ui, |ui| {
            let available = ui.available_size();
            let ppp = ui.ctx().pixels_per_point();
            let scale = self.settings.resolution_scale * ppp;
            let size = (
                ((available.x * scale) as u32).max(16),
                ((available.y * scale) as u32).max(16),
            );
            if size != self.requested_size {
                self.requested_size = size;
                changed = true;
            }
            let (rect, response) =
                ui.allocate_exact_size(available, egui::Sense::click_and_drag());
            if let Some(texture) = &self.texture {
                let uv = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
                ui.painter().image(texture.id(), rect, uv, Color32::WHITE);
            }
            let drag = response.drag_delta();
            if response.dragged_by(egui::PointerButton::Primary) && drag != egui::Vec2::ZERO {
                self.camera.orbit(drag.x * 0.01, drag.y * 0.01);
                changed = true;
            }
            if response.dragged_by(egui::PointerButton::Secondary) && drag != egui::Vec2::ZERO {
                self.camera.pan(-drag.x / rect.height(), drag.y / rect.height());
                changed = true;
            }
            if response.hovered() {
                let scroll = ui.input(|i| i.smooth_scroll_delta.y);
                if scroll != 0.0 {
                    self.camera.zoom(scroll * 0.002);
                    changed = true;
                }
            }
        });
        if changed {
            self.restart();
        }
        // Frames wake the UI through the worker's notify; this is only a slow heartbeat.
        ctx.request_repaint_after(Duration::from_millis(250));
    }

    fn save(&mut self, storage: &mut dyn eframe::Storage) {
        eframe::set_value(storage, eframe::APP_KEY, &self.settings);
    }
}

/// Opens the viewer window (blocks until it closes).
pub fn run_viewer(scene: Option<String>) -> Result<()> {
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title("portalview")
            .with_inner_size([1200.0, 760.0]),
        ..Default::default()
    };
    eframe::run_native(
        "portalview",
        options,
        Box::new(|cc| {
            let app = PortalViewApp::new(&cc.egui_ctx, cc.storage, scene)?;
            Ok(Box::new(app))
        }),
    )
    .map_err(|e| anyhow::anyhow!("cannot open the viewer window: {e}"))
}
