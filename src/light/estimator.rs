//! The estimator for one light (`docs/method.md` §5): a mixture of light sampling
//! (probability `alpha`) and one technique per portal, always weighted by the pdf of the whole
//! mixture
//!
//! `q(ω) = alpha · p_L(ω) + (1 − alpha) · Σ_j w_j(x) · p_{s_j}(ω | x)`,
//!
//! drawn once ([`LightSampler::sample`], the thesis's single sample) or once from each of its
//! two shares, the light technique's and the others' ([`LightSampler::sample_share`], each
//! sample then weighted by its share: `Mixture::EachShare`).
//!
//! Choices made here: a light's alpha is the largest `portal_light_probability` of its portals
//! (or the user's override); the weights `w_j` are proportional to the solid angle of the light
//! seen through portal `j` (computed only when a point is in front of several portals), so they
//! depend on the point and never on the sample.

use arrayvec::ArrayVec;
use glam::{Vec2, Vec3};

use super::antishadow::Region;
use super::area::{AreaLight, LightPoint};
use super::portal::Portal;
use super::punctual::Lamp;
use super::sky::windows_alpha;
use super::tree::{LightTree, TreeInputs};
use super::{LightSet, MAX_TERMS, Selection, Strategy, Technique, split_share};
use crate::sampling::polygon::{
    Cut, Plane, Verts, clip_convex_in, convex_hull_in_plane, merge_close_into,
    sample_polygon_area_ordered,
};
use crate::sampling::spherical::SphericalPolygon;
use crate::sampling::{Distribution1D, pick_by_weight};

/// One portal's part in the mixture at a shading point.
#[derive(Clone, Debug)]
pub struct PortalTerm {
    pub portal: usize,
    pub region: Region,
    pub technique: Technique,
    /// `w_j(x)`; the terms' weights sum to 1.
    pub weight: f32,
    /// Whether `polygon` holds this point's projection.
    projected: bool,
    /// Room for the light's projection through the portal, seen from x: built in place, and
    /// kept from one shading point to the next (it is over a kilobyte, and a move is a copy).
    polygon: SphericalPolygon,
}

impl PortalTerm {
    /// An unused term, to be filled in place.
    fn empty() -> Self {
        PortalTerm {
            portal: 0,
            region: Region::Behind,
            technique: Technique::Light,
            weight: 0.0,
            projected: false,
            polygon: SphericalPolygon::empty(),
        }
    }

    /// The light's projection through the portal, seen from x (built for the projection
    /// technique, and for every term of a point in front of several portals).
    #[inline(always)]
    pub fn projection(&self) -> Option<&SphericalPolygon> {
        self.projected.then_some(&self.polygon)
    }
}

/// What the estimator knows about one light at one shading point.
#[derive(Clone, Debug)]
pub struct LightContext {
    pub light: usize,
    pub x: Vec3,
    pub alpha: f32,
    /// Whether the strategy uses portals and the light has some.
    pub has_portals: bool,
    /// Whether `x` is in front of a portal of the light (else plain light sampling).
    pub uses_portals: bool,
    /// Whether the mixture is light sampling alone, `q = p_L`: `x` uses no portal, or every
    /// term uses the light technique (antiumbra), when `alpha · p_L + (1 − alpha) · Σ_j w_j ·
    /// p_L` is `p_L` since the weights sum to 1. Sampling and pdf then skip the mixture.
    light_only: bool,
    /// The terms of the mixture are the first `count` of these; the rest are room kept from
    /// earlier shading points, so that a reused context builds its terms without moving one.
    slots: ArrayVec<PortalTerm, MAX_TERMS>,
    count: usize,
    /// The region of `x` for the portal with the largest weight (Behind if it is in front of
    /// none; Outside if outside all), for statistics and overlays.
    pub region: Region,
    /// Whether the light technique samples the light by solid angle (`enclosure`) rather than
    /// by area: antishadow's choice behind every portal of a polygon light, inside its shade,
    /// where area sampling's `d² / cos` explodes a few centimetres from the emitter.
    pub by_solid_angle: bool,
    /// The light polygon seen from `x`, where `by_solid_angle`.
    enclosure: SphericalPolygon,
}

