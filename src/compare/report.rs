//! What `portalview compare` writes: CSV, Markdown and SVG, and the number formats and
//! strategy colours the viewer shares.

use anyhow::{Context, Result};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::equal_time::{ConvergencePoint, SceneComparison, StrategyResult};
use super::metrics::RELMSE_EPSILON;
use super::reference::{ReferenceInfo, ReferenceOrigin};
use crate::light::Strategy;

/// A number in scientific notation with four significant digits, or a dash.
pub fn sci(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.3e}")
    } else {
        "–".to_owned()
    }
}

/// Each strategy's colour, the same in every plot, table and legend (sRGB).
pub fn strategy_rgb(strategy: Strategy) -> [u8; 3] {
    match strategy {
        Strategy::Light => [31, 119, 180],
        Strategy::Portal => [255, 127, 14],
        Strategy::Projection => [44, 160, 44],
        Strategy::Antishadow => [214, 39, 40],
    }
}

/// A tick label on a log axis: plain between 0.01 and 1000 (trailing zeros dropped), else
/// `1e-5` style.
pub fn tick_label(v: f64) -> String {
    if (0.01..1000.0).contains(&v.abs()) {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_owned()
    } else {
        format!("{v:.0e}")
    }
}

/// Plot colours by strategy.
fn colour(strategy: Strategy) -> plotters::style::RGBColor {
    let [r, g, b] = strategy_rgb(strategy);
    plotters::style::RGBColor(r, g, b)
}

/// Writes `contents` atomically, as an error naming the file.
fn write_file(path: &Path, contents: &[u8]) -> Result<()> {
    crate::io::write_atomic(path, contents)
        .with_context(|| format!("{}: cannot write", path.display()))
}

/// A CSV field, quoted when it needs to be.
fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_owned()
    }
}

/// `scene,strategy,seconds,spp,mse,relmse`, one row per recorded point, grouped by strategy
/// (in the comparison's order), by time within each.
pub fn convergence_csv(c: &SceneComparison) -> String {
    let mut out = String::from("scene,strategy,seconds,spp,mse,relmse\n");
    let scene = csv_field(&c.scene);
    let mut points: Vec<&ConvergencePoint> = c.points.iter().collect();
    points.sort_by_key(|p| c.settings.strategies.iter().position(|&s| s == p.strategy));
    for p in points {
        let _ = writeln!(
            out,
            "{scene},{},{:.6},{},{:e},{:e}",
            p.strategy.name(),
            p.seconds,
            p.spp,
            p.mse,
            p.relmse
        );
    }
    out
}

/// `scene,strategy,seconds,mse,efficiency_vs_light`, one row per scene and strategy at the end
/// (an empty efficiency where light sampling was not compared).
pub fn figure8_csv(comparisons: &[SceneComparison]) -> String {
    let mut out = String::from("scene,strategy,seconds,mse,efficiency_vs_light\n");
    for c in comparisons {
        for r in &c.results {
            let efficiency = r
                .efficiency_vs_light
                .map(|e| format!("{e:.6}"))
                .unwrap_or_default();
            let _ = writeln!(
                out,
                "{},{},{:.6},{:e},{efficiency}",
                csv_field(&c.scene),
                r.strategy.name(),
                r.seconds,
                r.mse
            );
        }
    }
    out
}

fn ratio(v: Option<f64>) -> String {
    match v {
        Some(v) if v >= 0.1 => format!("{v:.2}×"),
        Some(v) => format!("{v:.2e}×"),
        None => "–".to_owned(),
    }
}

