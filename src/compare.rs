//! Equal-time comparison of the strategies against a converged reference (the thesis's
//! Figure 8): error metrics, the reference and its cache, a scheduler that gives every
//! strategy the same render time, and the files `portalview compare` writes.
//!
//! Quality is MSE against the reference over equal *time*. The reference is rendered with
//! antishadow sampling (the best strategy) from a different seed than the compared renders, so
//! its own noise is independent of theirs: it adds its per-pixel variance (the *noise floor*)
//! to every measured MSE. That floor is reported beside the results, never subtracted.

use anyhow::{Context, Result};
use glam::{DVec3, Vec3};
use indicatif::{ProgressBar, ProgressStyle};
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use crate::cli::{CompareArgs, default_height};
use crate::light::Strategy;
use crate::render::film::Film;
use crate::render::integrator::{Integrator, RenderSettings};
use crate::render::stats::Stats;
use crate::render::{Cancelled, render_pass, tonemap};
use crate::scene::Scene;

/// The ε of relMSE, in squared radiance units: `(x − r)² / (r² + ε)`. It keeps black and
/// near-black reference pixels (shadows, the unlit background) from dominating the mean; with
/// the built-in scenes' radiances of about 0.01 to 10, it weights pixels darker than 0.1 by
/// their absolute rather than relative error. 1e-2 is the usual choice (Rousselle et al.).
pub const RELMSE_EPSILON: f64 = 1e-2;

/// Mean squared error over pixels and channels. Both images are row-major and of equal size.
///
/// # Panics
/// If the lengths differ (a caller's bug: the sizes are checked where images are loaded).
pub fn mse(image: &[Vec3], reference: &[Vec3]) -> f64 {
    mean_channel_error(image, reference, |d, _| d * d)
}

/// Relative MSE: the mean over pixels and channels of `(x − r)² / (r² + ε)`, with
/// ε = [`RELMSE_EPSILON`].
///
/// # Panics
/// If the lengths differ.
pub fn relmse(image: &[Vec3], reference: &[Vec3]) -> f64 {
    mean_channel_error(image, reference, |d, r| d * d / (r * r + RELMSE_EPSILON))
}

/// The mean over pixels and channels of `error(x − r, r)`, in f64.
fn mean_channel_error(
    image: &[Vec3],
    reference: &[Vec3],
    error: impl Fn(DVec3, DVec3) -> DVec3,
) -> f64 {
    assert_eq!(image.len(), reference.len(), "images of different sizes");
    if image.is_empty() {
        return 0.0;
    }
    let sum: f64 = image
        .iter()
        .zip(reference)
        .map(|(&x, &r)| {
            let r = r.as_dvec3();
            let e = error(x.as_dvec3() - r, r);
            e.x + e.y + e.z
        })
        .sum();
    sum / (3 * image.len()) as f64
}

/// How converged a rendered image is, from its film's per-pixel variance of the mean.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Convergence {
    /// Mean over pixel channels of `sqrt(var / (r² + ε))`: the standard error relative to the
    /// pixel's value, with relMSE's ε. Exactly black channels with no variance (nothing was
    /// ever seen there) are left out.
    pub mean_relative_standard_error: f64,
    /// Mean variance of the pixel means: the expected MSE of this image against the true one,
    /// and what it adds to the MSE of any independent image measured against it.
    pub mse_floor: f64,
    /// The same floor for relMSE: mean of `var / (r² + ε)`.
    pub relmse_floor: f64,
}

impl Convergence {
    pub fn of(film: &Film) -> Convergence {
        let mean = film.mean();
        let variance = film.variance_of_mean();
        let (mut rse, mut counted) = (0.0f64, 0usize);
        let (mut floor, mut rel_floor) = (0.0f64, 0.0f64);
        for (m, v) in mean.iter().zip(&variance) {
            for (r, var) in [(m.x, v.x), (m.y, v.y), (m.z, v.z)] {
                let (r, var) = (r as f64, var as f64);
                floor += var;
                let rel = var / (r * r + RELMSE_EPSILON);
                rel_floor += rel;
                if r != 0.0 || var != 0.0 {
                    rse += rel.sqrt();
                    counted += 1;
                }
            }
        }
        let channels = (3 * mean.len()).max(1) as f64;
        Convergence {
            mean_relative_standard_error: rse / counted.max(1) as f64,
            mse_floor: floor / channels,
            relmse_floor: rel_floor / channels,
        }
    }
}

