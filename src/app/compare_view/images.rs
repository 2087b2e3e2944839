//! The comparison's images: the split view with its wipe line, the grid, per-pixel error maps
//! and their colour scale, and the reference's progress while it renders.

use egui::{Color32, ColorImage, FontId, Pos2, Rect, Sense, Stroke, TextureOptions, Ui};
use glam::Vec3;

use super::panels::reference_progress;
use super::{CompareLayout, CompareView, CompareViewSettings, Side, TextureKey, strategy_colour};
use crate::compare::report::{sci, tick_label};
use crate::compare::worker::{CompareFrame, ReferenceStatus, RunFrame};
use crate::compare::{REFERENCE_STRATEGY, RELMSE_EPSILON};
use crate::light::Strategy;
use crate::render::tonemap;

/// Error maps show log10 of the relative squared error over [LO, HI].
const ERROR_LOG_LO: f64 = -6.0;
const ERROR_LOG_HI: f64 = 0.0;

impl CompareView {
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

    pub(super) fn view(&mut self, ui: &mut Ui, settings: &mut CompareViewSettings, exposure: f32) {
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
}

/// Per-pixel relative squared error, `mean over channels of (x - r)^2 / (r^2 + eps)` (the
/// terms of relMSE), log-scaled over [`ERROR_LOG_LO`, `ERROR_LOG_HI`] in false colour.
fn error_map(image: &[Vec3], reference: &[Vec3]) -> Vec<Color32> {
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
