//! The path tracer: next-event estimation through the portal method, combined with BSDF
//! sampling by multiple importance sampling.

use arrayvec::ArrayVec;
use glam::Vec3;
use std::time::Instant;

mod glass;
mod packet;

use super::continuation::{Continuation, bounce_openings};
use super::shadows::{ShadowQueue, Shadows, TraceNow};
// What the integrator is asked to do (`render::settings`), named with it.
pub use super::settings::{GlassShadows, GuideBounces, RenderSettings};
use super::stats::{Stats, TIMING_STRIDE, timer_overhead};
use crate::asset::desc::AlphaMode;
use crate::light::area::LightPoint;
use crate::light::bounce::{BounceGuide, GuideContext};
use crate::light::estimator::{LightContext, LightSample, LightSampler, PickedLight};
use crate::light::sky::{SkyContext, SkySample, SkySampler};
use crate::light::{LightSet, Mixture, Technique};
use crate::material::Material;
use crate::sampling::{Frame, Sampler, power_heuristic};
use crate::scene::bvh::{Hit, Tracer};
use crate::scene::{NO_ATTRIBUTES, NO_LIGHT, Scene};
use crate::surface::SurfacePoint;

/// A shading point: where light is gathered and the next direction drawn.
struct Shading<'m> {
    /// Ray origin just off the surface, on the side the ray came from.
    x: Vec3,
    /// Geometric normal facing the incoming ray.
    ng: Vec3,
    frame: Frame,
    wo_local: Vec3,
    material: &'m Material,
    /// Where the shading normal is not the interpolated one (a normal map, or a normal bent
    /// toward the viewer), the interpolated normal and the shading normal: the BSDF's value
    /// is faded by Cycles' bump shadowing term ([`Shading::bump_shadowing`]).
    bump: Option<(Vec3, Vec3)>,
    /// Where rays leave for directions below the surface (`wi · ng < 0`), for a material that
    /// transmits through a rough lobe (light reaches it from both sides); `None` for one that
    /// only reflects.
    x_below: Option<Vec3>,
    /// The ray came from behind the geometric normal: inside the mesh, for a volume.
    back: bool,
    /// Beer–Lambert's coefficient of the medium above the surface (the path's) and beneath it
    /// (a volume's inside, entered from the front), for shadow rays that leave either way.
    sigma: Vec3,
    sigma_below: Vec3,
    /// What the next direction is drawn from: the BSDF, or the BSDF and the openings. Light
    /// sampling here is weighted against its density.
    continuation: Continuation<'m>,
}

impl Shading<'_> {
    /// Whether the surface may scatter along `wi` at all: above it, or beneath it if it
    /// transmits (a test before the shading frame's transform).
    #[inline(always)]
    fn may_scatter(&self, wi: Vec3) -> bool {
        self.x_below.is_some() || wi.dot(self.ng) > 0.0
    }

    /// The origin of a ray along `wi` (`wi_local` in the shading frame) if the surface
    /// scatters that way: `x` above the surface, `x_below` beneath it; none where the shading
    /// and the geometric normal disagree on the side (so no light leaks through either).
    #[inline(always)]
    fn origin(&self, wi: Vec3, wi_local: Vec3) -> Option<Vec3> {
        let above = wi.dot(self.ng) > 0.0;
        match (above, wi_local.z > 0.0) {
            (true, true) => Some(self.x),
            (false, false) => self.x_below,
            _ => None,
        }
    }

    /// The transmittance of the medium on the side of a ray leaving along `wi_local` (above
    /// the surface if `wi_local.z > 0`) over the distance `t`.
    #[inline(always)]
    fn absorption(&self, wi_local: Vec3, t: f32) -> Vec3 {
        beer_lambert(self.medium_along(wi_local), t)
    }

    /// The absorption of the medium a ray along `wi_local` travels in.
    #[inline(always)]
    fn medium_along(&self, wi_local: Vec3) -> Vec3 {
        if wi_local.z > 0.0 {
            self.sigma
        } else {
            self.sigma_below
        }
    }

    /// The normal the light selection weighs lights by: `Vec3::ZERO` (no side) where light
    /// arrives from both sides.
    #[inline(always)]
    fn pick_normal(&self) -> Vec3 {
        match self.x_below {
            Some(_) => Vec3::ZERO,
            None => self.ng,
        }
    }

    /// The factor Cycles puts on the BSDF's value for the world direction `wi`
    /// (`surface::bump_shadowing_term`), 1 where the shading normal is the interpolated one.
    #[inline(always)]
    fn bump_shadowing(&self, wi: Vec3) -> f32 {
        match self.bump {
            Some((ns, n)) => crate::surface::bump_shadowing_term(ns, n, wi),
            None => 1.0,
        }
    }
}

/// The fraction of light that crosses a distance `t` of a medium of absorption `sigma`
/// (1 where it does not absorb, whatever `t`).
#[inline(always)]
fn beer_lambert(sigma: Vec3, t: f32) -> Vec3 {
    if sigma == Vec3::ZERO {
        Vec3::ONE
    } else {
        (-sigma * t).exp()
    }
}

/// The medium beyond a volume's boundary for a ray crossing it from the `back` (leaving it:
/// none, as volumes are not nested) or from the front (its absorption).
#[inline(always)]
fn volume_sigma(material: &Material, back: bool) -> Vec3 {
    match material.volume {
        Some(v) if !back => v.sigma,
        _ => Vec3::ZERO,
    }
}

/// The two light contexts that a path's consecutive shading points fill in turn (the
/// previous one stays for the MIS weight of the BSDF sample). Kept from one path to the next:
/// a context's terms are then rewritten in place, never moved in (a term holds a spherical
/// polygon of over a kilobyte).
pub struct PathContexts {
    even: LightContext,
    odd: LightContext,
    guide: GuideContext,
}

impl PathContexts {
    #[inline(always)]
    pub fn new() -> Self {
        PathContexts {
            even: LightContext::new(),
            odd: LightContext::new(),
            guide: GuideContext::new(),
        }
    }
}

impl Default for PathContexts {
    fn default() -> Self {
        Self::new()
    }
}

