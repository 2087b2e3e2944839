//! `portalview render`: one image, headless.

use anyhow::Result;
use clap::Args;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use super::ImageArgs;
use crate::compare::progress_bar;
use crate::light::Technique;
use crate::light::antishadow::Region;
use crate::light::{Selection, Strategy};
use crate::render::integrator::{GlassShadows, GuideBounces, Integrator, RenderSettings};
use crate::render::stats::Stats;
use crate::render::{Isa, film::Film, render_pass, tonemap};

#[derive(Args, Debug, Clone)]
pub struct RenderArgs {
    /// Built-in name (lampshade, fig8a, fig8b, fig8c, window, windows2, desklamp, livingroom,
    /// panes, pendant) or a .gltf/.glb path.
    #[arg(long, default_value = "lampshade")]
    pub scene: String,
    /// Samples per pixel (default 64 unless --seconds is given).
    #[arg(long, conflicts_with = "seconds")]
    pub spp: Option<u32>,
    /// Render whole passes until this much time is spent.
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Image width.
    #[arg(long, default_value_t = 640)]
    pub width: u32,
    #[command(flatten)]
    pub image: ImageArgs,
    /// Exposure in stops, for PNG output.
    #[arg(long, default_value_t = 0.0)]
    pub exposure: f32,
    /// The light-sampling strategy (docs/method.md): the light alone, its portals, their
    /// projection, or antishadow, which picks by the region of each shading point.
    #[arg(long, value_enum, default_value_t = Strategy::Antishadow)]
    pub strategy: Strategy,
    /// How a shading point picks the light it samples: by a tree of the lights' bounds that
    /// knows their portals, or by power alone.
    #[arg(long, value_enum, default_value_t = Selection::default())]
    pub light_selection: Selection,
    /// What shadow rays do at smooth thin glass (panes, a bulb's globe): cross it, weighted by
    /// its transmittance, or stop there as in Cycles (light then crosses glass only along
    /// BSDF paths: the same image, noisier).
    #[arg(long, value_enum, default_value_t = GlassShadows::default())]
    pub glass_shadows: GlassShadows,
    /// Whether paths continue through the portals as well as by the BSDF (guided bounces,
    /// docs/method.md §12): on finds the light bounced inside a lamp's shade; off is BSDF
    /// sampling alone. Matters from --max-depth 2 on.
    #[arg(long, value_enum, default_value_t = GuideBounces::default())]
    pub guide_bounces: GuideBounces,
    /// Replace every portal's alpha (probability of sampling the light itself).
    #[arg(long)]
    pub alpha: Option<f32>,
    /// Output: .exr (linear radiance) or .png (tone-mapped sRGB).
    #[arg(long)]
    pub out: PathBuf,
}

pub fn run(args: &RenderArgs) -> Result<()> {
    anyhow::ensure!(args.width > 0, "--width must be positive");
    anyhow::ensure!(args.spp != Some(0), "--spp must be at least 1");
    if let Some(seconds) = args.seconds {
        anyhow::ensure!(
            seconds.is_finite() && seconds > 0.0,
            "--seconds must be positive"
        );
    }
    // Before the render, not after it: a wrong name or folder must not cost a render.
    tonemap::check_image_path(&args.out)?;
    if let Some(a) = args.alpha {
        anyhow::ensure!((0.0..=1.0).contains(&a), "--alpha {a} is not in [0, 1]");
    }
    let scene = super::open_scene(&args.scene, &args.image.environment)?;
    let width = args.width;
    let height = args
        .image
        .height
        .unwrap_or_else(|| scene.camera.height_for_width(width));
    anyhow::ensure!(height > 0, "--height must be positive");
    let settings = RenderSettings {
        strategy: args.strategy,
        alpha: args.alpha,
        max_depth: args.image.max_depth,
        seed: args.image.seed,
        sampler: args.image.sampler,
        mixture: args.image.mixture,
        selection: args.light_selection,
        glass: args.glass_shadows,
        bounces: args.guide_bounces,
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

/// Renders `spp` passes with a progress bar.
pub fn render_spp(
    integrator: &Integrator,
    width: u32,
    height: u32,
    spp: u32,
) -> (Film, Stats, Duration) {
    let progress = progress_bar(
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
    let progress = progress_bar(
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
    println!(
        "renderer compiled for: {} (PORTALVIEW_ISA=baseline forces the baseline); first \
         vertices shaded in a packet's lanes: {:.1}% (staged where a material is Lambertian; \
         PORTALVIEW_INTEGRATOR=path or staged forces one)",
        Isa::detect().name(),
        100.0 * stats.lane_vertices as f64 / stats.camera_rays.max(1) as f64
    );
    let regions: Vec<String> = Region::ALL
        .iter()
        .map(|&r| format!("{} {:.1}%", r.name(), 100.0 * stats.region_share(r)))
        .collect();
    println!(
        "shading points: {}; no portal {:.1}%",
        regions.join(", "),
        100.0 * stats.no_portal as f64 / stats.shading_points().max(1) as f64
    );
    let techniques: Vec<String> = Technique::ALL
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
    if stats.nonfinite > 0 {
        println!(
            "warning: {} non-finite radiance samples were replaced by zero",
            stats.nonfinite
        );
    }
}
