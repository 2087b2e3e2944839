//! The render worker: one background thread that owns the rendering threads and accumulates
//! passes for the newest request. A UI drives it through a [`RenderHandle`] and never blocks on
//! it: requests go down a channel, frames come back through a slot the UI polls.

use glam::Vec3;
use std::panic::AssertUnwindSafe;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::film::Film;
use super::integrator::{Integrator, RenderSettings};
use super::primary::PrimaryBuffer;
use super::render_pass;
use super::stats::Stats;
use crate::scene::Scene;

/// What the UI wants rendered. Any change restarts accumulation.
#[derive(Clone)]
pub struct RenderRequest {
    pub scene: Scene,
    pub settings: RenderSettings,
    pub width: u32,
    pub height: u32,
    pub paused: bool,
    /// Classify the overlay's regions by brute force (a debug view).
    pub brute_force_regions: bool,
}

/// The newest image of a request.
#[derive(Clone, Debug)]
pub struct Frame {
    /// Which request this belongs to (increments with every request).
    pub generation: u64,
    pub width: u32,
    pub height: u32,
    /// Mean linear radiance, row-major.
    pub pixels: Arc<Vec<Vec3>>,
    pub spp: u32,
    /// A reduced-resolution first pass shown while full resolution starts.
    pub preview: bool,
    /// Rendering time of this request so far.
    pub elapsed: Duration,
    pub stats: Stats,
    /// Per-pixel regions and techniques at full resolution (after the preview).
    pub primary: Option<Arc<PrimaryBuffer>>,
}

impl Frame {
    /// Camera samples per second over the request so far.
    pub fn samples_per_second(&self) -> f64 {
        let samples = self.spp as f64 * (self.width * self.height) as f64;
        samples / self.elapsed.as_secs_f64().max(1e-9)
    }
}

/// What the UI can read without waiting.
#[derive(Default)]
struct Shared {
    frame: Option<Frame>,
    /// A pass that panicked: its message, shown in the UI.
    error: Option<String>,
}

enum Message {
    /// A request and its generation (the handle numbers them, so that frames of coalesced
    /// requests still carry the number the UI waits for).
    Render(Box<RenderRequest>, u64),
    Stop,
}

/// Preview passes render at 1/PREVIEW_DIVISOR of the resolution in each direction.
pub const PREVIEW_DIVISOR: u32 = 4;

/// The handle the UI holds. Dropping it stops the worker.
pub struct RenderHandle {
    tx: Sender<Message>,
    shared: Arc<Mutex<Shared>>,
    /// Set to abandon the running pass (checked once per tile).
    cancel: Arc<AtomicBool>,
    generation: u64,
    thread: Option<JoinHandle<()>>,
}

impl RenderHandle {
    /// Starts the worker; `notify` is called after each published frame (a UI passes
    /// `egui::Context::request_repaint`). `threads` = 0 uses every core.
    pub fn spawn(threads: usize, notify: Box<dyn Fn() + Send>) -> std::io::Result<Self> {
        let (tx, rx) = mpsc::channel();
        let shared = Arc::new(Mutex::new(Shared::default()));
        let cancel = Arc::new(AtomicBool::new(false));
        let pool = super::worker_pool(threads, "portalview-render")?;
        let worker = Worker {
            rx,
            shared: shared.clone(),
            cancel: cancel.clone(),
            notify,
            pool,
        };
        let thread = std::thread::Builder::new()
            .name("portalview-worker".into())
            .spawn(move || worker.run())?;
        Ok(RenderHandle {
            tx,
            shared,
            cancel,
            generation: 0,
            thread: Some(thread),
        })
    }

    /// Replaces what is rendered; the running pass is abandoned at once. Returns the request's
    /// generation, which its frames carry.
    pub fn request(&mut self, request: RenderRequest) -> u64 {
        self.generation += 1;
        self.cancel.store(true, Ordering::Relaxed);
        // A send fails only if the worker is gone; its error slot then says why.
        let _ = self
            .tx
            .send(Message::Render(Box::new(request), self.generation));
        self.generation
    }

    /// The newest frame, if the worker is not publishing at this very moment.
    pub fn latest(&self) -> Option<Frame> {
        self.shared.try_lock().ok()?.frame.clone()
    }

    /// A failure of the worker, if any.
    pub fn error(&self) -> Option<String> {
        self.shared.try_lock().ok()?.error.clone()
    }

    pub fn generation(&self) -> u64 {
        self.generation
    }
}

