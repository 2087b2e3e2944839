//! The render mode's side panel (notices, render settings, the overlay and its legend, the
//! portal panel, statistics) and the status bar.

use egui::Color32;

use super::overlay::{self, OverlayKind};
use super::{Command, PortalViewApp, ViewMode, ViewerSettings};
use crate::light::antishadow::Region;
use crate::light::{Mixture, Selection, Strategy, Technique};
use crate::render::integrator::{GlassShadows, GuideBounces};
use crate::render::primary::SPREAD_SHARE;
use crate::sampling::SamplerKind;

impl PortalViewApp {
    /// The render mode's panels: controls on the left, the image in the middle.
    pub(super) fn render_panels(&mut self, ui: &mut egui::Ui, commands: &mut Vec<Command>) {
        egui::Panel::left("controls")
            .resizable(true)
            .default_size(330.0)
            .show(ui, |ui| {
                // Scrolls both ways, so that the panel's width is the user's (its dragged edge)
                // and never its content's: a line wider than the panel (the statistics, which
                // change every frame) would otherwise widen it, move the image's edge, and every
                // such move resizes and restarts the render. Text still wraps to the width.
                egui::ScrollArea::both().show(ui, |ui| {
                    notice(ui, &mut self.message);
                    egui::CollapsingHeader::new("Render")
                        .default_open(true)
                        .show(ui, |ui| self.render_controls(ui, commands));
                    egui::CollapsingHeader::new("Antishadow overlay")
                        .default_open(true)
                        .show(ui, |ui| self.overlay_controls(ui));
                    egui::CollapsingHeader::new("Portals")
                        .default_open(true)
                        .show(ui, |ui| self.portal_panel(ui, commands));
                    egui::CollapsingHeader::new("Environment")
                        .default_open(true)
                        .show(ui, |ui| self.environment_panel(ui, commands));
                    egui::CollapsingHeader::new("Statistics")
                        .default_open(false)
                        .show(ui, |ui| self.statistics(ui));
                });
            });
        egui::CentralPanel::default().show(ui, |ui| self.viewport(ui, commands));
    }

