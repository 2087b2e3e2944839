//! The first vertex of a packet of paths in lanes (issue #39's packet integrator, its second
//! stage): the camera hits' shading points, then each path's light sample (per lane: the pick,
//! the strategy's technique and the spherical polygons branch), then the BSDF's next
//! directions, each stage over the packet's lanes at once, in structure of arrays
//! (`sampling::lanes`). Each lane computes what [`Integrator::path`] computes at its first
//! vertex, operation for operation, so the pixels are the one-path integrator's bit for bit;
//! a lane the stages do not cover (a textured, emitting, transmitting or black surface, a
//! normal bent toward the viewer, no hit) runs the one-path integrator from its camera ray.
//! Every path then continues one at a time from its second vertex.

use glam::{Vec2, Vec3};

use super::{Integrator, PathContexts, PathStart, Shading};
use crate::render::continuation::Continuation;
use crate::render::shadows::{ShadowQueue, Shadows};
use crate::render::stats::Stats;
use crate::sampling::lanes::{F32s, LANES, Mask, Vec2s, Vec3s};
use crate::sampling::{
    Frames, Sampler, cosine_hemisphere_pdf_lanes, sample_cosine_hemisphere_lanes,
};
use crate::scene::bvh::{Hit, Tracer};
use crate::scene::{NO_ATTRIBUTES, NO_LIGHT, SceneTriangle};

// The stages take a packet of camera rays as it is traced.
const _: () = assert!(crate::scene::bvh::PACKET == LANES);

/// The first shading points of a packet's paths ([`Integrator::shading`] lane by lane, for
/// surfaces without a normal map that do not transmit), with their materials' Lambertian
/// values.
struct Points {
    x: Vec3s,
    ng: Vec3s,
    frames: Frames,
    wo_local: Vec3s,
    back: Mask,
    /// Lanes where the shading normal is the interpolated one and `wo` lies above it: where
    /// the scalar code's `shading` gives this point with no bump term.
    plain: Mask,
    /// Lanes whose material is exactly Lambertian (`Material::lambertian_albedo`), and its
    /// value `albedo / π` there (zero elsewhere).
    lambertian: Mask,
    f: Vec3s,
}

