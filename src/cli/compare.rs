//! `portalview compare`: strategies at equal time against a reference, with reports.

use anyhow::Result;
use clap::Args;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

use super::ImageArgs;
use crate::compare::report::sci;
use crate::compare::*;
use crate::light::{Selection, Strategy};
use crate::render::integrator::{GlassShadows, GuideBounces};

/// `portalview compare`: every strategy gets the same pass render time; MSE against a reference
/// is recorded as they converge. Writes convergence.csv, convergence.svg and summary.md into
/// --out (with --figure8: one subfolder per scene, plus figure8.csv, figure8.md, figure8.svg).
#[derive(Args, Debug, Clone)]
#[command(group(clap::ArgGroup::new("what").required(true).args(["scene", "figure8"])))]
pub struct CompareArgs {
    /// Built-in name (lampshade, fig8a, fig8b, fig8c, window, windows2, desklamp, livingroom,
    /// panes, pendant) or a .gltf/.glb path.
    #[arg(long, conflicts_with = "figure8")]
    pub scene: Option<String>,
    /// Compare on fig8a, fig8b and fig8c (the thesis's Figure 8).
    #[arg(long)]
    pub figure8: bool,
    /// Strategies to compare, comma-separated.
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = Strategy::ALL)]
    pub strategies: Vec<Strategy>,
    /// How the compared renders pick lights, comma-separated: with two, every strategy is
    /// rendered with each, side by side at equal time, each selection's files in
    /// --out/SELECTION, and the efficiency of the second over the first printed per strategy.
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [Selection::Tree])]
    pub light_selection: Vec<Selection>,
    /// What shadow rays do at smooth thin glass, comma-separated: with two (`pass,stop`),
    /// every strategy is rendered with each, side by side at equal time, each one's files in
    /// --out/glass-pass and --out/glass-stop, and the efficiency of the second over the first
    /// printed per strategy. Stop is what Cycles does.
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [GlassShadows::Pass])]
    pub glass_shadows: Vec<GlassShadows>,
    /// Whether paths continue through the portals as well as by the BSDF (guided bounces,
    /// docs/method.md §12), comma-separated: with two (`on,off`), every strategy is rendered
    /// with each, side by side at equal time, each one's files in --out/guide-on and
    /// --out/guide-off, and the efficiency of the second over the first printed per strategy.
    /// Matters from --max-depth 2 on (a bounce must lead to a vertex that gathers light).
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [GuideBounces::On])]
    pub guide_bounces: Vec<GuideBounces>,
    /// Pass render time per strategy, in seconds (the whole run takes this times the number
    /// of strategies, plus the reference).
    #[arg(long)]
    pub seconds: f64,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    /// Image width.
    #[arg(long, default_value_t = 256)]
    pub width: u32,
    /// Height, seed (the reference uses another, derived from it) and depth.
    #[command(flatten)]
    pub image: ImageArgs,
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
    /// Replace every portal's and window's alpha (probability of sampling the light or the
    /// environment itself) in the compared renders; the reference keeps the scene's.
    #[arg(long)]
    pub alpha: Option<f32>,
    /// Repeat the comparison this many times, with seeds --seed, --seed + 1, …, against the
    /// same reference, and report each strategy's efficiency as the mean over the runs ± its
    /// standard error (one run's ratio moves by several per cent from seed to seed). Each run's
    /// files go into --out/seed-S; runs.md and runs.csv into --out.
    #[arg(long, default_value_t = 1, conflicts_with = "figure8")]
    pub runs: u32,
    /// Where references are cached, by a hash of the scene, camera, size and depth [default:
    /// $XDG_CACHE_HOME/portalview or ~/.cache/portalview]. A cached reference is reused when
    /// it had at least the requested time or spp.
    #[arg(long)]
    pub cache_dir: Option<PathBuf>,
}

/// The built-in scenes of `--figure8`.
pub const FIGURE8_SCENES: [&str; 3] = ["fig8a", "fig8b", "fig8c"];

/// A reference budget's default: ten times one strategy's time, so that the reference's
/// noise floor is about a tenth of the best strategy's MSE.
pub const DEFAULT_REFERENCE_FACTOR: f64 = 10.0;

