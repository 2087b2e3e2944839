//! The estimator for the environment (`docs/method.md` §9): the same single-sample mixture as
//! for an area light, with the environment as the light and window portals as its portals,
//!
//! `q(ω) = alpha · p_env(ω) + (1 − alpha) · Σ_j w_j(x) · p_{s_j}(ω | x)`,
//!
//! always weighted by the whole mixture's pdf. A point in front of a window sees the sky
//! through all of it (its antiantumbra), so a window needs no antishadow planes: the region is
//! `Antiantumbra` in front, `Behind` otherwise. Weights follow each window's solid angle from
//! `x` (under the guided technique, the environment's table integral over the window's box);
//! alpha is the largest `portal_light_probability` of the windows, or the override.

use arrayvec::ArrayVec;
use glam::{Vec2, Vec3};

use super::antishadow::Region;
use super::window::{GuidedBox, Window};
use super::{LightSet, MAX_TERMS, Strategy, Technique, split_share};
use crate::sampling::pick_by_weight;
use crate::sampling::spherical::SphericalPolygon;

/// How one direction towards the sky is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SkyTechnique {
    /// Environment importance sampling (the light technique).
    Environment,
    /// Uniform on the window's area (the portal technique).
    WindowArea,
    /// Uniform in the window's solid angle (the projection technique).
    SolidAngle,
    /// Proportional to the environment within the window's solid angle.
    Guided,
}

impl SkyTechnique {
    pub fn name(self) -> &'static str {
        match self {
            SkyTechnique::Environment => "environment",
            SkyTechnique::WindowArea => "window area",
            SkyTechnique::SolidAngle => "window solid angle",
            SkyTechnique::Guided => "environment within window",
        }
    }

    /// The area-light technique it corresponds to (statistics, overlays).
    pub fn technique(self) -> Technique {
        match self {
            SkyTechnique::Environment => Technique::Light,
            SkyTechnique::WindowArea => Technique::Portal,
            SkyTechnique::SolidAngle | SkyTechnique::Guided => Technique::Projection,
        }
    }

    /// The window technique of `strategy` for a point in front of a window (`None` for light
    /// sampling, which ignores windows). Antishadow's region there is the antiantumbra; beyond
    /// the peers, it samples the environment within the window rather than the window alone.
    pub fn of(strategy: Strategy, guided_available: bool) -> Option<SkyTechnique> {
        match strategy {
            Strategy::Light => None,
            Strategy::Portal => Some(SkyTechnique::WindowArea),
            Strategy::Projection => Some(SkyTechnique::SolidAngle),
            Strategy::Antishadow if guided_available => Some(SkyTechnique::Guided),
            // A constant sky is uniform within the window: the solid angle is exact.
            Strategy::Antishadow => Some(SkyTechnique::SolidAngle),
        }
    }
}

/// One window's part in the mixture at a shading point.
#[derive(Clone, Debug)]
pub struct WindowTerm {
    pub window: usize,
    pub technique: SkyTechnique,
    /// `w_j(x)`; the terms' weights sum to 1.
    pub weight: f32,
    /// The window seen from x (solid-angle technique, and weights).
    pub spherical: Option<SphericalPolygon>,
    /// The window's box in the guided parameterisation (guided technique).
    pub guided: Option<GuidedBox>,
    /// Guided technique: the probability that it draws the environment's sun
    /// ([`Environment::sample_hot`](super::environment::Environment::sample_hot)) rather than
    /// the window's table, `A / (A + B)` (`docs/method.md` §9.4): `A` the sun's power where
    /// the whole sun shows through the window from `x` (the box then reads the table of the
    /// sky without it), else 0; `B` the box's table integral.
    pub hot_share: f32,
}

