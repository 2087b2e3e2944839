//! Strategies rendered at equal time against a reference: the scheduler and a whole comparison.

use anyhow::Result;
use indicatif::ProgressBar;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use super::metrics::{
    BULK_DROPPED, WORST_FRACTION, bulk_mse, mse, mse_above_floor, relmse, worst_pixels_share,
};
use super::reference::{ImageSpec, Reference, ReferenceInfo, ReferenceOrigin};
use crate::light::{Mixture, Selection, Strategy};
use crate::render::film::Film;
use crate::render::integrator::{GlassShadows, GuideBounces, Integrator, RenderSettings};
use crate::render::stats::Stats;
use crate::render::{Cancelled, render_pass};
use crate::sampling::SamplerKind;
use crate::scene::Scene;

/// One strategy's render in an [`EqualTime`] comparison.
#[derive(Clone, Debug)]
pub struct StrategyRun {
    pub strategy: Strategy,
    pub film: Film,
    pub stats: Stats,
    /// Accumulated pass render time.
    pub seconds: f64,
}

/// Renders several strategies of one scene, camera and resolution at equal wall time: each
/// step renders one pass of the strategy with the least accumulated pass time (ties go to the
/// earlier one), so that their times never differ by more than one pass. Only the passes are
/// timed: whatever the caller does between steps does not count. Owns its scene, so that a
/// worker thread can keep it between steps.
pub struct EqualTime {
    scene: Scene,
    settings: RenderSettings,
    width: u32,
    height: u32,
    runs: Vec<StrategyRun>,
}

impl EqualTime {
    /// `settings.strategy` is replaced by each of `strategies` in turn.
    pub fn new(
        scene: Scene,
        strategies: &[Strategy],
        width: u32,
        height: u32,
        settings: RenderSettings,
    ) -> Self {
        let runs = strategies
            .iter()
            .map(|&strategy| StrategyRun {
                strategy,
                film: Film::new(width, height),
                stats: Stats::default(),
                seconds: 0.0,
            })
            .collect();
        EqualTime {
            scene,
            settings,
            width,
            height,
            runs,
        }
    }

    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    pub fn runs(&self) -> &[StrategyRun] {
        &self.runs
    }

    /// The run that the next step renders: the least accumulated time, the first on ties.
    pub fn next(&self) -> Option<usize> {
        let mut best: Option<(usize, f64)> = None;
        for (i, run) in self.runs.iter().enumerate() {
            if best.is_none_or(|(_, s)| run.seconds < s) {
                best = Some((i, run.seconds));
            }
        }
        best.map(|(i, _)| i)
    }

    /// The least accumulated time over the runs (0 without runs).
    pub fn min_seconds(&self) -> f64 {
        self.next().map_or(0.0, |i| self.runs[i].seconds)
    }

    /// Renders one pass of [`Self::next`] and returns its index (`None` without runs). A
    /// cancelled pass changes nothing.
    pub fn step(&mut self, cancel: &AtomicBool) -> Result<Option<usize>, Cancelled> {
        let Some(i) = self.next() else {
            return Ok(None);
        };
        let run = &mut self.runs[i];
        let settings = RenderSettings {
            strategy: run.strategy,
            ..self.settings
        };
        // Built per pass (cheap next to a pass) so that the scheduler need not borrow its scene.
        let integrator = Integrator::new(&self.scene, settings);
        let start = Instant::now();
        let (pass, stats) =
            render_pass(&integrator, self.width, self.height, run.film.spp, cancel)?;
        run.seconds += start.elapsed().as_secs_f64();
        run.film.add_pass(&pass);
        run.stats += stats;
        Ok(Some(i))
    }
}

/// Each result's efficiency over light sampling's, from the raw MSE and from the MSE less the
/// reference's floor (at equal time both are ratios of inverse errors times times).
pub fn set_efficiency_ratios(results: &mut [StrategyResult]) {
    let light = results.iter().find(|r| r.strategy == Strategy::Light);
    let raw = light.map(|r| r.efficiency);
    let above = light.and_then(|r| Some(1.0 / (r.mse_above_floor? * r.seconds)));
    for r in results {
        r.efficiency_vs_light = raw.map(|l| r.efficiency / l).filter(|e| e.is_finite());
        r.efficiency_vs_light_above_floor = r
            .mse_above_floor
            .zip(above)
            .map(|(e, l)| 1.0 / (e * r.seconds) / l)
            .filter(|e| e.is_finite());
    }
}