impl LightContext {
    /// An empty context, to be filled by [`LightSampler::fill_context`]. Always inlined: a
    /// context is about 10 KB of mostly unused room, and a call returning it by value copies
    /// all of it (the renderer makes two per path; uninlined, that copy took a third of a
    /// light-sampling render).
    #[inline(always)]
    pub fn new() -> Self {
        LightContext {
            light: 0,
            x: Vec3::ZERO,
            alpha: 1.0,
            has_portals: false,
            uses_portals: false,
            light_only: true,
            slots: ArrayVec::new(),
            count: 0,
            region: Region::Behind,
            by_solid_angle: false,
            enclosure: SphericalPolygon::empty(),
        }
    }

    /// One term per portal the mixture uses at `x`.
    #[inline(always)]
    pub fn terms(&self) -> &[PortalTerm] {
        &self.slots[..self.count]
    }

    /// `(λ, w_other)`: the light technique's share of the mixture, and the summed weight of
    /// the terms that use another technique. `λ` is exactly 1 without portals or where every
    /// term uses the light technique (antiumbra), `alpha` outside every antishadow (no terms:
    /// the rest draws nothing), else `alpha + (1 − alpha) · Σ_{light terms} w_j`.
    #[inline(always)]
    pub fn light_share(&self) -> (f32, f32) {
        if self.light_only {
            return (1.0, 0.0);
        }
        let (mut light_terms, mut other) = (0.0, 0.0);
        for t in self.terms() {
            if t.technique == Technique::Light {
                light_terms += t.weight;
            } else {
                other += t.weight;
            }
        }
        let all_light = other == 0.0 && !self.terms().is_empty();
        let share = if !self.uses_portals || all_light {
            1.0
        } else {
            self.alpha + (1.0 - self.alpha) * light_terms
        };
        (share, other)
    }

    /// Whether both shares of the mixture draw something here: the light technique's share
    /// `λ` in (0, 1) and terms of another technique present (antipenumbra, antiantumbra, or
    /// a mix of regions). There [`Mixture::EachShare`](super::Mixture) draws from each.
    #[inline(always)]
    pub fn both_shares_draw(&self) -> bool {
        if self.light_only {
            return false;
        }
        let (light_share, other) = self.light_share();
        other > 0.0 && light_share > 0.0 && light_share < 1.0
    }
}

impl Default for LightContext {
    fn default() -> Self {
        Self::new()
    }
}

/// A direction drawn towards a light, with what it sees there.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Unit direction from the shading point.
    pub wi: Vec3,
    /// The light's point along `wi` and its distance; `None` when the direction misses the
    /// light (a portal sample that passes beside it).
    pub hit: Option<(LightPoint, f32)>,
    /// Radiance arriving along `wi` (zero for a miss or the light's back).
    pub le: Vec3,
    /// The mixture pdf `q(wi)`, solid angle, excluding the light-selection probability.
    pub pdf: f32,
    pub technique: Technique,
    /// The drawing technique's own density for `wi`, as its sampling procedure computed it.
    pub technique_pdf: f32,
}

pub use super::tree::PickedLight;

/// Samples lights for a scene under one strategy.
#[derive(Clone, Debug)]
pub struct LightSampler {
    strategy: Strategy,
    selection: Selection,
    /// Area lights, then lamps, then the environment (if any), by power.
    by_power: Distribution1D,
    /// The lights' bounds, for [`Selection::Tree`] (empty for power).
    tree: LightTree,
    /// How many area lights come first in `by_power`.
    area_lights: usize,
    /// How many lamps follow them.
    lamps: usize,
    /// Portal indices of each light.
    portals_of: Vec<ArrayVec<usize, MAX_TERMS>>,
    /// Alpha of each light.
    alpha_of: Vec<f32>,
}

