//! Opening and saving scenes off the UI thread: the app hands a [`Job`] over, polls it each
//! frame, and the thread wakes the UI when it is done. Every load goes through here, including
//! the first scene and the reload after saving.

use std::path::PathBuf;
use std::sync::mpsc::{Receiver, TryRecvError};

use crate::asset::desc::{PortalDesc, SceneDesc};
use crate::asset::environment::{EnvMap, EnvironmentOverrides, load_image};
use crate::asset::gltf;
use crate::scene::Scene;
use crate::scene::portals;

/// What a finished job produced.
pub(super) enum Done {
    /// A scene opened by built-in name or path; `environment_replaced`: its environment is
    /// the command line's, not its file's.
    Opened {
        name: String,
        scene: Scene,
        environment_replaced: bool,
    },
    /// The portals written to `path`, and the file read back (so that new portals know their
    /// nodes). `portals` are those written.
    Saved {
        path: PathBuf,
        scene: Scene,
        portals: Vec<PortalDesc>,
    },
    /// An environment image read from a file.
    /// An environment image read, and what was repaired in it (negative pixels).
    Environment { map: EnvMap, warnings: Vec<String> },
    /// The portals found for a scene (`portals::find`).
    Found(portals::Found),
    /// A check of `portals` (the editor's, when it was asked for).
    Checked {
        portals: Vec<PortalDesc>,
        checks: Vec<portals::SourceCheck>,
    },
}

/// Where and what to save.
pub(super) struct SaveRequest {
    pub target: PathBuf,
    /// Write the portals into the file the scene came from (only portal nodes change);
    /// otherwise export `desc` as a new `.glb`.
    pub into_source: bool,
    /// The scene with the portals and camera to save.
    pub desc: SceneDesc,
}

/// A job on its own thread.
pub(super) struct Job {
    /// What it does, in a few words ("opening fig8a").
    pub what: String,
    rx: Receiver<Result<Done, String>>,
}

impl Job {
    /// Loads a built-in scene or a `.gltf`/`.glb` file.
    pub fn open(name: String, ctx: &egui::Context) -> Job {
        Job::open_with_environment(name, EnvironmentOverrides::default(), ctx)
    }

    /// Loads a scene and replaces its environment as the command line says.
    pub fn open_with_environment(
        name: String,
        environment: EnvironmentOverrides,
        ctx: &egui::Context,
    ) -> Job {
        let what = format!("opening {name}");
        Job::spawn(what, ctx, move || {
            let scene =
                Scene::open_with_environment(&name, &environment).map_err(|e| e.to_string())?;
            Ok(Done::Opened {
                name,
                scene,
                environment_replaced: !environment.is_empty(),
            })
        })
    }

    /// Reads an environment image.
    pub fn load_environment(path: std::path::PathBuf, ctx: &egui::Context) -> Job {
        let what = format!("reading {}", path.display());
        Job::spawn(what, ctx, move || {
            let mut warnings = Vec::new();
            let image = load_image(&path, &mut warnings).map_err(|e| e.to_string())?;
            Ok(Done::Environment {
                map: EnvMap::Image {
                    file: Some(path),
                    image: std::sync::Arc::new(image),
                },
                warnings,
            })
        })
    }

    /// Writes the portals, then reads the file back.
    pub fn save(request: SaveRequest, ctx: &egui::Context) -> Job {
        let what = format!("saving {}", request.target.display());
        Job::spawn(what, ctx, move || {
            let SaveRequest {
                target,
                into_source,
                desc,
            } = request;
            let written = if into_source {
                gltf::save_portals(&target, &desc.portals).and_then(|()| {
                    // The environment's keys change only when it was changed.
                    let on_file = gltf::load_gltf(&target)?.environment;
                    if on_file == desc.environment {
                        Ok(())
                    } else {
                        gltf::save_environment(&target, desc.environment.as_ref())
                    }
                })
            } else {
                gltf::export_glb(&desc, &target)
            };
            written.map_err(|e| e.to_string())?;
            let scene = Scene::load(&target).map_err(|e| e.to_string())?;
            Ok(Done::Saved {
                path: target,
                scene,
                portals: desc.portals,
            })
        })
    }

    /// Finds the openings of the scene's lights and sky, and a portal for each.
    pub fn find_portals(scene: Scene, ctx: &egui::Context) -> Job {
        Job::spawn("finding portals".into(), ctx, move || {
            Ok(Done::Found(portals::find(&scene)))
        })
    }

    /// Checks the scene's portals (its description's are the editor's).
    pub fn check_portals(scene: Scene, ctx: &egui::Context) -> Job {
        Job::spawn("checking portals".into(), ctx, move || {
            Ok(Done::Checked {
                portals: scene.desc.portals.clone(),
                checks: portals::check(&scene, 0),
            })
        })
    }

    /// What it is doing, in a few words.
    pub fn what(&self) -> &str {
        &self.what
    }

    fn spawn(
        what: String,
        ctx: &egui::Context,
        work: impl FnOnce() -> Result<Done, String> + Send + 'static,
    ) -> Job {
        let (tx, rx) = std::sync::mpsc::channel();
        let ctx = ctx.clone();
        std::thread::spawn(move || {
            let _ = tx.send(work());
            ctx.request_repaint();
        });
        Job { what, rx }
    }

    /// The job's result, once it has one (a thread that died says so).
    pub fn poll(&self) -> Option<Result<Done, String>> {
        match self.rx.try_recv() {
            Ok(result) => Some(result),
            Err(TryRecvError::Empty) => None,
            Err(TryRecvError::Disconnected) => Some(Err(format!("{}: stopped", self.what))),
        }
    }
}