/// What one comparison renders.
#[derive(Clone, Debug, PartialEq)]
pub struct CompareSettings {
    pub strategies: Vec<Strategy>,
    /// Pass render time per strategy.
    pub seconds: f64,
    pub image: ImageSpec,
    pub seed: u64,
    /// The compared renders' random numbers (the reference's are always independent).
    pub sampler: SamplerKind,
    /// How the compared renders draw from a light mixture (the reference's: one sample).
    pub mixture: Mixture,
    /// How the compared renders pick lights.
    pub selection: Selection,
    /// What the compared renders' shadow rays do at thin glass.
    pub glass: GlassShadows,
    /// Whether the compared renders guide their bounces through the portals.
    pub bounces: GuideBounces,
    /// Replaces every portal's and window's alpha in the compared renders (not in the
    /// reference's, whose converged image does not depend on it).
    pub alpha: Option<f32>,
}

/// One recorded point of a strategy's convergence.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConvergencePoint {
    pub strategy: Strategy,
    pub seconds: f64,
    pub spp: u32,
    pub mse: f64,
    pub relmse: f64,
}

/// A strategy at the end of a comparison.
#[derive(Clone, Debug, PartialEq)]
pub struct StrategyResult {
    pub strategy: Strategy,
    pub spp: u32,
    pub seconds: f64,
    pub mse: f64,
    pub relmse: f64,
    /// `1 / (MSE × seconds)`.
    pub efficiency: f64,
    /// `efficiency` over light sampling's; `None` without light sampling in the comparison.
    pub efficiency_vs_light: Option<f64>,
    /// `mse` less the reference's noise floor ([`mse_above_floor`]): `None` without a known
    /// floor or at or below it.
    pub mse_above_floor: Option<f64>,
    /// The efficiency ratio to light sampling's from `mse_above_floor` (both must be known).
    pub efficiency_vs_light_above_floor: Option<f64>,
    /// The share of the squared error in the worst 1 % of pixels ([`worst_pixels_share`]):
    /// near 1 where fireflies carry the error.
    pub worst_share: f64,
    /// The MSE without the worst 0.1 % of pixels ([`bulk_mse`]).
    pub bulk_mse: f64,
    pub stats: Stats,
}

/// Everything one scene's comparison produced.
#[derive(Clone, Debug)]
pub struct SceneComparison {
    pub scene: String,
    pub settings: CompareSettings,
    pub reference_info: Option<ReferenceInfo>,
    pub reference_origin: ReferenceOrigin,
    /// In recording order; per strategy, seconds increase.
    pub points: Vec<ConvergencePoint>,
    /// In the order of `settings.strategies`.
    pub results: Vec<StrategyResult>,
}

/// A point is recorded when a strategy's time has grown by this factor since its last one
/// (about ten per decade), and at its first and last pass.
pub const RECORD_FACTOR: f64 = 1.25;

/// Renders every strategy for `settings.seconds` of pass time, by [`EqualTime`], recording MSE
/// and relMSE against `reference` at roughly log-spaced times. `progress` advances in
/// milliseconds of total pass time.
pub fn compare(
    scene: &Scene,
    settings: &CompareSettings,
    reference: &Reference,
    progress: &ProgressBar,
) -> SceneComparison {
    let mut all = compare_each(scene, std::slice::from_ref(settings), reference, progress);
    all.swap_remove(0)
}

