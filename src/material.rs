//! The BSDF: glTF metallic-roughness as Lambertian diffuse plus a GGX microfacet lobe.
//!
//! Energy conservation by construction: the dielectric part mixes diffuse and specular with a
//! weight `s = F(cos θo)` that depends on the outgoing direction only, and each lobe reflects at
//! most what it receives (single-scattering GGX loses energy, never gains it); the metallic part
//! is GGX tinted by a Fresnel term bounded by 1. All directions are in the local shading frame
//! (normal = +z) and `wo.z > 0`.

use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, PI};

use crate::asset::desc::MaterialDesc;
use crate::sampling::{cosine_hemisphere_pdf, sample_cosine_hemisphere, sin_cos_turn};

/// Roughness is clamped so the GGX lobe stays a density (no delta lobes, so MIS always applies).
const MIN_ALPHA: f32 = 1e-3;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    pub base_color: Vec3,
    pub metallic: f32,
    /// GGX alpha = perceptual roughness squared.
    pub alpha: f32,
    /// Normal-incidence reflectance of the dielectric specular layer (0.04 in glTF).
    pub f0_dielectric: f32,
    /// Weight of the dielectric specular layer: 1 for glTF materials, 0 for a pure Lambertian.
    pub specular: f32,
    /// Emitted radiance, W/(sr·m²).
    pub emission: Vec3,
    /// Emits (and is lit) from both sides; otherwise only from the front of its winding.
    pub double_sided: bool,
}

/// A direction drawn from the BSDF with its value and solid-angle pdf.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    pub wi: Vec3,
    pub f: Vec3,
    pub pdf: f32,
}

impl Material {
    pub fn from_desc(desc: &MaterialDesc) -> Self {
        let r = desc.roughness.clamp(0.0, 1.0);
        Material {
            base_color: desc.base_color.clamp(Vec3::ZERO, Vec3::ONE),
            metallic: desc.metallic.clamp(0.0, 1.0),
            alpha: (r * r).max(MIN_ALPHA),
            f0_dielectric: 0.04,
            specular: 1.0,
            emission: desc.radiance().max(Vec3::ZERO),
            double_sided: desc.double_sided,
        }
    }

    /// A pure Lambertian reflector (no specular layer).
    pub fn lambertian(albedo: Vec3) -> Self {
        Material {
            base_color: albedo,
            metallic: 0.0,
            alpha: 1.0,
            f0_dielectric: 0.0,
            specular: 0.0,
            emission: Vec3::ZERO,
            double_sided: true,
        }
    }

    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }

    /// Whether the material reflects at all (black materials skip shading).
    pub fn is_black(&self) -> bool {
        self.base_color.max_element() <= 0.0 && self.specular <= 0.0
    }

    /// The dielectric specular weight for this outgoing direction.
    fn specular_weight(&self, cos_o: f32) -> f32 {
        self.specular * schlick(self.f0_dielectric, cos_o)
    }

    /// Probability of sampling the specular lobe (the pdf in `eval_pdf` mixes by the same).
    fn specular_probability(&self, cos_o: f32) -> f32 {
        let m = self.metallic;
        m + (1.0 - m) * self.specular_weight(cos_o)
    }

    /// BSDF value `f(wo, wi)` (without the cosine).
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        self.eval_pdf(wo, wi).0
    }

    /// Solid-angle pdf of `sample` drawing `wi`.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval_pdf(wo, wi).1
    }

    /// `f(wo, wi)` and the pdf of `sample` drawing `wi`, sharing the microfacet terms.
    #[inline]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let m = self.metallic;
        let s = self.specular_weight(wo.z);
        let diffuse = (1.0 - m) * (1.0 - s) * self.base_color * FRAC_1_PI;
        // `specular_probability`, sharing `s`.
        let p_spec = m + (1.0 - m) * s;
        let pdf_diffuse = (1.0 - p_spec) * cosine_hemisphere_pdf(wi.z);
        if p_spec <= 0.0 {
            return (diffuse, pdf_diffuse);
        }
        let h = (wo + wi).normalize();
        let d = ggx_d(h, self.alpha);
        let (lambda_o, lambda_i) = (ggx_lambda(wo, self.alpha), ggx_lambda(wi, self.alpha));
        // Height-correlated masking-shadowing G2 for the value; the pdf of visible-normal
        // sampling uses the masking G1(wo) = 1 / (1 + Λo).
        let dg = d / ((1.0 + lambda_o + lambda_i) * 4.0 * wo.z * wi.z);
        let mut f = diffuse + ((1.0 - m) * s * dg) * Vec3::ONE;
        if m > 0.0 {
            let metal = self.base_color + (Vec3::ONE - self.base_color) * schlick(0.0, wo.dot(h));
            f += m * dg * metal;
        }
        let pdf_specular = d / ((1.0 + lambda_o) * 4.0 * wo.z);
        (f, pdf_diffuse + p_spec * pdf_specular)
    }

    /// Draws `wi`: the lobe by `u_lobe`, then the direction by `u`.
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        self.sampled(wo, self.sample_direction(wo, u_lobe, u)?)
    }

    /// The direction part of [`Self::sample`], for callers that may not need its value.
    pub fn sample_direction(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<Vec3> {
        if wo.z <= 0.0 {
            return None;
        }
        if u_lobe < self.specular_probability(wo.z) {
            let h = sample_ggx_vndf(wo, self.alpha, u);
            let wi = 2.0 * wo.dot(h) * h - wo;
            (wi.z > 0.0).then_some(wi)
        } else {
            Some(sample_cosine_hemisphere(u))
        }
    }

    /// The sample that [`Self::sample_direction`] drew as `wi`: its value and pdf.
    pub fn sampled(&self, wo: Vec3, wi: Vec3) -> Option<BsdfSample> {
        let (f, pdf) = self.eval_pdf(wo, wi);
        (pdf > 0.0).then_some(BsdfSample { wi, f, pdf })
    }
}

