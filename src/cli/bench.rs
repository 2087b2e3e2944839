//! `portalview bench`: the renderer's bare traversal against the whole renderer, and the cost
//! of each strategy, on the built-in scenes; and the bare traversal of rays read from files
//! (another renderer's). Multithreaded like the renderer, so the rays/s compare.

use anyhow::{Context, Result};
use glam::Vec3;
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use clap::Args;

use super::render::render_for;
use crate::asset::builtin;
use crate::compare::{
    ImageSpec, ReferenceBudget, TimeToError, cached_reference, default_cache_dir, error_at_spp,
    render_reference, time_to_error,
};
use crate::isa::Isa;
use crate::light::{Selection, Strategy};
use crate::render::integrator::{Integrator, RenderSettings};
use crate::render::record::{RecordedRay, record_pass};
use crate::render::stats::Stats;
use crate::render::{Tiles, render_tile};
use crate::sampling::SamplerKind;
use crate::scene::Scene;
use crate::scene::bvh::{Bvh, PACKET, Traversal};

/// How a replay traces its rays: through which tree, and one at a time or in packets of
/// [`PACKET`] consecutive rays (as the renderer traces its camera rays, and as Mitsuba hands its
/// rays to Embree).
#[derive(Clone, Copy, Debug)]
struct Replay {
    traversal: Traversal,
    packets: bool,
}

impl Replay {
    /// The renderer's traversal, one ray at a time.
    const SINGLE: Replay = Replay {
        traversal: Traversal::Wide,
        packets: false,
    };
}

