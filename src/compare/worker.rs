//! The comparison worker: one background thread that obtains a converged reference (from the
//! cache, a file, or a render), then renders the chosen strategies at equal time by
//! [`EqualTime`] and publishes, after each pass (at most [`PUBLISH_INTERVAL`] apart), every
//! strategy's mean image and its convergence against the reference. A UI drives it through a
//! [`CompareHandle`] and never waits on it: requests go down a channel, frames come back
//! through a slot the UI polls.

use glam::Vec3;
use indicatif::ProgressBar;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::compare::{
    ConvergencePoint, EqualTime, ImageSpec, Reference, ReferenceBudget, ReferenceOrigin,
    WORST_FRACTION, cache_key, find_cached_reference, load_reference, mse, relmse,
    render_reference, store_reference, worst_pixels_share,
};
use crate::light::{Mixture, Selection, Strategy};
use crate::render::Cancelled;
use crate::render::integrator::{GlassShadows, GuideBounces, RenderSettings};
use crate::render::shell::{Outbox, Work, WorkerHandle};
use crate::sampling::SamplerKind;
use crate::scene::Scene;

/// Where the reference comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum ReferenceSource {
    /// Rendered with `compare::REFERENCE_STRATEGY` for `budget`, through the cache in
    /// `cache_dir` when there is one (a cached reference that covers the budget is reused).
    Render {
        budget: ReferenceBudget,
        cache_dir: Option<PathBuf>,
    },
    /// An EXR file; the comparison then renders at the file's size.
    File(PathBuf),
}

/// What the UI wants compared. Any change starts a new comparison.
#[derive(Clone)]
pub struct CompareRequest {
    /// The scene, with the camera to compare at.
    pub scene: Scene,
    pub strategies: Vec<Strategy>,
    /// Size and depth (the size is replaced by the file's for [`ReferenceSource::File`]).
    pub image: ImageSpec,
    /// Overrides every portal's alpha in the compared renders (not in the reference, whose
    /// expectation it does not change).
    pub alpha: Option<f32>,
    /// Seed of the compared renders; the reference uses `compare::reference_seed(seed)`.
    pub seed: u64,
    /// The compared renders' random numbers (the reference's are always independent).
    pub sampler: SamplerKind,
    /// How the compared renders draw from a light mixture.
    pub mixture: Mixture,
    /// How the compared renders pick lights.
    pub selection: Selection,
    /// What the compared renders' shadow rays do at thin glass.
    pub glass: GlassShadows,
    /// Whether the compared renders guide their bounces through the portals.
    pub bounces: GuideBounces,
    pub reference: ReferenceSource,
    /// A reference the UI already holds: used instead of the source when it fits (same
    /// scene, camera, size and depth, and at least the budget; or the same file).
    pub known_reference: Option<Arc<Reference>>,
    /// Start paused: nothing is done (or published) until resumed.
    pub paused: bool,
}

/// The state of the reference.
#[derive(Clone, Debug)]
pub enum ReferenceStatus {
    /// Being looked up, loaded or rendered. The bar counts milliseconds of render time (or
    /// passes, for an spp budget); its message is "N spp".
    Rendering(ProgressBar),
    Ready(Arc<Reference>),
    Failed(String),
}

/// One strategy's state in a published frame.
#[derive(Clone, Debug)]
pub struct RunFrame {
    pub strategy: Strategy,
    /// Mean linear radiance, row-major (`width × height`; empty before its first pass).
    pub pixels: Arc<Vec<Vec3>>,
    pub spp: u32,
    /// Accumulated pass render time.
    pub seconds: f64,
    /// Against the reference, of `pixels` (NaN before the first pass).
    pub mse: f64,
    pub relmse: f64,
    /// The share of the squared error in the worst 1 % of pixels (NaN before the first pass).
    pub worst_share: f64,
    /// Recorded at log-spaced times (about 24 a decade), ending with the current state.
    pub history: Vec<ConvergencePoint>,
}