/// Markdown lines on the reference's origin and convergence.
fn reference_markdown(info: Option<&ReferenceInfo>, origin: &ReferenceOrigin) -> String {
    let mut out = String::new();
    let from = match origin {
        ReferenceOrigin::Rendered(Some(p)) => format!("rendered now, cached as `{}`", p.display()),
        ReferenceOrigin::Rendered(None) => "rendered now (not cached)".to_owned(),
        ReferenceOrigin::Cached(p) => format!("loaded from the cache, `{}`", p.display()),
        ReferenceOrigin::File(p) => format!("loaded from `{}`", p.display()),
    };
    let _ = writeln!(out, "Reference: {from}.");
    match info {
        Some(i) => {
            let c = &i.convergence;
            let _ = writeln!(
                out,
                "{} sampling, {} spp in {:.1} s (seed {:#x}). Mean relative standard error of \
                 its pixels: {:.3}%. Its noise floor, {} in MSE and {} in relMSE, is included \
                 in every measured error above (the MSE − floor columns take it out): errors \
                 within a few times the floor are limited by the reference.",
                i.strategy.name(),
                i.spp,
                i.seconds,
                i.seed,
                100.0 * c.mean_relative_standard_error,
                sci(c.mse_floor),
                sci(c.relmse_floor)
            );
        }
        None => {
            let _ = writeln!(
                out,
                "Its convergence is unknown (no sidecar JSON beside it)."
            );
        }
    }
    out
}

/// The per-scene summary: one row per strategy, then the reference's convergence.
pub fn summary_markdown(c: &SceneComparison) -> String {
    let s = &c.settings;
    let mut out = String::new();
    let _ = writeln!(out, "# Equal-time comparison: {}\n", c.scene);
    let _ = writeln!(
        out,
        "{}×{} px, max depth {}, seed {}, {} s of pass render time per strategy.\n",
        s.image.width, s.image.height, s.image.max_depth, s.seed, s.seconds
    );
    let floor = c.reference_info.as_ref().map(|i| i.convergence.mse_floor);
    out.push_str(
        "| strategy | spp | seconds | MSE | MSE − floor | relMSE | efficiency vs light | \
         (MSE − floor) | MSE / reference floor | MSE in worst 1 % px | bulk MSE |\n",
    );
    out.push_str("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for r in &c.results {
        let over_floor = floor.filter(|&f| f > 0.0).map(|f| r.mse / f);
        let _ = writeln!(
            out,
            "| {} | {} | {:.2} | {} | {} | {} | {} | {} | {} | {:.0} % | {} |",
            r.strategy.name(),
            r.spp,
            r.seconds,
            sci(r.mse),
            r.mse_above_floor.map_or("–".to_owned(), sci),
            sci(r.relmse),
            ratio(r.efficiency_vs_light),
            ratio(r.efficiency_vs_light_above_floor),
            over_floor.map_or("–".to_owned(), |v| format!("{v:.1}")),
            100.0 * r.worst_share,
            sci(r.bulk_mse)
        );
    }
    let _ = writeln!(
        out,
        "\nEfficiency is 1 / (MSE × seconds), relative to light sampling's: above 1 is better. \
         The reference's noise is independent of the compared images', so the measured MSE is \
         the true MSE plus the reference's floor: MSE − floor estimates the true MSE without \
         bias, and the efficiency from it is what a perfect reference would show (– where the \
         MSE is within the floor). relMSE = mean of (x − r)² / (r² + {RELMSE_EPSILON}) over \
         pixels and channels. MSE in worst 1 % px: the share of the squared error in the 1 % \
         of pixels with the most (about 1 % for evenly spread noise; near 100 % where a few \
         fireflies carry the error, which the mean hides). Bulk MSE: the MSE without the \
         worst 0.1 % of pixels, the error of what a user looks at.\n"
    );
    out.push_str(&reference_markdown(
        c.reference_info.as_ref(),
        &c.reference_origin,
    ));
    out
}

/// One run's ratio of efficiencies moves by several per cent from seed to seed (README): a
/// strategy is named the most efficient only when it is ahead of the next by more than this.
const CLEAR_LEAD: f64 = 1.1;

