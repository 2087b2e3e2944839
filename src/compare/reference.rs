//! The converged reference: rendering it, its cache (by a stable hash of what it depends on),
//! loading a user's EXR with its sidecar.

use anyhow::{Context, Result};
use glam::Vec3;
use indicatif::ProgressBar;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use super::metrics::Convergence;
use crate::light::{Mixture, Selection, Strategy};
use crate::render::film::Film;
use crate::render::integrator::{GlassShadows, GuideBounces, Integrator, RenderSettings};
use crate::render::{Cancelled, render_pass, tonemap};
use crate::sampling::SamplerKind;
use crate::scene::Scene;

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
const REFERENCE_FORMAT: u32 = 2;

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
        h.vec3(m.f0);
        h.f32(m.f90);
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
    // The environment lights the scene; windows only change how it is sampled, but are kept
    // like portals.
    if let Some(e) = &scene.desc.environment {
        h.str("environment");
        h.f32(e.strength);
        h.f32(e.rotation_degrees);
        match &e.map {
            crate::asset::environment::EnvMap::Constant(c) => h.vec3(*c),
            crate::asset::environment::EnvMap::Image { image, .. } => {
                h.u32(image.width);
                h.u32(image.height);
                image.pixels.iter().for_each(|&p| h.vec3(p));
            }
        }
    }
    h.u64(scene.windows.len() as u64);
    for w in &scene.windows {
        h.f32(w.alpha);
        w.polygon.vertices().iter().for_each(|&v| h.vec3(v));
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
        // Its noise floor comes from the per-pixel sample variance, which is an unbiased
        // estimate only for independent samples.
        sampler: SamplerKind::Independent,
        mixture: Mixture::default(),
        // The tree: in a room of many lights a reference picked by power converges several
        // times slower; tests/selection.rs shows the two agree.
        selection: Selection::Tree,
        // Shadow rays through thin glass: the same image as stopping them (tests/glass.rs),
        // far less noise behind panes.
        glass: GlassShadows::Pass,
        // Bounces through the portals: the same image as BSDF sampling alone
        // (tests/bounces.rs), without the fireflies of light bounced inside shades.
        bounces: GuideBounces::On,
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

fn read_sidecar(path: &Path) -> Result<ReferenceInfo> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    serde_json::from_str(&text)
        .with_context(|| format!("{}: not a reference sidecar", path.display()))
}

/// Loads a reference EXR of `width × height`, with its sidecar's information when there is one.
pub fn load_reference(path: &Path, width: u32, height: u32) -> Result<Reference> {
    let (w, h, pixels) = crate::io::read_exr(path).map_err(anyhow::Error::msg)?;
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
    let (w, h, pixels) = crate::io::read_exr(&exr).ok()?;
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
    crate::io::write_atomic(&json, text.as_bytes())
        .with_context(|| format!("{}: cannot write", json.display()))?;
    reference.origin = ReferenceOrigin::Rendered(Some(exr));
    Ok(())
}