/// The image settings a reference depends on besides the scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct ImageSpec {
    pub width: u32,
    pub height: u32,
    /// Path vertices after the camera (`RenderSettings::max_depth`).
    pub max_depth: u32,
}

impl ImageSpec {
    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }
}

/// FNV-1a, 64 bits: a hash that is the same on every machine and every run (std's is not).
#[derive(Clone, Copy, Debug)]
pub struct Fnv1a(u64);

impl Default for Fnv1a {
    fn default() -> Self {
        Fnv1a(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv1a {
    pub fn bytes(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= b as u64;
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    pub fn u32(&mut self, v: u32) {
        self.bytes(&v.to_le_bytes());
    }
    pub fn u64(&mut self, v: u64) {
        self.bytes(&v.to_le_bytes());
    }
    /// By its bits: 0.0 and -0.0 differ, which only costs a cache miss.
    pub fn f32(&mut self, v: f32) {
        self.u32(v.to_bits());
    }
    pub fn vec3(&mut self, v: Vec3) {
        self.f32(v.x);
        self.f32(v.y);
        self.f32(v.z);
    }
    /// Length-prefixed, so that consecutive strings cannot run into each other.
    pub fn str(&mut self, s: &str) {
        self.u64(s.len() as u64);
        self.bytes(s.as_bytes());
    }
    pub fn finish(&self) -> u64 {
        self.0
    }
}

/// Bumped whenever the renderer changes what a converged image looks like, so that old cached
/// references are not reused.
const REFERENCE_FORMAT: u32 = 1;

/// A stable hash of what the reference image depends on: the triangles, materials, portals and
/// camera as the renderer sees them, and the resolution and path depth.
pub fn scene_hash(scene: &Scene, image: ImageSpec) -> u64 {
    let mut h = Fnv1a::default();
    h.str("portalview reference");
    h.u32(REFERENCE_FORMAT);
    let g = &scene.geometry;
    h.u64(g.triangles.len() as u64);
    for t in &g.triangles {
        t.p.iter().chain(&t.n).for_each(|&v| h.vec3(v));
        h.u32(t.material);
        h.u32(t.light);
    }
    h.u64(g.materials.len() as u64);
    for m in &g.materials {
        h.vec3(m.base_color);
        h.f32(m.metallic);
        h.f32(m.alpha);
        h.f32(m.f0_dielectric);
        h.f32(m.specular);
        h.vec3(m.emission);
        h.u32(m.double_sided as u32);
    }
    h.u64(scene.portals.len() as u64);
    for p in &scene.portals {
        h.u64(p.light as u64);
        h.f32(p.alpha);
        h.u64(p.polygon.vertices().len() as u64);
        p.polygon.vertices().iter().for_each(|&v| h.vec3(v));
    }
    let c = &scene.camera;
    [c.eye, c.target, c.up].into_iter().for_each(|v| h.vec3(v));
    h.f32(c.yfov);
    h.f32(c.aspect);
    h.u32(image.width);
    h.u32(image.height);
    h.u32(image.max_depth);
    h.finish()
}

/// The cache key: the scene's name (made file-safe, for people browsing the cache) and
/// [`scene_hash`] in hex.
pub fn cache_key(scene: &Scene, image: ImageSpec) -> String {
    let name: String = scene
        .name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .take(40)
        .collect();
    let name = if name.is_empty() {
        "scene".to_owned()
    } else {
        name
    };
    format!("{name}-{:016x}", scene_hash(scene, image))
}

/// Where references are cached: `$XDG_CACHE_HOME/portalview`, else `~/.cache/portalview`.
pub fn default_cache_dir() -> Option<PathBuf> {
    let absolute = |v: std::ffi::OsString| {
        let p = PathBuf::from(v);
        p.is_absolute().then_some(p)
    };
    if let Some(p) = std::env::var_os("XDG_CACHE_HOME").and_then(absolute) {
        return Some(p.join("portalview"));
    }
    std::env::var_os("HOME")
        .and_then(absolute)
        .map(|home| home.join(".cache").join("portalview"))
}

/// The seed of the reference for compared renders of seed `seed`: the same `Rng::keyed`
/// family, another seed, so that its noise is independent of theirs.
pub fn reference_seed(seed: u64) -> u64 {
    seed ^ 0x9e37_79b9_7f4a_7c15
}

/// The strategy references are rendered with.
pub const REFERENCE_STRATEGY: Strategy = Strategy::Antishadow;

/// How long a reference renders.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ReferenceBudget {
    /// Whole passes until this much time is spent (at least two, for a variance).
    Seconds(f64),
    /// This many samples per pixel (at least two).
    Spp(u32),
}

/// What is known about a reference image: written beside a cached one as `<key>.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReferenceInfo {
    pub key: String,
    pub scene: String,
    pub width: u32,
    pub height: u32,
    pub max_depth: u32,
    pub strategy: Strategy,
    pub seed: u64,
    pub spp: u32,
    /// Pass render time.
    pub seconds: f64,
    pub convergence: Convergence,
}

impl ReferenceInfo {
    /// Whether a reference rendered like this is at least as good as `budget` asks.
    pub fn covers(&self, budget: ReferenceBudget) -> bool {
        match budget {
            ReferenceBudget::Seconds(s) => self.seconds >= 0.95 * s,
            ReferenceBudget::Spp(n) => self.spp >= n.max(2),
        }
    }
}

/// Where a reference came from.
#[derive(Clone, Debug, PartialEq)]
pub enum ReferenceOrigin {
    /// Rendered now (and stored at the path, when a cache was given).
    Rendered(Option<PathBuf>),
    /// Loaded from the cache.
    Cached(PathBuf),
    /// Given by the user (`--reference FILE.exr`).
    File(PathBuf),
}

/// A reference image: its pixels and, unless it is a user's EXR without a sidecar, how it was
/// made and how converged it is.
#[derive(Clone, Debug)]
pub struct Reference {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Vec3>,
    pub info: Option<ReferenceInfo>,
    pub origin: ReferenceOrigin,
}

fn bar(len: u64, template: &str) -> ProgressBar {
    let bar = ProgressBar::new(len);
    if let Ok(style) = ProgressStyle::with_template(template) {
        bar.set_style(style);
    }
    bar
}

/// Renders a reference of `scene` with [`REFERENCE_STRATEGY`] and seed
/// `reference_seed(compare_seed)`. Usable from any thread; `cancel` stops it within a tile.
/// `progress` advances in milliseconds (time budget) or passes (spp budget).
pub fn render_reference(
    scene: &Scene,
    image: ImageSpec,
    compare_seed: u64,
    budget: ReferenceBudget,
    cancel: &AtomicBool,
    progress: &ProgressBar,
) -> Result<Reference, Cancelled> {
    let seed = reference_seed(compare_seed);
    let settings = RenderSettings {
        strategy: REFERENCE_STRATEGY,
        alpha: None,
        max_depth: image.max_depth,
        seed,
    };
    let integrator = Integrator::new(scene, settings);
    let mut film = Film::new(image.width, image.height);
    let mut seconds = 0.0;
    let done = |film: &Film, seconds: f64| match budget {
        ReferenceBudget::Seconds(s) => film.spp >= 2 && seconds >= s,
        ReferenceBudget::Spp(n) => film.spp >= n.max(2),
    };
    progress.set_length(match budget {
        ReferenceBudget::Seconds(s) => (s * 1e3) as u64,
        ReferenceBudget::Spp(n) => n.max(2) as u64,
    });
    while !done(&film, seconds) {
        let start = Instant::now();
        let (pass, _) = render_pass(&integrator, image.width, image.height, film.spp, cancel)?;
        seconds += start.elapsed().as_secs_f64();
        film.add_pass(&pass);
        progress.set_position(match budget {
            ReferenceBudget::Seconds(_) => (seconds * 1e3) as u64,
            ReferenceBudget::Spp(_) => film.spp as u64,
        });
        progress.set_message(format!("{} spp", film.spp));
    }
    let info = ReferenceInfo {
        key: cache_key(scene, image),
        scene: scene.name.clone(),
        width: image.width,
        height: image.height,
        max_depth: image.max_depth,
        strategy: REFERENCE_STRATEGY,
        seed,
        spp: film.spp,
        seconds,
        convergence: Convergence::of(&film),
    };
    Ok(Reference {
        width: image.width,
        height: image.height,
        pixels: film.mean(),
        info: Some(info),
        origin: ReferenceOrigin::Rendered(None),
    })
}

/// The sidecar of a reference EXR: the same path with the extension `.json`.
pub fn sidecar_path(exr: &Path) -> PathBuf {
    exr.with_extension("json")
}

/// Writes `contents` to a temporary sibling of `path`, then renames it over `path`.
pub fn write_atomic(path: &Path, contents: &[u8]) -> Result<()> {
    let tmp = tonemap::temporary_sibling(path);
    if let Err(e) = std::fs::write(&tmp, contents) {
        let _ = std::fs::remove_file(&tmp);
        anyhow::bail!("{}: cannot write: {e}", path.display());
    }
    std::fs::rename(&tmp, path)
        .with_context(|| format!("{}: cannot replace the file", path.display()))
}

fn read_sidecar(path: &Path) -> Result<ReferenceInfo> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    serde_json::from_str(&text)
        .with_context(|| format!("{}: not a reference sidecar", path.display()))
}

/// Loads a reference EXR of `width × height`, with its sidecar's information when there is one.
pub fn load_reference(path: &Path, width: u32, height: u32) -> Result<Reference> {
    let (w, h, pixels) = tonemap::read_exr(path)?;
    anyhow::ensure!(
        (w, h) == (width, height),
        "{}: the reference is {w}x{h}, the comparison {width}x{height} (pass --width/--height)",
        path.display()
    );
    let sidecar = sidecar_path(path);
    let info = if sidecar.exists() {
        let info = read_sidecar(&sidecar)?;
        anyhow::ensure!(
            (info.width, info.height) == (w, h),
            "{}: describes a {}x{} image, but {} is {w}x{h}",
            sidecar.display(),
            info.width,
            info.height,
            path.display()
        );
        Some(info)
    } else {
        None
    };
    Ok(Reference {
        width: w,
        height: h,
        pixels,
        info,
        origin: ReferenceOrigin::File(path.to_owned()),
    })
}

/// The reference for `scene` at `image` from the cache in `cache_dir` if one there covers
/// `budget` (and its seed differs from `compare_seed`), else rendered and stored there as
/// `<key>.exr` and `<key>.json`.
pub fn cached_reference(
    cache_dir: &Path,
    scene: &Scene,
    image: ImageSpec,
    compare_seed: u64,
    budget: ReferenceBudget,
    progress: &ProgressBar,
) -> Result<Reference> {
    if let Some(reference) = find_cached_reference(cache_dir, scene, image, compare_seed, budget) {
        return Ok(reference);
    }
    let never = AtomicBool::new(false);
    let Ok(mut reference) = render_reference(scene, image, compare_seed, budget, &never, progress)
    else {
        anyhow::bail!(
            "{}: the reference render was cancelled",
            cache_dir.display()
        );
    };
    store_reference(cache_dir, &mut reference)?;
    Ok(reference)
}

/// The cached reference for `scene` at `image` in `cache_dir`, if one there covers `budget`
/// and its seed differs from `compare_seed`. An unreadable or unsuitable entry is a miss.
pub fn find_cached_reference(
    cache_dir: &Path,
    scene: &Scene,
    image: ImageSpec,
    compare_seed: u64,
    budget: ReferenceBudget,
) -> Option<Reference> {
    let key = cache_key(scene, image);
    let exr = cache_dir.join(format!("{key}.exr"));
    let info = read_sidecar(&sidecar_path(&exr)).ok().filter(|info| {
        info.key == key
            && (info.width, info.height) == (image.width, image.height)
            && info.seed != compare_seed
            && info.covers(budget)
    })?;
    let (w, h, pixels) = tonemap::read_exr(&exr).ok()?;
    ((w, h) == (image.width, image.height)).then_some(Reference {
        width: w,
        height: h,
        pixels,
        info: Some(info),
        origin: ReferenceOrigin::Cached(exr),
    })
}

/// Stores a rendered reference in `cache_dir` (created if needed) as `<key>.exr` and
/// `<key>.json`, replacing any entry of that key, and sets its origin to the stored file.
pub fn store_reference(cache_dir: &Path, reference: &mut Reference) -> Result<()> {
    let Some(info) = &reference.info else {
        anyhow::bail!("a reference without its information cannot be cached");
    };
    let exr = cache_dir.join(format!("{}.exr", info.key));
    let json = sidecar_path(&exr);
    std::fs::create_dir_all(cache_dir)
        .with_context(|| format!("{}: cannot create the cache folder", cache_dir.display()))?;
    tonemap::write_image(
        &exr,
        reference.width,
        reference.height,
        &reference.pixels,
        0.0,
    )?;
    let text = serde_json::to_string_pretty(info)
        .with_context(|| format!("{}: cannot encode", json.display()))?;
    write_atomic(&json, text.as_bytes())?;
    reference.origin = ReferenceOrigin::Rendered(Some(exr));
    Ok(())
}

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

/// What one comparison renders.
#[derive(Clone, Debug, PartialEq)]
pub struct CompareSettings {
    pub strategies: Vec<Strategy>,
    /// Pass render time per strategy.
    pub seconds: f64,
    pub image: ImageSpec,
    pub seed: u64,
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
    let image = settings.image;
    let render = RenderSettings {
        strategy: Strategy::Light,
        alpha: None,
        max_depth: image.max_depth,
        seed: settings.seed,
    };
    let mut schedule = EqualTime::new(
        scene.clone(),
        &settings.strategies,
        image.width,
        image.height,
        render,
    );
    let n = settings.strategies.len();
    progress.set_length((settings.seconds * n as f64 * 1e3) as u64);
    let mut next_record = vec![0.0; n];
    let mut points = Vec::new();
    let never = AtomicBool::new(false);
    while n > 0 && schedule.min_seconds() < settings.seconds {
        let Ok(Some(i)) = schedule.step(&never) else {
            break;
        };
        let run = &schedule.runs()[i];
        if run.seconds >= next_record[i] || run.seconds >= settings.seconds {
            let mean = run.film.mean();
            points.push(ConvergencePoint {
                strategy: run.strategy,
                seconds: run.seconds,
                spp: run.film.spp,
                mse: mse(&mean, &reference.pixels),
                relmse: relmse(&mean, &reference.pixels),
            });
            next_record[i] = run.seconds * RECORD_FACTOR;
        }
        let total: f64 = schedule
            .runs()
            .iter()
            .map(|r| r.seconds.min(settings.seconds))
            .sum();
        progress.set_position((total * 1e3) as u64);
        let spp: Vec<String> = schedule
            .runs()
            .iter()
            .map(|r| format!("{} {}", r.strategy.name(), r.film.spp))
            .collect();
        progress.set_message(format!("{} spp", spp.join(", ")));
    }
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
                stats: run.stats,
            }
        })
        .collect();
    let light = results
        .iter()
        .find(|r| r.strategy == Strategy::Light)
        .map(|r| r.efficiency);
    for r in &mut results {
        r.efficiency_vs_light = light.map(|l| r.efficiency / l).filter(|e| e.is_finite());
    }
    SceneComparison {
        scene: scene.name.clone(),
        settings: settings.clone(),
        reference_info: reference.info.clone(),
        reference_origin: reference.origin.clone(),
        points,
        results,
    }
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