impl Integrator<'_> {
    /// The radiance of `rays.len()` (at most [`LANES`]) camera rays, whose closest hits are
    /// `hits` if traced ahead ([`Self::camera_hits_traced`]): what each path gathers is
    /// queued in `queue` (lane `i` for ray `i`), which the caller resolves; returns what the
    /// paths added themselves, as [`Self::radiance_queued`] does. Lane `i` fills
    /// `contexts[i]` where its first vertex is shaded in lanes (it holds it until its second),
    /// else `contexts[LANES]`: `contexts` holds at least `LANES + 1`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn radiance_packet<T: Tracer>(
        &self,
        tracer: &T,
        rays: &[(Vec3, Vec3)],
        hits: Option<&[Option<Hit>]>,
        rngs: &mut [Sampler],
        stats: &mut Stats,
        contexts: &mut [PathContexts],
        queue: &mut ShadowQueue,
    ) -> [Vec3; LANES] {
        debug_assert!(self.queues_shadows());
        let n = rays.len().min(LANES);
        let mut radiance = [Vec3::ZERO; LANES];
        let geometry = &*self.scene.geometry;
        // The lanes whose first vertex the stages take.
        let staged = |i: usize| -> Option<&Hit> {
            if self.settings.max_depth == 0 {
                return None;
            }
            let hit = hits?.get(i)?.as_ref()?;
            let tri = geometry.triangles.get(hit.triangle as usize)?;
            let material = geometry.materials.get(tri.material as usize)?;
            let plain = tri.attributes == NO_ATTRIBUTES
                && tri.light == NO_LIGHT
                && material.volume.is_none()
                && !material.transmits_rough()
                && !material.is_black();
            plain.then_some(hit)
        };
        let mut lanes: [Option<&Hit>; LANES] = [None; LANES];
        for (i, lane) in lanes.iter_mut().enumerate().take(n) {
            *lane = staged(i);
        }
        let points = lanes
            .iter()
            .any(Option::is_some)
            .then(|| self.points(rays, &lanes));
        // The lanes past their light samples: their shading points and whether each picked
        // an area light (its context filled, for MIS at the next vertex).
        let mut next: [Option<(Shading, bool)>; LANES] = [const { None }; LANES];
        if contexts.len() <= LANES {
            // Too few contexts to hold (the tile renderer passes enough): one path at a time.
            let mut own = PathContexts::new();
            let contexts = contexts.first_mut().unwrap_or(&mut own);
            for i in 0..n {
                let ((o, d), hit) = (rays[i], hits.map(|h| h[i]));
                queue.set_lane(i);
                let rng = &mut rngs[i];
                radiance[i] = self.radiance_queued(tracer, o, d, hit, rng, stats, contexts, queue);
            }
            return radiance;
        }
        let (held, spare) = contexts.split_at_mut(LANES);
        for (i, held) in held.iter_mut().enumerate().take(n) {
            let (o, d) = rays[i];
            queue.set_lane(i);
            let staged = lanes[i].zip(points.as_ref()).filter(|(_, p)| p.plain[i]);
            let rng = &mut rngs[i];
            let Some((hit, points)) = staged else {
                // The one-path integrator from the camera ray, with the contexts that no lane
                // holds (one for all, as warm in the cache as the reference's).
                let hit = hits.map(|h| h[i]);
                let contexts = &mut spare[0];
                radiance[i] = self.radiance_queued(tracer, o, d, hit, rng, stats, contexts, queue);
                continue;
            };
            let PathContexts { even, guide, .. } = held;
            // The light sample, per lane: `path` at its first vertex.
            stats.camera_rays += 1;
            stats.lane_vertices += 1;
            let tri = &geometry.triangles[hit.triangle as usize];
            let mut shading = Shading {
                x: points.x.lane(i),
                ng: points.ng.lane(i),
                frame: points.frames.lane(i),
                wo_local: points.wo_local.lane(i),
                material: &geometry.materials[tri.material as usize],
                bump: None,
                x_below: None,
                back: points.back[i],
                sigma: Vec3::ZERO,
                sigma_below: Vec3::ZERO,
                continuation: Continuation::bsdf(),
            };
            if let Some(openings) = &self.guide {
                // `path`'s guided first bounce, in this lane's guide context.
                let diffuse = shading.material.diffuse_probability(shading.wo_local.z);
                let at = (shading.x, shading.pick_normal());
                shading.continuation = Continuation::guided(openings, guide, at, diffuse);
            }
            let from = queue.mark();
            let direct =
                self.sample_direct::<T, false, _>(tracer, &shading, rng, stats, even, queue);
            let picked = direct.is_some_and(|d| d.context_filled);
            let l = &mut radiance[i];
            queue.close(l, from, Vec3::ONE, direct.map_or(Vec3::ZERO, |d| d.l));
            next[i] = Some((shading, picked));
        }
        let Some(points) = points else {
            return radiance;
        };
        let mut starts = self.scatter_lanes((&points, &next), rngs);
        for i in 0..n {
            let Some(start) = starts[i].take() else {
                continue;
            };
            queue.set_lane(i);
            let rng = &mut rngs[i];
            let l = self.path::<T, false, _>(tracer, start, rng, stats, &mut contexts[i], queue);
            radiance[i] += l;
        }
        radiance
    }

    /// The shading points of the camera hits `hits` (lanes without one repeat another's):
    /// `SceneTriangle::point`, `geometric_normal` and [`Self::shading`], lane by lane.
    #[inline(always)]
    fn points(&self, rays: &[(Vec3, Vec3)], hits: &[Option<&Hit>; LANES]) -> Points {
        let geometry = &*self.scene.geometry;
        // Each lane's triangle, barycentrics, direction and albedo, gathered once.
        let any = hits.iter().flatten().next().copied();
        let (mut tris, mut bary, mut d) = ([None; LANES], [Vec2::ZERO; LANES], [Vec3::Z; LANES]);
        let (mut albedo, mut lambertian) = ([Vec3::ZERO; LANES], [false; LANES]);
        for i in 0..LANES {
            let Some(hit) = hits[i].or(any) else {
                continue;
            };
            let tri = geometry.triangles.get(hit.triangle as usize);
            let material = tri.and_then(|t| geometry.materials.get(t.material as usize));
            if let Some(a) = material.and_then(|m| m.lambertian_albedo()) {
                (albedo[i], lambertian[i]) = (a, true);
            }
            tris[i] = tri;
            bary[i] = hit.bary;
            d[i] = rays.get(i).or(rays.first()).map_or(Vec3::Z, |r| r.1);
        }
        let corners = |corner: fn(&SceneTriangle) -> Vec3| {
            Vec3s::from_fn(|i| tris[i].map_or(Vec3::ZERO, corner))
        };
        let (p0, p1, p2) = (
            corners(|t| t.p[0]),
            corners(|t| t.p[1]),
            corners(|t| t.p[2]),
        );
        let (n0, n1, n2) = (
            corners(|t| t.n[0]),
            corners(|t| t.n[1]),
            corners(|t| t.n[2]),
        );
        let bary = Vec2s::from_fn(|i| bary[i]);
        let wo = -Vec3s::from_fn(|i| d[i]);
        // The hit point and the interpolated normal.
        let w = (1.0 - bary.x) - bary.y;
        let p = p0.scale(w) + p1.scale(bary.x) + p2.scale(bary.y);
        let ns = (n0.scale(w) + n1.scale(bary.x) + n2.scale(bary.y)).normalize_or_zero();
        let ng = (p1 - p0).cross(p2 - p0).normalize_or_zero();
        // Both normals on the side `wo` comes from.
        let back = ng.dot(wo).test(F32s::splat(0.0), |a, b| a < b);
        let ng = Vec3s::select(back, -ng, ng);
        let ns = Vec3s::select(ns.is_zero(), ng, ns);
        let ns = Vec3s::select(ns.dot(ng).test(F32s::splat(0.0), |a, b| a < b), -ns, ns);
        // `ensure_valid_reflection` keeps `ns` where its mirror of `wo` rises far enough.
        let r = ns.scale(2.0 * ns.dot(wo)) - wo;
        let threshold = (0.9 * ng.dot(wo)).min(F32s::splat(0.01));
        let kept = ng.dot(r).test(threshold, |a, b| a >= b);
        let frames = Frames::from_normal(ns);
        let wo_local = frames.to_local(wo);
        let above = wo_local.z.test(F32s::splat(0.0), |a, b| a > b);
        // The origin off the surface: `Integrator::shading_origin`.
        let epsilon = 2e-4 * p.abs().max_element() + (2e-5 * self.scale).min(2e-4);
        let x = p + (ng + wo).scale(epsilon);
        let mut plain = kept;
        for (plain, &above) in plain.iter_mut().zip(&above) {
            *plain &= above;
        }
        Points {
            x,
            ng,
            frames,
            wo_local,
            back,
            plain,
            lambertian,
            f: Vec3s::from_fn(|i| albedo[i]).scale(F32s::splat(std::f32::consts::FRAC_1_PI)),
        }
    }

    /// The next directions from the shading points `next` (`points` in lanes):
    /// [`Self::scatter`] lane by lane, the Lambertian materials' warp, value and pdf in lanes,
    /// the others' one lane at a time; the paths' starts at their second vertex.
    #[inline(always)]
    fn scatter_lanes(
        &self,
        (points, next): (&Points, &[Option<(Shading, bool)>; LANES]),
        rngs: &mut [Sampler],
    ) -> [Option<PathStart>; LANES] {
        let last = self.settings.max_depth == 1;
        let mut starts: [Option<PathStart>; LANES] = [const { None }; LANES];
        // Every lane draws its numbers in the path's order; Lambertian lanes warp them below.
        let mut u = [Vec2::ZERO; LANES];
        let mut lambertian = [false; LANES];
        for (i, lane) in next.iter().enumerate() {
            let Some((s, picked)) = lane else {
                continue;
            };
            // The BSDF alone: a guided continuation's mixture draws one lane at a time.
            if !points.lambertian[i] || s.continuation.share() > 0.0 {
                let next = self.scatter(s, &mut rngs[i], last);
                // `path` multiplies its throughput, one, by the weight and ends where that is
                // not finite.
                starts[i] = next.filter(|n| n.weight.is_finite()).map(|next| PathStart {
                    o: next.origin,
                    d: next.wi,
                    hit: None,
                    at_pane: false,
                    beta: next.weight,
                    previous: Some((s.x, s.pick_normal(), *picked, next.pdf)),
                    depth: 1,
                });
                continue;
            }
            let ([_u_lobe], u2) = rngs[i].uniforms_uniform2::<1>();
            (u[i], lambertian[i]) = (u2, true);
        }
        if !lambertian.contains(&true) {
            return starts;
        }
        // `Material::sample_direction` and `eval_pdf` of a Lambertian material, in lanes.
        let wi_local = sample_cosine_hemisphere_lanes(Vec2s::from_fn(|i| u[i]));
        let wi = points.frames.to_world(wi_local);
        let above = wi.dot(points.ng).test(F32s::splat(0.0), |a, b| a > b);
        let rises = wi_local.z.test(F32s::splat(0.0), |a, b| a > b);
        let pdf = cosine_hemisphere_pdf_lanes(wi_local.z);
        let (f, cos) = (points.f, wi_local.z.abs());
        let weight = Vec3s::new(f.x * cos / pdf, f.y * cos / pdf, f.z * cos / pdf);
        // Before the last vertex, whether each direction meets a light polygon
        // (`Self::nearest_light_polygon`).
        let meets_light = (last && self.polygon_lights).then(|| {
            let mut any = [false; LANES];
            for light in &self.scene.geometry.lights {
                let Some(polygon) = &light.polygon else {
                    continue;
                };
                let hits = polygon.hits_lanes(points.x, wi);
                for (any, &hit) in any.iter_mut().zip(&hits) {
                    *any |= hit;
                }
            }
            any
        });
        for i in 0..LANES {
            let Some((s, picked)) = next[i].as_ref().filter(|_| lambertian[i]) else {
                continue;
            };
            let (wi, pdf, f) = (wi.lane(i), pdf.0[i], f.lane(i));
            // `Shading::origin`: above both the surface and the shading normal.
            if !(above[i] && rises[i]) {
                continue;
            }
            let origin = s.x;
            if meets_light.is_some_and(|m| !m[i]) {
                continue;
            }
            let beta = weight.lane(i);
            if pdf.is_nan() || pdf <= 0.0 || f == Vec3::ZERO || !beta.is_finite() {
                continue;
            }
            starts[i] = Some(PathStart {
                o: origin,
                d: wi,
                hit: None,
                at_pane: false,
                beta,
                previous: Some((s.x, s.pick_normal(), *picked, pdf)),
                depth: 1,
            });
        }
        starts
    }
}