/// Which strategy of `c` is the most efficient, if one run can tell: the best, if it leads the
/// next by more than [`CLEAR_LEAD`]; otherwise those within it of the best, as a tie (two
/// strategies that render the same image differ only by timing noise).
fn verdict(c: &SceneComparison) -> Option<String> {
    let mut ranked: Vec<&StrategyResult> = c
        .results
        .iter()
        .filter(|r| r.efficiency.is_finite())
        .collect();
    ranked.sort_by(|a, b| b.efficiency.total_cmp(&a.efficiency));
    let best = ranked.first()?;
    let close: Vec<&str> = ranked
        .iter()
        .filter(|r| best.efficiency <= CLEAR_LEAD * r.efficiency)
        .map(|r| r.strategy.name())
        .collect();
    Some(if close.len() == 1 {
        format!("most efficient is {}.", best.strategy.name())
    } else {
        format!(
            "{} are within {:.0}% of each other: one run cannot tell them apart (use --runs).",
            close.join(", "),
            100.0 * (CLEAR_LEAD - 1.0)
        )
    })
}

/// The Figure 8 summary: one row per scene and strategy, the best per scene, the references.
pub fn figure8_markdown(comparisons: &[SceneComparison]) -> String {
    let mut out = String::from("# Figure 8: equal-time MSE of each strategy\n\n");
    if let Some(c) = comparisons.first() {
        let s = &c.settings;
        let _ = writeln!(
            out,
            "{}×{} px, max depth {}, seed {}, {} s of pass render time per strategy.\n",
            s.image.width, s.image.height, s.image.max_depth, s.seed, s.seconds
        );
    }
    out.push_str(
        "| scene | strategy | spp | seconds | MSE | MSE − floor | efficiency vs light | \
         (MSE − floor) |\n",
    );
    out.push_str("|---|---|---:|---:|---:|---:|---:|---:|\n");
    for c in comparisons {
        for r in &c.results {
            let _ = writeln!(
                out,
                "| {} | {} | {} | {:.2} | {} | {} | {} | {} |",
                c.scene,
                r.strategy.name(),
                r.spp,
                r.seconds,
                sci(r.mse),
                r.mse_above_floor.map_or("–".to_owned(), sci),
                ratio(r.efficiency_vs_light),
                ratio(r.efficiency_vs_light_above_floor)
            );
        }
    }
    out.push_str(
        "\nEfficiency is 1 / (MSE × seconds), relative to light sampling's; the (MSE − floor) \
         column takes the reference's noise floor out of both errors first.\n\n",
    );
    for c in comparisons {
        if let Some(line) = verdict(c) {
            let _ = writeln!(out, "- {}: {line}", c.scene);
        }
    }
    for c in comparisons {
        let _ = write!(out, "\n## {}\n\n", c.scene);
        out.push_str(&reference_markdown(
            c.reference_info.as_ref(),
            &c.reference_origin,
        ));
    }
    out
}

/// A log range covering `values` (positive, finite ones only), padded a little.
fn log_range(values: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (lo, hi) = values
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if lo > hi {
        return 0.1..1.0;
    }
    let (lo, hi) = if hi / lo < 1.5 {
        (lo / 1.5, hi * 1.5)
    } else {
        (lo, hi)
    };
    lo / 1.2..hi * 1.2
}

type PlotError = Box<dyn std::error::Error>;

