//! The environment panel: the sky that rays leaving the scene see and that window portals let
//! in. Open an `.hdr`/`.exr` (in the in-window dialog), or use a constant colour; strength,
//! rotation about +Y, and off. Saving writes it into the glTF scene's `extras`.

use egui::Ui;

use super::files::Purpose;
use super::{Command, PortalViewApp};
use crate::asset::environment::{EnvMap, EnvironmentDesc, Interpolation};

/// What an edit of the environment panel asks for.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum EnvironmentEdit {
    /// Replace the environment (`None`: off).
    Set(Option<EnvironmentDesc>),
}

impl PortalViewApp {
    pub(super) fn environment_panel(&mut self, ui: &mut Ui, commands: &mut Vec<Command>) {
        let Some(current) = &self.current else {
            ui.label("no scene yet");
            return;
        };
        let environment = current.edited_environment();
        let description = match &environment {
            None => "none (black)".to_owned(),
            Some(e) => match &e.map {
                EnvMap::Constant(c) => format!("constant {:.3} {:.3} {:.3}", c.x, c.y, c.z),
                EnvMap::Image {
                    file: Some(file),
                    image,
                } => format!(
                    "{} ({}×{})",
                    file.file_name()
                        .map_or(file.display().to_string(), |n| n.to_string_lossy().into()),
                    image.width,
                    image.height
                ),
                EnvMap::Image { file: None, image } => {
                    format!("built-in sky ({}×{})", image.width, image.height)
                }
            },
        };
        ui.label(format!("environment: {description}"));
        ui.horizontal_wrapped(|ui| {
            if ui
                .button("Open environment…")
                .on_hover_text(
                    "An equirectangular .hdr or .exr (Blender's Environment Texture mapping)",
                )
                .clicked()
            {
                commands.push(Command::ShowDialog(Purpose::Environment));
            }
            if ui.button("Constant").clicked() {
                let strength = environment.as_ref().map_or(1.0, |e| e.strength);
                commands.push(Command::Environment(EnvironmentEdit::Set(Some(
                    EnvironmentDesc {
                        strength,
                        ..EnvironmentDesc::constant(glam::Vec3::ONE)
                    },
                ))));
            }
            if ui
                .add_enabled(environment.is_some(), egui::Button::new("Off"))
                .clicked()
            {
                commands.push(Command::Environment(EnvironmentEdit::Set(None)));
            }
        });
        let Some(mut edited) = environment.clone() else {
            return;
        };
        // An edit is what a widget reports as changed, never a comparison of values: the colour
        // button's round trip through HSV moves a colour by a rounding error each frame, and a
        // NaN never equals itself, so comparing restarted the render on every frame.
        let mut changed = false;
        egui::Grid::new("environment fields")
            .num_columns(2)
            .show(ui, |ui| {
                if let EnvMap::Constant(c) = &mut edited.map {
                    ui.label("colour");
                    let mut rgb = c.to_array();
                    if ui.color_edit_button_rgb(&mut rgb).changed() {
                        *c = glam::Vec3::from_array(rgb);
                        changed = true;
                    }
                    ui.end_row();
                }
                let label = ui.label("strength");
                changed |= ui
                    .add(
                        egui::Slider::new(&mut edited.strength, 0.0..=100.0)
                            .logarithmic(true)
                            .smallest_positive(0.01),
                    )
                    .labelled_by(label.id)
                    .changed();
                ui.end_row();
                let label = ui.label("rotation °");
                changed |= ui
                    .add(egui::Slider::new(
                        &mut edited.rotation_degrees,
                        -180.0..=180.0,
                    ))
                    .labelled_by(label.id)
                    .changed();
                ui.end_row();
                if matches!(edited.map, EnvMap::Image { .. }) {
                    ui.label("interpolation").on_hover_text(
                        "How the image is read between pixels (Blender's Environment Texture: \
                         Linear is its default)",
                    );
                    ui.horizontal(|ui| {
                        for mode in Interpolation::ALL {
                            changed |= ui
                                .radio_value(&mut edited.interpolation, mode, mode.name())
                                .changed();
                        }
                    });
                    ui.end_row();
                }
            });
        if changed {
            commands.push(Command::Environment(EnvironmentEdit::Set(Some(edited))));
        }
        if self.environment_dirty {
            ui.label(if current.scene.source.is_some() {
                "unsaved environment (File > Save portals)"
            } else {
                "unsaved environment (File > Save as .glb…)"
            });
        }
    }

    /// Applies an environment edit: the builder makes the environment and its windows' tables
    /// (once, off the UI thread) while the old scene renders, then the render restarts.
    pub(super) fn apply_environment(&mut self, edit: EnvironmentEdit) {
        let EnvironmentEdit::Set(environment) = edit;
        let Some(current) = &mut self.current else {
            return;
        };
        current.environment = Some(environment);
        self.environment_dirty = true;
        self.request_build();
    }

    /// A chosen environment file: loaded in the background, then applied with the current
    /// strength and rotation.
    pub(super) fn open_environment(&mut self, path: std::path::PathBuf) {
        self.message = None;
        self.job = Some(super::loader::Job::load_environment(path, &self.ctx));
    }
}
