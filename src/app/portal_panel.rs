//! The portal panel: the list of portals with their warnings, adding a portal for a light,
//! and the selected portal's exact fields (centre, rotation, scale, alpha).

use egui::{Color32, Ui};
use glam::Quat;

use super::{Command, PortalViewApp};

impl PortalViewApp {
    pub(super) fn portal_panel(&mut self, ui: &mut Ui, commands: &mut Vec<Command>) {
        let Self {
            current,
            editor,
            overlay_portal,
            placing_window,
            portal_job,
            ..
        } = self;
        let Some(current) = current else {
            ui.label("no scene yet");
            return;
        };
        for (i, portal) in editor.portals.iter().enumerate() {
            let broken = current.portal_errors.iter().any(|(e, _)| *e == i);
            let kind = if portal.is_window() { " (window)" } else { "" };
            let label = if broken {
                format!("(!) {}{kind}", portal.name)
            } else {
                format!("{}{kind}", portal.name)
            };
            if ui
                .selectable_label(editor.selected == Some(i), label)
                .clicked()
            {
                editor.selected = Some(i);
                *overlay_portal = current.rendered_index(i);
            }
        }
        for (i, message) in &current.portal_errors {
            ui.colored_label(
                Color32::from_rgb(255, 160, 60),
                format!("portal {i}: {message}"),
            );
        }
        // One button a line: a wrapped row changes the panel's height with its width, and the
        // scroll bar that height brings changes the width back, so the layout had two stable
        // states and the first frame decided which.
        ui.vertical(|ui| {
            ui.add_enabled_ui(portal_job.is_none(), |ui| {
                if ui
                    .button("Find portals")
                    .on_hover_text("Find the openings through which each light's light (and the sky's) leaves what surrounds it, and propose a portal over each, alpha auto. They replace the portals in the list (Undo brings those back); keep, edit or delete each, then save")
                    .clicked()
                {
                    commands.push(Command::FindPortals);
                }
                if ui
                    .button("Check portals")
                    .on_hover_text("Trace each light's light (and the sky's) past the portals: the share that leaves through them, the share that leaks past them, and portals no light passes (drawn red)")
                    .clicked()
                {
                    commands.push(Command::CheckPortals);
                }
            });
            if let Some(job) = portal_job {
                ui.horizontal(|ui| {
                    ui.spinner();
                    ui.label(format!("{}…", job.what()));
                });
            }
            check_report(ui, current, &editor.portals);
            if ui
                .button("Add window portal")
                .on_hover_text("Then click a window opening (a hole in a wall) in the image: the window portal is fitted to it, facing into the room; where there is none, a 1 m square at the camera's target. Also: right-click the image")
                .clicked()
            {
                commands.push(Command::AddWindow);
            }
            if *placing_window {
                ui.label("click a window opening in the image (Esc cancels)");
            }
            for (i, light) in current.scene.geometry.lights.iter().enumerate() {
                if ui
                    .button(format!("Add portal for {}", light.name))
                    .clicked()
                {
                    commands.push(Command::AddPortal(i));
                }
            }
        });
        let Some(i) = editor.selected.filter(|&i| i < editor.portals.len()) else {
            ui.label("no portal selected");
            return;
        };
        let Some(mut pose) = editor.pose(i) else {
            return;
        };
        let (mut ex, mut ey, mut ez) = pose.rotation.to_euler(glam::EulerRot::XYZ);
        let mut gesture = false;
        // What the widgets report as changed, never a comparison of values (a NaN never equals
        // itself, and a comparison that always differs restarts the render every frame).
        let (mut moved, mut turned) = (false, false);
        let mut alpha = editor.portals[i].alpha;
        let mut auto = editor.portals[i].auto_alpha;
        let mut auto_changed = false;
        // The alpha the render uses for `auto`, once the background build has measured it.
        let measured = current
            .rendered
            .portals
            .iter()
            .find(|p| p.desc_index == i)
            .map(|p| (p.alpha, p.alpha_pending))
            .or_else(|| {
                let w = current
                    .rendered
                    .windows
                    .iter()
                    .find(|w| w.desc_index == i)?;
                Some((w.alpha, w.alpha_pending))
            });
        egui::Grid::new("portal fields")
            .num_columns(2)
            .show(ui, |ui| {
                ui.label("centre");
                ui.horizontal(|ui| {
                    for (v, axis) in [
                        (&mut pose.center.x, "x"),
                        (&mut pose.center.y, "y"),
                        (&mut pose.center.z, "z"),
                    ] {
                        let r = ui.add(
                            egui::DragValue::new(v)
                                .speed(0.01)
                                .prefix(format!("{axis} ")),
                        );
                        gesture |= r.drag_started() || r.gained_focus();
                        moved |= r.changed();
                    }
                });
                ui.end_row();
                ui.label("rotation °");
                ui.horizontal(|ui| {
                    for (v, axis) in [(&mut ex, "x"), (&mut ey, "y"), (&mut ez, "z")] {
                        // Shown without the "-0.0" that a quaternion's round trip leaves
                        // (only an edit writes the value back).
                        let mut deg = v.to_degrees();
                        if deg.abs() < 1e-3 {
                            deg = 0.0;
                        }
                        let r = ui.add(
                            egui::DragValue::new(&mut deg)
                                .speed(0.5)
                                .prefix(format!("{axis} ")),
                        );
                        gesture |= r.drag_started() || r.gained_focus();
                        if r.changed() {
                            *v = deg.to_radians();
                            turned = true;
                        }
                    }
                });
                ui.end_row();
                let label = ui.label("scale");
                let mut s = pose.scale.max_element();
                let r = ui
                    .add(egui::DragValue::new(&mut s).speed(0.01).range(0.01..=100.0))
                    .labelled_by(label.id);
                gesture |= r.drag_started() || r.gained_focus();
                if r.changed() {
                    pose.scale *= s / pose.scale.max_element().max(1e-6);
                    moved = true;
                }
                ui.end_row();
                // The alpha and its auto switch on rows of their own: a wider row would widen
                // the panel, whose width must not depend on what is selected.
                let label = ui.label("alpha");
                if auto {
                    ui.label(match measured {
                        Some((a, false)) => format!("{a:.3} (auto)"),
                        Some((_, true)) => "auto: measuring…".to_owned(),
                        None => "auto".to_owned(),
                    });
                } else {
                    let r = ui
                        .add(egui::Slider::new(&mut alpha, 0.0..=1.0))
                        .labelled_by(label.id);
                    gesture |= r.drag_started() || r.gained_focus();
                    moved |= r.changed();
                }
                ui.end_row();
                ui.label("");
                auto_changed = ui
                    .checkbox(&mut auto, "auto")
                    .on_hover_text(
                        "Alpha measured from the portals' leak before rendering: small where they \
                         cover every opening, larger where light leaks past them",
                    )
                    .changed();
                ui.end_row();
            });
        if turned {
            pose.rotation = Quat::from_euler(glam::EulerRot::XYZ, ex, ey, ez);
        }
        if gesture || auto_changed {
            editor.checkpoint();
        }
        if moved || turned {
            editor.set_pose(i, pose);
            editor.portals[i].alpha = alpha;
            commands.push(Command::PortalEdited);
        }
        if auto_changed {
            editor.portals[i].auto_alpha = auto;
            commands.push(Command::PortalEdited);
        }
        ui.horizontal(|ui| {
            if editor.portals[i].is_window()
                && ui
                    .button("Flip")
                    .on_hover_text(
                        "Turn the window's front (the arrow: the side the sky light enters) over",
                    )
                    .clicked()
            {
                commands.push(Command::FlipPortal(i));
            }
            if ui.button("Delete portal").clicked() {
                commands.push(Command::DeletePortal(i));
            }
        });
        if editor.dirty {
            ui.label(if current.scene.source.is_some() {
                "unsaved changes (File > Save portals)"
            } else {
                "unsaved changes (File > Save as .glb…)"
            });
        }
    }
}