/// Draws one log–log chart of MSE against seconds, a line per strategy, on `area`.
fn draw_convergence<DB: plotters::prelude::DrawingBackend>(
    area: &plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    c: &SceneComparison,
) -> Result<(), PlotError>
where
    DB::ErrorType: 'static,
{
    use plotters::prelude::*;
    let x = log_range(c.points.iter().map(|p| p.seconds));
    let y = log_range(c.points.iter().map(|p| p.mse));
    let mut chart = ChartBuilder::on(area)
        .caption(
            format!("{}: MSE at equal time", c.scene),
            ("sans-serif", 20),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(x.log_scale(), y.log_scale())?;
    chart
        .configure_mesh()
        .x_desc("seconds of render time")
        .y_desc("MSE")
        .x_label_formatter(&|v| tick_label(*v))
        .y_label_formatter(&|v| tick_label(*v))
        .draw()?;
    for &strategy in &c.settings.strategies {
        let style = colour(strategy).stroke_width(2);
        let line: Vec<(f64, f64)> = c
            .points
            .iter()
            .filter(|p| p.strategy == strategy && p.seconds > 0.0 && p.mse > 0.0)
            .map(|p| (p.seconds, p.mse))
            .collect();
        chart
            .draw_series(LineSeries::new(line, style))?
            .label(strategy.name())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}

/// An SVG of one log–log chart per comparison, side by side.
pub fn convergence_svg(comparisons: &[SceneComparison]) -> Result<String> {
    use plotters::prelude::*;
    let mut svg = String::new();
    {
        let panels = comparisons.len().max(1);
        let root =
            SVGBackend::with_string(&mut svg, (640 * panels as u32, 480)).into_drawing_area();
        let drawn: Result<(), PlotError> = (|| {
            root.fill(&WHITE)?;
            for (area, c) in root.split_evenly((1, panels)).iter().zip(comparisons) {
                draw_convergence(area, c)?;
            }
            root.present()?;
            Ok(())
        })();
        drawn.map_err(|e| anyhow::anyhow!("cannot draw the plot: {e}"))?;
    }
    Ok(svg)
}

/// The mean of a quantity over repeated runs, with the standard error of that mean.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeanSe {
    pub mean: f64,
    /// The sample standard deviation over √n: `None` for a single run.
    pub se: Option<f64>,
    pub min: f64,
    pub max: f64,
}

impl MeanSe {
    /// `None` for no values.
    pub fn of(values: &[f64]) -> Option<Self> {
        if values.is_empty() {
            return None;
        }
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let se = (values.len() > 1).then(|| {
            let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
            (var / n).sqrt()
        });
        Some(MeanSe {
            mean,
            se,
            min: values.iter().copied().fold(f64::INFINITY, f64::min),
            max: values.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        })
    }

    /// `0.919× ± 0.005 (0.880–0.960)`, or the value alone for one run.
    fn ratio_text(&self) -> String {
        match self.se {
            Some(se) => format!(
                "{:.3}× ± {se:.3} ({:.3}–{:.3})",
                self.mean, self.min, self.max
            ),
            None => format!("{:.3}×", self.mean),
        }
    }
}

/// One strategy over the runs of [`runs_rows`].
#[derive(Clone, Debug, PartialEq)]
pub struct RunsRow {
    pub strategy: Strategy,
    pub runs: usize,
    pub spp: MeanSe,
    /// Efficiency over light sampling's, per run; `None` without light sampling.
    pub efficiency_vs_light: Option<MeanSe>,
    /// The same from the MSE less the reference's floor; `None` unless every run has it (a
    /// mean over only the runs above the floor would favour the noisier ones).
    pub efficiency_vs_light_above_floor: Option<MeanSe>,
}

/// Each strategy's samples and efficiency over repeated comparisons of one scene (the same
/// strategies, other seeds): one run's efficiency ratio moves by several per cent from seed to
/// seed, so a difference of that size needs the mean and its standard error.
pub fn runs_rows(runs: &[SceneComparison]) -> Vec<RunsRow> {
    let Some(first) = runs.first() else {
        return Vec::new();
    };
    first
        .settings
        .strategies
        .iter()
        .filter_map(|&strategy| {
            let results: Vec<_> = runs
                .iter()
                .filter_map(|c| c.results.iter().find(|r| r.strategy == strategy))
                .collect();
            let spp: Vec<f64> = results.iter().map(|r| r.spp as f64).collect();
            let all = |f: fn(&StrategyResult) -> Option<f64>| {
                let v: Option<Vec<f64>> = results.iter().map(|&r| f(r)).collect();
                v.and_then(|v| MeanSe::of(&v))
            };
            Some(RunsRow {
                strategy,
                runs: results.len(),
                spp: MeanSe::of(&spp)?,
                efficiency_vs_light: all(|r| r.efficiency_vs_light),
                efficiency_vs_light_above_floor: all(|r| r.efficiency_vs_light_above_floor),
            })
        })
        .collect()
}

/// `seed,strategy,spp,seconds,mse,mse_above_floor,efficiency_vs_light,efficiency_vs_light_above_floor`,
/// one row per run and strategy (empty fields where a value is unknown).
pub fn runs_csv(runs: &[SceneComparison]) -> String {
    let mut out = String::from(
        "seed,strategy,spp,seconds,mse,mse_above_floor,efficiency_vs_light,\
         efficiency_vs_light_above_floor\n",
    );
    let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:e}"));
    for c in runs {
        for r in &c.results {
            let _ = writeln!(
                out,
                "{},{},{},{:.6},{:e},{},{},{}",
                c.settings.seed,
                r.strategy.name(),
                r.spp,
                r.seconds,
                r.mse,
                opt(r.mse_above_floor),
                opt(r.efficiency_vs_light),
                opt(r.efficiency_vs_light_above_floor)
            );
        }
    }
    out
}

