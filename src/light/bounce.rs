//! Guided continuation (`docs/method.md` §12): the next direction of a path drawn from a
//! mixture of the BSDF's sampler and directions through the openings that bounced light
//! leaves by (the portals of lights in shades and cans, windows with something outside them),
//!
//! `p(ω) = (1 − g) · p_bsdf(ω) + g · Σ_j v_j · p_j(ω)`,
//!
//! `p_j` the density of directions through uniform points of opening `j` (`d² / (A |cos θ|)`),
//! `v_j` its weight at `x` (normalised), `g` the guide's share there. Points on the opening
//! rather than its solid angle: the guide only has to send directions into the opening, and
//! area sampling's density is a ray–polygon test, where the spherical polygon's set-up cost a
//! third of a guided sample's time (light sampling's MIS weight evaluates it at every vertex). This module holds the openings' part: the
//! weights, the draw and its density; the integrator mixes it with the BSDF.

use arrayvec::ArrayVec;
use glam::{Vec2, Vec3};

use crate::sampling::pick_by_weight;
use crate::sampling::polygon::ConvexPolygon;

/// The most openings one shading point weighs (past that, the lightest are left out: the
/// mixture stays exact, as the same weights serve the draw and the density).
pub const MAX_GUIDE_OPENINGS: usize = 64;

/// The smallest cosine an opening above the surface is weighed by: an opening whose centre is
/// near the horizon may still have most of its directions above it.
const MIN_COSINE: f32 = 0.1;

/// An opening that bounced light leaves by.
#[derive(Clone, Debug)]
pub struct Opening {
    /// The opening, its normal pointing to its front (where the paths it guides come from).
    pub polygon: ConvexPolygon,
    /// A guess at the luminance of the light leaving it (only the openings' relative weights
    /// depend on it).
    pub radiance: f32,
}

/// The openings of a scene.
#[derive(Clone, Debug, Default)]
pub struct BounceGuide {
    openings: Vec<Opening>,
}

/// The guide at one shading point: the openings with weight.
#[derive(Clone, Debug)]
pub struct GuideContext {
    x: Vec3,
    /// `(opening, w_j)` for every opening of positive weight (unnormalised).
    weights: ArrayVec<(u32, f32), MAX_GUIDE_OPENINGS>,
    total: f32,
}

impl GuideContext {
    pub fn new() -> Self {
        GuideContext {
            x: Vec3::ZERO,
            weights: ArrayVec::new(),
            total: 0.0,
        }
    }

    /// Whether any opening has weight here: elsewhere the guide's share is 0.
    pub fn is_empty(&self) -> bool {
        self.total <= 0.0
    }

    /// The openings weighed here, with their normalised weights `v_j`.
    pub fn weights(&self) -> impl Iterator<Item = (usize, f32)> + '_ {
        self.weights
            .iter()
            .map(|&(j, w)| (j as usize, w / self.total))
    }
}

impl Default for GuideContext {
    fn default() -> Self {
        Self::new()
    }
}

impl BounceGuide {
    /// Openings of zero or non-finite radiance are left out.
    pub fn new(openings: Vec<Opening>) -> Self {
        BounceGuide {
            openings: openings
                .into_iter()
                .filter(|o| o.radiance.is_finite() && o.radiance > 0.0)
                .collect(),
        }
    }

    pub fn openings(&self) -> &[Opening] {
        &self.openings
    }

    pub fn is_empty(&self) -> bool {
        self.openings.is_empty()
    }