/// Where [`Integrator::path`] starts: a ray (its closest hit traced ahead, if `hit` is `Some`;
/// with `at_pane`, that hit is thin glass the path reflects at), or the vertex after one that
/// the packet's stages drew (`render::packet`), with the throughput so far and the previous
/// vertex's `(x, ng, light context filled, continuation pdf)` for MIS.
pub(super) struct PathStart {
    pub o: Vec3,
    pub d: Vec3,
    pub hit: Option<Option<Hit>>,
    pub at_pane: bool,
    pub beta: Vec3,
    pub previous: Option<(Vec3, Vec3, bool, f32)>,
    pub depth: u32,
}

impl PathStart {
    /// A path that starts with the ray `o + t·d`.
    #[inline(always)]
    fn ray(o: Vec3, d: Vec3, hit: Option<Option<Hit>>, at_pane: bool) -> Self {
        PathStart {
            o,
            d,
            hit,
            at_pane,
            beta: Vec3::ONE,
            previous: None,
            depth: 0,
        }
    }
}

/// The next direction a path takes ([`Integrator::scatter`]).
struct Scatter {
    origin: Vec3,
    wi: Vec3,
    wi_local: Vec3,
    /// `f · cos θi / pdf`: what the throughput is multiplied by.
    weight: Vec3,
    pdf: f32,
}

/// Next-event estimation's result at one shading point.
#[derive(Clone, Copy)]
struct Direct {
    /// The MIS-weighted contribution.
    l: Vec3,
    /// Whether an area light was picked and its context filled (reusable for MIS).
    context_filled: bool,
}

/// The previous vertex, for weighting emission that BSDF sampling finds.
struct Previous<'c> {
    x: Vec3,
    /// Its geometric normal, facing the side the path left from (the light pick's `n`).
    ng: Vec3,
    /// The context of the light picked there, if one was.
    ctx: Option<&'c LightContext>,
    bsdf_pdf: f32,
}

pub struct Integrator<'a> {
    scene: &'a Scene,
    lights: LightSampler,
    /// The environment through the windows.
    sky: SkySampler,
    settings: RenderSettings,
    /// Every light is one polygon, and there are few: the last bounce can find the light it
    /// reaches by intersecting the polygons and tracing one occlusion ray, instead of a
    /// closest-hit ray through the whole scene.
    polygon_lights: bool,
    /// The scene's size ([`crate::scene::Geometry::scale`]), for ray offsets: computed once.
    scale: f32,
    /// The scene has thin glass that rays cross ([`crate::scene::Geometry::has_panes`]).
    panes: bool,
    /// The scene has volumes (`KHR_materials_volume`): boundaries that refract, media that
    /// absorb.
    volumes: bool,
    /// The openings paths continue through ([`GuideBounces::On`], a bounce to follow, and
    /// openings with light behind them).
    guide: Option<BounceGuide>,
    /// Some material that reflects and does not emit is exactly Lambertian
    /// ([`Self::stages_pay`]).
    lambertian: bool,
}

/// The most smooth dielectric events (reflections and refractions at a volume's boundary,
/// which do not count as path depth) one path makes; a path that would make more ends.
const MAX_INTERFACE_EVENTS: u32 = 64;

/// The most panes one ray crosses; a ray that would cross more is taken as stopped.
const MAX_PANE_CROSSINGS: u32 = 32;

/// What a BSDF path's ray does at the thin glass it meets ([`Integrator::cross_panes`]).
enum Crossing {
    /// It met `hit` (a surface, glass it stops at, or nothing), having crossed panes or not.
    Met { hit: Option<Hit>, crossed: bool },
    /// Its weight went to zero, or it crossed too many panes: the path ends.
    Absorbed,
}

/// Up to this many polygon lights, the last bounce intersects them directly.
const DIRECT_LIGHT_TEST_LIMIT: usize = 16;

impl<'a> Integrator<'a> {
    pub fn new(scene: &'a Scene, settings: RenderSettings) -> Self {
        let lights = LightSampler::with_selection(
            scene,
            settings.strategy,
            settings.alpha,
            settings.selection,
        );
        Self::with_lights(scene, settings, lights)
    }

    /// [`Self::new`] picking lights with `lights` (tests give it a tree with wrong bounds).
    pub fn with_lights(scene: &'a Scene, settings: RenderSettings, lights: LightSampler) -> Self {
        let settings = RenderSettings {
            selection: lights.selection(),
            ..settings
        };
        let area_lights = &scene.geometry.lights;
        let volumes = scene.geometry.materials.iter().any(|m| m.volume.is_some());
        // Guiding pays only where the vertex the bounce leads to gathers light (not the last).
        let guide = (settings.bounces == GuideBounces::On && settings.max_depth >= 2)
            .then(|| BounceGuide::new(bounce_openings(scene)))
            .filter(|g| !g.is_empty());
        Integrator {
            scene,
            lights,
            sky: SkySampler::new(scene, settings.strategy, settings.alpha),
            settings,
            scale: scene.geometry.scale(),
            panes: scene.geometry.has_panes,
            volumes,
            guide,
            lambertian: (scene.geometry.materials.iter()).any(|m| {
                m.lambertian_albedo().is_some() && !m.is_black() && m.emission == Vec3::ZERO
            }),
            // A cut-out light lets rays through its holes: it must be found by tracing.
            polygon_lights: area_lights.len() <= DIRECT_LIGHT_TEST_LIMIT
                && area_lights.iter().all(|l| l.polygon.is_some())
                // Rays that leave the scene see the environment: the shortcut would miss it.
                && scene.environment.is_none()
                // Light seen through refracting glass is not along the straight line.
                && !volumes
                && scene
                    .geometry
                    .light_surfaces
                    .iter()
                    .flatten()
                    .all(|s| s.surface.alpha_mode == AlphaMode::Opaque),
        }
    }

    /// Whether paths may meet thin glass: `GLASS` is false in the copy of the path that scenes
    /// without glass or volumes run ([`Self::radiance_from`]), which then has none of glass's
    /// branches.
    #[inline(always)]
    fn has_panes<const GLASS: bool>(&self) -> bool {
        GLASS && self.panes
    }

    /// Whether paths may meet volumes: as [`Self::has_panes`].
    #[inline(always)]
    fn has_volumes<const GLASS: bool>(&self) -> bool {
        GLASS && self.volumes
    }

