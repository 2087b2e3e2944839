//! The menu bar, the "open" field beside it, and the file dialogs they open.

use std::path::Path;

use super::files::{FilePicker, Purpose, folder_of};
use super::{Command, PortalViewApp, ViewMode};
use crate::asset::builtin;

impl PortalViewApp {
    pub(super) fn menu_bar(&mut self, ui: &mut egui::Ui, commands: &mut Vec<Command>) {
        egui::MenuBar::new().ui(ui, |ui| {
            ui.menu_button("File", |ui| self.file_menu(ui, commands));
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
            ui.separator();
            self.open_field(ui, commands);
            if let Some(job) = &self.job {
                ui.spinner();
                ui.label(format!("{}…", job.what));
            }
        });
    }

    fn file_menu(&mut self, ui: &mut egui::Ui, commands: &mut Vec<Command>) {
        if ui.button("Open glTF…").clicked() {
            commands.push(Command::ShowDialog(Purpose::OpenScene));
            ui.close();
        }
        ui.menu_button("Open recent", |ui| {
            if self.settings.recent.is_empty() {
                ui.label("(none)");
            }
            for r in &self.settings.recent {
                if ui.button(r).clicked() {
                    commands.push(Command::Open(r.clone()));
                    ui.close();
                }
            }
        });
        ui.separator();
        let source = self.scene().and_then(|s| s.source.as_ref());
        if ui
            .add_enabled(source.is_some(), egui::Button::new("Save portals"))
            .clicked()
        {
            commands.push(Command::Save);
            ui.close();
        }
        if ui
            .add_enabled(self.current.is_some(), egui::Button::new("Save as .glb…"))
            .clicked()
        {
            commands.push(Command::ShowDialog(Purpose::SaveGlb));
            ui.close();
        }
    }

    /// A path (or built-in name) to type, opened with Enter or the button.
    fn open_field(&mut self, ui: &mut egui::Ui, commands: &mut Vec<Command>) {
        let label = ui.label("Path:");
        let field = ui
            .add(
                egui::TextEdit::singleline(&mut self.path_input)
                    .hint_text("path to .gltf/.glb, Enter")
                    .desired_width(240.0)
                    // As tall as the bar's buttons, its text centred: on the label's line.
                    .min_size(egui::vec2(0.0, ui.spacing().interact_size.y))
                    .align(egui::Align2::LEFT_CENTER),
            )
            .labelled_by(label.id);
        let entered = field.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
        let path = self.path_input.trim();
        // Draw the button every frame, also the one on which Enter opens the path.
        let clicked = ui.button("Open path").clicked();
        if (entered || clicked) && !path.is_empty() {
            commands.push(Command::Open(path.to_owned()));
        }
        if ui
            .button("Browse…")
            .on_hover_text("Choose a .gltf/.glb file")
            .clicked()
        {
            commands.push(Command::ShowDialog(Purpose::OpenScene));
        }
    }

    /// Opens the file dialog for `purpose`, in the folder of the scene's file (else of the
    /// newest recent file, else the working folder).
    pub(super) fn show_dialog(&mut self, purpose: Purpose) {
        let source = self.scene().and_then(|s| s.source.clone());
        let folder = source
            .as_deref()
            .or_else(|| self.settings.recent.first().map(Path::new))
            .and_then(folder_of);
        let file_name = (purpose == Purpose::SaveGlb)
            .then(|| self.scene().map(|s| format!("{}.glb", s.name)))
            .flatten();
        self.picker = Some(FilePicker::new(
            purpose,
            folder.as_deref(),
            file_name,
            &self.ctx,
        ));
    }

    /// Draws the open file dialog; a chosen file becomes a command.
    pub(super) fn file_dialog(&mut self, ctx: &egui::Context, commands: &mut Vec<Command>) {
        let Some(picker) = &mut self.picker else {
            return;
        };
        let Some(chosen) = picker.show(ctx) else {
            return;
        };
        let purpose = picker.purpose();
        self.picker = None;
        let Some(path) = chosen else {
            return;
        };
        match purpose {
            Purpose::OpenScene => commands.push(Command::Open(path.display().to_string())),
            Purpose::SaveGlb => commands.push(Command::SaveAs(path)),
            // The comparison keeps its own dialog.
            Purpose::ReferenceExr => {}
            Purpose::Environment => self.open_environment(path),
        }
    }
}