impl LightSampler {
    /// `alpha_override` replaces every portal's alpha (the CLI's `--alpha`, the viewer's slider).
    /// Lights are picked by the tree ([`Selection::Tree`]).
    pub fn new(scene: &impl LightSet, strategy: Strategy, alpha_override: Option<f32>) -> Self {
        Self::with_selection(scene, strategy, alpha_override, Selection::Tree)
    }

    /// [`Self::new`] picking lights by `selection`.
    pub fn with_selection(
        scene: &impl LightSet,
        strategy: Strategy,
        alpha_override: Option<f32>,
        selection: Selection,
    ) -> Self {
        let lights = &scene.lights();
        let mut portals_of = vec![ArrayVec::new(); lights.len()];
        for (i, p) in scene.portals().iter().enumerate() {
            // Past MAX_TERMS portals on one light, the rest are ignored (counted in the UI).
            let _ = portals_of[p.light].try_push(i);
        }
        let alpha_of = portals_of
            .iter()
            .map(|ps| {
                let authored = ps
                    .iter()
                    .map(|&i| scene.portals()[i].alpha)
                    .fold(0.0, f32::max);
                alpha_override.unwrap_or(authored).clamp(0.0, 1.0)
            })
            .collect::<Vec<f32>>();
        let tree = match selection {
            Selection::Tree => LightTree::new(
                scene,
                &TreeInputs {
                    portal_aware: strategy != Strategy::Light,
                    portals_of: &portals_of,
                    alpha_of: &alpha_of,
                    environment_alpha: windows_alpha(scene, alpha_override),
                },
            ),
            Selection::Power => LightTree::default(),
        };
        LightSampler {
            strategy,
            selection,
            tree,
            by_power: Distribution1D::new(
                lights
                    .iter()
                    .map(AreaLight::power)
                    .chain(scene.lamps().iter().map(Lamp::power))
                    .chain(scene.environment().map(|e| e.power())),
            ),
            area_lights: lights.len(),
            lamps: scene.lamps().len(),
            portals_of,
            alpha_of,
        }
    }

    /// [`Self::new`] picking lights by `tree` (tests give it wrong bounds).
    pub fn with_tree(
        scene: &impl LightSet,
        strategy: Strategy,
        alpha_override: Option<f32>,
        tree: LightTree,
    ) -> Self {
        LightSampler {
            tree,
            selection: Selection::Tree,
            ..Self::with_selection(scene, strategy, alpha_override, Selection::Power)
        }
    }

    /// How lights are picked.
    pub fn selection(&self) -> Selection {
        self.selection
    }

    /// The light tree ([`Selection::Tree`]; empty for power).
    pub fn tree(&self) -> &LightTree {
        &self.tree
    }

    /// Picks an area light, a lamp or the environment for the shading point `x` with normal
    /// `n` (facing the side light is gathered from): which, and its probability. `None` where
    /// nothing can be picked (no light, or none that can reach `x`).
    #[inline(always)]
    pub fn pick(&self, u: f32, x: Vec3, n: Vec3) -> Option<(PickedLight, f32)> {
        if self.selection == Selection::Tree {
            return self.tree.pick(u, x, n);
        }
        let (i, p, _) = self.by_power.sample(u)?;
        let picked = match i.checked_sub(self.area_lights) {
            None => PickedLight::Area(i),
            Some(k) if k < self.lamps => PickedLight::Lamp(k),
            Some(_) => PickedLight::Environment,
        };
        Some((picked, p))
    }

    /// The probability that [`Self::pick`] picks `light` at `x` with normal `n`.
    #[inline(always)]
    pub fn probability(&self, light: PickedLight, x: Vec3, n: Vec3) -> f32 {
        if self.selection == Selection::Tree {
            return self.tree.probability(light, x, n);
        }
        self.by_power.pmf(match light {
            PickedLight::Area(i) => i,
            PickedLight::Lamp(k) => self.area_lights + k,
            PickedLight::Environment => self.area_lights + self.lamps,
        })
    }

