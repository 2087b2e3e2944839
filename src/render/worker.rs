//! The render worker: accumulates passes for the newest request, a quarter-resolution preview
//! first, on the [`shell`](super::shell) every worker shares. A UI drives it through a
//! [`RenderHandle`] and never blocks on it.

use glam::Vec3;
use std::sync::Arc;
use std::time::{Duration, Instant};

use super::film::Film;
use super::integrator::{Integrator, RenderSettings};
use super::primary::PrimaryBuffer;
use super::render_pass;
use super::shell::{Outbox, Work, WorkerHandle};
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

/// Preview passes render at 1/PREVIEW_DIVISOR of the resolution in each direction.
pub const PREVIEW_DIVISOR: u32 = 4;

/// The handle the UI holds. Dropping it stops the worker.
pub type RenderHandle = WorkerHandle<RenderWork>;

impl WorkerHandle<RenderWork> {
    /// Starts the render worker; `notify` is called after each published frame (a UI passes
    /// `egui::Context::request_repaint`). `threads` = 0 uses every core.
    pub fn spawn(threads: usize, notify: Box<dyn Fn() + Send>) -> std::io::Result<Self> {
        WorkerHandle::new(
            RenderWork { job: None },
            "portalview-render",
            threads,
            notify,
        )
    }
}

/// Accumulates passes of the newest request.
pub struct RenderWork {
    job: Option<Job>,
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

impl Work for RenderWork {
    type Request = RenderRequest;
    type Frame = Frame;

    fn start(&mut self, request: RenderRequest, generation: u64) {
        let film = Film::new(request.width.max(1), request.height.max(1));
        self.job = Some(Job {
            request,
            generation,
            film,
            stats: Stats::default(),
            elapsed: Duration::ZERO,
            preview_done: false,
            primary: None,
            last_publish: None,
        });
    }

    fn set_paused(&mut self, paused: bool) {
        if let Some(job) = self.job.as_mut() {
            job.request.paused = paused;
        }
    }

    fn has_work(&self) -> bool {
        self.job.as_ref().is_some_and(|j| !j.request.paused)
    }

    fn step(&mut self, out: &Outbox<Frame>) -> Result<(), String> {
        match self.job.as_mut() {
            Some(job) => job.step(out),
            None => Ok(()),
        }
    }

    fn stop(&mut self) {
        self.job = None;
    }
}

impl Job {
    /// Renders one pass of the job (the preview first) and publishes it.
    fn step(&mut self, out: &Outbox<Frame>) -> Result<(), String> {
        let job = self;
        let request = &job.request;
        if job.preview_done && job.primary.is_none() {
            let (scene, w, h) = (&request.scene, job.film.width, job.film.height);
            let brute_force = request.brute_force_regions;
            let cancel = out.cancel();
            let primary = out
                .install(|| PrimaryBuffer::compute_cancellable(scene, w, h, brute_force, cancel));
            let Some(primary) = primary else {
                // A newer request arrived: it is handled on the next turn.
                return Ok(());
            };
            job.primary = Some(Arc::new(primary));
        }
        let request = &job.request;
        let integrator = Integrator::new(&request.scene, request.settings);
        let start = Instant::now();
        let (width, height, spp) = (job.film.width, job.film.height, job.film.spp);
        let preview_done = job.preview_done;
        let cancel = out.cancel();
        let outcome = out.install(|| {
            if preview_done {
                render_pass(&integrator, width, height, spp, cancel).map(|r| (r, None))
            } else {
                let (w, h) = preview_size(width, height);
                render_pass(&integrator, w, h, 0, cancel).map(|r| (r, Some((w, h))))
            }
        });
        let pass_time = start.elapsed();
        let Ok(((pixels, stats), preview)) = outcome else {
            // A newer request arrived: it is handled on the next turn.
            return Ok(());
        };
        if let Some((w, h)) = preview {
            job.preview_done = true;
            out.publish(Frame {
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
            out.publish(Frame {
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
}

/// The preview's size: a quarter of the resolution in each direction, at least one pixel.
pub fn preview_size(width: u32, height: u32) -> (u32, u32) {
    (
        width.div_ceil(PREVIEW_DIVISOR).max(1),
        height.div_ceil(PREVIEW_DIVISOR).max(1),
    )
}
