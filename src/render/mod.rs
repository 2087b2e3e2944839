//! Rendering: the integrator, the film, passes over tiles, and the worker threads a UI drives.

pub mod continuation;
pub mod film;
pub mod integrator;
pub mod primary;
pub mod record;
pub mod settings;
pub mod shadows;
pub mod shell;
pub mod stats;
pub mod tonemap;
pub mod worker;

use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};

use crate::camera::RayGenerator;
pub use crate::isa::Isa;
use crate::scene::bvh::{PACKET, ShadowCache, Tracer};
use film::Film;
use integrator::{Integrator, PathContexts};
use shadows::ShadowQueue;
use stats::Stats;

/// How the tile renderer runs a packet's paths. Both give the same pixels, bit for bit
/// (`tests/core.rs`); `PORTALVIEW_INTEGRATOR=path` (or `staged`) in the environment forces one
/// for every command and the viewer, to compare the two.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Schedule {
    /// In stages over the packet (8 paths on AVX2): the camera rays together, then each
    /// path's shading and sampling, which queue their shadow rays with the contribution each
    /// carries, then the queued shadow rays, 8 at a time. Scenes with glass or volumes, whose
    /// shadow rays gather transmittance, and CPUs without AVX2 run [`Schedule::Paths`].
    Staged,
    /// Each path from the camera to its end, every ray traced where it is made: the reference.
    Paths,
}

impl Schedule {
    pub const ALL: [Schedule; 2] = [Schedule::Staged, Schedule::Paths];

    /// The schedule for `integrator`: the one `PORTALVIEW_INTEGRATOR` names (`staged` or
    /// `path`, read once; another value is reported on stderr and ignored), else staged where
    /// its scene has a material the stages shade in lanes ([`Integrator::stages_pay`]), else
    /// the reference, which is then the faster.
    pub fn detect(integrator: &Integrator) -> Schedule {
        static FORCED: std::sync::OnceLock<Option<Schedule>> = std::sync::OnceLock::new();
        let forced = FORCED.get_or_init(|| {
            let value = std::env::var_os("PORTALVIEW_INTEGRATOR")?;
            let found = Schedule::ALL.into_iter().find(|s| value == s.name());
            if found.is_none() {
                eprintln!(
                    "warning: PORTALVIEW_INTEGRATOR={}: not `staged` or `path`, ignored",
                    value.to_string_lossy()
                );
            }
            found
        });
        match (forced, integrator.stages_pay()) {
            (Some(schedule), _) => *schedule,
            (None, true) => Schedule::Staged,
            (None, false) => Schedule::Paths,
        }
    }

    /// As `PORTALVIEW_INTEGRATOR` names it.
    pub fn name(self) -> &'static str {
        match self {
            Schedule::Staged => "staged",
            Schedule::Paths => "path",
        }
    }
}

/// Side of the square tiles that threads take.
pub const TILE: u32 = 16;

/// The pass was cancelled before it finished (a newer request arrived).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("render pass cancelled")]
pub struct Cancelled;

/// The square tiles of a `width × height` image, in the order passes render them.
#[derive(Clone, Copy, Debug)]
pub struct Tiles {
    pub width: u32,
    pub height: u32,
}

impl Tiles {
    pub fn new(width: u32, height: u32) -> Self {
        Tiles { width, height }
    }

    /// Tiles in a row.
    fn across(&self) -> u32 {
        self.width.div_ceil(TILE)
    }

    pub fn count(&self) -> u32 {
        self.across() * self.height.div_ceil(TILE)
    }

    /// Top-left pixel and size of tile `tile`.
    pub fn rect(&self, tile: u32) -> (u32, u32, u32, u32) {
        let across = self.across();
        let (x0, y0) = ((tile % across) * TILE, (tile / across) * TILE);
        let (x1, y1) = ((x0 + TILE).min(self.width), (y0 + TILE).min(self.height));
        (x0, y0, x1 - x0, y1 - y0)
    }
}