    /// The probability of picking area light `light` at `x` with normal `n`.
    pub fn light_probability(&self, light: usize, x: Vec3, n: Vec3) -> f32 {
        self.probability(PickedLight::Area(light), x, n)
    }

    /// The probability of picking the environment at `x` with normal `n` (0 without one).
    pub fn environment_probability(&self, x: Vec3, n: Vec3) -> f32 {
        self.probability(PickedLight::Environment, x, n)
    }

    /// Classifies `x` against the light's portals and fixes the mixture there.
    pub fn context(&self, scene: &impl LightSet, light: usize, x: Vec3) -> LightContext {
        let mut ctx = LightContext::new();
        self.fill_context(scene, light, x, &mut ctx);
        ctx
    }

    /// [`Self::context`] into a reused buffer: a context holds a spherical polygon per portal,
    /// too large to move around per shading point. Inlined with the classification, which
    /// the renderer's instruction-set variants then compile with their features.
    #[inline(always)]
    pub fn fill_context(
        &self,
        scene: &impl LightSet,
        light: usize,
        x: Vec3,
        ctx: &mut LightContext,
    ) {
        self.fill_context_classified(scene, light, x, ctx, &ByPlanes);
    }

    /// [`Self::fill_context`] with the regions given by `classify`. Any classifier keeps the
    /// estimator unbiased (`docs/method.md` §5): a region only picks the techniques, whose
    /// densities are always evaluated exactly, and alpha's light share covers every direction
    /// to the light. Tests pass deliberately wrong classifiers to show it.
    #[inline(always)]
    pub fn fill_context_classified(
        &self,
        scene: &impl LightSet,
        light: usize,
        x: Vec3,
        ctx: &mut LightContext,
        classify: &(impl Classifier + ?Sized),
    ) {
        ctx.light = light;
        ctx.x = x;
        ctx.alpha = self.alpha_of[light];
        ctx.uses_portals = false;
        ctx.light_only = true;
        ctx.has_portals = self.strategy != Strategy::Light && !self.portals_of[light].is_empty();
        ctx.count = 0;
        ctx.region = Region::Behind;
        ctx.by_solid_angle = false;
        if !ctx.has_portals {
            return;
        }
        // Classify first, then build each term once, in place: a term holds a large
        // spherical polygon, so it is never moved (a context reused from point to point
        // rewrites the terms it already has room for).
        let mut candidates: ArrayVec<(usize, Region, Technique), MAX_TERMS> = ArrayVec::new();
        for &j in &self.portals_of[light] {
            let region = classify.region(&scene.portals()[j], x);
            if region == Region::Behind {
                continue;
            }
            ctx.uses_portals = true;
            ctx.region = Region::Outside;
            if let Some(technique) = self.strategy.technique(region) {
                candidates.push((j, region, technique));
            }
        }
        if !ctx.uses_portals {
            // Behind every portal: inside the enclosure, antishadow samples a polygon light
            // by its solid angle (none from a point in its plane: then by area).
            if self.strategy == Strategy::Antishadow
                && let Some(polygon) = &scene.lights()[light].polygon
            {
                ctx.by_solid_angle = ctx.enclosure.set(x, polygon.vertices());
            }
            return;
        }
        // One light-technique term (the antiumbra of one portal): weight 1, and the mixture
        // is light sampling; the general loop below would give the same term. Kept apart
        // because fig8b's antishadow costs 2.3% more instructions without it (measured).
        if let [(j, region, Technique::Light)] = candidates[..] {
            if ctx.slots.is_empty() {
                ctx.slots.push(PortalTerm::empty());
            }
            if let Some(term) = ctx.slots.first_mut() {
                term.portal = j;
                term.region = region;
                term.technique = Technique::Light;
                term.weight = 1.0;
                term.projected = false;
                ctx.count = 1;
                ctx.region = region;
                return;
            }
        }
        // Weights by the light's solid angle through each portal; one term needs none.
        let several = candidates.len() > 1;
        for (j, region, technique) in candidates {
            if ctx.count == ctx.slots.len() && ctx.slots.try_push(PortalTerm::empty()).is_err() {
                break;
            }
            let Some(term) = ctx.slots.get_mut(ctx.count) else {
                break;
            };
            term.portal = j;
            term.region = region;
            term.technique = technique;
            term.weight = 1.0;
            let needs_projection = several || technique == Technique::Projection;
            term.projected =
                needs_projection && projection_into(&scene.portals()[j], x, &mut term.polygon);
            if several {
                term.weight = if term.projected {
                    term.polygon.solid_angle()
                } else {
                    0.0
                };
            }
            let usable = technique != Technique::Projection || term.projected;
            if term.weight > 0.0 && usable {
                ctx.count += 1;
            }
        }
        let terms = &mut ctx.slots[..ctx.count];
        let total: f32 = terms.iter().map(|t| t.weight).sum();
        let mut all_light = !terms.is_empty();
        for term in terms.iter_mut() {
            term.weight /= total;
            all_light &= term.technique == Technique::Light;
        }
        // In front of portals but outside every antishadow (no terms), the mixture is the
        // `alpha` share of light sampling, not light sampling.
        ctx.light_only = !ctx.uses_portals || all_light;
        if let Some(best) = ctx
            .terms()
            .iter()
            .max_by(|a, b| a.weight.total_cmp(&b.weight))
        {
            ctx.region = best.region;
        }
    }