/// What the estimator knows about the environment at one shading point.
#[derive(Clone, Debug)]
pub struct SkyContext {
    pub x: Vec3,
    pub alpha: f32,
    /// Whether the strategy uses windows and the scene has some.
    pub has_windows: bool,
    /// Whether `x` is in front of a window (else environment sampling alone).
    pub uses_windows: bool,
    pub terms: ArrayVec<WindowTerm, MAX_TERMS>,
    /// `Antiantumbra` in front of a window, else `Behind`.
    pub region: Region,
}

impl SkyContext {
    pub fn new() -> Self {
        SkyContext {
            x: Vec3::ZERO,
            alpha: 1.0,
            has_windows: false,
            uses_windows: false,
            terms: ArrayVec::new(),
            region: Region::Behind,
        }
    }

    /// Whether both shares draw something here: the point is in front of a window that has
    /// a technique, and `0 < alpha < 1`. There `Mixture::EachShare` draws from each.
    pub fn both_shares_draw(&self) -> bool {
        self.uses_windows && !self.terms.is_empty() && self.alpha > 0.0 && self.alpha < 1.0
    }
}

impl Default for SkyContext {
    fn default() -> Self {
        Self::new()
    }
}

/// A direction drawn towards the sky.
#[derive(Clone, Copy, Debug)]
pub struct SkySample {
    pub wi: Vec3,
    /// The environment's radiance along `wi` (before occlusion).
    pub le: Vec3,
    /// The mixture pdf `q(wi)`, solid angle, excluding the light-selection probability.
    pub pdf: f32,
    pub technique: SkyTechnique,
    /// The drawing technique's own density for `wi`, as its sampling procedure computed it.
    pub technique_pdf: f32,
}

/// The environment's alpha: the largest of its windows' (0 without windows), or the override.
pub fn windows_alpha(scene: &impl LightSet, alpha_override: Option<f32>) -> f32 {
    let authored = scene.windows().iter().map(|w| w.alpha).fold(0.0, f32::max);
    alpha_override.unwrap_or(authored).clamp(0.0, 1.0)
}

/// Samples the environment through the scene's windows under one strategy.
#[derive(Clone, Debug)]
pub struct SkySampler {
    strategy: Strategy,
    alpha: f32,
}

impl SkySampler {
    /// `alpha_override` replaces every window's alpha.
    pub fn new(scene: &impl LightSet, strategy: Strategy, alpha_override: Option<f32>) -> Self {
        SkySampler {
            strategy,
            alpha: windows_alpha(scene, alpha_override),
        }
    }

    pub fn strategy(&self) -> Strategy {
        self.strategy
    }

    /// The windows `x` is in front of and the mixture there.
    pub fn context(&self, scene: &impl LightSet, x: Vec3) -> SkyContext {
        let mut ctx = SkyContext::new();
        self.fill_context(scene, x, &mut ctx);
        ctx
    }

