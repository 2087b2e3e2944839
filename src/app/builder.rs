//! What an edit needs that takes long, built off the UI thread: the guided tables of turned or
//! new window portals, and a changed environment with its windows. One build runs at a time on
//! the [`shell`](crate::render::shell) every worker shares; requests made while it runs
//! coalesce into the newest, and the result of any request but the newest is dropped. The app
//! renders meanwhile what it has (see [`PortalViewApp::apply_portal_edit`](super::PortalViewApp::apply_portal_edit)).

use std::panic::AssertUnwindSafe;
use std::sync::Arc;

use crate::asset::environment::EnvironmentDesc;
use crate::render::shell::{Outbox, Work, WorkerHandle};
use crate::scene::Scene;

/// A build: what it makes, or why it could not.
pub(super) type Build<T> = Box<dyn FnOnce() -> Result<T, String> + Send>;

/// The builder thread and the newest request the app waits for.
pub(super) struct Builder<T: Clone + Send + Sync + 'static> {
    handle: WorkerHandle<BuildWork<T>>,
    /// The newest request's generation, until its result is taken or it is forgotten.
    awaited: Option<u64>,
}

impl<T: Clone + Send + Sync + 'static> Builder<T> {
    /// Starts the thread (its pool has every core, as the renderer's: the build is what the
    /// user waits for); `notify` is called when a build is done.
    pub fn spawn(notify: Box<dyn Fn() + Send>) -> std::io::Result<Self> {
        Ok(Builder {
            handle: WorkerHandle::new(BuildWork { job: None }, "portalview-build", 0, notify)?,
            awaited: None,
        })
    }

    /// Builds `build` once the running build (if any) is done, unless a newer request comes
    /// first; only its result will be taken.
    pub fn request(&mut self, build: Build<T>) {
        self.awaited = Some(self.handle.request(build));
    }

    /// Forgets the awaited build (the state it was for is gone): its result will be dropped.
    pub fn forget(&mut self) {
        self.awaited = None;
    }

    /// Whether a result is awaited.
    pub fn is_building(&self) -> bool {
        self.awaited.is_some()
    }

    /// The newest request's result, once it is done; an older request's is dropped.
    pub fn poll(&mut self) -> Option<Result<T, String>> {
        let awaited = self.awaited?;
        let finished = self.handle.take()?;
        if finished.generation != awaited {
            return None;
        }
        self.awaited = None;
        Some(Arc::unwrap_or_clone(finished.result))
    }
}

/// A finished build and the request it answers.
#[derive(Clone)]
pub(super) struct Finished<T> {
    generation: u64,
    result: Arc<Result<T, String>>,
}

/// Runs the newest build.
struct BuildWork<T> {
    job: Option<(Build<T>, u64)>,
}

impl<T: Clone + Send + Sync + 'static> Work for BuildWork<T> {
    type Request = Build<T>;
    type Frame = Finished<T>;

    fn start(&mut self, build: Build<T>, generation: u64) {
        self.job = Some((build, generation));
    }

    fn set_paused(&mut self, _paused: bool) {}

    fn has_work(&self) -> bool {
        self.job.is_some()
    }

    fn step(&mut self, out: &Outbox<Finished<T>>) -> Result<(), String> {
        let Some((build, generation)) = self.job.take() else {
            return Ok(());
        };
        // A panic is this request's failure (the shell's error slot does not say whose).
        let result = out.install(|| std::panic::catch_unwind(AssertUnwindSafe(build)));
        let result = result.unwrap_or_else(|panic| {
            Err(format!(
                "building the scene failed: {}",
                crate::io::panic_message(&*panic)
            ))
        });
        out.publish(Finished {
            generation,
            result: Arc::new(result),
        });
        Ok(())
    }

    fn stop(&mut self) {
        self.job = None;
    }
}

/// What the app's builds make: the next state of the scene on screen.
#[derive(Clone)]
pub(super) struct Built {
    /// The scene as loaded or last saved, under the new environment (`None`: unchanged).
    pub scene: Option<Scene>,
    /// The scene to render, with every guided table.
    pub rendered: Scene,
}

