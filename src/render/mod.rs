//! Rendering: the integrator, the film, passes over tiles, and the worker threads a UI drives.

pub mod compare_worker;
pub mod film;
pub mod integrator;
pub mod primary;
pub mod stats;
pub mod tonemap;
pub mod worker;

use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};

use crate::sampling::Rng;
use film::Film;
use integrator::Integrator;
use stats::Stats;

/// The rayon pool a background worker renders with: `threads` named `{name}-{i}` (0 = every
/// core), kept apart from the global pool so that a worker's passes never queue behind others.
pub fn worker_pool(threads: usize, name: &'static str) -> std::io::Result<rayon::ThreadPool> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .thread_name(move |i| format!("{name}-{i}"))
        .build()
        .map_err(std::io::Error::other)
}

/// Side of the square tiles that threads take.
pub const TILE: u32 = 16;

/// The pass was cancelled before it finished (a newer request arrived).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("render pass cancelled")]
pub struct Cancelled;

/// One sample per pixel for a `width × height` image. Each pixel's random numbers depend only
/// on (seed, pass, pixel), so the image is the same whatever the thread count. Checks `cancel`
/// before each tile, so a pass stops within one tile's work.
pub fn render_pass(
    integrator: &Integrator,
    width: u32,
    height: u32,
    pass: u32,
    cancel: &AtomicBool,
) -> Result<(Vec<Vec3>, Stats), Cancelled> {
    let tiles_x = width.div_ceil(TILE);
    let tiles_y = height.div_ceil(TILE);
    let rays = integrator.scene().camera.rays(width as f32 / height as f32);
    let seed = integrator.settings().seed;
    let tiles: Vec<Option<(u32, Vec<Vec3>, Stats)>> = (0..tiles_x * tiles_y)
        .into_par_iter()
        .map(|tile| {
            if cancel.load(Ordering::Relaxed) {
                return None;
            }
            let (x0, y0) = ((tile % tiles_x) * TILE, (tile / tiles_x) * TILE);
            let mut stats = Stats::default();
            let mut pixels = Vec::with_capacity((TILE * TILE) as usize);
            for y in y0..(y0 + TILE).min(height) {
                for x in x0..(x0 + TILE).min(width) {
                    let index = (y * width + x) as u64;
                    let mut rng = Rng::keyed(seed, &[pass as u64, index]);
                    let jitter = rng.uniform2();
                    let ndc = (Vec2::new(x as f32, y as f32) + jitter)
                        / Vec2::new(width as f32, height as f32);
                    let (o, d) = rays.ray(ndc);
                    let l = integrator.radiance(o, d, &mut rng, &mut stats);
                    // A NaN or infinity would poison the mean forever; drop it loudly in tests.
                    debug_assert!(l.is_finite(), "non-finite radiance at pixel {x},{y}");
                    pixels.push(if l.is_finite() { l } else { Vec3::ZERO });
                }
            }
            Some((tile, pixels, stats))
        })
        .collect();
    let mut image = vec![Vec3::ZERO; (width * height) as usize];
    let mut total = Stats::default();
    for entry in tiles {
        let (tile, pixels, stats) = entry.ok_or(Cancelled)?;
        let (x0, y0) = ((tile % tiles_x) * TILE, (tile / tiles_x) * TILE);
        let w = (x0 + TILE).min(width) - x0;
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