    /// [`Self::context`] into a reused buffer.
    #[inline(always)]
    pub fn fill_context(&self, scene: &impl LightSet, x: Vec3, ctx: &mut SkyContext) {
        let windows = scene.windows();
        ctx.x = x;
        ctx.alpha = self.alpha;
        ctx.uses_windows = false;
        ctx.has_windows = self.strategy != Strategy::Light && !windows.is_empty();
        ctx.terms.clear();
        ctx.region = Region::Behind;
        if !ctx.has_windows {
            return;
        }
        let sun_power = scene
            .environment()
            .and_then(|e| e.hot_spot())
            .map_or(0.0, |(power, _, _)| power);
        let in_front = windows.iter().enumerate().filter(|(_, w)| w.in_front(x));
        let several = windows.iter().filter(|w| w.in_front(x)).count() > 1;
        for (j, window) in in_front.take(MAX_TERMS) {
            ctx.uses_windows = true;
            ctx.region = Region::Antiantumbra;
            let Some(technique) = SkyTechnique::of(self.strategy, window.is_guided()) else {
                continue;
            };
            if ctx
                .terms
                .try_push(WindowTerm {
                    window: j,
                    technique,
                    weight: 1.0,
                    spherical: None,
                    guided: None,
                    hot_share: 0.0,
                })
                .is_err()
            {
                break;
            }
            let Some(term) = ctx.terms.last_mut() else {
                break;
            };
            // The guided technique's weight `A + B` (see `WindowTerm::hot_share`).
            let mut guided_weight = 0.0;
            if technique == SkyTechnique::Guided {
                // Where the whole sun shows through the window, the table of the sky without
                // it and the sun drawn on its own; elsewhere the table of the whole sky.
                term.guided = window.guided_box_split(x);
                if let Some(b) = &term.guided {
                    let sky = b.integral() as f32;
                    let sun = match b.is_sunless() {
                        true => sun_power,
                        false => 0.0,
                    };
                    guided_weight = sky + sun;
                    term.hot_share = if guided_weight > 0.0 {
                        sun / guided_weight
                    } else {
                        0.0
                    };
                }
            }
            if technique == SkyTechnique::SolidAngle
                || (several && technique != SkyTechnique::Guided)
            {
                term.spherical = window.solid_angle(x);
            }
            if several {
                // Guided terms share by the environment's weight through each window's box
                // (its table integral), so that the window that sees the sun gets the samples;
                // the others by solid angle. Either depends on x alone.
                term.weight = match technique {
                    SkyTechnique::Guided => guided_weight,
                    _ => term.spherical.as_ref().map_or(0.0, |q| q.solid_angle()),
                };
            }
            let usable = match technique {
                SkyTechnique::SolidAngle => term.spherical.is_some(),
                SkyTechnique::Guided => term.guided.is_some(),
                _ => true,
            };
            if term.weight <= 0.0 || !usable {
                ctx.terms.pop();
            }
        }
        let total: f32 = ctx.terms.iter().map(|t| t.weight).sum();
        for term in ctx.terms.iter_mut() {
            term.weight /= total;
        }
    }

    /// Draws a direction from the mixture: the share by `u.x` (stretched back to a uniform
    /// number), the window by `u_technique`, the direction by `u`; `None` when the drawn share
    /// draws nothing (a guided draw outside its window, an edge-on window) or the scene has no
    /// environment.
    #[inline(always)]
    pub fn sample(
        &self,
        scene: &impl LightSet,
        ctx: &SkyContext,
        u_technique: f32,
        u: Vec2,
    ) -> Option<SkySample> {
        // The share (environment or windows) is picked by `u.x` ([`split_share`]), so that
        // under Sobol' points the count of draws that find the sun is stratified in each.
        let environment_share = if ctx.uses_windows { ctx.alpha } else { 1.0 };
        let (from_environment, u) = split_share(u, environment_share);
        self.sample_share(scene, ctx, from_environment, u_technique, u)
    }