/// What the worker publishes.
#[derive(Clone, Debug)]
pub struct CompareFrame {
    /// The request this belongs to.
    pub generation: u64,
    /// The comparison's size (the file's, for a file reference).
    pub width: u32,
    pub height: u32,
    pub reference: ReferenceStatus,
    /// In the order of the request's strategies; empty until the reference is ready.
    pub runs: Vec<RunFrame>,
    /// Passes rendered for this request (all strategies).
    pub passes: u64,
    pub paused: bool,
    /// Warnings: a reference that could not be cached, or whose sidecar names another scene.
    pub notes: Vec<String>,
}

impl CompareFrame {
    /// The least accumulated time over the strategies (what "equal time" has reached).
    pub fn min_seconds(&self) -> f64 {
        self.runs
            .iter()
            .map(|r| r.seconds)
            .reduce(f64::min)
            .unwrap_or(0.0)
    }

    pub fn run(&self, strategy: Strategy) -> Option<&RunFrame> {
        self.runs.iter().find(|r| r.strategy == strategy)
    }

    pub fn reference(&self) -> Option<&Arc<Reference>> {
        match &self.reference {
            ReferenceStatus::Ready(r) => Some(r),
            _ => None,
        }
    }
}

/// Frames are published at most this often (the UI uploads up to four images from each).
pub const PUBLISH_INTERVAL: Duration = Duration::from_millis(100);

/// A history point is recorded when a strategy's time has grown by this factor since its last.
pub const HISTORY_FACTOR: f64 = 1.1;

/// The handle the UI holds. Dropping it stops the worker (the running pass is abandoned).
pub type CompareHandle = WorkerHandle<CompareWork>;

impl WorkerHandle<CompareWork> {
    /// Starts the worker, idle; `notify` is called after each published frame. `threads` = 0
    /// uses every core.
    pub fn spawn(threads: usize, notify: Box<dyn Fn() + Send>) -> std::io::Result<Self> {
        let work = CompareWork {
            job: None,
            known: None,
        };
        WorkerHandle::new(work, "portalview-compare", threads, notify)
    }

    /// Starts a new comparison; the running one is abandoned at once. Returns the request's
    /// generation, which its frames carry.
    pub fn start(&mut self, request: CompareRequest) -> u64 {
        self.request(Box::new(request))
    }
}

/// Runs the newest comparison.
pub struct CompareWork {
    job: Option<Job>,
    /// The newest reference obtained, reused by later requests it fits.
    known: Option<Arc<Reference>>,
}

/// One strategy's running state.
struct RunState {
    pixels: Arc<Vec<Vec3>>,
    mse: f64,
    relmse: f64,
    worst_share: f64,
    history: Vec<ConvergencePoint>,
    next_record: f64,
}

/// The comparison being run.
struct Job {
    request: CompareRequest,
    generation: u64,
    paused: bool,
    width: u32,
    height: u32,
    reference: ReferenceStatus,
    schedule: Option<EqualTime>,
    runs: Vec<RunState>,
    passes: u64,
    notes: Vec<String>,
    last_publish: Option<Instant>,
    /// Nothing left to do: the reference failed, or no strategy was asked for.
    idle: bool,
}

impl Job {
    fn new(request: CompareRequest, generation: u64) -> Job {
        let image = request.image;
        Job {
            paused: request.paused,
            request,
            generation,
            width: image.width.max(1),
            height: image.height.max(1),
            reference: ReferenceStatus::Rendering(ProgressBar::hidden()),
            schedule: None,
            runs: Vec::new(),
            passes: 0,
            notes: Vec::new(),
            last_publish: None,
            idle: false,
        }
    }

    fn publish(&mut self, out: &Outbox<Arc<CompareFrame>>) {
        self.last_publish = Some(Instant::now());
        out.publish(Arc::new(self.frame()));
    }