    /// Draws a direction from the mixture: the light technique (the `alpha` share and the
    /// terms that use it) or another technique by `u.x` (`split_share`), that term among
    /// several by `u_technique`, the direction by the stretched `u`. Where every term uses the
    /// light technique (antiumbra) the mixture is light sampling and `u` is used as it is: one
    /// net over the light, not two stretched ones. `None` when the drawn share has no
    /// technique (a point outside every antishadow draws nothing with probability
    /// `1 − alpha`) or the draw degenerates; both contribute zero.
    #[inline(always)]
    pub fn sample(
        &self,
        scene: &impl LightSet,
        ctx: &LightContext,
        u_technique: f32,
        u: Vec2,
    ) -> Option<LightSample> {
        if ctx.light_only {
            // `split_share` at a share of 1 would return `u` as it is.
            return self.draw_share(scene, ctx, (true, 0.0), u_technique, u, false);
        }
        let (light_share, other) = ctx.light_share();
        let (from_light_share, u) = split_share(u, light_share);
        self.draw_share(scene, ctx, (from_light_share, other), u_technique, u, true)
    }

    /// A direction from one share of the mixture with `u` as it is: the light technique
    /// (`from_light_share`) or the other techniques' terms, picked among them by weight with
    /// `u_technique`. Its `pdf` is the whole mixture's `q`, as for [`Self::sample`]. Drawing
    /// from each share and weighting each sample by its share (`λ`, `1 − λ`) estimates the
    /// same integral as one draw of [`Self::sample`] (`docs/method.md` §5). `None` when the
    /// share has no technique or the draw degenerates.
    #[inline(always)]
    pub fn sample_share(
        &self,
        scene: &impl LightSet,
        ctx: &LightContext,
        from_light_share: bool,
        u_technique: f32,
        u: Vec2,
    ) -> Option<LightSample> {
        let other = ctx.light_share().1;
        // The light drawn plainly: beside a sample of the other share its zeros weigh only
        // `λ`, and the ordered draw's clips cost more than they save (fig8c: MSE 6% lower at
        // 37% more instructions per sample).
        self.draw_share(scene, ctx, (from_light_share, other), u_technique, u, false)
    }

