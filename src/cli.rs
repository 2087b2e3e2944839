//! The command line: render, export, bench (and the viewer, by default).

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use crate::light::Strategy;
use crate::render::integrator::{Integrator, RenderSettings};
use crate::render::stats::Stats;
use crate::render::{film::Film, render_pass, tonemap};
use crate::scene::{Scene, builtin, gltf_io};

#[derive(Parser, Debug)]
#[command(
    name = "portalview",
    version,
    about = "Light portals for area lights: a viewer and a renderer"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Open the viewer (the default) on a built-in scene or a .gltf/.glb file.
    View(ViewArgs),
    /// Render an image headless.
    Render(RenderArgs),
    /// Write a built-in scene as .glb, with the portal conventions.
    Export {
        #[arg(long)]
        scene: String,
        #[arg(long)]
        out: PathBuf,
    },
    /// Measure raw BVH traversal and renderer throughput on the built-in scenes.
    Bench(BenchArgs),
    /// Render strategies for equal time and measure their error against a converged reference.
    Compare(CompareArgs),
}

#[derive(Args, Debug, Clone, Default)]
pub struct ViewArgs {
    /// Built-in name (lampshade, fig8a, fig8b, fig8c) or a .gltf/.glb path.
    pub scene: Option<String>,
    /// Start with this strategy (else the one used last).
    #[arg(long, value_enum)]
    pub strategy: Option<Strategy>,
    /// Start with this overlay over the image.
    #[arg(long, value_enum)]
    pub overlay: Option<crate::app::overlay::OverlayKind>,
    /// Draw the edges of the antishadow volumes.
    #[arg(long)]
    pub volumes: bool,
    /// Path vertices after the camera (else the value used last).
    #[arg(long)]
    pub max_depth: Option<u32>,
}

#[derive(Args, Debug, Clone)]
pub struct RenderArgs {
    /// Built-in name or a .gltf/.glb path.
    #[arg(long, default_value = "lampshade")]
    pub scene: String,
    /// Samples per pixel (default 64 unless --seconds is given).
    #[arg(long, conflicts_with = "seconds")]
    pub spp: Option<u32>,
    /// Render whole passes until this much time is spent.
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Image width (default 640).
    #[arg(long, default_value_t = 640)]
    pub width: u32,
    /// Image height (default: from the width and the camera's aspect ratio).
    #[arg(long)]
    pub height: Option<u32>,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Path vertices after the camera (1 = direct light only).
    #[arg(long, default_value_t = 1)]
    pub max_depth: u32,
    /// Exposure in stops, for PNG output.
    #[arg(long, default_value_t = 0.0)]
    pub exposure: f32,
    #[arg(long, value_enum, default_value_t = Strategy::Antishadow)]
    pub strategy: Strategy,
    /// Replace every portal's alpha (probability of sampling the light itself).
    #[arg(long)]
    pub alpha: Option<f32>,
    /// Output: .exr (linear radiance) or .png (tone-mapped sRGB).
    #[arg(long)]
    pub out: PathBuf,
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
}

/// `portalview compare`: every strategy gets the same pass render time; MSE against a reference
/// is recorded as they converge. Writes convergence.csv, convergence.svg and summary.md into
/// --out (with --figure8: one subfolder per scene, plus figure8.csv, figure8.md, figure8.svg).
#[derive(Args, Debug, Clone)]
pub struct CompareArgs {
    /// Built-in name (lampshade, fig8a, fig8b, fig8c) or a .gltf/.glb path.
    #[arg(long, required_unless_present = "figure8", conflicts_with = "figure8")]
    pub scene: Option<String>,
    /// Compare on fig8a, fig8b and fig8c (the thesis's Figure 8).
    #[arg(long)]
    pub figure8: bool,
    /// Strategies to compare, comma-separated.
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = Strategy::ALL)]
    pub strategies: Vec<Strategy>,
    /// Pass render time per strategy, in seconds (the whole run takes this times the number
    /// of strategies, plus the reference).
    #[arg(long)]
    pub seconds: f64,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long, default_value_t = 256)]
    pub width: u32,
    /// Image height (default: from the width and the camera's aspect ratio).
    #[arg(long)]
    pub height: Option<u32>,
    /// Seed of the compared renders (the reference uses another, derived from it).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Path vertices after the camera (1 = direct light only, as in the thesis).
    #[arg(long, default_value_t = 1)]
    pub max_depth: u32,
    /// A reference image (.exr of the same size) instead of rendering one; a .json sidecar
    /// beside it, as the cache writes, tells its convergence.
    #[arg(long, conflicts_with_all = ["figure8", "reference_seconds", "reference_spp"])]
    pub reference: Option<PathBuf>,
    /// Render time of the reference, with antishadow sampling [default: 10 × --seconds, so
    /// that its noise floor is about a tenth of the best strategy's MSE].
    #[arg(long, conflicts_with = "reference_spp")]
    pub reference_seconds: Option<f64>,
    /// Samples per pixel of the reference, instead of a time.
    #[arg(long)]
    pub reference_spp: Option<u32>,
    /// Where references are cached, by a hash of the scene, camera, size and depth [default:
    /// $XDG_CACHE_HOME/portalview or ~/.cache/portalview]. A cached reference is reused when
    /// it had at least the requested time or spp.
    #[arg(long)]
    pub cache_dir: Option<PathBuf>,
}