/// One sample for each pixel of tile `tile`, row by row, every ray traced through `tracer`.
/// Each pixel's random numbers depend only on (sampler, seed, pass, pixel).
pub fn render_tile<T: Tracer>(
    integrator: &Integrator,
    tracer: &T,
    rays: &RayGenerator,
    tiles: Tiles,
    tile: u32,
    pass: u32,
    stats: &mut Stats,
) -> Vec<Vec3> {
    let (isa, schedule) = (Isa::detect(), Schedule::detect(integrator));
    render_tile_scheduled(
        isa, schedule, integrator, tracer, rays, tiles, tile, pass, stats,
    )
}

/// [`render_tile`] compiled for `isa` (or for the baseline if this CPU cannot run it), the
/// paths run as `schedule` says (where the scene and the CPU allow it).
#[allow(clippy::too_many_arguments)]
pub fn render_tile_scheduled<T: Tracer>(
    isa: Isa,
    schedule: Schedule,
    integrator: &Integrator,
    tracer: &T,
    rays: &RayGenerator,
    tiles: Tiles,
    tile: u32,
    pass: u32,
    stats: &mut Stats,
) -> Vec<Vec3> {
    let staged = schedule == Schedule::Staged && integrator.queues_shadows();
    if isa.available() {
        // SAFETY: each variant is called only where the CPU has its features, checked above.
        #[cfg(target_arch = "x86_64")]
        #[allow(unsafe_code)]
        match isa {
            Isa::Baseline => {}
            Isa::Avx2 => {
                // Two functions, so that each holds only its own copy of the path.
                let tile = (tiles, tile, pass);
                return match staged {
                    true => unsafe { tile_avx2::<T, true>(integrator, tracer, rays, tile, stats) },
                    false => unsafe {
                        tile_avx2::<T, false>(integrator, tracer, rays, tile, stats)
                    },
                };
            }
        }
    }
    // One camera ray at a time: packets are traced with AVX2 only.
    tile_samples::<T, 1, false>(integrator, tracer, rays, (tiles, tile, pass), stats)
}

/// [`tile_samples`] for [`Isa::Avx2`]: everything it inlines is compiled with these features.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn tile_avx2<T: Tracer, const STAGED: bool>(
    integrator: &Integrator,
    tracer: &T,
    rays: &RayGenerator,
    tile: (Tiles, u32, u32),
    stats: &mut Stats,
) -> Vec<Vec3> {
    tile_samples::<T, PACKET, STAGED>(integrator, tracer, rays, tile, stats)
}

/// The body of [`render_tile`], inlined into each instruction-set variant, which traces the
/// camera rays of `P` pixels at a time (at most [`PACKET`]) and, if `STAGED`, their paths'
/// shadow rays too ([`Schedule::Staged`], for scenes where
/// [`Integrator::queues_shadows`]).
#[inline(always)]
fn tile_samples<T: Tracer, const P: usize, const STAGED: bool>(
    integrator: &Integrator,
    tracer: &T,
    rays: &RayGenerator,
    (tiles, tile, pass): (Tiles, u32, u32),
    stats: &mut Stats,
) -> Vec<Vec3> {
    let settings = integrator.settings();
    let (x0, y0, w, h) = tiles.rect(tile);
    let size = Vec2::new(tiles.width as f32, tiles.height as f32);
    let mut pixels = Vec::with_capacity((w * h) as usize);
    // The tile's shading points lie close together: their shadow rays share blockers.
    let tracer = &ShadowCache::new(tracer);
    let samplers = settings.sampler.pass(settings.seed, pass);
    // Camera rays are traced in packets of a row's consecutive pixels, which take nearly the
    // same path through the BVH; each path then continues from its hit, pixel by pixel.
    let traced = integrator.camera_hits_traced();
    let mut queue = ShadowQueue::new();
    // The thread's light contexts, made once (copied in for every tile, a staged packet's took
    // 6% of a render): each lane of a staged packet keeps its path's until its second vertex,
    // and paths run one at a time share one more; the one-path schedule uses one.
    let mut contexts = CONTEXTS.take();
    let needed = if STAGED { P + 1 } else { 1 };
    while contexts.len() < needed {
        contexts.push(PathContexts::new());
    }
    for y in y0..y0 + h {
        for x in (x0..x0 + w).step_by(P) {
            let n = (x0 + w - x).min(P as u32) as usize;
            // A partial packet repeats its last pixel in the lanes it does not use.
            let xs = std::array::from_fn(|i| x + i.min(n - 1) as u32);
            let mut rngs: [_; P] = samplers.start_packet(xs, y, tiles.width);
            let (mut origins, mut dirs) = ([Vec3::ZERO; P], [Vec3::ZERO; P]);
            for (i, rng) in rngs.iter_mut().enumerate().take(n) {
                let jitter = rng.uniform2();
                let pixel = Vec2::new((x + i as u32) as f32, y as f32);
                (origins[i], dirs[i]) = rays.ray((pixel + jitter) / size);
            }
            let mut hits = [None; P];
            if traced {
                tracer.closest_hits(&origins[..n], &dirs[..n], 0.0, f32::INFINITY, &mut hits);
            }
            if STAGED {
                // The paths' first vertices run in lanes, each path then on its own; what
                // they gather is queued with its shadow ray, and the packet's shadow rays are
                // traced together.
                let rays: [(Vec3, Vec3); P] = std::array::from_fn(|i| (origins[i], dirs[i]));
                let mut radiance = integrator.radiance_packet(
                    tracer,
                    &rays[..n],
                    traced.then_some(&hits[..n]),
                    &mut rngs[..n],
                    stats,
                    &mut contexts,
                    &mut queue,
                );
                queue.resolve(tracer, &mut radiance[..n]);
                for &l in &radiance[..n] {
                    pixels.push(stats.finite_or_counted(l));
                }
                continue;
            }
            for (i, rng) in rngs.iter_mut().enumerate().take(n) {
                let hit = traced.then_some(hits[i]);
                let (o, d) = (origins[i], dirs[i]);
                let l = integrator.radiance_from(tracer, o, d, hit, rng, stats, &mut contexts[0]);
                pixels.push(stats.finite_or_counted(l));
            }
        }
    }
    CONTEXTS.set(contexts);
    pixels
}