    /// The weights at `x` with normal `n` (facing the side the path leaves by; `Vec3::ZERO`
    /// where it may leave by either): `w_j = L_j · Ω̃_j · max(cos, MIN_COSINE)`, with `Ω̃_j =
    /// A cos θ_j / d²` (at most 2π) the opening's approximate solid angle from its centre at
    /// distance `d`, zero for an opening `x` is behind or that lies wholly below the surface.
    /// Functions of `x` alone, as the mixture requires.
    pub fn fill(&self, x: Vec3, n: Vec3, ctx: &mut GuideContext) {
        ctx.x = x;
        ctx.weights.clear();
        ctx.total = 0.0;
        for (j, o) in self.openings.iter().enumerate() {
            let h = o.polygon.plane().signed_distance(x);
            if h <= 0.0 {
                continue;
            }
            let v = o.polygon.centroid() - x;
            let d2 = v.length_squared();
            if d2 <= 0.0 {
                continue;
            }
            let d = d2.sqrt();
            let cos = if n == Vec3::ZERO {
                1.0
            } else if o.polygon.vertices().iter().any(|&p| n.dot(p - x) > 0.0) {
                (n.dot(v) / d).max(MIN_COSINE)
            } else {
                continue;
            };
            let solid_angle = (o.polygon.area() * h / (d * d2)).min(std::f32::consts::TAU);
            let w = o.radiance * solid_angle * cos;
            if !(w.is_finite() && w > 0.0) {
                continue;
            }
            if ctx.weights.is_full() {
                // Keep the heaviest: replace the lightest if this one outweighs it.
                let Some((k, &(_, lightest))) = ctx
                    .weights
                    .iter()
                    .enumerate()
                    .min_by(|a, b| a.1.1.total_cmp(&b.1.1))
                else {
                    continue;
                };
                if w > lightest {
                    ctx.weights[k] = (j as u32, w);
                }
            } else {
                ctx.weights.push((j as u32, w));
            }
        }
        ctx.total = ctx.weights.iter().map(|&(_, w)| w).sum();
    }

    /// A direction from the openings' mixture `Σ_j v_j p_j`: the opening by `u_pick`, then
    /// the direction through a uniform point of it by `u`
    /// ([`ConvexPolygon::sample_direction`]). `None` where no opening has weight or the draw
    /// degenerates (a direction the caller then gives zero weight).
    pub fn sample(&self, ctx: &GuideContext, u_pick: f32, u: Vec2) -> Option<Vec3> {
        let &(j, _) = pick_by_weight(&ctx.weights, |&(_, w)| w, u_pick * ctx.total)?;
        let opening = self.openings.get(j as usize)?;
        opening.polygon.sample_direction(ctx.x, u).map(|(wi, _)| wi)
    }