fn sci(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.3e}")
    } else {
        "–".to_owned()
    }
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
                 in every measured error above (not subtracted): errors within a few times \
                 the floor are limited by the reference.",
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
        "| strategy | spp | seconds | MSE | relMSE | efficiency vs light | MSE / reference floor |\n",
    );
    out.push_str("|---|---:|---:|---:|---:|---:|---:|\n");
    for r in &c.results {
        let over_floor = floor.filter(|&f| f > 0.0).map(|f| r.mse / f);
        let _ = writeln!(
            out,
            "| {} | {} | {:.2} | {} | {} | {} | {} |",
            r.strategy.name(),
            r.spp,
            r.seconds,
            sci(r.mse),
            sci(r.relmse),
            ratio(r.efficiency_vs_light),
            over_floor.map_or("–".to_owned(), |v| format!("{v:.1}"))
        );
    }
    let _ = writeln!(
        out,
        "\nEfficiency is 1 / (MSE × seconds), relative to light sampling's: above 1 is better. \
         relMSE = mean of (x − r)² / (r² + {RELMSE_EPSILON}) over pixels and channels.\n"
    );
    out.push_str(&reference_markdown(
        c.reference_info.as_ref(),
        &c.reference_origin,
    ));
    out
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
    out.push_str("| scene | strategy | spp | seconds | MSE | efficiency vs light |\n");
    out.push_str("|---|---|---:|---:|---:|---:|\n");
    for c in comparisons {
        for r in &c.results {
            let _ = writeln!(
                out,
                "| {} | {} | {} | {:.2} | {} | {} |",
                c.scene,
                r.strategy.name(),
                r.spp,
                r.seconds,
                sci(r.mse),
                ratio(r.efficiency_vs_light)
            );
        }
    }
    out.push_str("\nEfficiency is 1 / (MSE × seconds), relative to light sampling's.\n\n");
    for c in comparisons {
        let best = c
            .results
            .iter()
            .filter(|r| r.efficiency.is_finite())
            .max_by(|a, b| a.efficiency.total_cmp(&b.efficiency));
        if let Some(best) = best {
            let _ = writeln!(
                out,
                "- {}: most efficient is {}.",
                c.scene,
                best.strategy.name()
            );
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

/// Plot colours by strategy, the same in every plot.
fn colour(strategy: Strategy) -> plotters::style::RGBColor {
    use plotters::style::RGBColor;
    match strategy {
        Strategy::Light => RGBColor(31, 119, 180),
        Strategy::Portal => RGBColor(255, 127, 14),
        Strategy::Projection => RGBColor(44, 160, 44),
        Strategy::Antishadow => RGBColor(214, 39, 40),
    }
}

/// Tick labels for a log axis.
fn tick_label(v: &f64) -> String {
    let a = v.abs();
    if (0.01..1000.0).contains(&a) {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_owned()
    } else {
        format!("{v:.0e}")
    }
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
        .x_label_formatter(&tick_label)
        .y_label_formatter(&tick_label)
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

/// Writes `convergence.csv`, `convergence.svg` and `summary.md` into `dir` (created if needed).
pub fn write_scene_outputs(dir: &Path, c: &SceneComparison) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    let csv = dir.join("convergence.csv");
    write_atomic(&csv, convergence_csv(c).as_bytes())?;
    let svg = dir.join("convergence.svg");
    let plot =
        convergence_svg(std::slice::from_ref(c)).with_context(|| svg.display().to_string())?;
    write_atomic(&svg, plot.as_bytes())?;
    let md = dir.join("summary.md");
    write_atomic(&md, summary_markdown(c).as_bytes())?;
    Ok(vec![csv, svg, md])
}

/// Writes `figure8.csv`, `figure8.md` and `figure8.svg` into `dir`.
pub fn write_figure8_outputs(dir: &Path, comparisons: &[SceneComparison]) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    let csv = dir.join("figure8.csv");
    write_atomic(&csv, figure8_csv(comparisons).as_bytes())?;
    let md = dir.join("figure8.md");
    write_atomic(&md, figure8_markdown(comparisons).as_bytes())?;
    let svg = dir.join("figure8.svg");
    let plot = convergence_svg(comparisons).with_context(|| svg.display().to_string())?;
    write_atomic(&svg, plot.as_bytes())?;
    Ok(vec![csv, md, svg])
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
    anyhow::ensure!(!args.strategies.is_empty(), "--strategies lists none");
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
        let mut scene = Scene::open(name)?;
        if scene.name.is_empty() {
            scene.name = name.clone();
        }
        let height = args
            .height
            .unwrap_or_else(|| default_height(&scene, args.width));
        anyhow::ensure!(height > 0, "--height must be positive");
        let image = ImageSpec {
            width: args.width,
            height,
            max_depth: args.max_depth,
        };
        eprintln!(
            "{}: {}x{} px, reference",
            scene.name, image.width, image.height
        );
        let progress = bar(0, "{bar:40} {pos}/{len} {msg}  {elapsed_precise}");
        let reference = match (&args.reference, &cache_dir) {
            (Some(file), _) => load_reference(file, image.width, image.height)?,
            (None, Some(dir)) => {
                cached_reference(dir, &scene, image, args.seed, budget, &progress)?
            }
            (None, None) => {
                eprintln!(
                    "no cache folder (set XDG_CACHE_HOME or HOME, or --cache-dir): not caching"
                );
                let never = AtomicBool::new(false);
                render_reference(&scene, image, args.seed, budget, &never, &progress)
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
            if info.seed == args.seed {
                eprintln!(
                    "warning: {}: rendered with the same seed as the comparison, so its noise \
                     is correlated with theirs (use another --seed)",
                    file.display()
                );
            }
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
        let settings = CompareSettings {
            strategies: args.strategies.clone(),
            seconds: args.seconds,
            image,
            seed: args.seed,
        };
        let progress = bar(0, "{bar:40} {msg}  {elapsed_precise}");
        let comparison = compare(&scene, &settings, &reference, &progress);
        progress.finish_and_clear();
        let dir = if args.figure8 {
            args.out.join(&scene.name)
        } else {
            args.out.clone()
        };
        written.extend(write_scene_outputs(&dir, &comparison)?);
        println!("{}", summary_markdown(&comparison));
        comparisons.push(comparison);
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
