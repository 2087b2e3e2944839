//! Thin glass on a path's rays (`docs/method.md` §6.3): BSDF rays cross panes as null
//! interfaces or stop there to reflect, and shadow rays pass them weighted by their
//! straight-through transmittance. Scenes without glass never call these.

use glam::Vec3;

use super::{Crossing, GlassShadows, Integrator, MAX_PANE_CROSSINGS, PathContexts, PathStart};
use crate::render::shadows::TraceNow;
use crate::render::stats::Stats;
use crate::sampling::Sampler;
use crate::scene::NO_ATTRIBUTES;
use crate::scene::bvh::{Hit, Tracer};

impl Integrator<'_> {
    /// A BSDF path's ray `o + t·d` whose closest hit is `hit`, in a scene with thin glass: it
    /// crosses each pane it meets as a null interface (no vertex, no depth) with the
    /// probability of the pane's transmittance, weighted by it over that probability, or stops
    /// there (weighted by one over the rest) to make it a vertex of its reflection; at the
    /// `last` vertex, where only emission beyond counts, it always crosses.
    ///
    /// A camera ray (`split`: its stats and radiance) always crosses, weighted by the
    /// transmittance; when the same roulette says "stop", the reflection's path is traced too,
    /// with the same weight, and its radiance (path weight included) added to the camera's. The expectation
    /// is the same, and the sky seen through a window loses the roulette's noise (about 4% of
    /// relative variance per face), while the dim room it reflects is traced about once in 25
    /// crossings. That took a pane's cost to antishadow from 29% to 17% (docs/performance.md).
    ///
    /// Out of line: scenes without glass never call it, and its traversals and the
    /// reflection's path would crowd the path loop's code.
    #[allow(clippy::too_many_arguments)]
    #[inline(never)]
    pub(super) fn cross_panes<T: Tracer>(
        &self,
        tracer: &T,
        (o, d): (Vec3, Vec3),
        mut hit: Option<Hit>,
        last: bool,
        beta: &mut Vec3,
        rng: &mut Sampler,
        mut split: Option<(&mut Stats, &mut Vec3)>,
    ) -> Crossing {
        let mut crossings = 0;
        while let Some(h) = hit {
            let Some(transmittance) = self.pane_at(&h, d) else {
                break;
            };
            let p_pass = if last {
                1.0
            } else {
                transmittance.max_element().min(1.0)
            };
            let stops = p_pass < 1.0 && rng.uniform() >= p_pass;
            match split.as_mut() {
                Some((stats, l)) => {
                    if stops {
                        let weight = *beta / (1.0 - p_pass);
                        **l += weight * self.pane_reflection(tracer, (o, d), h, rng, stats);
                    }
                    *beta *= transmittance;
                }
                None if stops => {
                    *beta /= 1.0 - p_pass;
                    break;
                }
                None => *beta *= transmittance / p_pass,
            }
            crossings += 1;
            if crossings > MAX_PANE_CROSSINGS || *beta == Vec3::ZERO {
                return Crossing::Absorbed;
            }
            // The same ray from the same origin, so `t` stays the distance to the vertex.
            let tmin = h.t + Self::epsilon(o + h.t * d, self.scale);
            hit = tracer.closest_hit(o, d, tmin, f32::INFINITY);
        }
        Crossing::Met {
            hit,
            crossed: crossings > 0,
        }
    }

    /// The radiance of a camera ray's reflection at the pane it meets at `hit`: a path whose
    /// first vertex is there. Out of line and cold: its frame (the path's contexts) would
    /// otherwise weigh on every crossing.
    #[cold]
    #[inline(never)]
    pub(super) fn pane_reflection<T: Tracer>(
        &self,
        tracer: &T,
        (o, d): (Vec3, Vec3),
        hit: Hit,
        rng: &mut Sampler,
        stats: &mut Stats,
    ) -> Vec3 {
        // Its own contexts: the camera path has filled none yet, but holds them borrowed.
        let mut contexts = PathContexts::new();
        let start = PathStart::ray(o, d, Some(Some(hit)), true);
        self.path::<T, true, _>(tracer, start, rng, stats, &mut contexts, &mut TraceNow)
    }

    /// What a shadow ray lets through on the open segment `o + t·d`, `t` in `(0, tmax)`: 0
    /// if something stands there, else 1, or with [`GlassShadows::Pass`] the product of the
    /// straight-through transmittances of the panes it crosses (METHOD.md, *Thin glass*:
    /// the sample's pdf is unchanged, the panes are a filter on its radiance).
    #[inline(always)]
    pub(super) fn visibility<T: Tracer, const GLASS: bool>(
        &self,
        tracer: &T,
        o: Vec3,
        d: Vec3,
        tmax: f32,
    ) -> Vec3 {
        if self.has_panes::<GLASS>() && self.settings.glass == GlassShadows::Pass {
            return self.through_panes(tracer, o, d, tmax).0;
        }
        if tracer.occluded(o, d, 0.0, tmax) {
            Vec3::ZERO
        } else {
            Vec3::ONE
        }
    }

    /// The product of the straight-through transmittances of the thin glass on the open
    /// segment `o + t·d`, `t` in `(0, tmax)`, and how many panes it crosses: zero if
    /// anything else stands there (or more than [`MAX_PANE_CROSSINGS`] panes). Out of line, as
    /// [`Self::cross_panes`].
    ///
    /// One traversal offers each surface on the segment: a pane multiplies its transmittance
    /// in (the product does not depend on the order) and lets the ray on; anything else stops
    /// it. (Three closest-hit traversals per pane's two faces cost a pane 31% of antishadow's
    /// efficiency, `docs/performance.md`.)
    #[inline(never)]
    pub(super) fn through_panes<T: Tracer>(
        &self,
        tracer: &T,
        o: Vec3,
        d: Vec3,
        tmax: f32,
    ) -> (Vec3, u32) {
        let mut transmittance = Vec3::ONE;
        let mut crossings = 0;
        let blocked = tracer.occluded_past(o, d, 0.0, tmax, &mut |hit: &Hit| {
            let Some(pane) = self.pane_at(hit, d) else {
                return false;
            };
            transmittance *= pane;
            crossings += 1;
            crossings <= MAX_PANE_CROSSINGS && transmittance != Vec3::ZERO
        });
        if blocked {
            (Vec3::ZERO, 0)
        } else {
            (transmittance, crossings)
        }
    }

    /// The straight-through transmittance ([`Material::straight_through`]) of the surface
    /// that `hit` meets along `d`, at its point (textures included), or `None` where it does
    /// not transmit: an opaque surface, or a light's (lights are opaque emitters).
    #[inline(always)]
    pub(super) fn pane_at(&self, hit: &Hit, d: Vec3) -> Option<Vec3> {
        let geometry = &*self.scene.geometry;
        if !geometry.is_pane(hit.triangle) {
            return None;
        }
        let tri = &geometry.triangles[hit.triangle as usize];
        let material = &geometry.materials[tri.material as usize];
        let (_, ns) = tri.point(hit.bary);
        let n = if ns == Vec3::ZERO {
            tri.geometric_normal()
        } else {
            ns
        };
        let cos_o = d.dot(n).abs();
        let surface = geometry
            .surfaces
            .get(tri.material as usize)
            .and_then(Option::as_ref);
        let point = (tri.attributes != NO_ATTRIBUTES)
            .then(|| geometry.attributes.get(tri.attributes as usize))
            .flatten();
        Some(match (surface, point) {
            (Some(s), Some(a)) => s
                .material(&a.at(hit.bary).uvs, cos_o)
                .straight_through(cos_o),
            _ => material.straight_through(cos_o),
        })
    }
}