    /// The openings' mixture density `Σ_j v_j p_j(wi)` in solid angle, for any unit direction
    /// `wi` from the context's point: each opening the ray crosses adds its weight times
    /// `d² / (A |cos θ|)` ([`ConvexPolygon::direction_pdf`], whose inside test allows for
    /// rounding at the edges, so that a drawn direction is never judged outside).
    pub fn pdf(&self, ctx: &GuideContext, wi: Vec3) -> f32 {
        if ctx.is_empty() {
            return 0.0;
        }
        let mut pdf = 0.0;
        for &(j, w) in &ctx.weights {
            // A ray that leaves the opening's plane behind cannot cross it: no f64 test.
            if let Some(opening) = self.openings.get(j as usize)
                && opening.polygon.normal().dot(wi) < 0.0
            {
                pdf += w * opening.polygon.direction_pdf(ctx.x, wi);
            }
        }
        pdf / ctx.total
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    fn square(z: f32, half: f32, facing: f32) -> ConvexPolygon {
        let mut v = vec![
            Vec3::new(-half, -half, z),
            Vec3::new(half, -half, z),
            Vec3::new(half, half, z),
            Vec3::new(-half, half, z),
        ];
        if facing < 0.0 {
            v.reverse();
        }
        ConvexPolygon::new(&v).expect("a square")
    }

    /// Two overlapping openings (one behind the other along z) and one to the side: the
    /// density of the drawn directions, binned on a cube map of the sphere, matches the
    /// evaluated density's integral over each bin within 5 standard errors (a bin's count is
    /// binomial: σ = √(N p (1 − p))). Leaving the overlapped opening's term out of the
    /// density (a mixture pdf that forgets a technique) is caught by the same test.
    #[test]
    fn drawn_directions_follow_the_evaluated_density() {
        let guide = BounceGuide::new(vec![
            Opening {
                polygon: square(1.0, 0.5, -1.0),
                radiance: 1.0,
            },
            Opening {
                polygon: square(2.0, 1.5, -1.0),
                radiance: 2.0,
            },
            Opening {
                polygon: ConvexPolygon::new(&[
                    Vec3::new(1.5, -0.2, 0.9),
                    Vec3::new(1.5, 0.2, 0.9),
                    Vec3::new(1.5, 0.2, 0.3),
                    Vec3::new(1.5, -0.2, 0.3),
                ])
                .expect("a rectangle"),
                radiance: 1.0,
            },
        ]);
        let x = Vec3::new(0.1, -0.05, 0.0);
        let mut ctx = GuideContext::new();
        guide.fill(x, Vec3::Z, &mut ctx);
        assert_eq!(
            ctx.weights.len(),
            3,
            "every opening is in front of x and above it"
        );
        let mut rng = Rng::new(7, 0);
        const N: usize = 200_000;
        const BINS: usize = 16;
        let bin = |w: Vec3| -> usize {
            // A bin of the upper hemisphere by (φ, cos θ).
            let phi = (w.y.atan2(w.x) / std::f32::consts::TAU + 0.5).clamp(0.0, 0.999_999);
            let c = w.z.clamp(0.0, 0.999_999);
            (phi * BINS as f32) as usize * BINS + (c * BINS as f32) as usize
        };
        let mut counts = vec![0.0f64; BINS * BINS];
        for _ in 0..N {
            let wi = guide
                .sample(&ctx, rng.uniform(), Vec2::new(rng.uniform(), rng.uniform()))
                .expect("a direction");
            assert!(wi.z > 0.0);
            let p = guide.pdf(&ctx, wi);
            assert!(p > 0.0, "a drawn direction has density");
            counts[bin(wi)] += 1.0;
        }
        // The evaluated density integrated per bin by a fine (φ, cos θ) grid (dω = dφ d cos θ).
        let ctx_eval = {
            let mut c = GuideContext::new();
            guide.fill(x, Vec3::Z, &mut c);
            c
        };
        let integrate = |pdf: &dyn Fn(Vec3) -> f32| -> Vec<f64> {
            let mut mass = vec![0.0f64; BINS * BINS];
            const FINE: usize = 400;
            let cell = std::f64::consts::TAU / FINE as f64 / FINE as f64;
            for a in 0..FINE {
                for b in 0..FINE {
                    let phi = ((a as f64 + 0.5) / FINE as f64 - 0.5) * std::f64::consts::TAU;
                    let c = (b as f64 + 0.5) / FINE as f64;
                    let s = (1.0 - c * c).sqrt();
                    let w = Vec3::new((s * phi.cos()) as f32, (s * phi.sin()) as f32, c as f32);
                    mass[bin(w)] += pdf(w) as f64 * cell;
                }
            }
            mass
        };
        let worst = |mass: &[f64]| -> f64 {
            counts
                .iter()
                .zip(mass)
                .map(|(&k, &m)| {
                    let expected = m * N as f64;
                    let sigma = (N as f64 * m * (1.0 - m)).sqrt().max(3.0);
                    (k - expected).abs() / sigma
                })
                .fold(0.0, f64::max)
        };
        let exact = integrate(&|w| guide.pdf(&ctx_eval, w));
        let total: f64 = exact.iter().sum();
        assert!(
            (total - 1.0).abs() < 0.01,
            "the density integrates to {total}"
        );
        assert!(worst(&exact) < 5.0, "z = {}", worst(&exact));
        // Negative case: the density without the inner opening's term (the one the outer
        // overlaps) misplaces its mass.
        let forgetful = |w: Vec3| -> f32 {
            let mut p = 0.0;
            for (j, v) in ctx_eval.weights() {
                if j == 0 {
                    continue;
                }
                let o = &guide.openings()[j];
                p += v * o.polygon.direction_pdf(x, w);
            }
            p
        };
        assert!(worst(&integrate(&forgetful)) > 20.0);
    }

    /// Behind an opening, or where it lies wholly below the surface, it has no weight; a
    /// point behind every opening has no guide at all.
    #[test]
    fn openings_behind_or_below_have_no_weight() {
        let guide = BounceGuide::new(vec![Opening {
            polygon: square(1.0, 0.5, -1.0),
            radiance: 1.0,
        }]);
        let mut ctx = GuideContext::new();
        guide.fill(Vec3::new(0.0, 0.0, 2.0), Vec3::Z, &mut ctx);
        assert!(ctx.is_empty(), "behind the opening");
        guide.fill(Vec3::ZERO, -Vec3::Z, &mut ctx);
        assert!(ctx.is_empty(), "the opening is below the surface");
        guide.fill(Vec3::ZERO, Vec3::Z, &mut ctx);
        assert!(!ctx.is_empty());
        guide.fill(Vec3::ZERO, Vec3::ZERO, &mut ctx);
        assert!(!ctx.is_empty(), "a two-sided point weighs it");
    }
}