fn schlick(f0: f32, cos: f32) -> f32 {
    let c = (1.0 - cos.clamp(0.0, 1.0)).powi(5);
    f0 + (1.0 - f0) * c
}

/// GGX normal distribution.
fn ggx_d(h: Vec3, alpha: f32) -> f32 {
    if h.z <= 0.0 {
        return 0.0;
    }
    let a2 = alpha * alpha;
    let c2 = h.z * h.z;
    let t = c2 * (a2 - 1.0) + 1.0;
    a2 / (PI * t * t)
}

/// Smith's Λ for GGX.
fn ggx_lambda(w: Vec3, alpha: f32) -> f32 {
    let c2 = w.z * w.z;
    let tan2 = ((1.0 - c2) / c2.max(1e-12)).max(0.0);
    0.5 * ((1.0 + alpha * alpha * tan2).sqrt() - 1.0)
}

/// Visible-normal sampling (Heitz 2018): a microfacet normal seen from `wo`.
fn sample_ggx_vndf(wo: Vec3, alpha: f32, u: Vec2) -> Vec3 {
    let vh = Vec3::new(alpha * wo.x, alpha * wo.y, wo.z).normalize();
    let lensq = vh.x * vh.x + vh.y * vh.y;
    let t1 = if lensq > 0.0 {
        Vec3::new(-vh.y, vh.x, 0.0) / lensq.sqrt()
    } else {
        Vec3::X
    };
    let t2 = vh.cross(t1);
    let r = u.x.sqrt();
    let (sin_phi, cos_phi) = sin_cos_turn(u.y);
    let p1 = r * cos_phi;
    let s = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * sin_phi;
    let nh = p1 * t1 + p2 * t2 + (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt() * vh;
    Vec3::new(alpha * nh.x, alpha * nh.y, nh.z.max(1e-7)).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    #[test]
    fn sample_pdf_matches_eval_pdf() {
        let mut rng = Rng::new(1, 2);
        for &(m, r) in &[(0.0, 1.0), (0.0, 0.2), (1.0, 0.3), (0.5, 0.05)] {
            let mat = Material::from_desc(&MaterialDesc {
                metallic: m,
                roughness: r,
                ..MaterialDesc::diffuse("t", Vec3::splat(0.7))
            });
            for _ in 0..1000 {
                let wo = sample_cosine_hemisphere(rng.uniform2());
                if let Some(s) = mat.sample(wo, rng.uniform(), rng.uniform2()) {
                    let p = mat.pdf(wo, s.wi);
                    assert!((p - s.pdf).abs() <= 1e-4 * p.max(1.0), "{p} vs {}", s.pdf);
                    assert!(s.f.is_finite() && s.pdf.is_finite());
                }
            }
        }
    }
}