/// The summary of repeated comparisons of one scene: per strategy the mean spp and the mean
/// efficiency over light sampling's, each ± its standard error over the runs.
pub fn runs_markdown(runs: &[SceneComparison]) -> String {
    let mut out = String::new();
    let Some(first) = runs.first() else {
        return out;
    };
    let s = &first.settings;
    let seeds: Vec<String> = runs.iter().map(|c| c.settings.seed.to_string()).collect();
    let _ = writeln!(
        out,
        "# Equal-time comparison over {} runs: {}\n",
        runs.len(),
        first.scene
    );
    let _ = writeln!(
        out,
        "{}×{} px, max depth {}, {} s of pass render time per strategy and run, seeds {}, \
         one reference.\n",
        s.image.width,
        s.image.height,
        s.image.max_depth,
        s.seconds,
        seeds.join(", ")
    );
    out.push_str(
        "| strategy | runs | spp | efficiency vs light | (MSE − floor) |\n|---|---:|---:|---:|---:|\n",
    );
    let text = |m: Option<MeanSe>| m.map_or("–".to_owned(), |m| m.ratio_text());
    for row in runs_rows(runs) {
        let spp = match row.spp.se {
            Some(se) => format!("{:.1} ± {se:.1}", row.spp.mean),
            None => format!("{:.0}", row.spp.mean),
        };
        let _ = writeln!(
            out,
            "| {} | {} | {spp} | {} | {} |",
            row.strategy.name(),
            row.runs,
            text(row.efficiency_vs_light),
            text(row.efficiency_vs_light_above_floor)
        );
    }
    out.push_str(
        "\nEach efficiency is one run's 1 / (MSE × seconds) over light sampling's in the same \
         run, then averaged over the runs: mean ± standard error of the mean (sample standard \
         deviation over √runs), and the lowest and highest run. The runs share the reference, \
         so its noise floor is common to them: the (MSE − floor) column takes it out of every \
         run (– unless every run's MSE is above the floor).\n",
    );
    out
}

/// Writes each `(file name, contents)` into `dir` (created if needed); the paths written.
fn write_files(dir: &Path, files: &[(&str, String)]) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    files
        .iter()
        .map(|(name, contents)| {
            let path = dir.join(name);
            write_file(&path, contents.as_bytes())?;
            Ok(path)
        })
        .collect()
}

/// Writes `runs.csv` and `runs.md` into `dir`.
pub fn write_runs_outputs(dir: &Path, runs: &[SceneComparison]) -> Result<Vec<PathBuf>> {
    write_files(
        dir,
        &[
            ("runs.csv", runs_csv(runs)),
            ("runs.md", runs_markdown(runs)),
        ],
    )
}

/// Writes `convergence.csv`, `convergence.svg` and `summary.md` into `dir`.
pub fn write_scene_outputs(dir: &Path, c: &SceneComparison) -> Result<Vec<PathBuf>> {
    let plot = convergence_svg(std::slice::from_ref(c))
        .with_context(|| dir.join("convergence.svg").display().to_string())?;
    write_files(
        dir,
        &[
            ("convergence.csv", convergence_csv(c)),
            ("convergence.svg", plot),
            ("summary.md", summary_markdown(c)),
        ],
    )
}