/// Completes `rendered` (the editor's portals, some windows perhaps without their tables) as
/// the background build: its missing tables, or, given a new `environment`, the environment
/// once and every window's table for it; `scene` (as saved) then takes the new environment and
/// shares the tables of the windows it has in common with `rendered`.
pub(super) fn complete(
    scene: Scene,
    rendered: Scene,
    environment: Option<Option<EnvironmentDesc>>,
) -> Result<Built, String> {
    let Some(environment) = environment else {
        let mut rendered = rendered;
        rendered.build_tables();
        return Ok(Built {
            scene: None,
            rendered,
        });
    };
    let under = scene
        .with_environment_deferred(environment)
        .map_err(|e| e.to_string())?;
    let (rendered, _) = under.with_portals_reusing(rendered.desc.portals.clone(), None);
    let (scene, _) = under.with_portals_deferred(under.desc.portals.clone(), Some(&rendered));
    Ok(Built {
        scene: Some(scene),
        rendered,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::mpsc;
    use std::time::{Duration, Instant};

    /// Polls until a result arrives; generous for a loaded two-core machine (nothing here is
    /// timed: a build waits for the test's go-ahead).
    fn wait_for(builder: &mut Builder<u32>) -> Result<u32, String> {
        let start = Instant::now();
        loop {
            if let Some(result) = builder.poll() {
                return result;
            }
            assert!(start.elapsed() < Duration::from_secs(60), "timed out");
            std::thread::sleep(Duration::from_millis(2));
        }
    }

    /// A build that returns `value` once `go` says so, counting its runs in `runs`.
    fn gated(value: u32, go: mpsc::Receiver<()>, runs: &Arc<AtomicUsize>) -> Build<u32> {
        let runs = runs.clone();
        Box::new(move || {
            runs.fetch_add(1, Ordering::SeqCst);
            go.recv().map_err(|e| e.to_string())?;
            Ok(value)
        })
    }

    /// Requests made while a build runs coalesce into the newest (the others never run), the
    /// running one's result is dropped when it arrives, and the newest's is taken once.
    #[test]
    fn only_the_newest_build_runs_next_and_a_stale_result_is_dropped() {
        let mut builder = Builder::<u32>::spawn(Box::new(|| {})).unwrap();
        let runs = Arc::new(AtomicUsize::new(0));
        let (go1, wait1) = mpsc::channel();
        builder.request(gated(1, wait1, &runs));
        // The first has started (it counted itself) before the others are requested.
        let start = Instant::now();
        while runs.load(Ordering::SeqCst) == 0 {
            assert!(start.elapsed() < Duration::from_secs(60), "never started");
            std::thread::sleep(Duration::from_millis(1));
        }
        let skipped = Arc::new(AtomicUsize::new(0));
        for value in [2, 3] {
            let (_go, wait) = mpsc::channel();
            builder.request(gated(value, wait, &skipped));
        }
        let (go4, wait4) = mpsc::channel();
        builder.request(gated(4, wait4, &runs));
        assert!(builder.is_building());
        // The first finishes: its result reaches the slot, and polling drops it.
        go1.send(()).unwrap();
        let start = Instant::now();
        while runs.load(Ordering::SeqCst) < 2 {
            assert!(
                start.elapsed() < Duration::from_secs(60),
                "the newest never started"
            );
            std::thread::sleep(Duration::from_millis(1));
        }
        // The newest is running and waits for its go-ahead: whatever is in the slot is the
        // first's result, which must not be taken.
        assert_eq!(builder.poll(), None);
        assert!(builder.is_building());
        go4.send(()).unwrap();
        assert_eq!(wait_for(&mut builder), Ok(4));
        assert!(!builder.is_building());
        assert_eq!(builder.poll(), None, "a result is taken once");
        assert_eq!(skipped.load(Ordering::SeqCst), 0, "a superseded build ran");
        assert_eq!(runs.load(Ordering::SeqCst), 2);
    }

    /// A forgotten build's result is dropped; a failing or panicking build reports its error
    /// to the request it answers, and the builder keeps working.
    #[test]
    fn forgotten_failed_and_panicking_builds() {
        let mut builder = Builder::<u32>::spawn(Box::new(|| {})).unwrap();
        let runs = Arc::new(AtomicUsize::new(0));
        let (go, wait) = mpsc::channel();
        builder.request(gated(1, wait, &runs));
        builder.forget();
        go.send(()).unwrap();
        assert_eq!(builder.poll(), None);
        builder.request(Box::new(|| Err("no sky".into())));
        assert_eq!(wait_for(&mut builder), Err("no sky".into()));
        builder.request(Box::new(|| panic!("a broken table")));
        let error = wait_for(&mut builder).unwrap_err();
        assert!(error.contains("a broken table"), "{error}");
        builder.request(Box::new(|| Ok(7)));
        assert_eq!(wait_for(&mut builder), Ok(7));
    }
}