/// [`compare`] for each of `settings` at once, side by side: every step renders one pass of
/// the run, over all of them, with the least pass time, so that a machine whose speed drifts
/// during the comparison slows all of them alike (two light selections, say).
pub fn compare_each(
    scene: &Scene,
    settings: &[CompareSettings],
    reference: &Reference,
    progress: &ProgressBar,
) -> Vec<SceneComparison> {
    let mut schedules: Vec<EqualTime> = settings
        .iter()
        .map(|settings| {
            let image = settings.image;
            let render = RenderSettings {
                strategy: Strategy::Light,
                alpha: settings.alpha,
                max_depth: image.max_depth,
                seed: settings.seed,
                sampler: settings.sampler,
                mixture: settings.mixture,
                selection: settings.selection,
                glass: settings.glass,
                bounces: settings.bounces,
            };
            EqualTime::new(
                scene.clone(),
                &settings.strategies,
                image.width,
                image.height,
                render,
            )
        })
        .collect();
    let seconds = settings.iter().map(|s| s.seconds).fold(0.0, f64::max);
    let n: usize = settings.iter().map(|s| s.strategies.len()).sum();
    progress.set_length((seconds * n as f64 * 1e3) as u64);
    let mut next_record: Vec<Vec<f64>> = settings
        .iter()
        .map(|s| vec![0.0; s.strategies.len()])
        .collect();
    let mut points: Vec<Vec<ConvergencePoint>> = vec![Vec::new(); settings.len()];
    let never = AtomicBool::new(false);
    loop {
        // The schedule whose next run has the least time, among those not yet done.
        let next = schedules
            .iter()
            .enumerate()
            .filter(|(k, s)| !s.runs().is_empty() && s.min_seconds() < settings[*k].seconds)
            .min_by(|a, b| a.1.min_seconds().total_cmp(&b.1.min_seconds()))
            .map(|(k, _)| k);
        let Some(k) = next else {
            break;
        };
        let schedule = &mut schedules[k];
        let Ok(Some(i)) = schedule.step(&never) else {
            break;
        };
        let run = &schedule.runs()[i];
        if run.seconds >= next_record[k][i] || run.seconds >= settings[k].seconds {
            let mean = run.film.mean();
            points[k].push(ConvergencePoint {
                strategy: run.strategy,
                seconds: run.seconds,
                spp: run.film.spp,
                mse: mse(&mean, &reference.pixels),
                relmse: relmse(&mean, &reference.pixels),
            });
            next_record[k][i] = run.seconds * RECORD_FACTOR;
        }
        let total: f64 = schedules
            .iter()
            .zip(settings)
            .flat_map(|(s, settings)| s.runs().iter().map(|r| r.seconds.min(settings.seconds)))
            .sum();
        progress.set_position((total * 1e3) as u64);
        let spp: Vec<String> = schedules
            .iter()
            .zip(settings)
            .flat_map(|(s, settings)| {
                let label = if schedules.len() > 1 {
                    format!(" ({})", settings.selection.name())
                } else {
                    String::new()
                };
                s.runs()
                    .iter()
                    .map(move |r| format!("{}{label} {}", r.strategy.name(), r.film.spp))
            })
            .collect();
        progress.set_message(format!("{} spp", spp.join(", ")));
    }
    let floor = reference.info.as_ref().map(|i| i.convergence.mse_floor);
    schedules
        .iter()
        .zip(settings)
        .zip(points)
        .map(|((schedule, settings), points)| {
            let mut results: Vec<StrategyResult> = schedule
                .runs()
                .iter()
                .map(|run| {
                    let mean = run.film.mean();
                    let error = mse(&mean, &reference.pixels);
                    StrategyResult {
                        strategy: run.strategy,
                        spp: run.film.spp,
                        seconds: run.seconds,
                        mse: error,
                        relmse: relmse(&mean, &reference.pixels),
                        efficiency: 1.0 / (error * run.seconds),
                        efficiency_vs_light: None,
                        mse_above_floor: mse_above_floor(error, floor),
                        efficiency_vs_light_above_floor: None,
                        worst_share: worst_pixels_share(&mean, &reference.pixels, WORST_FRACTION),
                        bulk_mse: bulk_mse(&mean, &reference.pixels, BULK_DROPPED),
                        stats: run.stats,
                    }
                })
                .collect();
            set_efficiency_ratios(&mut results);
            SceneComparison {
                scene: scene.name.clone(),
                settings: settings.clone(),
                reference_info: reference.info.clone(),
                reference_origin: reference.origin.clone(),
                points,
                results,
            }
        })
        .collect()
}
