//! The comparison's side panel: what is compared, the reference (rendered, cached or loaded
//! from an EXR) and the table of numbers.

use egui::{Color32, RichText, Ui};
use std::path::PathBuf;

use super::{CompareView, CompareViewSettings, strategy_colour};
use crate::app::files::{FilePicker, Purpose, folder_of};
use crate::compare::report::sci;
use crate::compare::worker::{ReferenceStatus, RunFrame};
use crate::compare::{REFERENCE_STRATEGY, ReferenceOrigin, mse_above_floor};
use crate::light::Strategy;

impl CompareView {
    pub(super) fn controls(
        &mut self,
        ui: &mut Ui,
        settings: &mut CompareViewSettings,
        exposure: &mut f32,
    ) {
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

    pub(super) fn reference_panel(&mut self, ui: &mut Ui, settings: &mut CompareViewSettings) {
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
            if ui.button("Load reference EXR...").clicked() {
                let folder = self.reference_file.as_deref().and_then(folder_of);
                self.picker = Some(FilePicker::new(
                    Purpose::ReferenceExr,
                    folder.as_deref(),
                    None,
                    ui.ctx(),
                ));
            }
            if self.reference_file.is_some() && ui.button("Render reference").clicked() {
                self.reference_file = None;
            }
        });
        ui.horizontal(|ui| {
            let field = ui.add(
                egui::TextEdit::singleline(&mut self.path_input)
                    .hint_text("path to a reference .exr")
                    .desired_width(180.0),
            );
            let entered = field.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
            let path = self.path_input.trim();
            if (entered || ui.button("Load path").clicked()) && !path.is_empty() {
                self.reference_file = Some(PathBuf::from(path));
            }
        });
        if let Some(path) = &self.reference_file {
            ui.label(format!(
                "using {} (the comparison takes its size)",
                path.display()
            ));
        }
    }

    pub(super) fn numbers(&mut self, ui: &mut Ui) {
        let Some(frame) = self.frame.as_ref().filter(|f| !f.runs.is_empty()) else {
            // The table's headers and an empty row from the start: the panel takes the table's
            // width now, so that the numbers arriving do not widen it and shift the images.
            egui::Grid::new("compare numbers")
                .num_columns(7)
                .striped(true)
                .show(ui, |ui| {
                    header_row(ui, "MSE", "relMSE");
                    ui.label("no numbers yet");
                    for _ in 0..6 {
                        ui.label("–");
                    }
                    ui.end_row();
                });
            return;
        };
        let floor = match &frame.reference {
            ReferenceStatus::Ready(r) => r.info.as_ref().map(|i| i.convergence),
            _ => None,
        };
        // The reference's own noise adds its floor to every measured error; subtracted, the
        // error is an unbiased estimate of the true one (see `compare::mse_above_floor`).
        let floor = floor.filter(|_| self.subtract_floor);
        let errors = |run: &RunFrame| match floor {
            Some(c) => (
                mse_above_floor(run.mse, Some(c.mse_floor)),
                mse_above_floor(run.relmse, Some(c.relmse_floor)),
            ),
            None => (Some(run.mse), Some(run.relmse)),
        };
        let light = frame.run(Strategy::Light).map(|l| (l, errors(l).0));
        egui::Grid::new("compare numbers")
            .num_columns(7)
            .striped(true)
            .show(ui, |ui| {
                let (mse, relmse) = match floor {
                    Some(_) => ("MSE − floor", "relMSE − floor"),
                    None => ("MSE", "relMSE"),
                };
                header_row(ui, mse, relmse);
                let shown = |e: Option<f64>| e.map_or("≤ floor".to_owned(), sci);
                for run in &frame.runs {
                    let (mse, relmse) = errors(run);
                    ui.colored_label(strategy_colour(run.strategy), run.strategy.name());
                    ui.label(format!("{}", run.spp));
                    ui.label(format!("{:.2}", run.seconds));
                    ui.label(shown(mse));
                    ui.label(shown(relmse));
                    ui.label(
                        efficiency_vs_light((mse, run.seconds), light)
                            .map_or("-".to_owned(), |e| format!("{e:.2}")),
                    );
                    ui.label(if run.worst_share.is_finite() {
                        format!("{:.0} %", 100.0 * run.worst_share)
                    } else {
                        "–".to_owned()
                    });
                    ui.end_row();
                }
            });
        ui.label(
            "Efficiency is 1 / (MSE × seconds), relative to light sampling's: above 1 is better.",
        );
        let has_floor = matches!(&frame.reference, ReferenceStatus::Ready(r) if r.info.is_some());
        ui.add_enabled(
            has_floor,
            egui::Checkbox::new(
                &mut self.subtract_floor,
                "subtract the reference's noise floor",
            ),
        )
        .on_hover_text(
            "The reference's own noise adds its per-pixel variance (the floor, above) to every \
             measured error. Subtracted, each error estimates the true one without bias, but \
             it is uncertain when it is close to the floor (shown as ≤ floor when below).",
        );
    }
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

/// Efficiency `1 / (MSE × seconds)` of a run's (MSE, seconds) over light sampling's, when
/// both MSEs are known.
fn efficiency_vs_light(
    (mse, seconds): (Option<f64>, f64),
    light: Option<(&RunFrame, Option<f64>)>,
) -> Option<f64> {
    let (light, light_mse) = light?;
    let e = light_mse? * light.seconds / (mse? * seconds);
    e.is_finite().then_some(e)
}

/// The reference render's progress: the fraction done and a line on it.
pub(super) fn reference_progress(bar: &indicatif::ProgressBar) -> (f32, String) {
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

/// The numbers table's header row, with the error columns named `mse` and `relmse`.
fn header_row(ui: &mut Ui, mse: &str, relmse: &str) {
    for h in ["strategy", "spp", "seconds", mse, relmse, "eff. vs light"] {
        ui.label(RichText::new(h).strong());
    }
    ui.label(RichText::new("worst 1 % px").strong())
        .on_hover_text(
            "The share of the squared error in the 1 % of pixels with the most: about 1 % where \
         the noise is spread evenly, near 100 % where a few fireflies carry the error (which \
         the mean hides).",
        );
    ui.end_row();
}
