//! Guided continuation (`docs/method.md` §12): the mixture a path's next direction is drawn
//! from, the BSDF's sampler and the openings bounced light leaves by, and those openings as a
//! scene has them.

use glam::{Vec2, Vec3};
use std::f32::consts::PI;

use super::integrator::Integrator;
use crate::light::LightSet;
use crate::light::area::luminance;
use crate::light::bounce::{BounceGuide, GuideContext, Opening};
use crate::light::split_share;
use crate::light::tree::flux_through;
use crate::material::Material;
use crate::sampling::polygon::ConvexPolygon;
use crate::sampling::{Frame, Rng, sample_cosine_hemisphere};
use crate::scene::{Geometry, Scene};

/// The guide's share `g` of the continuation where an opening has weight and the BSDF draws
/// only its diffuse lobe (scaled by the diffuse lobe's probability elsewhere): the mixture's
/// density is never below `(1 − g)` times the BSDF's, so no direction the BSDF serves loses more
/// than a factor `1 / (1 − g)` in variance.
pub const GUIDE_SHARE: f32 = 0.5;

/// Rays per window cast outwards to see what lies outside it (see [`bounce_openings`]).
const WINDOW_PROBES: u32 = 64;

/// The mixture at one shading point: `p(ω) = (1 − g) · p_bsdf(ω) + g · Σ_j v_j p_j(ω)`, the
/// BSDF's sampler alone where `g = 0`. Light sampling's MIS weight at the point takes this
/// density too, as the emission the continuation finds does.
#[derive(Clone, Copy)]
pub struct Continuation<'g> {
    guide: Option<(&'g BounceGuide, &'g GuideContext)>,
    g: f32,
}

impl<'g> Continuation<'g> {
    /// The BSDF alone.
    pub fn bsdf() -> Self {
        Continuation {
            guide: None,
            g: 0.0,
        }
    }

    /// The mixture at `x` with normal `n` (`Vec3::ZERO` where paths leave by either side) for
    /// a material whose sampler draws its diffuse lobe with probability `diffuse`: `g =`
    /// [`GUIDE_SHARE`]` · diffuse` where an opening has weight, else 0 (behind every opening,
    /// or where every opening lies below the surface). `ctx` is filled here.
    pub fn guided(
        guide: &'g BounceGuide,
        ctx: &'g mut GuideContext,
        (x, n): (Vec3, Vec3),
        diffuse: f32,
    ) -> Self {
        let g = GUIDE_SHARE * diffuse;
        if g.is_nan() || g <= 0.0 {
            return Self::bsdf();
        }
        guide.fill(x, n, ctx);
        if ctx.is_empty() {
            return Self::bsdf();
        }
        let ctx: &'g GuideContext = ctx;
        Continuation {
            guide: Some((guide, ctx)),
            g,
        }
    }

    /// The guide's share `g`.
    pub fn share(&self) -> f32 {
        self.g
    }

    /// Draws the next direction (world and shading frame): the branch by `u_lobe` (stretched
    /// back to a uniform number for the branch taken, so that no random number is added), then
    /// the BSDF's lobe and direction, or the opening and a direction through it. `None` where
    /// the draw degenerates.
    pub fn sample(
        &self,
        material: &Material,
        frame: &Frame,
        wo: Vec3,
        u_lobe: f32,
        u: Vec2,
    ) -> Option<(Vec3, Vec3)> {
        let (guide, ctx) = match self.guide {
            Some(guide) => guide,
            None => {
                let wi_local = material.sample_direction(wo, u_lobe, u)?;
                return Some((frame.to_world(wi_local), wi_local));
            }
        };
        let (guided, u_lobe) = split_share(Vec2::new(u_lobe, 0.0), self.g);
        if guided {
            let wi = guide.sample(ctx, u_lobe.x, u)?;
            return Some((wi, frame.to_local(wi)));
        }
        let wi_local = material.sample_direction(wo, u_lobe.x, u)?;
        Some((frame.to_world(wi_local), wi_local))
    }

    /// The mixture's density for the world direction `wi`, given the BSDF's `bsdf_pdf` there:
    /// never below `(1 − g) · bsdf_pdf`, so a direction the openings cannot produce keeps the
    /// BSDF's share.
    pub fn pdf(&self, bsdf_pdf: f32, wi: Vec3) -> f32 {
        match &self.guide {
            Some((guide, ctx)) => (1.0 - self.g) * bsdf_pdf + self.g * guide.pdf(ctx, wi),
            None => bsdf_pdf,
        }
    }
}

/// The openings bounced light leaves by, with a guess at the luminance leaving each (only their
/// relative weights depend on it). A lamp portal's: the light's power that does not leave its
/// portals directly (what its enclosure's walls receive, [`flux_through`] taken from its power),
/// spread over all the light's portals, `(Φ − Φ_through) / (π Σ A)`: a can whose emitter faces
/// its opening sends little light by bounces, a bulb in a shade most of it. A window's: the
/// environment's mean luminance times the mean albedo of what rays cast out of it meet, zero
/// where nothing stands outside (the sky itself is light sampling's).
pub fn bounce_openings(scene: &Scene) -> Vec<Opening> {
    let geometry = &*scene.geometry;
    let lights = &geometry.lights;
    let (mut portal_area, mut through) = (vec![0.0f32; lights.len()], vec![0.0f32; lights.len()]);
    for p in &scene.portals {
        portal_area[p.light] += p.polygon.area();
        through[p.light] += flux_through(&lights[p.light], &p.polygon);
    }
    let mut openings: Vec<Opening> = scene
        .portals
        .iter()
        .map(|p| {
            let bounced = (lights[p.light].power() - through[p.light]).max(0.0);
            Opening {
                polygon: p.polygon.clone(),
                radiance: bounced / (PI * portal_area[p.light]),
            }
        })
        .collect();
    if let Some(env) = scene.environment() {
        let mean = env.power() / (4.0 * PI * PI * geometry.radius * geometry.radius);
        for (k, w) in scene.windows.iter().enumerate() {
            openings.push(Opening {
                polygon: w.polygon.clone(),
                radiance: mean * outside_albedo(geometry, &w.polygon, k as u64),
            });
        }
    }
    openings
}

/// The mean albedo (luminance of the base colour) of what [`WINDOW_PROBES`] rays cast out of
/// `window` (cosine-distributed, from uniform points) meet through the panes: 0 for a window
/// onto nothing. Seeded, so a scene always gets the same guide.
fn outside_albedo(geometry: &Geometry, window: &ConvexPolygon, seed: u64) -> f32 {
    let mut rng = Rng::new(seed, 0x006f_7574_7369_6465);
    let out = -window.normal();
    let frame = Frame::from_normal(out);
    let scale = geometry.scale();
    let mut sum = 0.0;
    for _ in 0..WINDOW_PROBES {
        let p = window.sample_uniform(rng.uniform2());
        let d = frame.to_world(sample_cosine_hemisphere(rng.uniform2()));
        let o = Integrator::offset(p, out, scale);
        let Some(hit) = geometry.closest_hit_through_panes(o, d, 0.0, f32::INFINITY) else {
            continue;
        };
        if let Some(m) = geometry
            .triangles
            .get(hit.triangle as usize)
            .and_then(|t| geometry.materials.get(t.material as usize))
        {
            sum += luminance(m.base_color * (1.0 - m.metallic)).clamp(0.0, 1.0);
        }
    }
    sum / WINDOW_PROBES as f32
}
