//! The background-worker shell every worker is built on: one thread that owns a rayon pool,
//! takes requests from a channel (only the newest of those queued matters), abandons the
//! running step when a request arrives (a shared cancel flag, checked once per tile),
//! publishes frames into a slot the UI polls without waiting, and turns a panic into an error
//! message instead of a dead thread. What a worker computes is a [`Work`].

use std::panic::AssertUnwindSafe;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

/// The work a worker does, one step at a time, on its own thread.
pub trait Work: Send + 'static {
    type Request: Send + 'static;
    /// What the UI reads: cheap to clone (hold images in `Arc`s).
    type Frame: Clone + Send + 'static;

    /// Replaces the current job with `request`, numbered `generation` by the handle.
    fn start(&mut self, request: Self::Request, generation: u64);
    /// Pauses or resumes the current job without restarting it.
    fn set_paused(&mut self, paused: bool);
    /// Whether [`Work::step`] has something to do; if not, the worker sleeps until a message.
    fn has_work(&self) -> bool;
    /// Called after a batch of messages was applied (for example to publish the new state).
    fn after_messages(&mut self, _out: &Outbox<Self::Frame>) {}
    /// One step of the current job (typically one pass). An error stops the job and is shown.
    fn step(&mut self, out: &Outbox<Self::Frame>) -> Result<(), String>;
    /// Drops the current job (after an error or a panic).
    fn stop(&mut self);
}

/// What a step works with: the pool, the cancel flag, and the slot it publishes into.
pub struct Outbox<F> {
    pool: rayon::ThreadPool,
    cancel: Arc<AtomicBool>,
    shared: Arc<Mutex<Shared<F>>>,
    notify: Box<dyn Fn() + Send>,
}

impl<F> Outbox<F> {
    /// Runs `f` on the worker's pool.
    pub fn install<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        self.pool.install(f)
    }

    /// Set when a newer message arrived: a pass checks it once per tile and gives up.
    pub fn cancel(&self) -> &AtomicBool {
        &self.cancel
    }

    /// Makes `frame` the newest one, clears any error, and wakes the UI.
    pub fn publish(&self, frame: F) {
        if let Ok(mut shared) = self.shared.lock() {
            shared.frame = Some(frame);
            shared.error = None;
        }
        (self.notify)();
    }

    fn fail(&self, message: String) {
        if let Ok(mut shared) = self.shared.lock() {
            shared.error = Some(message);
        }
        (self.notify)();
    }
}

/// What the UI can read without waiting.
struct Shared<F> {
    frame: Option<F>,
    /// Why the last job stopped, if it failed.
    error: Option<String>,
}

enum Message<R> {
    /// A request and its generation (the handle numbers them, so that frames of coalesced
    /// requests still carry the number the UI waits for).
    Request(R, u64),
    Pause(bool),
    Stop,
}

/// The handle the UI holds. Dropping it stops the worker (the running step is abandoned).
pub struct WorkerHandle<W: Work> {
    tx: Sender<Message<W::Request>>,
    shared: Arc<Mutex<Shared<W::Frame>>>,
    cancel: Arc<AtomicBool>,
    generation: u64,
    thread: Option<JoinHandle<()>>,
}

impl<W: Work> WorkerHandle<W> {
    /// Starts a thread named `name` running `work` with a pool of `threads` (0 = every core);
    /// `notify` is called after each published frame or error (a UI passes
    /// `egui::Context::request_repaint`).
    pub fn new(
        work: W,
        name: &'static str,
        threads: usize,
        notify: Box<dyn Fn() + Send>,
    ) -> std::io::Result<Self> {
        let (tx, rx) = mpsc::channel();
        let shared = Arc::new(Mutex::new(Shared {
            frame: None,
            error: None,
        }));
        let cancel = Arc::new(AtomicBool::new(false));
        let outbox = Outbox {
            pool: worker_pool(threads, name)?,
            cancel: cancel.clone(),
            shared: shared.clone(),
            notify,
        };
        let thread = std::thread::Builder::new()
            .name(name.into())
            .spawn(move || run(work, rx, outbox))?;
        Ok(WorkerHandle {
            tx,
            shared,
            cancel,
            generation: 0,
            thread: Some(thread),
        })
    }

    /// Replaces what the worker does; the running step is abandoned at once. Returns the
    /// request's generation, which its frames carry.
    pub fn request(&mut self, request: W::Request) -> u64 {
        self.generation += 1;
        self.send(Message::Request(request, self.generation));
        self.generation
    }

    /// Pauses (abandoning the running step) or resumes, without restarting the job.
    pub fn set_paused(&self, paused: bool) {
        self.send(Message::Pause(paused));
    }

    fn send(&self, message: Message<W::Request>) {
        self.cancel.store(true, Ordering::Relaxed);
        // A send fails only if the worker is gone; its error slot then says why.
        let _ = self.tx.send(message);
    }

    /// The newest frame, if the worker is not publishing at this very moment.
    pub fn latest(&self) -> Option<W::Frame> {
        self.shared.try_lock().ok()?.frame.clone()
    }