    fn render_controls(&mut self, ui: &mut egui::Ui, commands: &mut Vec<Command>) {
        let ViewerSettings {
            strategy,
            alpha,
            max_depth,
            sampler,
            mixture,
            selection,
            glass,
            bounces,
            exposure,
            false_colour,
            resolution_scale,
            ..
        } = &mut self.settings;
        let name = self.current.as_ref().map_or("(loading)", |c| &c.scene.name);
        ui.label(egui::RichText::new(format!("Scene: {name}")).strong());
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
        ui.horizontal(|ui| {
            ui.label("sampler")
                .on_hover_text("sobol: Owen-scrambled Sobol' points, stratified per pixel (less noise at equal samples); independent: uniform random numbers");
            for s in SamplerKind::ALL {
                if ui.selectable_value(sampler, s, s.name()).changed() {
                    commands.push(Command::Restart);
                }
            }
        });
        ui.horizontal(|ui| {
            ui.label("mixture").on_hover_text(
                "Where a point's light mixture has both a light share and a portal share \
                 (antipenumbra, antiantumbra): one-sample draws one sample of the mixture (the \
                 thesis's estimator); each-share draws one from each, weighted by its share \
                 (less noise where the light share's samples are often blocked, a second \
                 shadow ray there). Both are unbiased.",
            );
            for m in Mixture::ALL {
                if ui.selectable_value(mixture, m, m.name()).changed() {
                    commands.push(Command::Restart);
                }
            }
        });
        ui.horizontal(|ui| {
            ui.label("light selection").on_hover_text(
                "How a shading point picks the light it samples. tree: by a tree of the \
                 lights' bounds (position, direction, power) in which a light behind portals is \
                 bounded by its portals, so a point far from a lamp or behind its shade rarely \
                 picks it. power: by power alone, the same everywhere.",
            );
            for s in Selection::ALL {
                if ui.selectable_value(selection, s, s.name()).changed() {
                    commands.push(Command::Restart);
                }
            }
        });
        ui.horizontal(|ui| {
            ui.label("glass").on_hover_text(
                "What shadow rays do at smooth thin glass (window panes, a bulb's globe). pass: \
                 they cross it, weighted by its transmittance, so lights and windows behind \
                 glass are sampled directly. stop: glass blocks them, as in Cycles, and light \
                 crosses it only along bounced paths (the same image, far noisier).",
            );
            for g in GlassShadows::ALL {
                if ui.selectable_value(glass, g, g.label()).changed() {
                    commands.push(Command::Restart);
                }
            }
        });
        ui.horizontal(|ui| {
            ui.label("guide bounces").on_hover_text(
                "At a path's first bounce (max depth 2 and more): on draws the next direction \
                 through the portals of lamps and cans (and windows with something outside) \
                 as well as from the surface's BSDF, so the light a shade reflects inside before \
                 it leaves is found with far fewer fireflies. off: from the BSDF alone. The \
                 same image either way.",
            );
            for b in GuideBounces::ALL {
                if ui.selectable_value(bounces, b, b.label()).changed() {
                    commands.push(Command::Restart);
                }
            }
        });
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
                commands.push(Command::ResetCamera);
            }
        });
        if retone {
            self.view.upload(ui.ctx(), *exposure, *false_colour);
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
        let portals = self
            .current
            .as_ref()
            .map_or(Vec::new(), |c| c.rendered.overlay_portal_names());
        let portal_name = |i: Option<usize>| match i {
            None => "all portals".to_owned(),
            Some(i) => portals.get(i).cloned().unwrap_or_else(|| "?".into()),
        };
        egui::ComboBox::from_label("regions of")
            .selected_text(portal_name(self.overlay_portal))
            .show_ui(ui, |ui| {
                ui.selectable_value(&mut self.overlay_portal, None, portal_name(None));
                for i in 0..portals.len() {
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
        // The legend: colours and the share of pixels in each region, and what antishadow
        // samples there for the kinds of portal it describes (overlay portals list area-light
        // portals first, then windows).
        let (areas, windows) = self.current.as_ref().map_or((true, false), |c| {
            let n = c.rendered.portals.len();
            match self.overlay_portal {
                Some(i) => (i < n, i >= n),
                None => (n > 0, !c.rendered.windows.is_empty()),
            }
        });
        let lines = Region::ALL.map(|region| overlay::legend_line(region, areas, windows));
        if settings.overlay == OverlayKind::LightSelection {
            // As wide as the regions' legend: switching overlays must not resize the panel,
            // which would resize the image and restart the render.
            let font = egui::TextStyle::Body.resolve(ui.style());
            let width = ui.ctx().fonts_mut(|f| {
                lines
                    .iter()
                    .map(|l| {
                        f.layout_no_wrap(l.clone(), font.clone(), Color32::WHITE)
                            .size()
                            .x
                    })
                    .fold(0.0, f32::max)
            });
            self.spread_legend(ui, width);
            return;
        }
        let shares = self.view.shares(self.overlay_portal);
        egui::Grid::new("legend").num_columns(3).show(ui, |ui| {
            for (k, (region, line)) in Region::ALL.into_iter().zip(lines).enumerate() {
                let (rect, _) =
                    ui.allocate_exact_size(egui::vec2(14.0, 14.0), egui::Sense::hover());
                ui.painter()
                    .rect_filled(rect, 2.0, overlay::region_colour(region));
                // The share before the name: in a panel narrower than the legend (a width
                // remembered from an earlier session) the number stays in view. Fixed width
                // ("100.0%" as wide as " 99.9%"): a share that reaches 100% must not widen
                // the panel, which would resize the image and restart it.
                let share = shares.map_or("   –  ".into(), |s| format!("{:>5.1}%", 100.0 * s[k]));
                ui.label(egui::RichText::new(share).monospace());
                ui.label(line);
                ui.end_row();
            }
        });
    }

    /// The *light selection* overlay's legend: what it counts, and each bucket's colour and
    /// share of the pixels; its names' column at least `name_width` wide.
    fn spread_legend(&mut self, ui: &mut egui::Ui, name_width: f32) {
        // Short lines, the full story in the hover text: a wrapped paragraph would widen the
        // panel to its full width.
        ui.label(format!(
            "lights carrying {:.0}% of picks",
            100.0 * SPREAD_SHARE
        ))
        .on_hover_text(overlay::spread_caption());
        ui.weak("(the light tree, as under antishadow)")
            .on_hover_text(overlay::spread_caption());
        let shares = self.view.spread_shares();
        // The regions' grid's id: its remembered column widths spare the new grid the
        // narrower first frame that would shrink the panel.
        egui::Grid::new("legend").num_columns(3).show(ui, |ui| {
            for k in 0..overlay::SPREAD_BUCKETS.len() {
                let (colour, name) = overlay::spread_legend(k);
                let (rect, _) =
                    ui.allocate_exact_size(egui::vec2(14.0, 14.0), egui::Sense::hover());
                ui.painter().rect_filled(rect, 2.0, colour);
                // Fixed width, as the regions' shares.
                let share = shares.map_or("   –  ".into(), |s| format!("{:>5.1}%", 100.0 * s[k]));
                ui.label(egui::RichText::new(share).monospace());
                ui.scope(|ui| {
                    ui.set_min_width(name_width);
                    ui.label(name);
                });
                ui.end_row();
            }
        });
    }

    fn statistics(&self, ui: &mut egui::Ui) {
        let Some(f) = &self.view.frame else {
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
            if s.nonfinite > 0 {
                ui.label("non-finite samples (zeroed)");
                ui.colored_label(ui.visuals().warn_fg_color, format!("{}", s.nonfinite));
                ui.end_row();
            }
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

    pub(super) fn status_bar(&self, ui: &mut egui::Ui) {
        if self.mode == ViewMode::Compare {
            ui.horizontal(|ui| self.compare.status(ui));
            return;
        }
        ui.horizontal(|ui| {
            match &self.view.frame {
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
            if let Some(what) = self.building() {
                ui.separator();
                ui.spinner();
                ui.label(format!("{what}…"));
            }
        });
    }
}

/// An error or notice at the top of a side panel, wrapped to the panel's width, with a button
/// that dismisses it.
pub(super) fn notice(ui: &mut egui::Ui, message: &mut Option<String>) {
    let Some(text) = message.as_deref() else {
        return;
    };
    let mut dismissed = false;
    ui.horizontal(|ui| {
        dismissed = ui.small_button("x").on_hover_text("Dismiss").clicked();
        ui.add(egui::Label::new(egui::RichText::new(text).color(Color32::LIGHT_RED)).wrap());
    });
    if dismissed {
        *message = None;
    }
}