/// `portalview compare`.
pub fn run(args: &CompareArgs) -> Result<()> {
    anyhow::ensure!(
        args.seconds.is_finite() && args.seconds > 0.0,
        "--seconds {} must be positive",
        args.seconds
    );
    anyhow::ensure!(args.width > 0, "--width must be positive");
    if let Some(a) = args.alpha {
        anyhow::ensure!((0.0..=1.0).contains(&a), "--alpha {a} is not in [0, 1]");
    }
    anyhow::ensure!(!args.strategies.is_empty(), "--strategies lists none");
    anyhow::ensure!(
        !args.light_selection.is_empty(),
        "--light-selection lists none"
    );
    anyhow::ensure!(!args.glass_shadows.is_empty(), "--glass-shadows lists none");
    anyhow::ensure!(!args.guide_bounces.is_empty(), "--guide-bounces lists none");
    let varied = [
        args.light_selection.len(),
        args.glass_shadows.len(),
        args.guide_bounces.len(),
    ]
    .iter()
    .filter(|&&n| n > 1)
    .count();
    anyhow::ensure!(
        !args.figure8 || varied == 0,
        "--figure8 takes one --light-selection, one --glass-shadows and one --guide-bounces"
    );
    anyhow::ensure!(
        varied <= 1,
        "compare one of --light-selection, --glass-shadows and --guide-bounces at a time"
    );
    for (i, s) in args.light_selection.iter().enumerate() {
        anyhow::ensure!(
            !args.light_selection[..i].contains(s),
            "--light-selection lists {} twice",
            s.name()
        );
    }
    for (i, g) in args.glass_shadows.iter().enumerate() {
        anyhow::ensure!(
            !args.glass_shadows[..i].contains(g),
            "--glass-shadows lists {} twice",
            g.label()
        );
    }
    for (i, g) in args.guide_bounces.iter().enumerate() {
        anyhow::ensure!(
            !args.guide_bounces[..i].contains(g),
            "--guide-bounces lists {} twice",
            g.label()
        );
    }
    anyhow::ensure!(args.runs > 0, "--runs must be at least 1");
    for (i, s) in args.strategies.iter().enumerate() {
        anyhow::ensure!(
            !args.strategies[..i].contains(s),
            "--strategies lists {} twice",
            s.name()
        );
    }
    let budget = match (args.reference_seconds, args.reference_spp) {
        (_, Some(n)) => ReferenceBudget::Spp(n),
        (Some(s), None) => {
            anyhow::ensure!(
                s.is_finite() && s > 0.0,
                "--reference-seconds {s} must be positive"
            );
            ReferenceBudget::Seconds(s)
        }
        (None, None) => ReferenceBudget::Seconds(DEFAULT_REFERENCE_FACTOR * args.seconds),
    };
    let names: Vec<String> = if args.figure8 {
        FIGURE8_SCENES.iter().map(|&s| s.to_owned()).collect()
    } else {
        match &args.scene {
            Some(s) => vec![s.clone()],
            None => anyhow::bail!("give --scene (a built-in name or a glTF file) or --figure8"),
        }
    };
    let cache_dir = args.cache_dir.clone().or_else(default_cache_dir);
    let mut comparisons = Vec::new();
    let mut written = Vec::new();
    for name in &names {
        let mut scene = super::open_scene(name, &args.image.environment)?;
        if scene.name.is_empty() {
            scene.name = name.clone();
        }
        let height = args
            .image
            .height
            .unwrap_or_else(|| scene.camera.height_for_width(args.width));
        anyhow::ensure!(height > 0, "--height must be positive");
        let image = ImageSpec {
            width: args.width,
            height,
            max_depth: args.image.max_depth,
        };
        eprintln!(
            "{}: {}x{} px, reference",
            scene.name, image.width, image.height
        );
        // Its length is milliseconds or samples by the budget: the message says the samples.
        let progress = progress_bar(0, "reference {bar:40} {msg}  {elapsed_precise}");
        let reference = match (&args.reference, &cache_dir) {
            (Some(file), _) => load_reference(file, image.width, image.height)?,
            (None, Some(dir)) => {
                cached_reference(dir, &scene, image, args.image.seed, budget, &progress)?
            }
            (None, None) => {
                eprintln!(
                    "no cache folder (set XDG_CACHE_HOME or HOME, or --cache-dir): not caching"
                );
                let never = AtomicBool::new(false);
                render_reference(&scene, image, args.image.seed, budget, &never, &progress)
                    .map_err(|e| anyhow::anyhow!("{}: {e}", scene.name))?
            }
        };
        progress.finish_and_clear();
        if let (Some(file), Some(info)) = (&args.reference, &reference.info) {
            if info.key != cache_key(&scene, image) {
                eprintln!(
                    "warning: {}: its sidecar says it was rendered for another scene, camera or \
                     depth ({})",
                    file.display(),
                    info.key
                );
            }
            if info.seed == args.image.seed {
                eprintln!(
                    "warning: {}: rendered with the same seed as the comparison, so its noise \
                     is correlated with theirs (use another --seed)",
                    file.display()
                );
            }
        }
        let seeds: Vec<u64> = (0..u64::from(args.runs))
            .map(|k| args.image.seed.wrapping_add(k))
            .collect();
        if let Some(info) = reference
            .info
            .as_ref()
            .filter(|i| seeds[1..].contains(&i.seed))
        {
            eprintln!(
                "warning: {}: the reference was rendered with seed {}, which one of the runs \
                 uses too, so its noise is correlated with that run's (use another --seed)",
                scene.name, info.seed
            );
        }
        if let Some(info) = &reference.info {
            eprintln!(
                "{}: reference {} spp in {:.1} s, mean relative standard error {:.3}%, MSE floor {}",
                scene.name,
                info.spp,
                info.seconds,
                100.0 * info.convergence.mean_relative_standard_error,
                sci(info.convergence.mse_floor)
            );
        }
        let dir = if args.figure8 {
            args.out.join(&scene.name)
        } else {
            args.out.clone()
        };
        let variants = Variant::all(
            &args.light_selection,
            &args.glass_shadows,
            &args.guide_bounces,
        );
        // Per variant, its folder and its runs (one per seed).
        let dirs: Vec<PathBuf> = variants
            .iter()
            .map(|v| match variants.len() {
                1 => dir.clone(),
                _ => dir.join(v.folder()),
            })
            .collect();
        let mut runs: Vec<Vec<SceneComparison>> = vec![Vec::new(); variants.len()];
        for &seed in &seeds {
            let settings: Vec<CompareSettings> = variants
                .iter()
                .map(|v| CompareSettings {
                    strategies: args.strategies.clone(),
                    seconds: args.seconds,
                    image,
                    seed,
                    sampler: args.image.sampler,
                    mixture: args.image.mixture,
                    selection: v.selection,
                    glass: v.glass,
                    bounces: v.bounces,
                    alpha: args.alpha,
                })
                .collect();
            let progress = progress_bar(0, "{bar:40} {msg}  {elapsed_precise}");
            let each = compare_each(&scene, &settings, &reference, &progress);
            progress.finish_and_clear();
            for (((comparison, dir), runs), variant) in
                each.into_iter().zip(&dirs).zip(&mut runs).zip(&variants)
            {
                let label = match variants.len() {
                    1 => String::new(),
                    _ => format!("{}: ", variant.label()),
                };
                if seeds.len() == 1 {
                    written.extend(write_scene_outputs(dir, &comparison)?);
                    println!("{label}{}", summary_markdown(&comparison));
                } else {
                    written.extend(write_scene_outputs(
                        &dir.join(format!("seed-{seed}")),
                        &comparison,
                    )?);
                    println!("{label}{}", run_line(&comparison));
                }
                runs.push(comparison);
            }
        }
        for (runs, dir) in runs.iter().zip(&dirs) {
            if runs.len() > 1 {
                written.extend(write_runs_outputs(dir, runs)?);
                println!("\n{}", runs_markdown(runs));
            }
        }
        if let ([first, second], [a, b]) = (&runs[..], &variants[..]) {
            println!("\n{}", variant_ratios((a, first), (b, second)));
        }
        comparisons.extend(runs.into_iter().flatten());
    }
    if args.figure8 {
        written.extend(write_figure8_outputs(&args.out, &comparisons)?);
        println!("{}", figure8_markdown(&comparisons));
    }
    for path in written {
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// One of the configurations `compare` renders side by side: a light selection, what shadow
/// rays do at glass and whether bounces are guided (at most one of the three varies).
#[derive(Clone, Copy, Debug)]
struct Variant {
    selection: Selection,
    glass: GlassShadows,
    bounces: GuideBounces,
    /// Which of the three varies.
    varies: Varies,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Varies {
    Selection,
    Glass,
    Bounces,
}

impl Variant {
    fn all(
        selections: &[Selection],
        glass: &[GlassShadows],
        bounces: &[GuideBounces],
    ) -> Vec<Variant> {
        let varies = if glass.len() > 1 {
            Varies::Glass
        } else if bounces.len() > 1 {
            Varies::Bounces
        } else {
            Varies::Selection
        };
        let mut all = Vec::new();
        for &selection in selections {
            for &glass in glass {
                for &bounces in bounces {
                    all.push(Variant {
                        selection,
                        glass,
                        bounces,
                        varies,
                    });
                }
            }
        }
        all
    }

    fn folder(&self) -> String {
        match self.varies {
            Varies::Glass => format!("glass-{}", self.glass.label()),
            Varies::Bounces => format!("guide-{}", self.bounces.label()),
            Varies::Selection => self.selection.name().to_owned(),
        }
    }

    fn label(&self) -> String {
        match self.varies {
            Varies::Glass => format!("shadow rays at glass {}", self.glass.label()),
            Varies::Bounces => format!("guided bounces {}", self.bounces.label()),
            Varies::Selection => format!("light selection {}", self.selection.name()),
        }
    }
}

/// Per strategy, the efficiency of the second variant's render over the first's, both
/// rendered side by side: per seed `e_2 / e_1` (`e = 1 / (MSE × seconds)`, and from the MSE
/// less the reference's floor), then the mean over the seeds ± its standard error.
fn variant_ratios(
    (a_variant, first): (&Variant, &[SceneComparison]),
    (b_variant, second): (&Variant, &[SceneComparison]),
) -> String {
    let Some(a) = first.first() else {
        return String::new();
    };
    let mut out = format!(
        "Efficiency of {} over {}, side by side at equal time ({} run{}):\n\n\
         | strategy | efficiency ratio | from MSE − floor |\n|---|---:|---:|\n",
        b_variant.label(),
        a_variant.label(),
        first.len(),
        if first.len() == 1 { "" } else { "s" }
    );
    for &strategy in &a.settings.strategies {
        let ratios = |floor: bool| -> Vec<f64> {
            first
                .iter()
                .zip(second)
                .filter_map(|(x, y)| {
                    let find = |c: &SceneComparison| {
                        c.results
                            .iter()
                            .find(|r| r.strategy == strategy)
                            .and_then(|r| {
                                if floor {
                                    r.mse_above_floor.map(|e| 1.0 / (e * r.seconds))
                                } else {
                                    Some(r.efficiency)
                                }
                            })
                    };
                    Some(find(y)? / find(x)?).filter(|v| v.is_finite())
                })
                .collect()
        };
        let show = |v: Vec<f64>| match v.len() {
            0 => "–".to_owned(),
            1 => format!("{}×", ratio(v[0])),
            n => {
                let mean = v.iter().sum::<f64>() / n as f64;
                let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
                format!("{}× ± {}", ratio(mean), ratio((var / n as f64).sqrt()))
            }
        };
        out.push_str(&format!(
            "| {} | {} | {} |\n",
            strategy.name(),
            show(ratios(false)),
            show(ratios(true))
        ));
    }
    out
}

/// A ratio with two decimals, or three significant digits where two decimals would hide it
/// (stopping shadow rays at glass can cost a factor of thousands).
fn ratio(v: f64) -> String {
    if v != 0.0 && (v.abs() < 0.01 || v.abs() >= 1000.0) {
        format!("{v:.2e}")
    } else {
        format!("{v:.2}")
    }
}

/// One run of `--runs`, in a line: each strategy's spp and efficiency over light sampling's.
fn run_line(c: &SceneComparison) -> String {
    let parts: Vec<String> = c
        .results
        .iter()
        .map(|r| {
            let ratio = |v: Option<f64>| v.map_or("–".to_owned(), |v| format!("{v:.3}×"));
            format!(
                "{} {} spp, {} ({} above the floor)",
                r.strategy.name(),
                r.spp,
                ratio(r.efficiency_vs_light),
                ratio(r.efficiency_vs_light_above_floor)
            )
        })
        .collect();
    format!("{} seed {}: {}", c.scene, c.settings.seed, parts.join("; "))
}