thread_local! {
    /// The light contexts of a thread's paths ([`tile_samples`]), kept from tile to tile.
    static CONTEXTS: std::cell::RefCell<Vec<PathContexts>> =
        const { std::cell::RefCell::new(Vec::new()) };
}

/// One sample per pixel for a `width × height` image, tiles spread over the rayon pool; the
/// image is the same whatever the thread count. Checks `cancel` before each tile, so a pass
/// stops within one tile's work.
pub fn render_pass(
    integrator: &Integrator,
    width: u32,
    height: u32,
    pass: u32,
    cancel: &AtomicBool,
) -> Result<(Vec<Vec3>, Stats), Cancelled> {
    let tiles = Tiles::new(width, height);
    let rays = integrator.scene().camera.rays(width as f32 / height as f32);
    let bvh = &integrator.scene().geometry.bvh;
    let rendered: Vec<Option<(u32, Vec<Vec3>, Stats)>> = (0..tiles.count())
        .into_par_iter()
        .map(|tile| {
            if cancel.load(Ordering::Relaxed) {
                return None;
            }
            let mut stats = Stats::default();
            let pixels = render_tile(integrator, bvh, &rays, tiles, tile, pass, &mut stats);
            Some((tile, pixels, stats))
        })
        .collect();
    let mut image = vec![Vec3::ZERO; (width * height) as usize];
    let mut total = Stats::default();
    for entry in rendered {
        let (tile, pixels, stats) = entry.ok_or(Cancelled)?;
        let (x0, y0, w, _) = tiles.rect(tile);
        for (i, p) in pixels.into_iter().enumerate() {
            let (dx, dy) = (i as u32 % w, i as u32 / w);
            image[((y0 + dy) * width + x0 + dx) as usize] = p;
        }
        total += stats;
    }
    total.samples = 1;
    Ok((image, total))
}

/// Renders `spp` passes into a new film (tests, CLI): the film and the summed statistics.
pub fn render(integrator: &Integrator, width: u32, height: u32, spp: u32) -> (Film, Stats) {
    let mut film = Film::new(width, height);
    let mut stats = Stats::default();
    let never = AtomicBool::new(false);
    for pass in 0..spp {
        if let Ok((image, s)) = render_pass(integrator, width, height, pass, &never) {
            film.add_pass(&image);
            stats += s;
        }
    }
    (film, stats)
}