/// Writes `figure8.csv`, `figure8.md` and `figure8.svg` into `dir`.
pub fn write_figure8_outputs(dir: &Path, comparisons: &[SceneComparison]) -> Result<Vec<PathBuf>> {
    let plot = convergence_svg(comparisons)
        .with_context(|| dir.join("figure8.svg").display().to_string())?;
    write_files(
        dir,
        &[
            ("figure8.csv", figure8_csv(comparisons)),
            ("figure8.md", figure8_markdown(comparisons)),
            ("figure8.svg", plot),
        ],
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compare::metrics::{Convergence, mse_above_floor};
    use crate::compare::{CompareSettings, ImageSpec, StrategyResult, set_efficiency_ratios};
    use crate::render::stats::Stats;

    fn result(strategy: Strategy, mse: f64, floor: f64) -> StrategyResult {
        StrategyResult {
            strategy,
            spp: 10,
            seconds: 2.0,
            mse,
            relmse: mse,
            efficiency: 1.0 / (mse * 2.0),
            efficiency_vs_light: None,
            mse_above_floor: mse_above_floor(mse, Some(floor)),
            efficiency_vs_light_above_floor: None,
            worst_share: 0.01,
            bulk_mse: mse,
            stats: Stats::default(),
        }
    }

    fn comparison(floor: f64, antishadow_mse: f64) -> SceneComparison {
        let mut results = vec![
            result(Strategy::Light, 5e-5, floor),
            result(Strategy::Antishadow, antishadow_mse, floor),
        ];
        set_efficiency_ratios(&mut results);
        SceneComparison {
            scene: "window".to_owned(),
            settings: CompareSettings {
                strategies: vec![Strategy::Light, Strategy::Antishadow],
                seconds: 2.0,
                image: ImageSpec {
                    width: 4,
                    height: 3,
                    max_depth: 1,
                },
                seed: 0,
                sampler: Default::default(),
                mixture: Default::default(),
                selection: Default::default(),
                glass: Default::default(),
                bounces: Default::default(),
                alpha: None,
            },
            reference_info: Some(ReferenceInfo {
                key: "window-0".to_owned(),
                scene: "window".to_owned(),
                width: 4,
                height: 3,
                max_depth: 1,
                strategy: Strategy::Antishadow,
                seed: 1,
                spp: 100,
                seconds: 20.0,
                convergence: Convergence {
                    mean_relative_standard_error: 0.01,
                    mse_floor: floor,
                    relmse_floor: floor,
                },
            }),
            reference_origin: ReferenceOrigin::Rendered(None),
            points: Vec::new(),
            results,
        }
    }

    /// Light at 5e-5 and antishadow at 2e-5 over a floor of 1e-5: 2.5× raw, 4× (4e-5 / 1e-5)
    /// with the floor out. Negative case: at a floor of 0 the two columns agree, and an MSE
    /// within the floor shows a dash instead of an efficiency.
    #[test]
    fn the_summary_gives_raw_and_floor_subtracted_efficiency() {
        let c = comparison(1e-5, 2e-5);
        let a = &c.results[1];
        assert!((a.efficiency_vs_light.unwrap_or(0.0) - 2.5).abs() < 1e-9);
        assert!((a.efficiency_vs_light_above_floor.unwrap_or(0.0) - 4.0).abs() < 1e-9);
        let md = summary_markdown(&c);
        assert!(md.contains("| MSE − floor |"), "{md}");
        let row = md
            .lines()
            .find(|l| l.starts_with("| antishadow"))
            .unwrap_or_default();
        assert!(
            row.contains("| 1.000e-5 |") && row.contains("| 2.50× | 4.00× |"),
            "{row}"
        );
        let f8 = figure8_markdown(std::slice::from_ref(&c));
        assert!(f8.contains("| 2.50× | 4.00× |"), "{f8}");

        let no_floor = comparison(0.0, 2e-5);
        let a = &no_floor.results[1];
        assert_eq!(a.efficiency_vs_light, a.efficiency_vs_light_above_floor);
        let within = comparison(3e-5, 2e-5);
        assert_eq!(within.results[1].efficiency_vs_light_above_floor, None);
        let md = summary_markdown(&within);
        let row = md
            .lines()
            .find(|l| l.starts_with("| antishadow"))
            .unwrap_or_default();
        assert!(row.contains("| 2.50× | – |"), "{row}");
    }

    /// The summary names a most efficient strategy only when it leads by more than 10%: at
    /// 2.5× it does; at 1.05× (two strategies rendering alike, apart by timing noise) it calls
    /// them a tie (issue 40: fig8b named one from noise).
    #[test]
    fn a_strategy_is_named_most_efficient_only_with_a_clear_lead() {
        let clear = figure8_markdown(&[comparison(0.0, 2e-5)]);
        assert!(clear.contains("most efficient is antishadow"), "{clear}");
        let tie = figure8_markdown(&[comparison(0.0, 5e-5 / 1.05)]);
        assert!(!tie.contains("most efficient"), "{tie}");
        assert!(tie.contains("antishadow, light are within 10%"), "{tie}");
    }

    /// Three runs whose antishadow efficiencies over light are 2.5, 2 and 1 (light's MSE 5e-5,
    /// antishadow's 2e-5, 2.5e-5, 5e-5, the same time, no floor): mean 11/6, sample variance
    /// 7/12, standard error √(7/36) = 0.441. Negative cases: one run has no standard error,
    /// and one run within the reference's floor leaves the floor-subtracted mean unknown
    /// rather than averaged over the other runs.
    #[test]
    fn runs_give_the_mean_efficiency_and_its_standard_error() {
        let runs: Vec<SceneComparison> = [2e-5, 2.5e-5, 5e-5]
            .iter()
            .enumerate()
            .map(|(k, &mse)| {
                let mut c = comparison(0.0, mse);
                c.settings.seed = 10 + k as u64;
                c
            })
            .collect();
        let rows = runs_rows(&runs);
        assert_eq!(rows.len(), 2);
        let light = rows[0].efficiency_vs_light.expect("light's own ratio");
        assert_eq!((light.mean, light.se), (1.0, Some(0.0)));
        let a = rows[1].efficiency_vs_light.expect("antishadow's ratio");
        assert!((a.mean - 11.0 / 6.0).abs() < 1e-12, "{a:?}");
        assert!(
            (a.se.unwrap_or(0.0) - (7.0f64 / 36.0).sqrt()).abs() < 1e-12,
            "{a:?}"
        );
        assert!(a.min == 1.0 && (a.max - 2.5).abs() < 1e-12, "{a:?}");
        assert_eq!(rows[1].efficiency_vs_light_above_floor, Some(a));
        let md = runs_markdown(&runs);
        assert!(md.contains("seeds 10, 11, 12"), "{md}");
        assert!(
            md.contains("| antishadow | 3 | 10.0 ± 0.0 | 1.833× ± 0.441 (1.000–2.500) |"),
            "{md}"
        );
        let csv = runs_csv(&runs);
        assert_eq!(csv.lines().count(), 1 + 3 * 2, "{csv}");
        assert!(
            csv.contains("\n12,antishadow,10,2.000000,5e-5,5e-5,1e0,1e0\n"),
            "{csv}"
        );

        let one = runs_rows(&runs[..1]);
        assert_eq!(one[1].efficiency_vs_light.and_then(|m| m.se), None);
        let mut within = runs.clone();
        within[2] = comparison(6e-5, 5e-5);
        let rows = runs_rows(&within);
        assert!(rows[1].efficiency_vs_light.is_some());
        assert_eq!(rows[1].efficiency_vs_light_above_floor, None);
        assert!(runs_rows(&[]).is_empty());
    }
}