    /// [`Self::sample_share`] given the other techniques' summed weight `other`; `ordered`
    /// draws the light technique's part hidden by the portal from the lowest `u.x`.
    #[inline(always)]
    fn draw_share(
        &self,
        scene: &impl LightSet,
        ctx: &LightContext,
        (from_light_share, other): (bool, f32),
        u_technique: f32,
        u: Vec2,
        ordered: bool,
    ) -> Option<LightSample> {
        let light = &scene.lights()[ctx.light];
        let x = ctx.x;
        // Each route returns the direction, the light hit, and the technique's density as the
        // sampling procedure sees it (tests compare it with the evaluation in `pdf`).
        let from_light = |y: LightPoint| {
            let v = y.p - x;
            let dist = v.length();
            let wi = v / dist;
            (dist > 0.0).then(|| {
                (
                    wi,
                    Some((y, dist)),
                    light.pdf_solid_angle(dist, y.n.dot(wi)),
                )
            })
        };
        let term = if from_light_share {
            None
        } else {
            // The term among the others by weight (their weights sum to `other`).
            let others = ctx
                .terms()
                .iter()
                .filter(|t| t.technique != Technique::Light);
            Some(pick_by_weight(others, |t| t.weight, u_technique * other)?)
        };
        let technique = term.map_or(Technique::Light, |t| t.technique);
        let (wi, hit, technique_pdf) = match (technique, term) {
            (Technique::Portal, Some(t)) => {
                let (wi, pdf) = sample_portal(&scene.portals()[t.portal], x, u)?;
                (wi, self.light_hit(scene, ctx.light, x, wi), pdf)
            }
            (Technique::Projection, Some(t)) => {
                let (wi, pdf) = t.projection()?.sample(u)?;
                (wi, self.light_hit(scene, ctx.light, x, wi), pdf)
            }
            // The light technique beside another one: its part that `x` does not see through
            // the heaviest other term's portal comes from the lowest `u.x`. Where the portal
            // is the only opening that part is occluded, and its zeros are then as evenly
            // counted as stratified `u.x` allows (`docs/method.md` §5). Same density.
            _ if ctx.by_solid_angle => {
                let (wi, pdf) = ctx.enclosure.sample(u)?;
                (wi, self.light_hit(scene, ctx.light, x, wi), pdf)
            }
            _ => match (
                &light.polygon,
                ordered
                    .then(|| self.seen_through_portal(scene, ctx, other))
                    .flatten(),
            ) {
                (Some(polygon), Some(cut)) => from_light(LightPoint {
                    p: sample_polygon_area_ordered(polygon.vertices(), &cut, u),
                    n: polygon.normal(),
                })?,
                _ => from_light(light.sample_point(u)?)?,
            },
        };
        let le = hit.map_or(Vec3::ZERO, |(y, _)| light.emitted(y.n, -wi));
        // Where the mixture is light sampling alone, its density is in hand.
        let pdf = if ctx.light_only {
            technique_pdf
        } else {
            self.pdf(scene, ctx, wi, hit)
        };
        Some(LightSample {
            wi,
            hit,
            le,
            pdf,
            technique,
            technique_pdf,
        })
    }

    /// The half-spaces that hold the part of the light that the context's point sees through
    /// the portal of its heaviest term of another technique than the light's (`other` is
    /// their total weight); `None` without such a term.
    #[inline(always)]
    fn seen_through_portal(
        &self,
        scene: &impl LightSet,
        ctx: &LightContext,
        other: f32,
    ) -> Option<Cut> {
        if other <= 0.0 {
            return None;
        }
        let term = ctx
            .terms()
            .iter()
            .filter(|t| t.technique != Technique::Light)
            .max_by(|a, b| a.weight.total_cmp(&b.weight))?;
        scene.portals()[term.portal].seen_through_from(ctx.x)
    }

    /// Where the ray from the context's point along `wi` first meets the light, ignoring
    /// occluders (the shadow ray checks them): the point a portal or projection sample lands
    /// on, whose area density enters `p_L`.
    #[inline(always)]
    pub fn light_hit(
        &self,
        scene: &impl LightSet,
        light: usize,
        x: Vec3,
        wi: Vec3,
    ) -> Option<(LightPoint, f32)> {
        scene.lights()[light].intersect(x, wi)
    }