    pub fn settings(&self) -> RenderSettings {
        self.settings
    }

    pub fn scene(&self) -> &Scene {
        self.scene
    }

    pub fn lights(&self) -> &LightSampler {
        &self.lights
    }

    pub fn sky(&self) -> &SkySampler {
        &self.sky
    }

    /// A ray origin just off the surface at `p` on the side of `n`: by [`Self::epsilon`], so
    /// that a scene gives the same image in any units.
    pub fn offset(p: Vec3, n: Vec3, scale: f32) -> Vec3 {
        p + n * Self::epsilon(p, scale)
    }

    /// The origin of a ray leaving `p` along `wi` after a specular event: moved along the ray
    /// itself until it is [`Self::epsilon`] off the surface (normal `ng`), so that the ray's
    /// line stays the one the event made. Moved along the normal instead, a chain of
    /// refractions shifts every ray sideways: through a thick glass globe a bulb looked 0.8%
    /// larger in radius than in Cycles. At grazing angles the step is capped at ten times
    /// the offset.
    #[inline(always)]
    pub fn along(p: Vec3, wi: Vec3, ng: Vec3, scale: f32) -> Vec3 {
        let cos = wi.dot(ng).abs().max(0.1);
        p + wi * (Self::epsilon(p, scale) / cos)
    }

    /// How far off a surface at `p` a ray starts, in a scene of size `scale`
    /// ([`crate::scene::Geometry::scale`]): 2e-4 of `p`'s largest coordinate, above the
    /// rounding of a hit point far from the origin, and 2e-4 more, or 2e-5 of the scene's size
    /// in a scene smaller than 10 units, so that a small scene is not lifted off its own
    /// surfaces (a room in millimetres renders as in metres).
    pub fn epsilon(p: Vec3, scale: f32) -> f32 {
        2e-4 * p.abs().max_element() + (2e-5 * scale).min(2e-4)
    }

    /// How far short of a light its shadow rays stop, so that the light's own triangles do not
    /// occlude it: 1e-5, or 1e-6 of the scene's size in a scene smaller than 10 units.
    fn shadow_gap(scale: f32) -> f32 {
        (1e-6 * scale).min(1e-5)
    }

    /// Where rays leave a shading point at `p` seen along `-wo` (`ng` facing `wo`): off the
    /// surface, and back along the ray that arrived. That segment is empty, so in a corner,
    /// where `p` may round to just behind the other wall, the origin is still in front of both.
    pub fn shading_origin(p: Vec3, ng: Vec3, wo: Vec3, scale: f32) -> Vec3 {
        p + (ng + wo) * Self::epsilon(p, scale)
    }

    /// Radiance arriving at `origin` from direction `-dir`.
    pub fn radiance(&self, origin: Vec3, dir: Vec3, rng: &mut Sampler, stats: &mut Stats) -> Vec3 {
        let mut contexts = PathContexts::new();
        self.radiance_traced(
            &self.scene.geometry.bvh,
            origin,
            dir,
            rng,
            stats,
            &mut contexts,
        )
    }

    /// [`Self::radiance`] with every ray traced through `tracer`: the scene's BVH, or the
    /// benchmark's recorder of it. Always inlined, with the steps it calls: the tile renderer
    /// compiles it once per instruction set (`render::render_tile_scheduled`). `contexts` is
    /// scratch room, reused from path to path.
    #[inline(always)]
    pub fn radiance_traced<T: Tracer>(
        &self,
        tracer: &T,
        origin: Vec3,
        dir: Vec3,
        rng: &mut Sampler,
        stats: &mut Stats,
        contexts: &mut PathContexts,
    ) -> Vec3 {
        self.radiance_from(tracer, origin, dir, None, rng, stats, contexts)
    }

    /// Whether a path's first ray is a closest-hit query, whose answer a caller may trace
    /// ahead for [`Self::radiance_from`]: with polygon lights and no bounce, the camera sees
    /// the lights through `emission_along` instead.
    pub fn camera_hits_traced(&self) -> bool {
        self.settings.max_depth > 0 || !self.polygon_lights
    }

