//! Choosing files inside the window: a file dialog drawn by egui (egui_file), so that opening
//! and saving work on any desktop, with no native dialog or portal service behind it.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};

use egui_file::{FileDialog, State};

/// What a file is chosen for: sets the dialog's title, kind and the files it lists.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Purpose {
    /// A `.gltf`/`.glb` scene to open.
    OpenScene,
    /// A `.glb` to save the scene and its portals as.
    SaveGlb,
    /// A reference `.exr` for the comparison.
    ReferenceExr,
    /// An equirectangular `.hdr`/`.exr` environment.
    Environment,
}

impl Purpose {
    fn extensions(self) -> &'static [&'static str] {
        match self {
            Purpose::OpenScene => &["gltf", "glb"],
            Purpose::SaveGlb => &["glb"],
            Purpose::ReferenceExr => &["exr"],
            Purpose::Environment => &["hdr", "exr"],
        }
    }

    fn title(self) -> &'static str {
        match self {
            Purpose::OpenScene => "Open glTF scene (.gltf, .glb)",
            Purpose::SaveGlb => "Save as .glb",
            Purpose::ReferenceExr => "Load reference EXR",
            Purpose::Environment => "Open environment (.hdr, .exr)",
        }
    }
}

/// Whether `path` has one of `extensions` (case-insensitive).
fn has_extension(path: &Path, extensions: &[&str]) -> bool {
    path.extension()
        .and_then(OsStr::to_str)
        .is_some_and(|e| extensions.iter().any(|x| e.eq_ignore_ascii_case(x)))
}

/// An open file dialog for one purpose.
pub struct FilePicker {
    dialog: FileDialog,
    purpose: Purpose,
}

impl FilePicker {
    /// Opens a dialog in `folder` (else the working folder); a save dialog proposes `file_name`.
    pub fn new(purpose: Purpose, folder: Option<&Path>, file_name: Option<String>) -> Self {
        let extensions = purpose.extensions();
        let mut dialog = match purpose {
            Purpose::SaveGlb => FileDialog::save_file(),
            Purpose::OpenScene | Purpose::ReferenceExr | Purpose::Environment => {
                FileDialog::open_file()
            }
        }
        .id(egui::Id::unique(("file dialog", purpose)))
        .title(purpose.title())
        .default_size(egui::vec2(560.0, 420.0))
        .show_rename(false)
        .show_new_folder(false)
        .show_files_filter(Box::new(move |p: &Path| has_extension(p, extensions)))
        .filename_filter(Box::new(move |name: &str| {
            has_extension(Path::new(name), extensions)
        }));
        if let Some(folder) = folder.filter(|f| f.is_dir()) {
            dialog = dialog.initial_path(folder);
        }
        if let Some(name) = file_name {
            dialog = dialog.default_filename(name);
        }
        dialog.open();
        FilePicker { dialog, purpose }
    }

    pub fn purpose(&self) -> Purpose {
        self.purpose
    }

    /// Draws the dialog. `Some(Some(path))` once a file is chosen, `Some(None)` once it is
    /// cancelled (either way it is done), `None` while it stays open.
    pub fn show(&mut self, ctx: &egui::Context) -> Option<Option<PathBuf>> {
        match self.dialog.show(ctx).state() {
            State::Open => None,
            State::Selected => Some(self.dialog.path().map(Path::to_owned)),
            State::Closed | State::Cancelled => Some(None),
        }
    }
}

/// The folder a dialog starts in: that of `file` as an absolute path, if it exists.
pub fn folder_of(file: &Path) -> Option<PathBuf> {
    let parent = file.parent()?;
    let parent = if parent.as_os_str().is_empty() {
        Path::new(".")
    } else {
        parent
    };
    std::fs::canonicalize(parent).ok().filter(|p| p.is_dir())
}