    /// A direction from one share of the mixture with `u` as it is: the environment's
    /// (`from_environment`) or the windows', `u_technique` picking the window among several.
    /// Its pdf is the whole mixture's, whichever share drew it; one sample from each share,
    /// each weighted by its share (`alpha`, `1 − alpha`), estimates the same integral
    /// (`docs/method.md` §9.2, `Mixture::EachShare`).
    #[inline(always)]
    pub fn sample_share(
        &self,
        scene: &impl LightSet,
        ctx: &SkyContext,
        from_environment: bool,
        u_technique: f32,
        u: Vec2,
    ) -> Option<SkySample> {
        let env = scene.environment()?;
        let x = ctx.x;
        let (drawn, (wi, own_pdf)) = match from_environment {
            true => (None, env.sample(u)?),
            false => {
                let term = pick_by_weight(&ctx.terms, |t| t.weight, u_technique)?;
                let window = &scene.windows()[term.window];
                let sampled = match term.technique {
                    SkyTechnique::Environment => env.sample(u)?,
                    SkyTechnique::WindowArea => window.sample_area(x, u)?,
                    SkyTechnique::SolidAngle => term.spherical.as_ref()?.sample(u)?,
                    SkyTechnique::Guided => {
                        // The sun or the table, by `u.x` again (stratified like the shares);
                        // either way `own_pdf` is the table's density, the sun's added below.
                        let b = term.guided.as_ref()?;
                        match split_share(u, term.hot_share) {
                            (true, u) => {
                                let wi = env.sample_hot(u)?;
                                (wi, window.guided_pdf(b, x, wi))
                            }
                            (false, u) => window.sample_guided(b, x, u)?,
                        }
                    }
                };
                (Some(term), sampled)
            }
        };
        // One pixel lookup gives the radiance and the environment's and its sun's densities.
        let (le, p_env, p_hot) = env.radiance_pdfs(wi);
        let technique = drawn.map_or(SkyTechnique::Environment, |t| t.technique);
        let technique_pdf = match drawn {
            Some(t) if t.technique == SkyTechnique::Guided => hot_mixture(t, own_pdf, p_hot),
            _ => own_pdf,
        };
        let drawn = drawn.map(|t| t.window);
        let pdf = if ctx.uses_windows {
            let windows: f32 = ctx
                .terms
                .iter()
                .map(|t| {
                    let p = if Some(t.window) == drawn {
                        technique_pdf
                    } else {
                        window_term_pdf(scene, x, t, p_env, p_hot, wi)
                    };
                    t.weight * p
                })
                .sum();
            ctx.alpha * p_env + (1.0 - ctx.alpha) * windows
        } else {
            technique_pdf
        };
        Some(SkySample {
            wi,
            le,
            pdf,
            technique,
            technique_pdf,
        })
    }

    /// The mixture pdf `q(wi)`.
    #[inline(always)]
    pub fn pdf(&self, scene: &impl LightSet, ctx: &SkyContext, wi: Vec3) -> f32 {
        let Some(env) = scene.environment() else {
            return 0.0;
        };
        if !ctx.uses_windows {
            return env.pdf(wi);
        }
        let (_, p_env, p_hot) = env.radiance_pdfs(wi);
        let windows: f32 = ctx
            .terms
            .iter()
            .map(|t| t.weight * window_term_pdf(scene, ctx.x, t, p_env, p_hot, wi))
            .sum();
        ctx.alpha * p_env + (1.0 - ctx.alpha) * windows
    }
}

/// `p_{s_j}(wi | x)`: one window term's technique density (`p_env` is `p_env(wi)`, `p_hot`
/// the sun's [`Environment::hot_pdf`](super::environment::Environment::hot_pdf) at `wi`).
pub fn window_term_pdf(
    scene: &impl LightSet,
    x: Vec3,
    term: &WindowTerm,
    p_env: f32,
    p_hot: f32,
    wi: Vec3,
) -> f32 {
    let window: &Window = &scene.windows()[term.window];
    match term.technique {
        SkyTechnique::Environment => p_env,
        SkyTechnique::WindowArea => window.area_pdf(x, wi),
        SkyTechnique::SolidAngle => term.spherical.as_ref().map_or(0.0, |q| q.pdf(wi)),
        SkyTechnique::Guided => {
            let table = term
                .guided
                .as_ref()
                .map_or(0.0, |b| window.guided_pdf(b, x, wi));
            hot_mixture(term, table, p_hot)
        }
    }
}

/// The guided technique's density: the sun's share `hot_share` at the sun's density, the rest
/// at the table's. With `A`, `B` as in [`WindowTerm::hot_share`] this is
/// `(weight(S) + weight(K)) / (A + B) = weight(L) / (A + B)`, the environment within the window.
#[inline(always)]
fn hot_mixture(term: &WindowTerm, p_table: f32, p_hot: f32) -> f32 {
    if term.hot_share > 0.0 {
        term.hot_share * p_hot + (1.0 - term.hot_share) * p_table
    } else {
        p_table
    }
}