    fn frame(&self) -> CompareFrame {
        let runs = match &self.schedule {
            Some(schedule) => schedule
                .runs()
                .iter()
                .zip(&self.runs)
                .map(|(run, state)| {
                    let mut history = state.history.clone();
                    if run.film.spp > 0 && history.last().is_none_or(|p| p.spp < run.film.spp) {
                        history.push(ConvergencePoint {
                            strategy: run.strategy,
                            seconds: run.seconds,
                            spp: run.film.spp,
                            mse: state.mse,
                            relmse: state.relmse,
                        });
                    }
                    RunFrame {
                        strategy: run.strategy,
                        pixels: state.pixels.clone(),
                        spp: run.film.spp,
                        seconds: run.seconds,
                        mse: state.mse,
                        relmse: state.relmse,
                        worst_share: state.worst_share,
                        history,
                    }
                })
                .collect(),
            None => Vec::new(),
        };
        CompareFrame {
            generation: self.generation,
            width: self.width,
            height: self.height,
            reference: self.reference.clone(),
            runs,
            passes: self.passes,
            paused: self.paused,
            notes: self.notes.clone(),
        }
    }
}

/// Whether `known` can stand in for the reference `request` asks for.
fn fits(known: &Reference, request: &CompareRequest) -> bool {
    match &request.reference {
        ReferenceSource::Render { budget, .. } => {
            let image = request.image;
            !matches!(known.origin, ReferenceOrigin::File(_))
                && known.info.as_ref().is_some_and(|info| {
                    info.key == cache_key(&request.scene, image)
                        && info.seed != request.seed
                        && info.covers(*budget)
                })
        }
        ReferenceSource::File(path) => known.origin == ReferenceOrigin::File(path.clone()),
    }
}

/// The size of an EXR image, from its header.
fn exr_size(path: &Path) -> Result<(u32, u32), String> {
    let meta = exr::meta::MetaData::read_from_file(path, false)
        .map_err(|e| format!("{}: cannot read EXR: {e}", path.display()))?;
    let header = meta
        .headers
        .first()
        .ok_or_else(|| format!("{}: an EXR without layers", path.display()))?;
    let size = header.layer_size;
    Ok((size.width() as u32, size.height() as u32))
}

impl Work for CompareWork {
    type Request = Box<CompareRequest>;
    type Frame = Arc<CompareFrame>;

    fn start(&mut self, request: Box<CompareRequest>, generation: u64) {
        self.job = Some(Job::new(*request, generation));
    }

    fn set_paused(&mut self, paused: bool) {
        if let Some(job) = self.job.as_mut() {
            job.paused = paused;
        }
    }

    fn has_work(&self) -> bool {
        self.job.as_ref().is_some_and(|j| !j.paused && !j.idle)
    }

    fn after_messages(&mut self, out: &Outbox<Arc<CompareFrame>>) {
        if let Some(job) = self.job.as_mut()
            && (job.schedule.is_some() || !job.paused)
        {
            job.publish(out);
        }
    }

    fn step(&mut self, out: &Outbox<Arc<CompareFrame>>) -> Result<(), String> {
        if let Some(mut job) = self.job.take() {
            self.advance(&mut job, out);
            self.job = Some(job);
        }
        Ok(())
    }

    fn stop(&mut self) {
        self.job = None;
    }
}