/// Rays per second of the raw traversal over the recorded rays that `keep` selects, tiles
/// spread over all cores as the renderer spreads them, repeated for `budget`.
fn replay(
    bvh: &Bvh,
    tiles: &[Vec<RecordedRay>],
    budget: Duration,
    mode: Replay,
    keep: impl Fn(&RecordedRay) -> bool + Sync,
) -> f64 {
    let isa = Isa::detect();
    let start = Instant::now();
    let mut count = 0usize;
    let mut sink = 0.0f32;
    while start.elapsed() < budget {
        let (n, s) = tiles
            .par_iter()
            .map(|tile| trace_tile_isa(isa, bvh, tile, mode, &keep))
            .reduce(|| (0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
        count += n;
        sink += s;
    }
    // Keep the traversal from being optimised away.
    std::hint::black_box(sink);
    count as f64 / start.elapsed().as_secs_f64()
}

/// [`trace_tile`] compiled for `isa` where this CPU runs it, as the renderer is
/// (`render::render_tile_scheduled`): the raw side gets the same instructions as the renderer's.
fn trace_tile_isa(
    isa: Isa,
    bvh: &Bvh,
    tile: &[RecordedRay],
    mode: Replay,
    keep: &impl Fn(&RecordedRay) -> bool,
) -> (usize, f32) {
    if isa == Isa::Avx2 && isa.available() {
        // SAFETY: called only where the CPU has the variant's features, checked above.
        #[cfg(target_arch = "x86_64")]
        #[allow(unsafe_code)]
        return unsafe { trace_tile_avx2(bvh, tile, mode, keep) };
    }
    trace_tile(bvh, tile, mode, keep)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn trace_tile_avx2(
    bvh: &Bvh,
    tile: &[RecordedRay],
    mode: Replay,
    keep: &impl Fn(&RecordedRay) -> bool,
) -> (usize, f32) {
    trace_tile(bvh, tile, mode, keep)
}

/// The rays of one tile that `keep` selects: their count, and a sum of their answers that the
/// optimiser cannot drop. In packets, runs of consecutive rays of one kind and one `tmin` (and,
/// for closest hits, one `tmax`) are traced together.
#[inline(always)]
fn trace_tile(
    bvh: &Bvh,
    tile: &[RecordedRay],
    mode: Replay,
    keep: &impl Fn(&RecordedRay) -> bool,
) -> (usize, f32) {
    let (mut n, mut sum) = (0, 0.0);
    let one = |r: &RecordedRay| {
        if r.closest {
            bvh.raw_closest_t(mode.traversal, r.origin, r.dir, r.tmin, r.tmax)
                .min(1e30)
        } else {
            bvh.raw_occluded(mode.traversal, r.origin, r.dir, r.tmin, r.tmax) as u8 as f32
        }
    };
    if !mode.packets {
        for r in tile.iter().filter(|r| keep(r)) {
            n += 1;
            sum += one(r);
        }
        return (n, sum);
    }
    for chunk in tile.chunks(PACKET) {
        let first = &chunk[0];
        let together = chunk.iter().all(|r| {
            keep(r)
                && r.closest == first.closest
                && r.tmin == first.tmin
                && (!r.closest || r.tmax == first.tmax)
        });
        if !together {
            for r in chunk.iter().filter(|r| keep(r)) {
                n += 1;
                sum += one(r);
            }
            continue;
        }
        let origins: [Vec3; PACKET] =
            std::array::from_fn(|i| chunk.get(i).map_or(Vec3::ZERO, |r| r.origin));
        let dirs: [Vec3; PACKET] = std::array::from_fn(|i| chunk.get(i).map_or(Vec3::X, |r| r.dir));
        let k = chunk.len();
        n += k;
        if first.closest {
            let mut hits = [None; PACKET];
            bvh.closest_hits(
                &origins[..k],
                &dirs[..k],
                first.tmin,
                first.tmax,
                &mut hits[..k],
            );
            sum += hits.iter().flatten().map(|h| h.t.min(1e30)).sum::<f32>();
        } else {
            let tmaxes: [f32; PACKET] =
                std::array::from_fn(|i| chunk.get(i).map_or(0.0, |r| r.tmax));
            let mut blocked = [false; PACKET];
            bvh.occluded_each(
                &origins[..k],
                &dirs[..k],
                first.tmin,
                &tmaxes[..k],
                &mut blocked[..k],
            );
            sum += blocked.iter().filter(|&&b| b).count() as f32;
        }
    }
    (n, sum)
}

#[derive(Args, Debug, Clone)]
pub struct BenchArgs {
    /// Seconds per measurement.
    #[arg(long, default_value_t = 2.0)]
    pub seconds: f64,
    /// Image size for the render measurements.
    #[arg(long, default_value_t = 256)]
    pub size: u32,
    /// Measure the viewer instead (headless): UI frame time while the renderer saturates the
    /// CPU, and the time from a portal edit to the first new preview.
    #[arg(long)]
    pub ui: bool,
    /// Which measurements: throughput (traversal, samples/s, the cost of textures),
    /// convergence (MSE at equal spp per sampler, time to the target relMSE), textures (only
    /// their cost: each built-in scene with and without textures), tiles (the cost of a sample
    /// on one thread, robust to other load: each tile's fastest of `--repeats` renders), rays
    /// (raw traversal of rays read from files: `--rays-scene`, `--closest-rays`,
    /// `--occlusion-rays`), portals (the time to find and check portals), or all (everything
    /// but tiles, rays and portals).
    #[arg(long, value_enum, default_value_t = BenchPart::All)]
    pub only: BenchPart,
    /// The relMSE that "time to an equal error" waits for.
    #[arg(long, default_value_t = 1e-4)]
    pub target_relmse: f64,
    /// Pass time after which a run that has not reached the target is stopped and its time
    /// extrapolated (as relMSE ∝ 1/time).
    #[arg(long, default_value_t = 20.0)]
    pub cap_seconds: f64,
    /// Samples per pixel of the MSE-at-equal-spp comparison of the samplers.
    #[arg(long, default_value_t = 64)]
    pub mse_spp: u32,
    /// Samples per pixel of the references (antishadow, independent samples, cached in the
    /// cache folder of `portalview compare`).
    #[arg(long, default_value_t = 4096)]
    pub reference_spp: u32,
    /// Where references are cached [default: $XDG_CACHE_HOME/portalview or
    /// ~/.cache/portalview].
    #[arg(long)]
    pub cache_dir: Option<std::path::PathBuf>,
    /// Renders of each tile in `--only tiles`, finds and checks of each scene in `--only
    /// portals`; the fastest counts.
    #[arg(long, default_value_t = 5)]
    pub repeats: u32,
    /// With `--only rays`: the scene (built-in name or glTF file) to trace the rays through.
    #[arg(long)]
    pub rays_scene: Option<String>,
    /// With `--only rays`: closest-hit rays, as little-endian f32 records of 8 values
    /// (origin x y z, direction x y z, tmin, tmax).
    #[arg(long)]
    pub closest_rays: Option<PathBuf>,
    /// With `--only rays`: occlusion rays, records as for `--closest-rays`.
    #[arg(long)]
    pub occlusion_rays: Option<PathBuf>,
}

/// The parts of `portalview bench`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum BenchPart {
    All,
    Throughput,
    Convergence,
    Textures,
    Tiles,
    /// Raw traversal of rays read from files (`--rays-scene`, `--closest-rays`,
    /// `--occlusion-rays`): another renderer's rays, traced as portalview traces its own.
    Rays,
    /// The time to find portals (each built-in with its portals removed) and to check them
    /// (with its own), and both in `livingroom` with a million more triangles.
    Portals,
}

/// `portalview bench`: raw traversal against the renderer, each strategy's cost, and each
/// strategy's and sampler's error at equal spp and time to an equal error.
pub fn run(args: &BenchArgs) -> Result<()> {
    if args.only == BenchPart::Textures {
        return textures(args.size, Duration::from_secs_f64(args.seconds));
    }
    if args.only == BenchPart::Tiles {
        return tiles(args.size, args.repeats);
    }
    if args.only == BenchPart::Rays {
        return rays_from_files(args);
    }
    if args.only == BenchPart::Portals {
        return portals(args.repeats);
    }
    if args.only != BenchPart::Convergence {
        throughput(args)?;
    }
    if args.only != BenchPart::Throughput {
        convergence(args)?;
    }
    Ok(())
}

/// Values per record of a ray file: origin, direction, tmin, tmax.
const RAY_RECORD_FLOATS: usize = 8;

/// Rays a file holds as little-endian f32 records (origin x y z, direction x y z, tmin,
/// tmax): closest-hit queries if `closest`, else occlusion queries.
fn read_ray_file(path: &Path, closest: bool) -> Result<Vec<RecordedRay>> {
    let bytes =
        std::fs::read(path).with_context(|| format!("{}: cannot read rays", path.display()))?;
    let record = RAY_RECORD_FLOATS * 4;
    anyhow::ensure!(
        bytes.len() % record == 0,
        "{}: {} bytes is not a whole number of {record}-byte ray records (origin, direction, tmin, tmax as little-endian f32)",
        path.display(),
        bytes.len()
    );
    let mut rays = Vec::with_capacity(bytes.len() / record);
    for (i, chunk) in bytes.chunks_exact(record).enumerate() {
        let mut v = [0.0f32; RAY_RECORD_FLOATS];
        for (value, b) in v.iter_mut().zip(chunk.chunks_exact(4)) {
            *value = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        }
        let ray = RecordedRay {
            origin: Vec3::new(v[0], v[1], v[2]),
            dir: Vec3::new(v[3], v[4], v[5]),
            tmin: v[6],
            tmax: v[7],
            closest,
        };
        anyhow::ensure!(
            ray.origin.is_finite()
                && ray.dir.is_finite()
                && ray.dir != Vec3::ZERO
                && ray.tmin.is_finite()
                && ray.tmin <= ray.tmax,
            "{}: ray {i} is not a ray (origin {}, direction {}, tmin {}, tmax {})",
            path.display(),
            ray.origin,
            ray.dir,
            ray.tmin,
            ray.tmax
        );
        rays.push(ray);
    }
    Ok(rays)
}

/// `--only rays`: the raw traversal's rays/s (one ray at a time, as in the throughput table)
/// over rays another renderer traced, in the files' order, spread over all cores in runs of
/// [`RAY_FILE_TILE`] rays.
fn rays_from_files(args: &BenchArgs) -> Result<()> {
    let name = args
        .rays_scene
        .as_deref()
        .context("--only rays needs --rays-scene")?;
    anyhow::ensure!(
        args.closest_rays.is_some() || args.occlusion_rays.is_some(),
        "--only rays needs --closest-rays or --occlusion-rays"
    );
    let scene = Scene::open(name).with_context(|| format!("{name}: cannot open the scene"))?;
    let bvh = &scene.geometry.bvh;
    let budget = Duration::from_secs_f64(args.seconds);
    println!(
        "portalview bench --only rays: {name}, {} threads, {:.1} s per measurement",
        rayon::current_num_threads(),
        args.seconds
    );
    println!(
        "layout: {} triangles, {:.1} bytes per triangle",
        bvh.triangle_count(),
        bvh.bytes_per_triangle()
    );
    for (path, closest) in [(&args.closest_rays, true), (&args.occlusion_rays, false)] {
        let Some(path) = path else {
            continue;
        };
        let rays = read_ray_file(path, closest)?;
        let tiles: Vec<Vec<RecordedRay>> = rays.chunks(RAY_FILE_TILE).map(<[_]>::to_vec).collect();
        let answered = rays
            .iter()
            .filter(|r| {
                if closest {
                    bvh.closest_hit(r.origin, r.dir, r.tmin, r.tmax).is_some()
                } else {
                    bvh.occluded(r.origin, r.dir, r.tmin, r.tmax)
                }
            })
            .count();
        let kind = if closest { "closest-hit" } else { "occlusion" };
        // Side by side in one run: the layout in packets (as Mitsuba hands its rays to
        // Embree), one at a time (as the renderer traces shadow rays), and obvhs's traversal
        // one at a time (the renderer's before the layout).
        for (label, mode) in [
            (
                "",
                Replay {
                    traversal: Traversal::Wide,
                    packets: true,
                },
            ),
            (" one at a time", Replay::SINGLE),
            (
                " obvhs",
                Replay {
                    traversal: Traversal::Cwbvh,
                    packets: false,
                },
            ),
        ] {
            let rate = replay(bvh, &tiles, budget, mode, |_| true);
            println!(
                "{kind}{label}: {} rays, {answered} {}, {:.1} Mrays/s",
                rays.len(),
                if closest { "hit" } else { "occluded" },
                rate / 1e6
            );
        }
    }
    Ok(())
}

/// Rays per task of `--only rays`.
const RAY_FILE_TILE: usize = 4096;

/// The cost of one sample on one thread, per built-in scene and strategy, with lights picked by
/// power and by the tree: every tile of a `size²` image (pass 0) is rendered `repeats` times in
/// this thread by each selection in turn (each first in every other round), and the fastest
/// time of each tile counts. On a machine shared with other work, a tile's fastest render
/// (about a millisecond) is rarely disturbed, where a whole render's rate moves by tens of
/// percent; alternating the two selections tile by tile puts them side by side.
/// The fastest of `repeats` calls of `f`, in seconds.
fn fastest(repeats: u32, mut f: impl FnMut()) -> f64 {
    (0..repeats.max(1))
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

/// Times `portals::find` on each built-in without its portals and `portals::check` with them,
/// then both in `livingroom` under a rug of a million triangles.
fn portals(repeats: u32) -> Result<()> {
    use crate::scene::portals::{check, find};
    println!("| scene | triangles | find (s) | check (s) | portals found |");
    println!("|---|---:|---:|---:|---:|");
    let mut scenes: Vec<(String, Scene)> = builtin::NAMES
        .iter()
        .map(|&name| Ok((name.to_owned(), Scene::open(name)?)))
        .collect::<Result<_>>()?;
    scenes.push((
        "livingroom + 1M-triangle rug".to_owned(),
        million_triangle_room()?,
    ));
    for (name, scene) in scenes {
        let bare = scene.with_portals(Vec::new())?;
        let mut found = 0;
        let find_seconds = fastest(repeats, || found = find(&bare).portals.len());
        let check_seconds = fastest(repeats, || {
            check(&scene, 0);
        });
        println!(
            "| {name} | {} | {find_seconds:.3} | {check_seconds:.3} | {found} |",
            scene.geometry.triangles.len()
        );
    }
    Ok(())
}

/// `livingroom` with a rug of 1,000,000 triangles (a 500 × 1000 grid of quads) on its floor.
fn million_triangle_room() -> Result<Scene> {
    let mut desc = builtin::desc("livingroom").context("the livingroom built-in")?;
    let (nx, nz) = (500usize, 1000usize);
    let (x0, x1, z0, z1, y) = (-2.0f32, 2.0f32, -1.0f32, 3.0f32, 0.002f32);
    let at = |i: usize, j: usize| {
        Vec3::new(
            x0 + (x1 - x0) * i as f32 / nx as f32,
            y,
            z0 + (z1 - z0) * j as f32 / nz as f32,
        )
    };
    let quads: Vec<Vec<Vec3>> = (0..nx)
        .flat_map(|i| (0..nz).map(move |j| (i, j)))
        .map(|(i, j)| vec![at(i, j), at(i, j + 1), at(i + 1, j + 1), at(i + 1, j)])
        .collect();
    desc.meshes.push(builtin::flat_mesh("rug", 0, &quads));
    Ok(Scene::from_desc(desc, "livingroom + rug")?)
}

fn tiles(size: u32, repeats: u32) -> Result<()> {
    anyhow::ensure!(
        repeats > 0 && size > 0,
        "--repeats and --size must be positive"
    );
    println!(
        "Cost of a sample on one thread, {size}x{size} px, each tile's fastest of {repeats} renders"
    );
    println!();
    println!(
        "| scene | strategy | ns per sample, power | ns per sample, tree | tree / power | \
         M samples/s per thread, tree |"
    );
    println!("|---|---|---:|---:|---:|---:|");
    let grid = Tiles::new(size, size);
    for name in builtin::NAMES {
        let scene = Scene::open(name)?;
        let rays = scene.camera.rays(1.0);
        let bvh = &scene.geometry.bvh;
        for strategy in Strategy::ALL {
            let integrators = [Selection::Power, Selection::Tree].map(|selection| {
                Integrator::new(
                    &scene,
                    RenderSettings {
                        strategy,
                        selection,
                        ..RenderSettings::default()
                    },
                )
            });
            let mut stats = Stats::default();
            // Warm-up (the BSDF's albedo table is built on first use).
            for integrator in &integrators {
                std::hint::black_box(render_tile(integrator, bvh, &rays, grid, 0, 0, &mut stats));
            }
            let mut fastest = [(); 2].map(|_| vec![Duration::MAX; grid.count() as usize]);
            for round in 0..repeats {
                for tile in 0..grid.count() {
                    // Each goes first in every other round: whichever runs first warms caches.
                    let order = if round % 2 == 0 { [0, 1] } else { [1, 0] };
                    for k in order {
                        let (integrator, best) = (&integrators[k], &mut fastest[k]);
                        let start = Instant::now();
                        let pixels = render_tile(integrator, bvh, &rays, grid, tile, 0, &mut stats);
                        let best = &mut best[tile as usize];
                        *best = (*best).min(start.elapsed());
                        std::hint::black_box(pixels);
                    }
                }
            }
            let [power, tree] = fastest
                .map(|f| f.iter().sum::<Duration>().as_secs_f64() * 1e9 / f64::from(size * size));
            println!(
                "| {name} | {} | {power:.1} | {tree:.1} | {:.3} | {:.3} |",
                strategy.name(),
                tree / power,
                1e3 / tree
            );
        }
    }
    Ok(())
}

/// Per built-in scene, strategy and sampler: MSE and relMSE at `--mse-spp` against the cached
/// reference, and the time to reach `--target-relmse`.
fn convergence(args: &BenchArgs) -> Result<()> {
    anyhow::ensure!(
        args.target_relmse > 0.0 && args.cap_seconds > 0.0 && args.mse_spp > 0,
        "--target-relmse, --cap-seconds and --mse-spp must be positive"
    );
    let cache_dir = args.cache_dir.clone().or_else(default_cache_dir);
    let image = ImageSpec {
        width: args.size,
        height: args.size,
        max_depth: 1,
    };
    let budget = ReferenceBudget::Spp(args.reference_spp);
    println!();
    println!(
        "Error against the reference ({} spp, antishadow, independent samples), {}x{} px, direct light: MSE at {} spp per sampler, and the pass time to relMSE <= {:.1e} (stopped at {:.0} s, then extrapolated as relMSE ~ 1/time, marked ~)",
        args.reference_spp,
        args.size,
        args.size,
        args.mse_spp,
        args.target_relmse,
        args.cap_seconds
    );
    println!();
    println!(
        "| scene | strategy | MSE independent | MSE sobol | MSE ratio | time to target, independent | time to target, sobol | speed-up |"
    );
    println!("|---|---|---:|---:|---:|---:|---:|---:|");
    for name in builtin::NAMES {
        let scene = Scene::open(name)?;
        // Named, and on stderr even when the tables are piped: this takes minutes per scene.
        eprintln!("{name}: reference, {} spp", args.reference_spp);
        let progress = crate::compare::progress_bar(
            0,
            &format!("{name}: reference {{bar:40}} {{pos}}/{{len}} spp  {{elapsed_precise}}"),
        );
        let reference = match &cache_dir {
            Some(dir) => cached_reference(dir, &scene, image, 0, budget, &progress)?,
            None => {
                let never = std::sync::atomic::AtomicBool::new(false);
                render_reference(&scene, image, 0, budget, &never, &progress)
                    .map_err(|e| anyhow::anyhow!("{name}: {e}"))?
            }
        };
        progress.finish_and_clear();
        if let Some(info) = &reference.info
            && info.convergence.relmse_floor > 0.25 * args.target_relmse
        {
            eprintln!(
                "warning: {name}: the reference's relMSE floor {:.1e} is not far below the target {:.1e} (raise --reference-spp)",
                info.convergence.relmse_floor, args.target_relmse
            );
        }
        for strategy in Strategy::ALL {
            let settings = |sampler| RenderSettings {
                strategy,
                sampler,
                ..RenderSettings::default()
            };
            let [independent, sobol] = SamplerKind::ALL.map(|sampler| {
                let at_spp = error_at_spp(&scene, settings(sampler), &reference, args.mse_spp);
                let timed = time_to_error(
                    &scene,
                    settings(sampler),
                    &reference,
                    args.target_relmse,
                    args.cap_seconds,
                );
                (at_spp, timed)
            });
            let time = |t: &TimeToError| {
                let s = t.estimated_seconds(args.target_relmse);
                let mark = if t.reached { "" } else { "~" };
                format!("{mark}{s:.2} s ({} spp)", t.spp)
            };
            println!(
                "| {name} | {} | {:.3e} | {:.3e} | {:.2}x | {} | {} | {:.2}x |",
                strategy.name(),
                independent.0.0,
                sobol.0.0,
                independent.0.0 / sobol.0.0,
                time(&independent.1),
                time(&sobol.1),
                independent.1.estimated_seconds(args.target_relmse)
                    / sobol.1.estimated_seconds(args.target_relmse),
            );
        }
    }
    Ok(())
}

/// Raw traversal against the renderer, and each strategy's cost (samples/s).
fn throughput(args: &BenchArgs) -> Result<()> {
    let budget = Duration::from_secs_f64(args.seconds);
    println!(
        "portalview bench: {} threads, {}x{} px, {:.1} s per measurement",
        rayon::current_num_threads(),
        args.size,
        args.size,
        args.seconds
    );
    println!();
    println!(
        "| scene | triangles | raw closest-hit Mrays/s | raw occlusion Mrays/s | raw, all rays Mrays/s | renderer (light) Mrays/s | renderer / raw |"
    );
    println!("|---|---|---|---|---|---|---|");
    for name in builtin::NAMES {
        let scene = Scene::open(name)?;
        let bvh = &scene.geometry.bvh;
        let integrator = Integrator::new(
            &scene,
            RenderSettings {
                strategy: Strategy::Light,
                ..RenderSettings::default()
            },
        );
        // The raw side traces exactly the rays of the renderer's first pass, in its order.
        let (recorded, counted) = record_pass(&integrator, args.size);
        let traced: usize = recorded.iter().map(Vec::len).sum();
        anyhow::ensure!(
            traced as u64 == counted,
            "{name}: the renderer traced {traced} rays but counted {counted}"
        );
        let closest = replay(bvh, &recorded, budget, Replay::SINGLE, |r| r.closest);
        let occlusion = replay(bvh, &recorded, budget, Replay::SINGLE, |r| !r.closest);
        let raw = replay(bvh, &recorded, budget, Replay::SINGLE, |_| true);
        let (_, stats, elapsed) = render_for(&integrator, args.size, args.size, budget);
        let renderer = stats.rays() as f64 / elapsed.as_secs_f64();
        println!(
            "| {name} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.0}% |",
            bvh.triangle_count(),
            closest / 1e6,
            occlusion / 1e6,
            raw / 1e6,
            renderer / 1e6,
            100.0 * renderer / raw
        );
    }
    println!();
    println!("| scene | strategy | M samples/s | ns per light sample | shadow rays per sample |");
    println!("|---|---|---|---|---|");
    for name in builtin::NAMES {
        let scene = Scene::open(name)?;
        for strategy in Strategy::ALL {
            let integrator = Integrator::new(
                &scene,
                RenderSettings {
                    strategy,
                    ..RenderSettings::default()
                },
            );
            let (film, stats, elapsed) = render_for(&integrator, args.size, args.size, budget);
            let samples = film.spp as f64 * film.pixel_count() as f64;
            println!(
                "| {name} | {} | {:.3} | {:.0} | {:.2} |",
                strategy.name(),
                samples / elapsed.as_secs_f64() / 1e6,
                stats.sampling_ns as f64 / stats.light_samples().max(1) as f64,
                stats.shadow_rays as f64 / samples,
            );
        }
    }
    textures(args.size, budget)
}

/// The cost of texture lookups: each built-in scene with and without procedural textures
/// (base colour, roughness, normal map; `builtin::with_test_textures`), antishadow strategy,
/// direct light and three bounces.
fn textures(size: u32, budget: Duration) -> Result<()> {
    println!();
    println!(
        "| scene | bounces | untextured M samples/s | textured M samples/s | textured / untextured |"
    );
    println!("|---|---|---|---|---|");
    for name in builtin::NAMES {
        let Some(desc) = builtin::desc(name) else {
            continue;
        };
        let plain = Scene::from_desc(desc.clone(), name)?;
        let textured = Scene::from_desc(builtin::with_test_textures(desc), name)?;
        for max_depth in [1, 3] {
            let rate = |scene: &Scene| {
                let settings = RenderSettings {
                    max_depth,
                    ..RenderSettings::default()
                };
                let integrator = Integrator::new(scene, settings);
                let (film, _, elapsed) = render_for(&integrator, size, size, budget);
                film.spp as f64 * film.pixel_count() as f64 / elapsed.as_secs_f64() / 1e6
            };
            let (untextured, with_textures) = (rate(&plain), rate(&textured));
            println!(
                "| {name} | {max_depth} | {untextured:.3} | {with_textures:.3} | {:.0}% |",
                100.0 * with_textures / untextured
            );
        }
    }
    Ok(())
}

/// The viewer, headless: egui frames at 60 Hz on a 1280×800 screen while the worker renders
/// the lampshade with every core, then portal edits timed to their first preview frame.
pub fn run_ui(args: &BenchArgs) -> Result<()> {
    use crate::app::PortalViewApp;
    let ctx = egui::Context::default();
    let mut app = PortalViewApp::new(&ctx, None, Some("lampshade".into()))?;
    let input = || egui::RawInput {
        screen_rect: Some(egui::Rect::from_min_size(
            egui::Pos2::ZERO,
            egui::vec2(1280.0, 800.0),
        )),
        ..Default::default()
    };
    // One UI frame: layout and painting (`show`), then tessellation, as eframe does before
    // handing triangles to the GPU.
    let frame = |app: &mut PortalViewApp| {
        let start = Instant::now();
        let output = ctx.run_ui(input(), |ui| app.show(ui));
        std::hint::black_box(ctx.tessellate(output.shapes, output.pixels_per_point));
        start.elapsed()
    };
    let warm = Instant::now();
    while app.frame().is_none_or(|f| f.preview) && warm.elapsed() < Duration::from_secs(30) {
        frame(&mut app);
        std::thread::sleep(Duration::from_millis(16));
    }
    let budget = Duration::from_secs_f64(args.seconds.max(1.0));
    let mut times = Vec::new();
    let start = Instant::now();
    while start.elapsed() < budget {
        times.push(frame(&mut app).as_secs_f64() * 1e3);
        std::thread::sleep(Duration::from_millis(16));
    }
    times.sort_by(f64::total_cmp);
    let spp = app.frame().map_or(0, |f| f.spp);
    println!(
        "UI frame time over {} frames while rendering ({spp} spp reached): mean {:.2} ms, median {:.2} ms, 95th percentile {:.2} ms, max {:.2} ms",
        times.len(),
        times.iter().sum::<f64>() / times.len().max(1) as f64,
        percentile(&times, 0.5),
        percentile(&times, 0.95),
        percentile(&times, 1.0),
    );
    // Portal edits: nudge the top portal and wait for the preview of the new placement.
    let mut latencies = Vec::new();
    for k in 0..20 {
        let Some(mut pose) = app.editor.pose(0) else {
            break;
        };
        pose.center.x += if k % 2 == 0 { 0.01 } else { -0.01 };
        app.editor.set_pose(0, pose);
        app.apply_portal_edit();
        app.first_frame_latency = None;
        let edited = Instant::now();
        while app.first_frame_latency.is_none() && edited.elapsed() < Duration::from_secs(10) {
            frame(&mut app);
            std::thread::sleep(Duration::from_millis(2));
        }
        latencies.push(edited.elapsed().as_secs_f64() * 1e3);
        // Let full-resolution passes run between edits, as between a user's drags.
        let settle = Instant::now();
        while settle.elapsed() < Duration::from_millis(300) {
            frame(&mut app);
            std::thread::sleep(Duration::from_millis(16));
        }
    }
    latencies.sort_by(f64::total_cmp);
    println!(
        "portal edit to first preview over {} edits: median {:.1} ms, 95th percentile {:.1} ms, max {:.1} ms",
        latencies.len(),
        percentile(&latencies, 0.5),
        percentile(&latencies, 0.95),
        percentile(&latencies, 1.0),
    );
    Ok(())
}

/// The `q` quantile of sorted values (nearest rank).
fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len()) - 1]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(path: &Path, values: &[f32]) {
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        std::fs::write(path, bytes).unwrap();
    }

    #[test]
    fn ray_files_read_back_and_bad_ones_are_named() {
        let dir = std::env::temp_dir().join(format!("portalview-ray-file-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let good = dir.join("good.rays");
        let rays = [
            [0.0, 1.0, 5.0, 0.0, 0.0, -1.0, 0.0, f32::INFINITY],
            [0.5, 0.25, 2.0, 0.0, -1.0, 0.0, 1e-4, 3.0],
        ];
        write(&good, rays.as_flattened());
        let read = read_ray_file(&good, false).unwrap();
        assert_eq!(read.len(), 2);
        for (r, v) in read.iter().zip(&rays) {
            assert_eq!(r.origin, Vec3::new(v[0], v[1], v[2]));
            assert_eq!(r.dir, Vec3::new(v[3], v[4], v[5]));
            assert_eq!((r.tmin, r.tmax, r.closest), (v[6], v[7], false));
        }

        // A truncated record: the file and the record layout are named.
        let short = dir.join("short.rays");
        write(&short, &rays.as_flattened()[..11]);
        let message = format!("{:#}", read_ray_file(&short, true).unwrap_err());
        assert!(
            message.contains("short.rays") && message.contains("32-byte ray records"),
            "{message}"
        );

        // A record that is not a ray: the file and the ray's number.
        let bad = dir.join("bad.rays");
        let mut values = rays.as_flattened().to_vec();
        values[8 + 3..8 + 6].fill(0.0);
        write(&bad, &values);
        let message = format!("{:#}", read_ray_file(&bad, true).unwrap_err());
        assert!(
            message.contains("bad.rays") && message.contains("ray 1 "),
            "{message}"
        );

        let missing = format!(
            "{:#}",
            read_ray_file(&dir.join("none.rays"), true).unwrap_err()
        );
        assert!(missing.contains("none.rays"), "{missing}");

        // End to end on a built-in scene (the form `bench/peers/mitsuba_rays.py` reads).
        let args = BenchArgs {
            seconds: 0.01,
            size: 16,
            ui: false,
            only: BenchPart::Rays,
            target_relmse: 1e-4,
            cap_seconds: 1.0,
            mse_spp: 1,
            reference_spp: 1,
            cache_dir: None,
            repeats: 1,
            rays_scene: Some("fig8a".into()),
            closest_rays: Some(good.clone()),
            occlusion_rays: Some(good),
        };
        rays_from_files(&args).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