    /// The mixture pdf `q(wi)` for a direction whose light hit is `hit` (point and distance).
    #[inline(always)]
    pub fn pdf(
        &self,
        scene: &impl LightSet,
        ctx: &LightContext,
        wi: Vec3,
        hit: Option<(LightPoint, f32)>,
    ) -> f32 {
        let p_light = self.light_technique_pdf(scene, ctx, wi, hit);
        if ctx.light_only {
            return p_light;
        }
        // A plain loop: the iterator's `sum` was left out of line, compiled without the
        // renderer's instruction-set features (about 150 instructions per call in fig8c).
        let mut portals = 0.0f32;
        for t in ctx.terms() {
            portals += t.weight * term_pdf(scene, ctx.x, t, p_light, wi);
        }
        ctx.alpha * p_light + (1.0 - ctx.alpha) * portals
    }

    /// The density of the directions [`Self::sample`] draws, for tests that integrate or bin
    /// them: [`Self::pdf`] at the first light hit, plus the light technique's share of the
    /// density of the points further along `wi` (a ray crosses a bulb twice). The estimator
    /// weights each sample by [`Self::pdf`] at its own light point instead, which is exact in
    /// area measure; the two agree for a polygon light.
    pub fn direction_pdf(&self, scene: &impl LightSet, ctx: &LightContext, wi: Vec3) -> f32 {
        let hit = self.light_hit(scene, ctx.light, ctx.x, wi);
        let first = self.light_pdf(scene, ctx.light, wi, hit);
        let beyond = (scene.lights()[ctx.light].direction_pdf(ctx.x, wi) - first).max(0.0);
        self.pdf(scene, ctx, wi, hit) + ctx.light_share().0 * beyond
    }

    /// The light technique's pdf at the context's point for a direction whose light hit is
    /// `hit`: [`Self::light_pdf`], or by solid angle where the context says so.
    #[inline(always)]
    pub fn light_technique_pdf(
        &self,
        scene: &impl LightSet,
        ctx: &LightContext,
        wi: Vec3,
        hit: Option<(LightPoint, f32)>,
    ) -> f32 {
        if ctx.by_solid_angle {
            return hit.map_or(0.0, |_| ctx.enclosure.pdf(wi));
        }
        self.light_pdf(scene, ctx.light, wi, hit)
    }

    /// The light technique's area-sampling pdf `p_L(wi)` for a direction whose light hit is
    /// `hit`.
    #[inline(always)]
    pub fn light_pdf(
        &self,
        scene: &impl LightSet,
        light: usize,
        wi: Vec3,
        hit: Option<(LightPoint, f32)>,
    ) -> f32 {
        let light = &scene.lights()[light];
        hit.map_or(0.0, |(y, d)| light.pdf_solid_angle(d, y.n.dot(wi)))
    }
}

/// What gives [`LightSampler::fill_context_classified`] a point's region for a portal: the
/// portal's precomputed planes ([`ByPlanes`]), or any function of (portal, point).
pub trait Classifier {
    fn region(&self, portal: &Portal, x: Vec3) -> Region;
}

/// The classifier of [`LightSampler::fill_context`]: the portal's precomputed planes. A type
/// rather than a function item, whose `Fn::call` shim the renderer's instruction-set variants
/// called out of line (about 200 instructions per shading point in fig8b).
pub struct ByPlanes;

impl Classifier for ByPlanes {
    #[inline(always)]
    fn region(&self, portal: &Portal, x: Vec3) -> Region {
        portal.planes.classify(x)
    }
}

impl<F: Fn(&Portal, Vec3) -> Region + ?Sized> Classifier for F {
    #[inline(always)]
    fn region(&self, portal: &Portal, x: Vec3) -> Region {
        self(portal, x)
    }
}

/// `p_{s_j}(wi | x)`: one portal term's technique density (`p_light` is `p_L(wi)`).
#[inline(always)]
pub fn term_pdf(scene: &impl LightSet, x: Vec3, term: &PortalTerm, p_light: f32, wi: Vec3) -> f32 {
    match term.technique {
        Technique::Light => p_light,
        Technique::Portal => portal_pdf(&scene.portals()[term.portal], x, wi),
        Technique::Projection => term.projection().map_or(0.0, |q| q.pdf(wi)),
    }
}