impl CompareWork {
    /// Obtains the reference, or renders one pass.
    fn advance(&mut self, job: &mut Job, out: &Outbox<Arc<CompareFrame>>) {
        if job.schedule.is_none() {
            match self.obtain_reference(job, out) {
                Ok(reference) => {
                    self.known = Some(reference.clone());
                    job.width = reference.width;
                    job.height = reference.height;
                    job.reference = ReferenceStatus::Ready(reference);
                    let request = &job.request;
                    let settings = RenderSettings {
                        strategy: Strategy::Light,
                        alpha: request.alpha,
                        max_depth: request.image.max_depth,
                        seed: request.seed,
                        sampler: request.sampler,
                        mixture: request.mixture,
                        selection: request.selection,
                        glass: request.glass,
                        bounces: request.bounces,
                    };
                    let schedule = EqualTime::new(
                        request.scene.clone(),
                        &request.strategies,
                        job.width,
                        job.height,
                        settings,
                    );
                    job.runs = request
                        .strategies
                        .iter()
                        .map(|_| RunState {
                            pixels: Arc::new(Vec::new()),
                            mse: f64::NAN,
                            relmse: f64::NAN,
                            worst_share: f64::NAN,
                            history: Vec::new(),
                            next_record: 0.0,
                        })
                        .collect();
                    job.idle = request.strategies.is_empty();
                    job.schedule = Some(schedule);
                }
                // A message arrived: it is handled on the next turn.
                Err(None) => return,
                Err(Some(message)) => {
                    job.reference = ReferenceStatus::Failed(message);
                    job.idle = true;
                }
            }
            job.publish(out);
            return;
        }
        let (Some(schedule), ReferenceStatus::Ready(reference)) =
            (job.schedule.as_mut(), &job.reference)
        else {
            job.idle = true;
            return;
        };
        let cancel = out.cancel();
        let i = match out.install(|| schedule.step(cancel)) {
            Ok(Some(i)) => i,
            Ok(None) => {
                job.idle = true;
                return;
            }
            // A message arrived: it is handled on the next turn.
            Err(Cancelled) => return,
        };
        let run = &schedule.runs()[i];
        let mean = run.film.mean();
        let state = &mut job.runs[i];
        state.mse = mse(&mean, &reference.pixels);
        state.relmse = relmse(&mean, &reference.pixels);
        state.worst_share = worst_pixels_share(&mean, &reference.pixels, WORST_FRACTION);
        state.pixels = Arc::new(mean);
        if run.seconds >= state.next_record {
            state.history.push(ConvergencePoint {
                strategy: run.strategy,
                seconds: run.seconds,
                spp: run.film.spp,
                mse: state.mse,
                relmse: state.relmse,
            });
            state.next_record = run.seconds * HISTORY_FACTOR;
        }
        job.passes += 1;
        if job
            .last_publish
            .is_none_or(|t| t.elapsed() >= PUBLISH_INTERVAL)
        {
            job.publish(out);
        }
    }

    /// The reference: known, cached, loaded or rendered. `Err(None)`: cancelled.
    fn obtain_reference(
        &self,
        job: &mut Job,
        out: &Outbox<Arc<CompareFrame>>,
    ) -> Result<Arc<Reference>, Option<String>> {
        let request = &job.request;
        let known = [request.known_reference.as_ref(), self.known.as_ref()];
        if let Some(k) = known.into_iter().flatten().find(|k| fits(k, request)) {
            return Ok(k.clone());
        }
        let progress = ProgressBar::hidden();
        job.reference = ReferenceStatus::Rendering(progress.clone());
        job.publish(out);
        let request = &job.request;
        match &request.reference {
            ReferenceSource::File(path) => {
                let (width, height) = exr_size(path)?;
                let reference =
                    load_reference(path, width, height).map_err(|e| format!("{e:#}"))?;
                if let Some(info) = &reference.info {
                    let image = ImageSpec {
                        width,
                        height,
                        ..request.image
                    };
                    if info.key != cache_key(&request.scene, image) {
                        job.notes.push(format!(
                            "{}: its sidecar says it was rendered for another scene, camera or \
                             depth",
                            path.display()
                        ));
                    }
                    if info.seed == request.seed {
                        job.notes.push(format!(
                            "{}: rendered with the comparison's seed, so its noise is \
                             correlated with theirs",
                            path.display()
                        ));
                    }
                }
                Ok(Arc::new(reference))
            }
            ReferenceSource::Render { budget, cache_dir } => {
                let (scene, image, seed) = (&request.scene, request.image, request.seed);
                if let Some(dir) = cache_dir
                    && let Some(found) = find_cached_reference(dir, scene, image, seed, *budget)
                {
                    return Ok(Arc::new(found));
                }
                let cancel = out.cancel();
                let rendered = out
                    .install(|| render_reference(scene, image, seed, *budget, cancel, &progress));
                let Ok(mut reference) = rendered else {
                    return Err(None);
                };
                if let Some(dir) = cache_dir
                    && let Err(e) = store_reference(dir, &mut reference)
                {
                    job.notes
                        .push(format!("the reference could not be cached: {e:#}"));
                }
                Ok(Arc::new(reference))
            }
        }
    }
}