/// The last check's shares and problems, red where something is wrong; what the last *Find
/// portals* noted.
fn check_report(ui: &mut Ui, current: &super::Current, portals: &[crate::asset::desc::PortalDesc]) {
    let red = Color32::from_rgb(255, 90, 80);
    for note in &current.found_notes {
        ui.label(format!("found: {note}"));
    }
    let Some(checks) = current.fresh_checks(portals) else {
        if current.checks.is_some() {
            ui.label("the portals changed since the check: Check portals again");
        }
        return;
    };
    if checks.is_empty() {
        ui.label("checked: no portals to check");
    }
    for check in checks {
        let problems = check.problems();
        let line = format!(
            "{}: {:.1}% through its portals, {:.1}% ± {:.1}% past them",
            check.name,
            100.0 * check.through,
            100.0 * check.leak,
            100.0 * check.leak_error
        );
        if problems.is_empty() {
            ui.label(line);
        } else {
            ui.colored_label(red, line);
        }
        for p in &check.portals {
            let line = format!("    {}: {:.1}%", p.name, 100.0 * p.share);
            if p.share == 0.0 {
                ui.colored_label(red, line);
            } else {
                ui.label(line);
            }
        }
        for problem in problems {
            ui.colored_label(red, format!("    {problem}"));
        }
    }
}
