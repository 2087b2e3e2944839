//! Choosing files inside the window: a file dialog drawn by egui (egui_file), so that opening
//! and saving work on any desktop, with no native dialog or portal service behind it. Folders
//! are read on a thread of their own ([`BackgroundFs`]): a slow or network folder never
//! freezes the window.

use std::collections::HashMap;
use std::ffi::OsStr;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use egui_file::vfs::VfsFile;
use egui_file::{FileDialog, State, Vfs};

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

/// One entry of a folder, as read off the UI thread.
#[derive(Clone, Debug)]
pub struct Entry {
    path: PathBuf,
    is_dir: bool,
    is_file: bool,
    selected: bool,
}

impl VfsFile for Entry {
    fn is_file(&self) -> bool {
        self.is_file
    }
    fn is_dir(&self) -> bool {
        self.is_dir
    }
    fn path(&self) -> &Path {
        &self.path
    }
    fn selected(&self) -> bool {
        self.selected
    }
    fn set_selected(&mut self, selected: bool) {
        self.selected = selected;
    }
    fn get_file_name(&self) -> &str {
        self.path
            .file_name()
            .and_then(OsStr::to_str)
            .unwrap_or_default()
    }
}

/// A folder's entries, in the file system's order: what a [`BackgroundFs`] reads.
pub type FolderReader = dyn Fn(&Path) -> io::Result<Vec<Entry>> + Send + Sync;

/// The entries of `folder` (each with its kind, from its metadata: the slow part on a network
/// folder).
pub fn read_entries(folder: &Path) -> io::Result<Vec<Entry>> {
    Ok(std::fs::read_dir(folder)?
        .filter_map(Result::ok)
        .map(|entry| {
            let path = entry.path();
            let kind = std::fs::metadata(&path).ok().map(|m| m.file_type());
            Entry {
                is_dir: kind.is_some_and(|k| k.is_dir()),
                is_file: kind.is_some_and(|k| k.is_file()),
                path,
                selected: false,
            }
        })
        .collect())
}

/// A folder's read: under way (`None`), or ended with its entries or error.
type Listing = Option<io::Result<Vec<Entry>>>;

/// egui_file's file system, with folders read on threads of their own: the dialog waits at
/// most [`BackgroundFs::PATIENCE`] for a folder, then shows that it is being read, and the
/// listing appears when the read ends (the thread asks for a repaint, and [`FilePicker::show`]
/// refreshes the dialog). Renaming and new folders are not offered by the dialogs here.
#[derive(Clone)]
pub struct BackgroundFs {
    reader: Arc<FolderReader>,
    /// Reads under way (`None`) and ended ones not yet shown, by folder.
    reads: Arc<Mutex<HashMap<PathBuf, Listing>>>,
    repaint: Option<egui::Context>,
}

impl BackgroundFs {
    /// How long the UI thread waits for a folder before it shows "reading…" instead.
    pub const PATIENCE: Duration = Duration::from_millis(50);

    pub fn new(reader: Arc<FolderReader>, repaint: Option<egui::Context>) -> Self {
        BackgroundFs {
            reader,
            reads: Arc::new(Mutex::new(HashMap::new())),
            repaint,
        }
    }

    /// Whether the read of `folder` has ended and is waiting to be shown.
    pub fn is_ready(&self, folder: &Path) -> bool {
        self.reads
            .lock()
            .is_ok_and(|reads| matches!(reads.get(folder), Some(Some(_))))
    }

    /// The entries of `folder`, if read within [`Self::PATIENCE`] (or read since the last
    /// call); else `None`, and the read goes on.
    pub fn entries(&self, folder: &Path) -> Option<io::Result<Vec<Entry>>> {
        {
            let mut reads = self.reads.lock().ok()?;
            match reads.get(folder) {
                Some(Some(_)) => return reads.remove(folder).flatten(),
                Some(None) => return None,
                None => {
                    reads.insert(folder.to_owned(), None);
                }
            }
        }
        let (done, wait) = mpsc::channel();
        let (reader, reads, repaint) = (
            self.reader.clone(),
            self.reads.clone(),
            self.repaint.clone(),
        );
        let owned = folder.to_owned();
        let spawned = std::thread::Builder::new()
            .name("folder".into())
            .spawn(move || {
                let listing = reader(&owned);
                if let Ok(mut reads) = reads.lock() {
                    reads.insert(owned, Some(listing));
                }
                let _ = done.send(());
                if let Some(ctx) = repaint {
                    ctx.request_repaint();
                }
            });
        if let Err(e) = spawned {
            if let Ok(mut reads) = self.reads.lock() {
                reads.remove(folder);
            }
            return Some(Err(e));
        }
        wait.recv_timeout(Self::PATIENCE).ok()?;
        self.reads.lock().ok()?.remove(folder).flatten()
    }
}