    /// [`Self::radiance_traced`] given the closest hit of the first ray, `origin + t·dir` with
    /// `t` in `(0, ∞)`, if the caller traced it (`Some`, where [`Self::camera_hits_traced`]).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn radiance_from<T: Tracer>(
        &self,
        tracer: &T,
        origin: Vec3,
        dir: Vec3,
        camera_hit: Option<Option<Hit>>,
        rng: &mut Sampler,
        stats: &mut Stats,
        contexts: &mut PathContexts,
    ) -> Vec3 {
        stats.camera_rays += 1;
        // Two copies of the path: scenes without glass run the one without its branches
        // (with them, those scenes' samples took 3–5% longer: docs/performance.md).
        if self.panes || self.volumes {
            let now = &mut TraceNow;
            let start = PathStart::ray(origin, dir, camera_hit, false);
            self.path::<T, true, _>(tracer, start, rng, stats, contexts, now)
        } else {
            let now = &mut TraceNow;
            let start = PathStart::ray(origin, dir, camera_hit, false);
            self.path::<T, false, _>(tracer, start, rng, stats, contexts, now)
        }
    }

    /// Whether paths may queue their shadow rays ([`Self::radiance_queued`]): in scenes
    /// without glass or volumes, whose shadow rays answer only "blocked" or not.
    pub fn queues_shadows(&self) -> bool {
        !(self.panes || self.volumes)
    }

    /// Whether the staged schedule pays ([`crate::render::Schedule::detect`]): where paths
    /// queue their shadow rays and some material is exactly Lambertian, whose first vertices
    /// the packet shades in lanes. Without one the stage only adds its bookkeeping: the
    /// built-ins whose materials all have a specular layer ran up to 5% slower staged
    /// (`docs/performance.md`, the staged schedule).
    pub fn stages_pay(&self) -> bool {
        self.queues_shadows() && self.lambertian
    }

    /// [`Self::radiance_from`] of a path that queues what it gathers in `shadows` (where
    /// [`Self::queues_shadows`]): its shadow rays with their contributions, and what it finds
    /// without one, in order; [`ShadowQueue::resolve`] then adds them to its pixel. Returns
    /// what the path added itself (nothing, in the scenes it runs in).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn radiance_queued<T: Tracer>(
        &self,
        tracer: &T,
        origin: Vec3,
        dir: Vec3,
        camera_hit: Option<Option<Hit>>,
        rng: &mut Sampler,
        stats: &mut Stats,
        contexts: &mut PathContexts,
        shadows: &mut ShadowQueue,
    ) -> Vec3 {
        debug_assert!(self.queues_shadows());
        stats.camera_rays += 1;
        let start = PathStart::ray(origin, dir, camera_hit, false);
        self.path::<T, false, _>(tracer, start, rng, stats, contexts, shadows)
    }

    /// The radiance a path gathers from `start`: a ray whose first hit may be traced ahead
    /// (as in [`Self::radiance_from`]; with `at_pane`, that hit is thin glass the path reflects
    /// at instead of crossing: a camera ray's pane reflection, [`Self::cross_panes`]), or a
    /// later vertex's ray with the path's throughput and previous vertex (the packet's stages,
    /// `packet`).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub(super) fn path<T: Tracer, const GLASS: bool, Q: Shadows>(
        &self,
        tracer: &T,
        start: PathStart,
        rng: &mut Sampler,
        stats: &mut Stats,
        contexts: &mut PathContexts,
        shadows: &mut Q,
    ) -> Vec3 {
        let geometry = &*self.scene.geometry;
        let mut l = Vec3::ZERO;
        let PathStart {
            mut o,
            mut d,
            hit: mut camera_hit,
            mut at_pane,
            mut beta,
            mut previous,
            mut depth,
        } = start;
        // Two context buffers, reused in turn by consecutive vertices (see `fill_context`).
        let PathContexts { even, odd, guide } = contexts;
        // The medium the ray travels in (absorbing inside a volume), and the smooth
        // dielectric events so far, which do not count as depth.
        let mut sigma = Vec3::ZERO;
        let mut interface_events = 0;
        while depth <= self.settings.max_depth {
            // At the last vertex only emission matters: with polygon lights, test them directly.
            if depth == self.settings.max_depth && self.polygon_lights {
                let prev = previous.map(|(x, ng, picked, bsdf_pdf)| Previous {
                    x,
                    ng,
                    ctx: picked.then_some(if depth % 2 == 0 { &*odd } else { &*even }),
                    bsdf_pdf,
                });
                let from = shadows.mark();
                let le =
                    self.emission_along::<T, GLASS, Q>(tracer, o, d, prev.as_ref(), stats, shadows);
                shadows.close(&mut l, from, beta, le);
                break;
            }
            if depth > 0 {
                stats.bounce_rays += 1;
            }
            let mut hit = match camera_hit.take() {
                Some(hit) => hit,
                None => tracer.closest_hit(o, d, 0.0, f32::INFINITY),
            };
            if self.has_panes::<GLASS>() && hit.is_some() && !std::mem::take(&mut at_pane) {
                let last = depth == self.settings.max_depth;
                // A camera ray in the open traces its pane reflections beside the crossing.
                let split = (depth == 0 && sigma == Vec3::ZERO).then_some((&mut *stats, &mut l));
                match self.cross_panes(tracer, (o, d), hit, last, &mut beta, rng, split) {
                    Crossing::Absorbed => break,
                    Crossing::Met { hit: next, crossed } => {
                        hit = next;
                        // Light sampling through glass is off: what lies beyond takes the
                        // full weight.
                        if crossed && self.settings.glass == GlassShadows::Stop {
                            previous = None;
                        }
                    }
                }
            }
            if self.has_volumes::<GLASS>() && sigma != Vec3::ZERO {
                // Inside a volume: absorbed on the way (all of it, if it never leaves).
                match &hit {
                    Some(h) => beta *= beer_lambert(sigma, h.t),
                    None => break,
                }
            }
            let Some(hit) = hit else {
                let le = self.environment_along(d, previous.map(|(x, ng, _, pdf)| (x, ng, pdf)));
                shadows.add(&mut l, beta * le);
                break;
            };
            let tri = &geometry.triangles[hit.triangle as usize];
            let (p, ns) = tri.point(hit.bary);
            let ng = tri.geometric_normal();
            let wo = -d;
            // Textured triangles: the attributes at the hit.
            let point: Option<SurfacePoint> = (tri.attributes != NO_ATTRIBUTES)
                .then(|| geometry.attributes.get(tri.attributes as usize))
                .flatten()
                .map(|a| a.at(hit.bary));
            let surface = point.and_then(|_| {
                geometry
                    .surfaces
                    .get(tri.material as usize)
                    .and_then(Option::as_ref)
            });

            if tri.light != NO_LIGHT {
                let light = tri.light as usize;
                let mut le = geometry.lights[light].emitted(ng, wo);
                if let (Some(s), Some(point)) = (surface, &point) {
                    le *= s.emission_scale(&point.uvs);
                }
                match previous {
                    None => shadows.add(&mut l, beta * le),
                    Some((x, prev_ng, picked, bsdf_pdf)) if le != Vec3::ZERO => {
                        let prev = Previous {
                            x,
                            ng: prev_ng,
                            ctx: picked.then_some(if depth % 2 == 0 { &*odd } else { &*even }),
                            bsdf_pdf,
                        };
                        let y = LightPoint { p, n: ng };
                        let light_pdf = self.light_pdf(&prev, light, d, y, hit.t);
                        shadows.add(
                            &mut l,
                            beta * le * power_heuristic(prev.bsdf_pdf, light_pdf),
                        );
                    }
                    Some(_) => {}
                }
            }
            let material = &geometry.materials[tri.material as usize];
            // A volume's smooth boundary is crossed at any depth: it is not a path vertex.
            let volume = self.has_volumes::<GLASS>() && material.volume.is_some();
            if (depth == self.settings.max_depth && !volume) || material.is_black() {
                break;
            }
            let mapped = surface
                .zip(point.as_ref())
                .and_then(|(s, q)| s.mapped_normal(q, ns));
            let scale = self.scale;
            let Some(mut shading) = Self::shading(p, ns, ng, wo, material, mapped, scale) else {
                break;
            };
            // A textured material is evaluated at the point, for this shading point's `wo`.
            let textured;
            if let (Some(s), Some(point)) = (surface, &point) {
                textured = s.material(&point.uvs, shading.wo_local.z);
                shading.material = &textured;
            }
            // A volume's boundary: its dielectric with the probability of its share, or the rest.
            let component;
            if self.has_volumes::<GLASS>() {
                shading.sigma = sigma;
                shading.sigma_below = sigma;
            }
            if volume {
                let material = shading.material;
                if rng.uniform() < material.dielectric_share() {
                    component = material.dielectric(shading.back);
                    if component.is_smooth_dielectric() {
                        interface_events += 1;
                        if interface_events > MAX_INTERFACE_EVENTS {
                            break;
                        }
                        let (wi_local, weight) =
                            component.sample_smooth_dielectric(shading.wo_local, rng.uniform());
                        let wi = shading.frame.to_world(wi_local);
                        let below = wi_local.z < 0.0;
                        // The shading normal sent it to the other side of the surface.
                        if (wi.dot(shading.ng) < 0.0) != below {
                            break;
                        }
                        if below {
                            sigma = volume_sigma(material, shading.back);
                        }
                        o = Self::along(p, wi, shading.ng, scale);
                        beta *= weight;
                        d = wi;
                        // No light sampling here: what the path meets next takes full weight.
                        previous = None;
                        continue;
                    }
                    shading.x_below = Some(Self::offset(p, -shading.ng, scale));
                    shading.sigma_below = volume_sigma(material, shading.back);
                } else {
                    component = material.opaque_part(shading.wo_local.z);
                }
                shading.material = &component;
                if depth == self.settings.max_depth {
                    break;
                }
            }
            let material = shading.material;
            if let Some(openings) = &self.guide
                && depth == 0
            {
                // The first bounce only: the one the camera sees (a guided vertex pays for its
                // weights and densities, which deeper, dimmer vertices do not repay: measured in
                // docs/performance.md). `guide` exists only from max depth 2 on, so the vertex
                // this bounce leads to gathers light.
                shading.continuation = Continuation::guided(
                    openings,
                    guide,
                    (shading.x, shading.pick_normal()),
                    material.diffuse_probability(shading.wo_local.z),
                );
            }

            // Next-event estimation through the chosen strategy, weighted against the
            // continuation's density.
            let from = shadows.mark();
            let direct = self.sample_direct::<T, GLASS, Q>(
                tracer,
                &shading,
                rng,
                stats,
                if depth % 2 == 0 {
                    &mut *even
                } else {
                    &mut *odd
                },
                shadows,
            );
            let picked = direct.is_some_and(|d| d.context_filled);
            shadows.close(&mut l, from, beta, direct.map_or(Vec3::ZERO, |d| d.l));

            // The next direction: from the BSDF, or through the openings (guided continuation),
            // and MIS for the light it may hit with the mixture's density.
            let last = depth + 1 == self.settings.max_depth;
            let Some(Scatter {
                origin,
                wi,
                wi_local,
                weight,
                pdf,
            }) = self.scatter(&shading, rng, last)
            else {
                break;
            };
            beta *= weight;
            if !beta.is_finite() {
                break;
            }
            // Russian roulette past the second bounce keeps long paths cheap and unbiased.
            if depth >= 2 {
                let survive = beta.max_element().min(0.95);
                if rng.uniform() >= survive {
                    break;
                }
                beta /= survive;
            }
            previous = Some((shading.x, shading.pick_normal(), picked, pdf));
            if self.has_volumes::<GLASS>() {
                sigma = shading.medium_along(wi_local);
            }
            o = origin;
            d = wi;
            depth += 1;
        }
        l
    }

    /// Emitted radiance reaching `o` from direction `-d` when the first surface along `d` is a
    /// light, MIS-weighted against the light technique of the previous vertex (if any). Only
    /// for scenes whose lights are all polygons: the nearest light polygon along the ray is
    /// found directly, and one occlusion ray checks that nothing lies before it.
    #[inline(always)]
    fn emission_along<T: Tracer, const GLASS: bool, Q: Shadows>(
        &self,
        tracer: &T,
        o: Vec3,
        d: Vec3,
        prev: Option<&Previous>,
        stats: &mut Stats,
        shadows: &mut Q,
    ) -> Vec3 {
        let geometry = &*self.scene.geometry;
        let Some((light, t)) = self.nearest_light_polygon(o, d) else {
            return Vec3::ZERO;
        };
        let Some(polygon) = &geometry.lights[light].polygon else {
            return Vec3::ZERO;
        };
        let mut le = geometry.lights[light].emitted(polygon.normal(), -d);
        if let Some(Some(surface)) = geometry.light_surfaces.get(light) {
            le *= surface.emission_scale(o + t * d);
        }
        if le == Vec3::ZERO {
            return Vec3::ZERO;
        }
        stats.shadow_rays += 1;
        // Stop short of the light so that its own triangles do not occlude it. A BSDF path:
        // it crosses panes whatever shadow rays do.
        let tmax = t * (1.0 - 1e-4) - Self::shadow_gap(self.scale);
        // MIS against the light technique at the previous vertex, if any.
        let weighted = |le: Vec3, prev: Option<&Previous>| match prev {
            None => le,
            Some(prev) => {
                let y = LightPoint {
                    p: o + t * d,
                    n: polygon.normal(),
                };
                let light_pdf = self.light_pdf(prev, light, d, y, t);
                le * power_heuristic(prev.bsdf_pdf, light_pdf)
            }
        };
        if Q::QUEUES && !GLASS {
            shadows.queue(o, d, tmax, weighted(le, prev));
            return Vec3::ZERO;
        }
        let (transmittance, crossings) = if self.has_panes::<GLASS>() {
            self.through_panes(tracer, o, d, tmax)
        } else if tracer.occluded(o, d, 0.0, tmax) {
            (Vec3::ZERO, 0)
        } else {
            (Vec3::ONE, 0)
        };
        if transmittance == Vec3::ZERO {
            return Vec3::ZERO;
        }
        let le = le * transmittance;
        // Light sampling through glass is off: past a pane, the full weight.
        let prev = prev.filter(|_| crossings == 0 || self.settings.glass == GlassShadows::Pass);
        weighted(le, prev)
    }

    /// The environment's radiance along `d` for a ray that left the scene, MIS-weighted against
    /// the environment's technique at the previous vertex `(x, ng, bsdf_pdf)` (if any; a camera
    /// ray sees it unweighted). Always inlined, as `sky_direct` is.
    #[inline(always)]
    fn environment_along(&self, d: Vec3, previous: Option<(Vec3, Vec3, f32)>) -> Vec3 {
        let Some(env) = self.scene.environment() else {
            return Vec3::ZERO;
        };
        let le = env.radiance(d);
        match previous {
            None => le,
            Some(_) if le == Vec3::ZERO => Vec3::ZERO,
            Some((x, ng, bsdf_pdf)) => {
                let prob = self.lights.environment_probability(x, ng);
                let light_pdf = if prob > 0.0 {
                    // Filled in place: a context is kilobytes, too large to return by value.
                    let mut ctx = SkyContext::new();
                    self.sky.fill_context(self.scene, x, &mut ctx);
                    prob * self.sky.pdf(self.scene, &ctx, d)
                } else {
                    0.0
                };
                le * power_heuristic(bsdf_pdf, light_pdf)
            }
        }
    }

    /// The next direction from shading point `s`: drawn from its continuation (the BSDF, or
    /// the BSDF and the openings), where a ray leaves for it, and the throughput's factor
    /// `f · cos / pdf` with the continuation's `pdf`; `None` where the path ends there. With
    /// `last` (the vertex it leads to only gathers emission), in a scene of polygon lights, a
    /// direction that meets none ends it before the BSDF is evaluated.
    #[inline(always)]
    fn scatter(&self, s: &Shading, rng: &mut Sampler, last: bool) -> Option<Scatter> {
        let ([u_lobe], u) = rng.uniforms_uniform2();
        let (wi, wi_local) = s
            .continuation
            .sample(s.material, &s.frame, s.wo_local, u_lobe, u)?;
        let origin = s.origin(wi, wi_local)?;
        // Before the last vertex, a direction that meets no light polygon gathers nothing:
        // skip evaluating the BSDF for it (most directions, in these scenes).
        if last && self.polygon_lights && self.nearest_light_polygon(origin, wi).is_none() {
            return None;
        }
        let (f, bsdf_pdf) = s.material.eval_pdf(s.wo_local, wi_local);
        let pdf = s.continuation.pdf(bsdf_pdf, wi);
        if pdf.is_nan() || pdf <= 0.0 || f == Vec3::ZERO {
            return None;
        }
        let weight = f * s.bump_shadowing(wi) * wi_local.z.abs() / pdf;
        Some(Scatter {
            origin,
            wi,
            wi_local,
            weight,
            pdf,
        })
    }

    /// The light whose polygon the ray `o + t·d` meets first, and the distance `t`.
    #[inline(always)]
    fn nearest_light_polygon(&self, o: Vec3, d: Vec3) -> Option<(usize, f32)> {
        // A plain loop: the iterator's `min_by` was left out of line with the polygon test in
        // it, compiled without the renderer's instruction-set features. The first of equal
        // distances wins, as with `min_by`.
        let mut nearest: Option<(usize, f32)> = None;
        for (i, light) in self.scene.geometry.lights.iter().enumerate() {
            let Some(t) = light.polygon.as_ref().and_then(|p| p.intersect(o, d)) else {
                continue;
            };
            if nearest.is_none_or(|(_, best)| t.total_cmp(&best).is_lt()) {
                nearest = Some((i, t));
            }
        }
        nearest
    }

    /// The shading frame on the side the ray came from, or `None` where the shading normal
    /// makes the outgoing direction go below the surface. The shading normal, the normal
    /// map's (`mapped`, for the front side) or else the interpolated one, is bent as Cycles
    /// bends every closure's normal where it would mirror `wo` below the surface
    /// ([`crate::surface::ensure_valid_reflection`]); where it then differs from the
    /// interpolated normal, the BSDF's value is faded as Cycles fades it
    /// ([`crate::surface::bump_shadowing_term`]). Light from below the geometric surface is
    /// refused separately (`wi · ng > 0`), so a tilted normal never leaks light.
    #[inline(always)]
    fn shading<'m>(
        p: Vec3,
        ns: Vec3,
        ng: Vec3,
        wo: Vec3,
        material: &'m Material,
        mapped: Option<Vec3>,
        scale: f32,
    ) -> Option<Shading<'m>> {
        let back = ng.dot(wo) < 0.0;
        let ng = if back { -ng } else { ng };
        let ns = if ns == Vec3::ZERO { ng } else { ns };
        let ns = if ns.dot(ng) < 0.0 { -ns } else { ns };
        // As Cycles' closures: the normal (mapped or interpolated) bent so that it mirrors
        // `wo` above the surface, and where it is no longer the interpolated normal, the
        // BSDF's value faded by the bump shadowing term.
        let n = mapped.map_or(ns, |n| if back { -n } else { n });
        let n = crate::surface::ensure_valid_reflection(ng, wo, n);
        let bump = (n != ns).then_some((ns, n));
        let ns = n;
        let frame = Frame::from_normal(ns);
        let wo_local = frame.to_local(wo);
        (wo_local.z > 0.0).then(|| Shading {
            x: Self::shading_origin(p, ng, wo, scale),
            ng,
            frame,
            wo_local,
            material,
            bump,
            x_below: material
                .transmits_rough()
                .then(|| Self::offset(p, -ng, scale)),
            back,
            sigma: Vec3::ZERO,
            sigma_below: Vec3::ZERO,
            continuation: Continuation::bsdf(),
        })
    }

    /// Picks a light, draws one sample from the strategy's mixture and traces its shadow ray:
    /// the MIS-weighted contribution, or `None` when no light was picked. Leaves an area
    /// light's context in `ctx` for later MIS (a lamp's sample leaves it untouched).
    #[inline(always)]
    fn sample_direct<T: Tracer, const GLASS: bool, Q: Shadows>(
        &self,
        tracer: &T,
        s: &Shading,
        rng: &mut Sampler,
        stats: &mut Stats,
        ctx: &mut LightContext,
        shadows: &mut Q,
    ) -> Option<Direct> {
        let ([u_pick, u_technique], u) = rng.uniforms_uniform2();
        let (light, light_prob) = match self.lights.pick(u_pick, s.x, s.pick_normal())? {
            (PickedLight::Area(light), p) => (light, p),
            (PickedLight::Lamp(lamp), p) => {
                // `ctx` is left as it was: the caller must not reuse it for MIS.
                stats.no_portal += 1;
                stats.count_technique(Technique::Light);
                return Some(Direct {
                    l: self.lamp_direct::<T, GLASS, Q>(tracer, lamp, p, s, stats, shadows),
                    context_filled: false,
                });
            }
            (PickedLight::Environment, p) => {
                return Some(Direct {
                    l: self.sky_direct::<T, GLASS, Q>(
                        tracer,
                        p,
                        s,
                        (u_technique, u),
                        stats,
                        shadows,
                    ),
                    context_filled: false,
                });
            }
        };
        let timed = stats.shading_points().is_multiple_of(TIMING_STRIDE);
        let start = timed.then(Instant::now);
        self.lights.fill_context(self.scene, light, s.x, ctx);
        if self.settings.mixture == Mixture::EachShare && ctx.both_shares_draw() {
            let l = self.each_share_direct::<T, GLASS, Q>(
                tracer,
                (light, light_prob),
                s,
                (u_technique, u),
                ctx,
                start,
                stats,
                shadows,
            );
            return Some(Direct {
                l,
                context_filled: true,
            });
        }
        let sample = self.lights.sample(self.scene, ctx, u_technique, u);
        if let Some(start) = start {
            let spent = start.elapsed().saturating_sub(timer_overhead());
            stats.sampling_ns += spent.as_nanos() as u64 * TIMING_STRIDE;
        }
        if ctx.has_portals {
            stats.count_region(ctx.region);
        } else {
            stats.no_portal += 1;
        }
        let l = match &sample {
            Some(sample) => {
                stats.count_technique(sample.technique);
                self.direct::<T, GLASS, Q>(
                    tracer,
                    sample,
                    (light, light_prob),
                    1.0,
                    s,
                    stats,
                    shadows,
                )
            }
            None => {
                stats.empty_samples += 1;
                Vec3::ZERO
            }
        };
        Some(Direct {
            l,
            context_filled: true,
        })
    }

    /// Where both shares of the light mixture draw (`Mixture::EachShare`): one sample from
    /// each, with the same `u`, weighted by its share `λ` or `1 − λ` (`docs/method.md` §5;
    /// each sample's expectation is its share of the integral whatever their correlation).
    /// `start` is the light-sampling timer, stopped here after both draws.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn each_share_direct<T: Tracer, const GLASS: bool, Q: Shadows>(
        &self,
        tracer: &T,
        (light, light_prob): (usize, f32),
        s: &Shading,
        (u_technique, u): (f32, glam::Vec2),
        ctx: &LightContext,
        start: Option<Instant>,
        stats: &mut Stats,
        shadows: &mut Q,
    ) -> Vec3 {
        let light_share = ctx.light_share().0;
        let from_light = self
            .lights
            .sample_share(self.scene, ctx, true, u_technique, u);
        let from_portals = self
            .lights
            .sample_share(self.scene, ctx, false, u_technique, u);
        if let Some(start) = start {
            let spent = start.elapsed().saturating_sub(timer_overhead());
            stats.sampling_ns += spent.as_nanos() as u64 * TIMING_STRIDE;
        }
        stats.count_region(ctx.region);
        let mut l = Vec3::ZERO;
        for (sample, share) in [(from_light, light_share), (from_portals, 1.0 - light_share)] {
            match sample {
                Some(sample) => {
                    stats.count_technique(sample.technique);
                    let picked = (light, light_prob);
                    l += self
                        .direct::<T, GLASS, Q>(tracer, &sample, picked, share, s, stats, shadows);
                }
                None => stats.empty_samples += 1,
            }
        }
        l
    }

    /// A lamp's contribution, `f · E · cos θ / P(lamp)` with `E` its irradiance at normal
    /// incidence. A lamp is a delta light: BSDF sampling never finds it, so its sample's MIS
    /// weight is 1.
    #[inline(always)]
    fn lamp_direct<T: Tracer, const GLASS: bool, Q: Shadows>(
        &self,
        tracer: &T,
        lamp: usize,
        lamp_prob: f32,
        s: &Shading,
        stats: &mut Stats,
        shadows: &mut Q,
    ) -> Vec3 {
        let Some(sample) = self.scene.geometry.lamps[lamp].sample(s.x) else {
            return Vec3::ZERO;
        };
        if lamp_prob <= 0.0 || !s.may_scatter(sample.wi) {
            return Vec3::ZERO;
        }
        let wi_local = s.frame.to_local(sample.wi);
        let Some(origin) = s.origin(sample.wi, wi_local) else {
            return Vec3::ZERO;
        };
        let f = s.material.eval_pdf(s.wo_local, wi_local).0 * s.bump_shadowing(sample.wi);
        if f == Vec3::ZERO || wi_local.z == 0.0 {
            return Vec3::ZERO;
        }
        stats.shadow_rays += 1;
        // To the lamp's position (nothing stands at a point light), or to infinity.
        let tmax = if sample.dist.is_finite() {
            sample.dist * (1.0 - 1e-4)
        } else {
            f32::INFINITY
        };
        if Q::QUEUES && !GLASS {
            let c = f * sample.irradiance * wi_local.z.abs() / lamp_prob;
            shadows.queue(origin, sample.wi, tmax, c);
            return Vec3::ZERO;
        }
        let mut transmittance = self.visibility::<T, GLASS>(tracer, origin, sample.wi, tmax);
        if transmittance == Vec3::ZERO {
            return Vec3::ZERO;
        }
        if self.has_volumes::<GLASS>() {
            transmittance *= s.absorption(wi_local, sample.dist);
        }
        f * transmittance * sample.irradiance * wi_local.z.abs() / lamp_prob
    }

    /// The environment's contribution through the windows: one sample of the sky mixture,
    /// its shadow ray to infinity, weighted against BSDF sampling by the power heuristic.
    /// Always inlined, like the area lights' steps: out of line, it and its shadow ray were
    /// compiled for baseline x86-64, not for the renderer's instruction set.
    #[inline(always)]
    fn sky_direct<T: Tracer, const GLASS: bool, Q: Shadows>(
        &self,
        tracer: &T,
        env_prob: f32,
        s: &Shading,
        (u_technique, u): (f32, glam::Vec2),
        stats: &mut Stats,
        shadows: &mut Q,
    ) -> Vec3 {
        let timed = stats.shading_points().is_multiple_of(TIMING_STRIDE);
        let start = timed.then(Instant::now);
        let mut ctx = SkyContext::new();
        self.sky.fill_context(self.scene, s.x, &mut ctx);
        // One sample of the mixture, or one from each share weighted by it (as for area lights).
        let mut samples: ArrayVec<(Option<SkySample>, f32), 2> = ArrayVec::new();
        if self.settings.mixture == Mixture::EachShare && ctx.both_shares_draw() {
            for (from_environment, share) in [(true, ctx.alpha), (false, 1.0 - ctx.alpha)] {
                let sample =
                    self.sky
                        .sample_share(self.scene, &ctx, from_environment, u_technique, u);
                samples.push((sample, share));
            }
        } else {
            samples.push((self.sky.sample(self.scene, &ctx, u_technique, u), 1.0));
        }
        if let Some(start) = start {
            let spent = start.elapsed().saturating_sub(timer_overhead());
            stats.sampling_ns += spent.as_nanos() as u64 * TIMING_STRIDE;
        }
        if ctx.has_windows {
            stats.count_region(ctx.region);
        } else {
            stats.no_portal += 1;
        }
        let mut l = Vec3::ZERO;
        for (sample, share) in samples {
            let Some(sample) = sample else {
                stats.empty_samples += 1;
                continue;
            };
            stats.count_technique(sample.technique.technique());
            let light_pdf = env_prob * sample.pdf;
            l += self.weighted::<T, GLASS, Q>(
                tracer,
                s,
                (sample.wi, sample.le, light_pdf),
                f32::INFINITY,
                share,
                stats,
                shadows,
            );
        }
        l
    }

    /// A light sample's contribution, weighted against BSDF sampling by the power heuristic,
    /// times `share` (as [`Self::weighted`]).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn direct<T: Tracer, const GLASS: bool, Q: Shadows>(
        &self,
        tracer: &T,
        sample: &LightSample,
        (light, light_prob): (usize, f32),
        share: f32,
        s: &Shading,
        stats: &mut Stats,
        shadows: &mut Q,
    ) -> Vec3 {
        let Some((y, dist)) = sample.hit else {
            return Vec3::ZERO;
        };
        // A textured light's emission at the sampled point.
        let le = match self.scene.geometry.light_surfaces.get(light) {
            Some(Some(surface)) => sample.le * surface.emission_scale(y.p),
            _ => sample.le,
        };
        // Stop short of the light so that its own triangles do not occlude it.
        let tmax = dist * (1.0 - 1e-4) - Self::shadow_gap(self.scale);
        let light_pdf = light_prob * sample.pdf;
        let radiance = (sample.wi, le, light_pdf);
        self.weighted::<T, GLASS, Q>(tracer, s, radiance, tmax, share, stats, shadows)
    }

    /// Radiance `le` arriving along `wi`, drawn with density `light_pdf` (selection times
    /// mixture), weighted against BSDF sampling by the power heuristic, times `share` (of the
    /// light mixture, where each share draws); zero if something stands before `tmax`, or the
    /// direction is below the surface or has no density; times the transmittance of the thin
    /// glass crossed ([`Self::visibility`]). Where `shadows` queues, it takes the shadow ray
    /// and the contribution instead: then zero.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn weighted<T: Tracer, const GLASS: bool, Q: Shadows>(
        &self,
        tracer: &T,
        s: &Shading,
        (wi, le, light_pdf): (Vec3, Vec3, f32),
        tmax: f32,
        share: f32,
        stats: &mut Stats,
        shadows: &mut Q,
    ) -> Vec3 {
        if le == Vec3::ZERO || light_pdf.is_nan() || light_pdf <= 0.0 || !s.may_scatter(wi) {
            return Vec3::ZERO;
        }
        let wi_local = s.frame.to_local(wi);
        let Some(origin) = s.origin(wi, wi_local) else {
            return Vec3::ZERO;
        };
        let (f, bsdf_pdf) = s.material.eval_pdf(s.wo_local, wi_local);
        let f = f * s.bump_shadowing(wi);
        if f == Vec3::ZERO {
            return Vec3::ZERO;
        }
        let bsdf_pdf = s.continuation.pdf(bsdf_pdf, wi);
        stats.shadow_rays += 1;
        if Q::QUEUES && !GLASS {
            let c = f * le * wi_local.z.abs() * power_heuristic(light_pdf, bsdf_pdf) / light_pdf;
            shadows.queue(origin, wi, tmax, share * c);
            return Vec3::ZERO;
        }
        let mut transmittance = self.visibility::<T, GLASS>(tracer, origin, wi, tmax);
        if transmittance == Vec3::ZERO {
            return Vec3::ZERO;
        }
        if self.has_volumes::<GLASS>() {
            transmittance *= s.absorption(wi_local, tmax);
        }
        share
            * (f * transmittance * le * wi_local.z.abs() * power_heuristic(light_pdf, bsdf_pdf)
                / light_pdf)
    }

    /// The light technique's pdf (selection times mixture) for the direction `d` from the
    /// previous vertex, which reached point `y` of light `light` at distance `t`.
    #[inline(always)]
    fn light_pdf(&self, prev: &Previous, light: usize, d: Vec3, y: LightPoint, t: f32) -> f32 {
        let prob = self.lights.light_probability(light, prev.x, prev.ng);
        if prob <= 0.0 {
            return 0.0;
        }
        let hit = Some((y, t));
        let q = match prev.ctx {
            Some(ctx) if ctx.light == light => self.lights.pdf(self.scene, ctx, d, hit),
            _ => {
                let ctx = self.lights.context(self.scene, light, prev.x);
                self.lights.pdf(self.scene, &ctx, d, hit)
            }
        };
        prob * q
    }
}