impl Drop for RenderHandle {
    fn drop(&mut self) {
        self.cancel.store(true, Ordering::Relaxed);
        let _ = self.tx.send(Message::Stop);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

struct Worker {
    rx: Receiver<Message>,
    shared: Arc<Mutex<Shared>>,
    cancel: Arc<AtomicBool>,
    notify: Box<dyn Fn() + Send>,
    pool: rayon::ThreadPool,
}

/// The request being accumulated.
struct Job {
    request: RenderRequest,
    generation: u64,
    film: Film,
    stats: Stats,
    /// Rendering time (excluding pauses and publishing).
    elapsed: Duration,
    preview_done: bool,
    primary: Option<Arc<PrimaryBuffer>>,
    last_publish: Option<Instant>,
}

/// Full-resolution frames are published at most this often (the UI uploads each one).
const PUBLISH_INTERVAL: Duration = Duration::from_millis(100);

impl Worker {
    fn run(self) {
        let mut job: Option<Job> = None;
        loop {
            // Idle or paused: wait for a message. Working: take any that arrived.
            let working = job.as_ref().is_some_and(|j| !j.request.paused);
            let message = if working {
                self.rx.try_recv().ok()
            } else {
                match self.rx.recv_timeout(Duration::from_secs(3600)) {
                    Ok(m) => Some(m),
                    Err(RecvTimeoutError::Timeout) => continue,
                    Err(RecvTimeoutError::Disconnected) => return,
                }
            };
            match message {
                Some(Message::Stop) => return,
                Some(Message::Render(request, generation)) => {
                    // Only the newest request matters; skip any that queued behind it.
                    let (mut request, mut generation) = (request, generation);
                    while let Ok(next) = self.rx.try_recv() {
                        match next {
                            Message::Render(r, g) => (request, generation) = (r, g),
                            Message::Stop => return,
                        }
                    }
                    self.cancel.store(false, Ordering::Relaxed);
                    let film = Film::new(request.width.max(1), request.height.max(1));
                    job = Some(Job {
                        request: *request,
                        generation,
                        film,
                        stats: Stats::default(),
                        elapsed: Duration::ZERO,
                        preview_done: false,
                        primary: None,
                        last_publish: None,
                    });
                    continue;
                }
                None => {}
            }
            if let Some(j) = job.as_mut()
                && let Err(message) = self.step(j)
            {
                if let Ok(mut shared) = self.shared.lock() {
                    shared.error = Some(message);
                }
                (self.notify)();
                job = None;
            }
        }
    }

    /// Renders one pass of the job (the preview first) and publishes it.
    fn step(&self, job: &mut Job) -> Result<(), String> {
        let request = &job.request;
        if job.preview_done && job.primary.is_none() {
            let (scene, w, h) = (&request.scene, job.film.width, job.film.height);
            let brute_force = request.brute_force_regions;
            let primary = self
                .pool
                .install(|| PrimaryBuffer::compute(scene, w, h, brute_force));
            job.primary = Some(Arc::new(primary));
        }
        let request = &job.request;
        let integrator = Integrator::new(&request.scene, request.settings);
        let start = Instant::now();
        let (width, height, spp) = (job.film.width, job.film.height, job.film.spp);
        let preview_done = job.preview_done;
        let cancel: &AtomicBool = &self.cancel;
        let outcome = std::panic::catch_unwind(AssertUnwindSafe(|| {
            self.pool.install(|| {
                if preview_done {
                    render_pass(&integrator, width, height, spp, cancel).map(|r| (r, None))
                } else {
                    let (w, h) = preview_size(width, height);
                    render_pass(&integrator, w, h, 0, cancel).map(|r| (r, Some((w, h))))
                }
            })
        }));
        let pass_time = start.elapsed();
        let ((pixels, stats), preview) = match outcome {
            Ok(Ok(result)) => result,
            // A newer request arrived: it is handled on the next turn.
            Ok(Err(_cancelled)) => return Ok(()),
            Err(panic) => {
                let what = panic
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| panic.downcast_ref::<String>().cloned())
                    .unwrap_or_else(|| "unknown panic".into());
                return Err(format!("the renderer failed: {what}"));
            }
        };
        if let Some((w, h)) = preview {
            job.preview_done = true;
            self.publish(Frame {
                generation: job.generation,
                width: w,
                height: h,
                pixels: Arc::new(pixels),
                spp: 1,
                preview: true,
                elapsed: pass_time,
                stats,
                primary: None,
            });
            return Ok(());
        }
        job.film.add_pass(&pixels);
        job.stats += stats;
        job.elapsed += pass_time;
        let due = job
            .last_publish
            .is_none_or(|t| t.elapsed() >= PUBLISH_INTERVAL);
        if due {
            job.last_publish = Some(Instant::now());
            self.publish(Frame {
                generation: job.generation,
                width: job.film.width,
                height: job.film.height,
                pixels: Arc::new(job.film.mean()),
                spp: job.film.spp,
                preview: false,
                elapsed: job.elapsed,
                stats: job.stats,
                primary: job.primary.clone(),
            });
        }
        Ok(())
    }

    fn publish(&self, frame: Frame) {
        if let Ok(mut shared) = self.shared.lock() {
            shared.frame = Some(frame);
            shared.error = None;
        }
        (self.notify)();
    }
}

/// The preview's size: a quarter of the resolution in each direction, at least one pixel.
pub fn preview_size(width: u32, height: u32) -> (u32, u32) {
    (
        width.div_ceil(PREVIEW_DIVISOR).max(1),
        height.div_ceil(PREVIEW_DIVISOR).max(1),
    )
}