impl Vfs for BackgroundFs {
    fn create_dir(&self, path: &Path) -> io::Result<()> {
        std::fs::create_dir(path)
    }

    fn rename(&self, from: &Path, to: &Path) -> io::Result<()> {
        std::fs::rename(from, to)
    }

    fn read_folder(
        &self,
        path: &Path,
        show_system_files: bool,
        show_files_filter: &egui_file::Filter<PathBuf>,
        #[cfg(unix)] show_hidden: bool,
        #[cfg(windows)] show_drives: bool,
    ) -> io::Result<Vec<Box<dyn VfsFile>>> {
        #[cfg(windows)]
        let _ = show_drives;
        let Some(listing) = self.entries(path) else {
            return Err(io::Error::other(format!(
                "Reading {} … (a slow folder: the window stays responsive)",
                path.display()
            )));
        };
        let mut entries: Vec<Entry> = listing?
            .into_iter()
            .filter(|e| {
                e.is_dir || ((show_system_files || e.is_file) && show_files_filter(&e.path))
            })
            .collect();
        #[cfg(unix)]
        entries.retain(|e| show_hidden || !e.get_file_name().starts_with('.'));
        // Folders first, then by name, as egui_file's own file system lists them.
        entries.sort_by(|a, b| {
            b.is_dir
                .cmp(&a.is_dir)
                .then_with(|| a.path.file_name().cmp(&b.path.file_name()))
        });
        Ok(entries
            .into_iter()
            .map(|e| Box::new(e) as Box<dyn VfsFile>)
            .collect())
    }
}

/// An open file dialog for one purpose.
pub struct FilePicker {
    dialog: FileDialog,
    purpose: Purpose,
    fs: BackgroundFs,
}

impl FilePicker {
    /// Opens a dialog in `folder` (else the working folder); a save dialog proposes `file_name`.
    pub fn new(
        purpose: Purpose,
        folder: Option<&Path>,
        file_name: Option<String>,
        ctx: &egui::Context,
    ) -> Self {
        let extensions = purpose.extensions();
        let fs = BackgroundFs::new(Arc::new(read_entries), Some(ctx.clone()));
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
        .with_fs(Box::new(fs.clone()))
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
        FilePicker {
            dialog,
            purpose,
            fs,
        }
    }

    pub fn purpose(&self) -> Purpose {
        self.purpose
    }

    /// Draws the dialog. `Some(Some(path))` once a file is chosen, `Some(None)` once it is
    /// cancelled (either way it is done), `None` while it stays open.
    pub fn show(&mut self, ctx: &egui::Context) -> Option<Option<PathBuf>> {
        // A folder read in the background has ended: show it.
        let folder = self.dialog.directory().to_owned();
        if self.fs.is_ready(&folder) {
            self.dialog.set_path(folder);
        }
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A folder that takes as long as the test wants to read: the dialog's reads return at
    /// once while it is being read (the UI thread is never held by it), and its entries, once
    /// read, are listed as egui_file lists them (folders first, filtered by extension).
    #[test]
    fn a_slow_folder_never_blocks_the_dialog() {
        let (release, gate) = mpsc::channel::<()>();
        let gate = Mutex::new(gate);
        let slow: Arc<FolderReader> = Arc::new(move |folder: &Path| {
            // Held until the test releases it, however long that is.
            let _ = gate.lock().map(|g| g.recv());
            Ok(["b.glb", "a.txt", "sub", "c.gltf"]
                .iter()
                .map(|name| Entry {
                    path: folder.join(name),
                    is_dir: *name == "sub",
                    is_file: *name != "sub",
                    selected: false,
                })
                .collect())
        });
        let fs = BackgroundFs::new(slow, None);
        let folder = Path::new("/far/away");
        let filter: egui_file::Filter<PathBuf> =
            Box::new(|p: &Path| has_extension(p, &["gltf", "glb"]));
        let read = || {
            fs.read_folder(
                folder,
                false,
                &filter,
                #[cfg(unix)]
                false,
                #[cfg(windows)]
                false,
            )
        };
        // The reader is still held: the dialog is told the folder is being read.
        let pending = read().expect_err("no listing while the folder is read");
        assert!(
            pending.to_string().contains("Reading /far/away"),
            "{pending}"
        );
        assert!(!fs.is_ready(folder));
        assert!(
            read().is_err(),
            "a second look does not start or wait for a second read"
        );
        release.send(()).unwrap();
        while !fs.is_ready(folder) {
            std::thread::yield_now();
        }
        let names: Vec<String> = read()
            .unwrap()
            .iter()
            .map(|e| e.get_file_name().to_owned())
            .collect();
        assert_eq!(names, ["sub", "b.glb", "c.gltf"]);
    }
}