    /// Takes the newest frame out of the slot, for a worker whose frames are results each
    /// used once (the slot then holds none of their memory).
    pub fn take(&self) -> Option<W::Frame> {
        self.shared.try_lock().ok()?.frame.take()
    }

    /// Why the last job failed, if it did (cleared by the next published frame).
    pub fn error(&self) -> Option<String> {
        self.shared.try_lock().ok()?.error.clone()
    }

    /// The number of the newest request.
    pub fn generation(&self) -> u64 {
        self.generation
    }
}

impl<W: Work> Drop for WorkerHandle<W> {
    fn drop(&mut self) {
        self.send(Message::Stop);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// The worker thread's loop.
fn run<W: Work>(mut work: W, rx: Receiver<Message<W::Request>>, out: Outbox<W::Frame>) {
    loop {
        // Working: take any message that arrived. Idle or paused: sleep until one does.
        let first = if work.has_work() {
            rx.try_recv().ok()
        } else {
            match rx.recv() {
                Ok(m) => Some(m),
                Err(_) => return,
            }
        };
        if let Some(first) = first {
            let mut batch = vec![first];
            batch.extend(rx.try_iter());
            // Only the newest request matters, and only pauses sent after it.
            let newest = batch
                .iter()
                .rposition(|m| matches!(m, Message::Request(..)));
            for (i, message) in batch.into_iter().enumerate() {
                match message {
                    Message::Stop => return,
                    Message::Request(request, generation) if Some(i) == newest => {
                        work.start(request, generation);
                    }
                    Message::Pause(paused) if newest.is_none_or(|k| i > k) => {
                        work.set_paused(paused);
                    }
                    Message::Request(..) | Message::Pause(_) => {}
                }
            }
            out.cancel.store(false, Ordering::Relaxed);
            work.after_messages(&out);
            continue;
        }
        let outcome = std::panic::catch_unwind(AssertUnwindSafe(|| work.step(&out)));
        let failure = match outcome {
            Ok(Ok(())) => None,
            Ok(Err(message)) => Some(message),
            Err(panic) => Some(format!(
                "the renderer failed: {}",
                crate::io::panic_message(&*panic)
            )),
        };
        if let Some(message) = failure {
            work.stop();
            out.fail(message);
        }
    }
}

/// The rayon pool a background worker renders with: `threads` named `{name}-{i}` (0 = every
/// core), kept apart from the global pool so that a worker's passes never queue behind others.
fn worker_pool(threads: usize, name: &'static str) -> std::io::Result<rayon::ThreadPool> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .thread_name(move |i| format!("{name}-{i}"))
        .build()
        .map_err(std::io::Error::other)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::{Duration, Instant};

    /// Counts steps of the newest request; panics on request 99.
    struct Counter {
        job: Option<(u64, u32)>,
        paused: bool,
    }

    impl Work for Counter {
        type Request = u32;
        type Frame = (u64, u32);
        fn start(&mut self, request: u32, generation: u64) {
            self.job = Some((generation, request));
        }
        fn set_paused(&mut self, paused: bool) {
            self.paused = paused;
        }
        fn has_work(&self) -> bool {
            self.job.is_some() && !self.paused
        }
        fn step(&mut self, out: &Outbox<(u64, u32)>) -> Result<(), String> {
            let Some((generation, n)) = self.job.as_mut() else {
                return Ok(());
            };
            assert!(*n != 99, "ninety-nine");
            *n += 1;
            out.publish((*generation, *n));
            std::thread::sleep(Duration::from_millis(1));
            Ok(())
        }
        fn stop(&mut self) {
            self.job = None;
        }
    }

    fn wait_for<T>(mut f: impl FnMut() -> Option<T>) -> T {
        let start = Instant::now();
        loop {
            if let Some(v) = f() {
                return v;
            }
            assert!(start.elapsed() < Duration::from_secs(20), "timed out");
            std::thread::sleep(Duration::from_millis(2));
        }
    }

    #[test]
    fn frames_carry_the_newest_generation_and_panics_become_errors() {
        let work = Counter {
            job: None,
            paused: false,
        };
        let mut h = WorkerHandle::new(work, "shell-test", 1, Box::new(|| {})).unwrap();
        for r in 0..5 {
            h.request(r * 1000);
        }
        let g = h.generation();
        assert_eq!(g, 5);
        // The first frame of the newest generation counts on from its own request (4000), not
        // from an older one's: the worker started the newest request, not a stale one.
        let (_, n) = wait_for(|| h.latest().filter(|f| f.0 == g));
        assert!(n > 4000, "{n}");
        // And no older generation's frame is published after it (counted frames, not time).
        let mut last = n;
        for _ in 0..20 {
            let (generation, m) = wait_for(|| h.latest().filter(|f| f.1 > last || f.0 != g));
            assert_eq!(generation, g, "a stale frame after the newest");
            last = m;
        }
        h.request(98);
        wait_for(|| h.error());
        let error = h.error().unwrap();
        assert!(error.contains("ninety-nine"), "{error}");
        // A new request after a failure works again and clears the error.
        let g = h.request(0);
        wait_for(|| h.latest().filter(|f| f.0 == g));
        assert!(h.error().is_none());
    }
}