/// The portal technique: a direction through a uniform point of the portal, with its
/// solid-angle pdf ([`crate::sampling::polygon::ConvexPolygon::sample_direction`]).
pub fn sample_portal(portal: &Portal, x: Vec3, u: Vec2) -> Option<(Vec3, f32)> {
    portal.polygon.sample_direction(x, u)
}

/// The solid-angle pdf of [`sample_portal`]: `d² / (A_P |cos θ_P|)` through the portal.
pub fn portal_pdf(portal: &Portal, x: Vec3, wi: Vec3) -> f32 {
    portal.polygon.direction_pdf(x, wi)
}

/// `Q(x)`: the light (clipped behind the portal plane; for a light of any shape, its solid)
/// projected from `x` onto the portal plane and clipped to the portal, as seen from `x`.
pub fn projection(portal: &Portal, x: Vec3) -> Option<SphericalPolygon> {
    let mut q = SphericalPolygon::empty();
    projection_into(portal, x, &mut q).then_some(q)
}

/// [`projection`] built in `q` (over a kilobyte, so built where the context keeps it); false,
/// leaving `q` empty, where `projection` gives `None`.
#[inline(always)]
pub fn projection_into(portal: &Portal, x: Vec3, q: &mut SphericalPolygon) -> bool {
    let mut vertices = Verts::new();
    projected_light_into(portal, x, &mut vertices);
    vertices.len() >= 3 && q.set(x, &vertices)
}

/// The vertices of `Q(x)` on the portal plane.
pub fn projected_light(portal: &Portal, x: Vec3) -> Verts {
    let mut q = Verts::new();
    projected_light_into(portal, x, &mut q);
    q
}

/// [`projected_light`] into `q`.
#[inline(always)]
pub fn projected_light_into(portal: &Portal, x: Vec3, q: &mut Verts) {
    q.clear();
    let plane: Plane = portal.polygon.plane();
    let dx = plane.signed_distance(x);
    if dx <= 0.0 {
        return;
    }
    let mut projected = Verts::new();
    for &v in portal.planes.light_behind_portal() {
        // x is in front and v on or behind the plane, so the segment crosses it once.
        let dv = plane.signed_distance(v);
        let _ = projected.try_push(x + (v - x) * (dx / (dx - dv)));
    }
    // A solid's vertices project to a point set: its outline is their convex hull.
    if portal.planes.is_hull() {
        projected = convex_hull_in_plane(&projected, plane.n);
    }
    let (mut first, mut second) = (Verts::new(), Verts::new());
    let clipped = clip_convex_in(&projected, &portal.polygon, &mut first, &mut second);
    // From x on (or within rounding of) an antishadow plane, a projected light vertex lies on a
    // portal edge's line, or a portal vertex on a projected light edge: the clip keeps two
    // copies of one point, and the plane through x and the edge between them, which the
    // spherical polygon's inside test uses, would cut through Q. The copies differ by the
    // clip's rounding, a few ulps of the coordinates; edges as short as 1e-5 of the scene
    // (the light clip's tolerance) carry no shape worth keeping either.
    let mut max_coordinate = 0.0f32;
    for v in clipped {
        max_coordinate = max_coordinate.max(v.abs().max_element());
    }
    let tol = MERGE_TOLERANCE * portal.planes.scale() + 64.0 * f32::EPSILON * max_coordinate;
    // Merged as it is copied into `q`.
    merge_close_into(clipped, tol, q);
    // Wound clockwise as seen from x, as `SphericalPolygon::set` takes it (its winding normal
    // pointing away from x): reversed here in f32, not there in f64 with the edge normals
    // formed again (set still checks the winding, so a wrong guess, from x within rounding
    // of the light's plane, costs only that).
    if portal.planes.projection_winds_counter_clockwise(x) {
        q.reverse();
    }
}

/// Relative to the scene's scale: vertices of `Q(x)` this close merge (see [`projected_light`]).
const MERGE_TOLERANCE: f32 = 1e-5;