pub fn run(command: Command) -> Result<()> {
    match command {
        Command::View(args) => crate::app::run_viewer(args),
        Command::Render(args) => render(&args),
        Command::Export { scene, out } => export(&scene, &out),
        Command::Bench(args) if args.ui => crate::bench::run_ui(&args),
        Command::Bench(args) => crate::bench::run(&args),
        Command::Compare(args) => crate::compare::run(&args),
    }
}

/// The height for `width` that keeps the camera's aspect ratio.
pub fn default_height(scene: &Scene, width: u32) -> u32 {
    ((width as f32 / scene.camera.aspect.max(1e-3)).round() as u32).max(1)
}

fn render(args: &RenderArgs) -> Result<()> {
    anyhow::ensure!(args.width > 0, "--width must be positive");
    if let Some(a) = args.alpha {
        anyhow::ensure!((0.0..=1.0).contains(&a), "--alpha {a} is not in [0, 1]");
    }
    let scene = Scene::open(&args.scene)?;
    let width = args.width;
    let height = args.height.unwrap_or_else(|| default_height(&scene, width));
    anyhow::ensure!(height > 0, "--height must be positive");
    let settings = RenderSettings {
        strategy: args.strategy,
        alpha: args.alpha,
        max_depth: args.max_depth,
        seed: args.seed,
    };
    let integrator = Integrator::new(&scene, settings);
    let (film, stats, elapsed) = match args.seconds {
        Some(seconds) => render_for(&integrator, width, height, Duration::from_secs_f64(seconds)),
        None => render_spp(&integrator, width, height, args.spp.unwrap_or(64)),
    };
    tonemap::write_image(&args.out, width, height, &film.mean(), args.exposure)?;
    print_summary(&film, &stats, elapsed);
    println!("wrote {}", args.out.display());
    Ok(())
}

fn bar(len: u64, template: &str) -> ProgressBar {
    let bar = ProgressBar::new(len);
    if let Ok(style) = ProgressStyle::with_template(template) {
        bar.set_style(style);
    }
    bar
}

/// Renders `spp` passes with a progress bar.
pub fn render_spp(
    integrator: &Integrator,
    width: u32,
    height: u32,
    spp: u32,
) -> (Film, Stats, Duration) {
    let progress = bar(
        spp as u64,
        "{bar:40} {pos}/{len} spp  {elapsed_precise}  eta {eta}",
    );
    let mut film = Film::new(width, height);
    let mut stats = Stats::default();
    let never = AtomicBool::new(false);
    let start = Instant::now();
    for pass in 0..spp {
        if let Ok((image, s)) = render_pass(integrator, width, height, pass, &never) {
            film.add_pass(&image);
            stats += s;
        }
        progress.inc(1);
    }
    progress.finish_and_clear();
    (film, stats, start.elapsed())
}

/// Renders whole passes until `budget` is spent (at least one), with a progress bar.
pub fn render_for(
    integrator: &Integrator,
    width: u32,
    height: u32,
    budget: Duration,
) -> (Film, Stats, Duration) {
    let progress = bar(
        budget.as_millis() as u64,
        "{bar:40} {msg}  {elapsed_precise}",
    );
    let mut film = Film::new(width, height);
    let mut stats = Stats::default();
    let never = AtomicBool::new(false);
    let start = Instant::now();
    let mut pass = 0;
    while pass == 0 || start.elapsed() < budget {
        if let Ok((image, s)) = render_pass(integrator, width, height, pass, &never) {
            film.add_pass(&image);
            stats += s;
        }
        pass += 1;
        progress.set_position(start.elapsed().as_millis() as u64);
        progress.set_message(format!("{pass} spp"));
    }
    progress.finish_and_clear();
    (film, stats, start.elapsed())
}

fn print_summary(film: &Film, stats: &Stats, elapsed: Duration) {
    let secs = elapsed.as_secs_f64().max(1e-9);
    let samples = film.spp as f64 * film.pixel_count() as f64;
    println!(
        "{} spp in {:.2} s: {:.3} M samples/s, {:.3} M rays/s ({} shadow rays)",
        film.spp,
        secs,
        samples / secs / 1e6,
        stats.rays() as f64 / secs / 1e6,
        stats.shadow_rays
    );
    let regions: Vec<String> = crate::light::antishadow::Region::ALL
        .iter()
        .map(|&r| format!("{} {:.1}%", r.name(), 100.0 * stats.region_share(r)))
        .collect();
    println!(
        "shading points: {}; no portal {:.1}%",
        regions.join(", "),
        100.0 * stats.no_portal as f64 / stats.shading_points().max(1) as f64
    );
    let techniques: Vec<String> = crate::light::Technique::ALL
        .iter()
        .zip(stats.techniques)
        .map(|(t, n)| format!("{} {n}", t.name()))
        .chain(std::iter::once(format!("none {}", stats.empty_samples)))
        .collect();
    println!(
        "light samples by technique: {}; sampling {:.1} ns per sample",
        techniques.join(", "),
        stats.sampling_ns as f64 / stats.light_samples().max(1) as f64
    );
}

fn export(name: &str, out: &std::path::Path) -> Result<()> {
    let desc = builtin::desc(name).with_context(|| {
        format!(
            "unknown built-in scene '{name}' (built-ins: {})",
            builtin::NAMES.join(", ")
        )
    })?;
    // Validate before writing, so an export always loads back.
    Scene::from_desc(desc.clone(), name)?;
    gltf_io::export_glb(&desc, out)?;
    println!("wrote {}", out.display());
    Ok(())
}
