//! The BSDF: glTF metallic-roughness with `KHR_materials_specular`, `KHR_materials_ior` and
//! `KHR_materials_transmission`, as a Lambertian diffuse under a dielectric GGX layer, mixed
//! with a GGX metal.
//!
//! Transmission (thin-walled, as glTF means a surface without `KHR_materials_volume`) takes
//! the share `transmission` of the dielectric base from the diffuse and sends it through:
//! `T(wo) = (1 − metallic)·(1 − E(wo))·transmission·baseColor`. Smooth, it is a delta lobe that
//! changes no direction ([`Material::straight_through`]): the integrator crosses such a surface
//! as a null interface (METHOD.md, *Thin glass*), so [`Material::eval_pdf`] and
//! [`Material::sample`] are the reflection alone. Rough, it is the GGX lobe about the
//! straight-through direction (the reflection lobe mirrored through the surface), normalised
//! to carry exactly `T(wo)`: directions with `wi.z < 0`.
//!
//! With `KHR_materials_volume` the transmitted share is instead the boundary of a refracting
//! volume ([`Material::dielectric`]): exact Fresnel, total internal reflection, `η²` across
//! it; the integrator picks between it and the rest ([`Material::opaque_part`]) per vertex
//! and attenuates rays inside by Beer–Lambert ([`Volume::sigma`]).
//!
//! The dielectric layer's Fresnel is Schlick's with, per the extension texts,
//! `F0 = min(((ior − 1)/(ior + 1))² · specularColor, 1) · specularFactor` and
//! `F90 = specularFactor`, evaluated at the microfacet (`wo·h`) as the glTF Sample Viewer does.
//! One exception: a layer whose F0 is zero in every channel reflects nothing (F90 = 0), which
//! is what Blender means by Principled *Specular* 0 (see `docs/method.md`), and F90 fades
//! to that continuously below F0 = 1e-3.
//!
//! A clear coat (`KHR_materials_clearcoat`, written by Blender's exporter from the Principled
//! BSDF's *Clearcoat*) is rendered as Cycles 3.4 renders that input, and as Mitsuba 3's
//! `principled` and the Disney BRDF it follows: a lobe added over the rest, `0.25·clearcoat·
//! F(wi·h)·D_GTR1(h)·G1(wo)·G1(wi) / (4 cos θo cos θi)`, with the exact Fresnel of IOR 1.5,
//! Berry's GTR1 distribution of alpha = coat roughness², and Smith's separable masking of a
//! fixed alpha 0.25. It takes nothing from the base, so a white base under a full coat
//! reflects up to `1 + 0.25·E_coat` (`docs/method.md` §6.1). The glTF extension's own text
//! defines the coat differently (a GGX layer that darkens the base by its Fresnel at `n·wo`).
//!
//! Energy conservation by construction: the diffuse loses exactly the directional albedo
//! `E(wo)` of the specular layer (its largest channel), looked up in a table of the GGX
//! albedo with Schlick's Fresnel, so `diffuse + specular ≤ 1` for every `wo`, and a layer
//! with F0 = F90 = 0 leaves exactly Lambert. The metallic part is GGX tinted by a Fresnel
//! bounded by 1. All directions are in the local shading frame (normal = +z) and `wo.z > 0`.

use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, PI};
use std::sync::OnceLock;

use crate::asset::desc::{MaterialDesc, SMOOTH_TRANSMISSION_ROUGHNESS};
use crate::sampling::{cosine_hemisphere_pdf, sample_cosine_hemisphere, sin_cos_turn};

/// The F0 below which F90 fades to 0 in proportion (the specular layer's rim vanishes with
/// its interface): a hundredth of glass's F0 of 0.04 at ior 1.5 (Blender's Specular 0.0125);
/// every ordinary dielectric keeps F90 = specularFactor.
const F90_FADE: f32 = 1e-3;

/// Roughness is clamped so the GGX lobe stays a density (no delta lobes, so MIS always applies).
const MIN_ALPHA: f32 = 1e-3;
/// Up to this GGX alpha, transmission goes straight through ([`SMOOTH_TRANSMISSION_ROUGHNESS`]
/// squared); above it, it is a rough lobe.
const SMOOTH_ALPHA: f32 = SMOOTH_TRANSMISSION_ROUGHNESS * SMOOTH_TRANSMISSION_ROUGHNESS;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    pub base_color: Vec3,
    pub metallic: f32,
    /// GGX alpha = perceptual roughness squared.
    pub alpha: f32,
    /// Reflectance of the dielectric specular layer at normal incidence, per channel, with the
    /// specular factor applied (0.04 for a glTF material without extensions).
    pub f0: Vec3,
    /// Reflectance of the dielectric specular layer at grazing incidence: the specular factor,
    /// or 0 when `f0` is zero (no layer).
    pub f90: f32,
    /// Emitted radiance, W/(sr·m²).
    pub emission: Vec3,
    /// Emits (and is lit) from both sides; otherwise only from the front of its winding.
    pub double_sided: bool,
    /// The share of the dielectric base transmitted straight through (thin-walled), in [0, 1].
    pub transmission: f32,
    /// `KHR_materials_volume`: the transmitted share is the boundary of a refracting volume,
    /// resolved at each vertex into [`Self::dielectric`] or [`Self::opaque_part`].
    pub volume: Option<Volume>,
    /// A dielectric boundary's relative IOR, `n` beyond over `n` on the side of `wo` (0 for
    /// every other material): see [`Self::dielectric`].
    eta: f32,
    /// The clear coat's weight (Principled *Clearcoat*, `clearcoatFactor`), in [0, 1].
    pub clearcoat: f32,
    /// The clear coat's GTR1 alpha: its roughness squared, in [[`MIN_ALPHA`], [`MAX_COAT_ALPHA`]].
    pub clearcoat_alpha: f32,
    /// What depends on `wo` only, at the albedo table's columns of `√cos θo`: see
    /// [`Material::lobe_weights`].
    lobes: [[f32; 2]; ALBEDO_COS_CELLS + 1],
}

/// The clear coat's IOR, its weight's scale and its masking's fixed alpha (Cycles 3.4,
/// `bsdf_microfacet_ggx_clearcoat_setup` and `_eval_reflect`; the Disney BRDF's numbers).
const COAT_IOR: f32 = 1.5;
const COAT_SCALE: f32 = 0.25;
const COAT_MASKING_ALPHA: f32 = 0.25;
/// GTR1's density degenerates at alpha 1 (`(α² − 1)/ln α²` → 1): the largest alpha kept.
const MAX_COAT_ALPHA: f32 = 0.999;

/// What fills a closed mesh of a refracting material (`KHR_materials_volume`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Volume {
    /// The glass's index of refraction (the outside's is 1).
    pub ior: f32,
    /// Beer–Lambert's absorption coefficient per metre.
    pub sigma: Vec3,
}

/// A direction drawn from the BSDF with its value and solid-angle pdf.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    pub wi: Vec3,
    pub f: Vec3,
    pub pdf: f32,
}

/// Normal-incidence reflectance of a dielectric interface with air: `((ior − 1)/(ior + 1))²`.
/// `ior = 0` is glTF's "infinite" IOR and gives 1.
pub fn f0_from_ior(ior: f32) -> f32 {
    let r = (ior - 1.0) / (ior + 1.0);
    r * r
}

/// The glTF parameters a material is made of (factors times textures at a point).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MaterialParams {
    pub base_color: Vec3,
    pub metallic: f32,
    /// Perceptual roughness.
    pub roughness: f32,
    pub specular_factor: f32,
    pub specular_color: Vec3,
    pub ior: f32,
    /// `transmissionFactor` (times its texture's R).
    pub transmission: f32,
    pub volume: Option<Volume>,
    pub emission: Vec3,
    pub double_sided: bool,
    /// `clearcoatFactor` (times its texture's R) and `clearcoatRoughnessFactor` (times its
    /// texture's G).
    pub clearcoat: f32,
    pub clearcoat_roughness: f32,
}

impl MaterialParams {
    pub fn from_desc(desc: &MaterialDesc) -> Self {
        MaterialParams {
            base_color: desc.base_color,
            metallic: desc.metallic,
            roughness: desc.roughness,
            specular_factor: desc.specular_factor,
            specular_color: desc.specular_color,
            ior: desc.ior,
            transmission: desc.transmission,
            volume: desc.volume.map(|v| Volume {
                ior: desc.ior,
                sigma: v.sigma(),
            }),
            emission: desc.radiance(),
            double_sided: desc.double_sided,
            clearcoat: desc.clearcoat,
            clearcoat_roughness: desc.clearcoat_roughness,
        }
    }
}

impl Material {
    pub fn from_desc(desc: &MaterialDesc) -> Self {
        Self::without_lobes(&MaterialParams::from_desc(desc)).with_lobes()
    }

    /// The material of a textured point seen from directions `wo` with `cos θo = cos_o`: its
    /// `wo`-only terms are computed at that one angle, so it must be evaluated and sampled
    /// for that `wo` only (as a shading point is).
    pub fn at_incidence(params: &MaterialParams, cos_o: f32) -> Self {
        let mut m = Self::without_lobes(params);
        let lobe = m.lobe_at(cos_o);
        m.lobes = [lobe; ALBEDO_COS_CELLS + 1];
        m
    }

    fn without_lobes(p: &MaterialParams) -> Self {
        let r = p.roughness.clamp(0.0, 1.0);
        let weight = p.specular_factor.clamp(0.0, 1.0);
        let f0 = (f0_from_ior(p.ior.max(0.0)) * p.specular_color.max(Vec3::ZERO)).min(Vec3::ONE)
            * weight;
        // Schlick's F90 = 1 describes an interface; F0 = 0 in every channel means there is
        // none (Blender's Specular 0, or ior = 1), so the layer is absent rather than a rim.
        // Below F90_FADE, F90 fades with F0, so that a texel of F0 = 0 and one just above it
        // (a specular-colour texel of 1/255) shade alike, with no seam between them.
        let f90 = weight * (f0.max_element() / F90_FADE).clamp(0.0, 1.0);
        Material {
            base_color: p.base_color.clamp(Vec3::ZERO, Vec3::ONE),
            metallic: p.metallic.clamp(0.0, 1.0),
            alpha: (r * r).max(MIN_ALPHA),
            f0,
            f90,
            emission: p.emission.max(Vec3::ZERO),
            double_sided: p.double_sided,
            transmission: p.transmission.clamp(0.0, 1.0),
            volume: p.volume,
            eta: 0.0,
            clearcoat: p.clearcoat.clamp(0.0, 1.0),
            clearcoat_alpha: {
                let r = p.clearcoat_roughness.clamp(0.0, 1.0);
                (r * r).clamp(MIN_ALPHA, MAX_COAT_ALPHA)
            },
            lobes: [[0.0; 2]; ALBEDO_COS_CELLS + 1],
        }
    }

    /// Fills `lobes` from the other fields: the specular layer's albedo and the probability
    /// of sampling the specular lobes at each column of `√cos θo`.
    fn with_lobes(mut self) -> Self {
        for i in 0..=ALBEDO_COS_CELLS {
            let cos_o = (i as f32 / ALBEDO_COS_CELLS as f32).powi(2);
            self.lobes[i] = self.lobe_at(cos_o);
        }
        self
    }

    /// `[E(wo), P(GGX lobes: the specular ones and the rough transmission)]` at `cos θo` (see
    /// [`Self::lobe_weights`]).
    fn lobe_at(&self, cos_o: f32) -> [f32; 2] {
        // Without a specular lobe or a rough transmission both are exactly zero: skip the table
        // (building it takes about 0.1 s that Lambertian scenes need not wait for).
        if !self.has_specular() && !self.transmits_rough() {
            return [0.0; 2];
        }
        let (a, b) = ggx_albedo(cos_o, self.alpha);
        let m = self.metallic;
        let mean = |v: Vec3| (v.x + v.y + v.z) / 3.0;
        // Rounded up by the table's relative error, so the diffuse never keeps energy the
        // lobe reflects (a layer with F0 = F90 = 0 still takes exactly nothing).
        let e_max = ((self.f0.max_element() * a + self.f90 * b) * ALBEDO_ROUND_UP).min(1.0);
        let dielectric = mean(self.f0) * a + self.f90 * b;
        let specular = (1.0 - m) * dielectric + m * (mean(self.base_color) * a + b);
        let base = (1.0 - m) * (1.0 - e_max) * mean(self.base_color);
        let diffuse = base * (1.0 - self.transmission);
        let transmitted = if self.transmits_rough() {
            base * self.transmission
        } else {
            0.0
        };
        let total = specular + diffuse + transmitted;
        if total > 0.0 {
            [e_max, (specular + transmitted) / total]
        } else {
            [e_max, 0.0]
        }
    }

    /// A pure Lambertian reflector (no specular layer).
    pub fn lambertian(albedo: Vec3) -> Self {
        Material {
            base_color: albedo,
            metallic: 0.0,
            alpha: 1.0,
            f0: Vec3::ZERO,
            f90: 0.0,
            emission: Vec3::ZERO,
            double_sided: true,
            transmission: 0.0,
            volume: None,
            eta: 0.0,
            clearcoat: 0.0,
            clearcoat_alpha: MAX_COAT_ALPHA,
            lobes: [[0.0; 2]; ALBEDO_COS_CELLS + 1],
        }
    }

    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }

    /// Whether the material reflects at all (black materials skip shading).
    pub fn is_black(&self) -> bool {
        self.metallic <= 0.0
            && self.diffuse_color().max_element() <= 0.0
            && self.f0.max_element() <= 0.0
            && self.f90 <= 0.0
            && self.clearcoat <= 0.0
            && (self.dielectric_share() <= 0.0 || self.base_color.max_element() <= 0.0)
    }

    /// Whether light goes straight through it (smooth thin-walled transmission): see
    /// [`Self::straight_through`].
    pub fn transmits(&self) -> bool {
        self.has_transmission() && self.alpha <= SMOOTH_ALPHA
    }

    /// Whether it transmits through a rough lobe (directions below the surface, `wi.z < 0`):
    /// a real vertex, which light reaches from both sides.
    pub fn transmits_rough(&self) -> bool {
        self.has_transmission() && self.alpha > SMOOTH_ALPHA
    }

    /// Whether any light passes the surface thin-walled: a transmitting dielectric share with a
    /// colour, and no volume behind it.
    #[inline(always)]
    fn has_transmission(&self) -> bool {
        self.transmission > 0.0
            && self.metallic < 1.0
            && self.base_color.max_element() > 0.0
            && self.volume.is_none()
    }

    /// The share of a volume's surface that is the boundary of its dielectric,
    /// `(1 − metallic)·transmission` (0 without a volume): a vertex is [`Self::dielectric`]
    /// with this probability and [`Self::opaque_part`] otherwise, each then with weight 1
    /// (one sample of the mixture `share·dielectric + (1 − share)·rest`).
    pub fn dielectric_share(&self) -> f32 {
        match self.volume {
            Some(_) => (1.0 - self.metallic) * self.transmission,
            None => 0.0,
        }
    }

    /// The boundary of the volume's dielectric seen from the side of `wo`, `inside` the mesh
    /// or out: a GGX dielectric (Walter et al. 2007, as pbrt-v4's `DielectricBxDF`) of
    /// relative IOR `ior` entering and `1/ior` leaving, with the exact Fresnel, transmission
    /// tinted by the base colour and divided by `η²` (radiance is compressed entering a
    /// denser medium and expanded leaving it); smooth ([`Self::is_smooth_dielectric`]) it is a
    /// delta interface ([`Self::sample_smooth_dielectric`]).
    pub fn dielectric(&self, inside: bool) -> Material {
        let ior = self.volume.map_or(1.0, |v| v.ior).max(1.0);
        Material {
            base_color: self.base_color,
            metallic: 0.0,
            alpha: self.alpha,
            f0: Vec3::splat(f0_from_ior(ior)),
            f90: 1.0,
            emission: Vec3::ZERO,
            double_sided: true,
            transmission: 0.0,
            volume: None,
            clearcoat: 0.0,
            clearcoat_alpha: MAX_COAT_ALPHA,
            eta: if inside { 1.0 / ior } else { ior },
            lobes: [[0.0; 2]; ALBEDO_COS_CELLS + 1],
        }
    }

    /// What a volume's surface is besides its dielectric (see [`Self::dielectric_share`]):
    /// the material without transmission, its metal renormalised to the rest,
    /// `m / (1 − share)`; its `wo`-only terms at `cos θo = cos_o` (as [`Self::at_incidence`]).
    pub fn opaque_part(&self, cos_o: f32) -> Material {
        let rest = 1.0 - self.dielectric_share();
        let mut m = Material {
            transmission: 0.0,
            volume: None,
            metallic: if rest > 0.0 {
                (self.metallic / rest).min(1.0)
            } else {
                0.0
            },
            ..*self
        };
        let lobe = m.lobe_at(cos_o);
        m.lobes = [lobe; ALBEDO_COS_CELLS + 1];
        m
    }

    /// Whether this is a dielectric boundary smooth enough to be a delta interface.
    pub fn is_smooth_dielectric(&self) -> bool {
        self.eta > 0.0 && self.alpha <= SMOOTH_ALPHA
    }

    /// A smooth dielectric boundary's event for `wo` (`wo.z > 0`): reflection with the exact
    /// Fresnel's probability `F` (certainly past the critical angle), else refraction; the
    /// direction and its weight `f·|cos θi| / P`: 1 for the reflection, `baseColor / η²` for
    /// the refraction.
    pub fn sample_smooth_dielectric(&self, wo: Vec3, u: f32) -> (Vec3, Vec3) {
        let f = fresnel_dielectric(wo.z, self.eta);
        if u >= f
            && let Some(wt) = refract(wo, Vec3::Z, self.eta)
        {
            return (wt, self.base_color / (self.eta * self.eta));
        }
        (Vec3::new(-wo.x, -wo.y, wo.z), Vec3::ONE)
    }

    /// A rough dielectric boundary's `f(wo, wi)` and the pdf of drawing `wi` (pbrt-v4's
    /// `DielectricBxDF::f` and `PDF`, radiance transport): the generalised half vector
    /// `ωm ∝ η·wi + wo` for transmission, the lobes drawn in proportion to `F` and `1 − F`.
    fn eval_pdf_dielectric(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        if wo.z <= 0.0 || wi.z == 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let reflect = wi.z > 0.0;
        let etap = if reflect { 1.0 } else { self.eta };
        let wm = wi * etap + wo;
        if wm.length_squared() <= 1e-12 {
            return (Vec3::ZERO, 0.0);
        }
        let wm = wm.normalize();
        let wm = if wm.z < 0.0 { -wm } else { wm };
        let (cos_om, cos_im) = (wo.dot(wm), wi.dot(wm));
        // Microfacets that face away from either direction take no part.
        if cos_om <= 0.0 || cos_im * wi.z <= 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let f = fresnel_dielectric(cos_om, self.eta);
        let d = ggx_d(wm, self.alpha);
        let (lambda_o, lambda_i) = (ggx_lambda(wo, self.alpha), ggx_lambda(wi, self.alpha));
        let g2 = 1.0 / (1.0 + lambda_o + lambda_i);
        // The visible normals' density: G1(wo)·D(ωm)·(wo·ωm) / cos θo.
        let pdf_wm = d / (1.0 + lambda_o) * cos_om / wo.z;
        if reflect {
            let value = d * g2 * f / (4.0 * wo.z * wi.z);
            return (Vec3::splat(value), pdf_wm / (4.0 * cos_om) * f);
        }
        let denom = cos_im + cos_om / etap;
        let denom2 = denom * denom;
        if denom2 <= 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let value =
            (1.0 - f) * d * g2 * (cos_im * cos_om / (wi.z * wo.z * denom2)).abs() / (etap * etap);
        let pdf = pdf_wm * cos_im.abs() / denom2 * (1.0 - f);
        (self.base_color * value, pdf)
    }

    /// Draws a rough dielectric boundary's `wi`: a visible microfacet normal, then reflection
    /// with probability `F` or else refraction through it.
    fn sample_dielectric_direction(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<Vec3> {
        if wo.z <= 0.0 {
            return None;
        }
        let wm = sample_ggx_vndf(wo, self.alpha, u);
        let cos_om = wo.dot(wm);
        if u_lobe < fresnel_dielectric(cos_om, self.eta) {
            let wi = 2.0 * cos_om * wm - wo;
            return (wi.z > 0.0).then_some(wi);
        }
        refract(wo, wm, self.eta).filter(|wi| wi.z < 0.0)
    }

    /// The Lambertian base's albedo: what the transmission leaves of the base colour.
    #[inline(always)]
    fn diffuse_color(&self) -> Vec3 {
        self.base_color * (1.0 - self.transmission)
    }

    /// The weight with which light crosses the surface straight through, seen along `wo` with
    /// `cos θo = cos_o` (either side): `(1 − metallic)·(1 − E(wo))·transmission·baseColor`,
    /// the dielectric base's transmitted share of what the specular layer does not reflect
    /// (so reflection plus transmission never exceed 1). A delta lobe: the integrator crosses
    /// it as a null interface, and the reflection is [`Self::eval_pdf`].
    #[inline(always)]
    pub fn straight_through(&self, cos_o: f32) -> Vec3 {
        if !self.transmits() {
            return Vec3::ZERO;
        }
        let e_spec = self.lobe_weights(cos_o.abs()).0;
        (1.0 - self.metallic) * (1.0 - e_spec) * self.transmission * self.base_color
    }

    /// The dielectric specular layer's directional albedo `E(wo)` in its largest channel:
    /// the energy it takes from the diffuse beneath.
    pub fn specular_albedo(&self, cos_o: f32) -> f32 {
        self.lobe_weights(cos_o).0
    }

    /// The probability that [`Self::sample_direction`] draws the diffuse lobe at `wo`: the part
    /// of the sampler whose broad directions guided continuation may share (0 for a dielectric
    /// boundary and below the surface, 1 for a plain diffuse surface).
    pub fn diffuse_probability(&self, cos_o: f32) -> f32 {
        if self.eta > 0.0 || cos_o <= 0.0 {
            return 0.0;
        }
        if !self.has_specular() && !self.transmits_rough() && !self.has_coat() {
            return 1.0;
        }
        let (e, p_spec, p_trans) = self.lobe_weights(cos_o);
        (1.0 - self.coat_probability(cos_o, e)) * (1.0 - p_spec - p_trans).max(0.0)
    }

    /// Whether it has a clear coat.
    #[inline(always)]
    fn has_coat(&self) -> bool {
        self.clearcoat > 0.0
    }

    /// The probability of drawing the clear coat's lobe at `wo` (`E(wo)` = `e`): its weight's
    /// share, `0.25·clearcoat·F(cos θo)`, against an estimate of the rest's albedo. Any
    /// function of `wo` keeps the estimator unbiased; this one follows the lobes' sizes.
    #[inline(always)]
    fn coat_probability(&self, cos_o: f32, e: f32) -> f32 {
        if !self.has_coat() {
            return 0.0;
        }
        let coat = COAT_SCALE * self.clearcoat * fresnel_dielectric(cos_o, COAT_IOR);
        let m = self.metallic;
        let mean = |v: Vec3| (v.x + v.y + v.z) / 3.0;
        let rest = (1.0 - m) * ((1.0 - e) * mean(self.base_color) + e) + m * mean(self.base_color);
        coat / (coat + rest.max(1e-3))
    }

    /// The clear coat's `f(wo, wi)` (both above the surface) and the density of drawing `wi`
    /// from its lobe: a GTR1 normal `h`, `wi` its mirror of `wo`.
    #[inline(always)]
    fn eval_pdf_coat(&self, wo: Vec3, wi: Vec3) -> (f32, f32) {
        let h = (wo + wi).normalize();
        let cos_oh = wo.dot(h);
        if h.z <= 0.0 || cos_oh <= 0.0 {
            return (0.0, 0.0);
        }
        let d = gtr1_d(h.z, self.clearcoat_alpha);
        let g = 1.0
            / ((1.0 + ggx_lambda(wo, COAT_MASKING_ALPHA))
                * (1.0 + ggx_lambda(wi, COAT_MASKING_ALPHA)));
        let f = fresnel_dielectric(cos_oh, COAT_IOR);
        let value = COAT_SCALE * self.clearcoat * f * g * d / (4.0 * wo.z * wi.z);
        (value, d * h.z / (4.0 * cos_oh))
    }

    /// `E(wo)` (see [`Self::specular_albedo`], at most 1) and the probabilities of sampling
    /// the specular lobes and the rough transmission, from the lobes' albedos: functions of `wo`
    /// only, shared by `eval_pdf` and `sample_direction`, interpolated between the columns of
    /// `lobes`.
    ///
    /// The GGX draws' split between reflection and rough transmission is any function of `wo`
    /// (both `eval_pdf` and `sample_direction` take it from here): their shares of the albedo,
    /// the specular one taken as `(1 − m)·E + m·mean(baseColor)`. Materials that do not
    /// transmit keep the table's two columns (and their numbers) as they were.
    #[inline(always)]
    fn lobe_weights(&self, cos_o: f32) -> (f32, f32, f32) {
        let x = cos_o.clamp(0.0, 1.0).sqrt() * ALBEDO_COS_CELLS as f32;
        let i = (x as usize).min(ALBEDO_COS_CELLS - 1);
        let t = x - i as f32;
        let ([e0, p0], [e1, p1]) = (self.lobes[i], self.lobes[i + 1]);
        let (e, p_ggx) = (e0 + (e1 - e0) * t, p0 + (p1 - p0) * t);
        if !self.transmits_rough() {
            return (e, p_ggx, 0.0);
        }
        let m = self.metallic;
        let mean = (self.base_color.x + self.base_color.y + self.base_color.z) / 3.0;
        let transmitted = (1.0 - m) * (1.0 - e) * self.transmission * mean;
        let specular = (1.0 - m) * e + m * mean;
        let q = if transmitted > 0.0 {
            transmitted / (transmitted + specular)
        } else {
            0.0
        };
        (e, p_ggx * (1.0 - q), p_ggx * q)
    }

    /// The rough transmission lobe at `wi` below the surface: the GGX reflection lobe about the
    /// mirror of `wi` through the surface (`wr`), with F = 1, normalised by its albedo
    /// `A + B` (F0 = F90 = 1) so that it carries exactly `T(wo)`; and the pdf of drawing it.
    fn eval_pdf_transmitted(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        let (e_spec, _, p_trans) = self.lobe_weights(wo.z);
        let p_trans = p_trans * (1.0 - self.coat_probability(wo.z, e_spec));
        let wr = Vec3::new(wi.x, wi.y, -wi.z);
        let h = (wo + wr).normalize();
        let d = ggx_d(h, self.alpha);
        let (lambda_o, lambda_r) = (ggx_lambda(wo, self.alpha), ggx_lambda(wr, self.alpha));
        let (a, b) = ggx_albedo(wo.z, self.alpha);
        let albedo = (a + b).max(1e-4);
        let dg = d / ((1.0 + lambda_o + lambda_r) * 4.0 * wo.z * wr.z);
        let weight = (1.0 - self.metallic) * (1.0 - e_spec) * self.transmission / albedo;
        let pdf = p_trans * d / ((1.0 + lambda_o) * 4.0 * wo.z);
        (dg * weight * self.base_color, pdf)
    }

    /// Whether there is any specular lobe (dielectric layer or metal).
    fn has_specular(&self) -> bool {
        self.metallic > 0.0 || self.f90 > 0.0 || self.f0.max_element() > 0.0
    }

    /// The albedo of a material that is exactly Lambertian (no dielectric boundary, specular
    /// layer, coat or rough transmission): its `eval_pdf` above the surface is then
    /// `(albedo / π, cos θi / π)` and `sample_direction` the cosine-weighted hemisphere, which
    /// the packet integrator computes in lanes.
    pub fn lambertian_albedo(&self) -> Option<Vec3> {
        let plain =
            self.eta <= 0.0 && !self.has_specular() && !self.transmits_rough() && !self.has_coat();
        plain.then(|| self.diffuse_color())
    }

    /// `f(wo, wi)` and the pdf of `sample` drawing `wi`, sharing the microfacet terms.
    #[inline(always)]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        if self.eta > 0.0 {
            return self.eval_pdf_dielectric(wo, wi);
        }
        if wo.z <= 0.0 || wi.z <= 0.0 {
            if wo.z > 0.0 && wi.z < 0.0 && self.transmits_rough() {
                return self.eval_pdf_transmitted(wo, wi);
            }
            return (Vec3::ZERO, 0.0);
        }
        let m = self.metallic;
        if !self.has_specular() && !self.transmits_rough() && !self.has_coat() {
            return (
                self.diffuse_color() * FRAC_1_PI,
                cosine_hemisphere_pdf(wi.z),
            );
        }
        // The diffuse keeps what the specular layer does not reflect.
        let (e_spec, p_spec, p_trans) = self.lobe_weights(wo.z);
        let (coat, pdf_coat, p_coat) = if self.has_coat() {
            let (value, pdf) = self.eval_pdf_coat(wo, wi);
            (value, pdf, self.coat_probability(wo.z, e_spec))
        } else {
            (0.0, 0.0, 0.0)
        };
        let diffuse = (1.0 - m) * (1.0 - e_spec) * self.diffuse_color() * FRAC_1_PI;
        let pdf_diffuse = (1.0 - p_spec - p_trans) * cosine_hemisphere_pdf(wi.z);
        let h = (wo + wi).normalize();
        let d = ggx_d(h, self.alpha);
        let (lambda_o, lambda_i) = (ggx_lambda(wo, self.alpha), ggx_lambda(wi, self.alpha));
        // Height-correlated masking-shadowing G2 for the value; the pdf of visible-normal
        // sampling uses the masking G1(wo) = 1 / (1 + Λo).
        let dg = d / ((1.0 + lambda_o + lambda_i) * 4.0 * wo.z * wi.z);
        let c5 = schlick_weight(wo.dot(h));
        let dielectric = self.f0 + (Vec3::splat(self.f90) - self.f0) * c5;
        let mut f = diffuse + dg * (1.0 - m) * dielectric;
        if m > 0.0 {
            f += dg * m * (self.base_color + (Vec3::ONE - self.base_color) * c5);
        }
        let pdf_specular = d / ((1.0 + lambda_o) * 4.0 * wo.z);
        (
            f + Vec3::splat(coat),
            (1.0 - p_coat) * (pdf_diffuse + p_spec * pdf_specular) + p_coat * pdf_coat,
        )
    }

    /// Draws `wi`: the lobe by `u_lobe`, then the direction by `u`.
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        self.sampled(wo, self.sample_direction(wo, u_lobe, u)?)
    }

    /// The direction part of [`Self::sample`], for callers that may not need its value.
    #[inline(always)]
    pub fn sample_direction(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<Vec3> {
        if self.eta > 0.0 {
            return self.sample_dielectric_direction(wo, u_lobe, u);
        }
        if wo.z <= 0.0 {
            return None;
        }
        if !self.has_specular() && !self.transmits_rough() && !self.has_coat() {
            return Some(sample_cosine_hemisphere(u));
        }
        let (e, p_spec, p_trans) = self.lobe_weights(wo.z);
        let p_coat = self.coat_probability(wo.z, e);
        if u_lobe < p_coat {
            let h = sample_gtr1(self.clearcoat_alpha, u);
            let wi = 2.0 * wo.dot(h) * h - wo;
            return (wi.z > 0.0).then_some(wi);
        }
        // The rest's lobes by `u_lobe` stretched back over [0, 1).
        let u_lobe = ((u_lobe - p_coat) / (1.0 - p_coat)).min(crate::sampling::ONE_BELOW);
        if u_lobe < p_spec + p_trans {
            let h = sample_ggx_vndf(wo, self.alpha, u);
            let wi = 2.0 * wo.dot(h) * h - wo;
            if wi.z <= 0.0 {
                return None;
            }
            // The rough transmission: the reflection mirrored through the surface.
            Some(if u_lobe < p_spec {
                wi
            } else {
                Vec3::new(wi.x, wi.y, -wi.z)
            })
        } else {
            Some(sample_cosine_hemisphere(u))
        }
    }

    /// The sample that [`Self::sample_direction`] drew as `wi`: its value and pdf.
    #[inline(always)]
    pub fn sampled(&self, wo: Vec3, wi: Vec3) -> Option<BsdfSample> {
        let (f, pdf) = self.eval_pdf(wo, wi);
        (pdf > 0.0).then_some(BsdfSample { wi, f, pdf })
    }
}

/// The exact Fresnel reflectance of unpolarised light at a dielectric interface of relative
/// IOR `eta` (beyond over incident), for `cos θ` on the incident side; 1 past the critical
/// angle (total internal reflection).
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let r_parallel = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perpendicular = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (r_parallel * r_parallel + r_perpendicular * r_perpendicular)
}

/// `wo` refracted through the interface of normal `n` (`wo · n > 0`) into the medium of
/// relative IOR `eta`; `None` past the critical angle.
pub fn refract(wo: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
    let cos_i = wo.dot(n);
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some(-wo / eta + (cos_i / eta - cos_t) * n)
}

/// Schlick's `(1 − cos)⁵`: `F = F0 + (F90 − F0)·(1 − cos)⁵`.
fn schlick_weight(cos: f32) -> f32 {
    (1.0 - cos.clamp(0.0, 1.0)).powi(5)
}

/// Cells of the albedo table along `√cos θo` and along perceptual roughness `√α`.
const ALBEDO_COS_CELLS: usize = 32;
const ALBEDO_ROUGHNESS_CELLS: usize = 24;
/// Factor on the tabulated albedo covering its error relative to the true one (measured below
/// 1.5e-3 against an independent quadrature, `tests::albedo_table_matches_…`).
const ALBEDO_ROUND_UP: f32 = 1.003;
/// Midpoint-rule points per axis of the visible-normal sample square, per table entry.
const ALBEDO_QUADRATURE: usize = 64;

/// `(A, B)` with `E(wo) = F0·A + F90·B`: the directional albedo of single-scattering GGX with
/// Schlick's Fresnel (linear in F0 and F90), interpolated in a table computed once.
pub fn ggx_albedo(cos_o: f32, alpha: f32) -> (f32, f32) {
    static TABLE: OnceLock<Vec<[f32; 2]>> = OnceLock::new();
    let table = TABLE.get_or_init(albedo_table);
    let x = cos_o.clamp(0.0, 1.0).sqrt() * ALBEDO_COS_CELLS as f32;
    let y = alpha.clamp(0.0, 1.0).sqrt() * ALBEDO_ROUGHNESS_CELLS as f32;
    let (i, j) = (
        (x as usize).min(ALBEDO_COS_CELLS - 1),
        (y as usize).min(ALBEDO_ROUGHNESS_CELLS - 1),
    );
    let (tx, ty) = (x - i as f32, y - j as f32);
    let at = |i: usize, j: usize| table[j * (ALBEDO_COS_CELLS + 1) + i];
    let lerp =
        |a: [f32; 2], b: [f32; 2], t: f32| [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t];
    let [a, b] = lerp(
        lerp(at(i, j), at(i + 1, j), tx),
        lerp(at(i, j + 1), at(i + 1, j + 1), tx),
        ty,
    );
    (a, b)
}

/// The table behind [`ggx_albedo`]: rows of roughness, columns of `cos θo`, each entry the
/// midpoint-rule integral of `F·G2/G1` over visible-normal samples (whose density makes
/// `f·cos/pdf` exactly that weight).
fn albedo_table() -> Vec<[f32; 2]> {
    let n = ALBEDO_QUADRATURE;
    let mut table = Vec::with_capacity((ALBEDO_COS_CELLS + 1) * (ALBEDO_ROUGHNESS_CELLS + 1));
    for j in 0..=ALBEDO_ROUGHNESS_CELLS {
        let r = j as f32 / ALBEDO_ROUGHNESS_CELLS as f32;
        let alpha = (r * r).max(MIN_ALPHA);
        for i in 0..=ALBEDO_COS_CELLS {
            // Columns are uniform in √cos θo (finer towards grazing, where E changes fastest);
            // the first is the limit at grazing incidence, approached from just above it.
            let cos_o = (i as f32 / ALBEDO_COS_CELLS as f32).powi(2).max(1e-4);
            let wo = Vec3::new((1.0 - cos_o * cos_o).sqrt(), 0.0, cos_o);
            let lambda_o = ggx_lambda(wo, alpha);
            let (mut a, mut b) = (0.0f64, 0.0f64);
            for k in 0..n * n {
                // `u.x = 1 − (1 − t)²` crowds the points towards the rim of the sampled disk
                // (the far tail of normals, where wi meets the horizon); `2(1 − t)` is dx/dt.
                let t = ((k % n) as f32 + 0.5) / n as f32;
                let u = Vec2::new(
                    1.0 - (1.0 - t) * (1.0 - t),
                    ((k / n) as f32 + 0.5) / n as f32,
                );
                let h = sample_ggx_vndf(wo, alpha, u);
                let wi = 2.0 * wo.dot(h) * h - wo;
                if wi.z <= 0.0 {
                    continue;
                }
                let weight =
                    2.0 * (1.0 - t) * (1.0 + lambda_o) / (1.0 + lambda_o + ggx_lambda(wi, alpha));
                let c5 = schlick_weight(wo.dot(h));
                a += (weight * (1.0 - c5)) as f64;
                b += (weight * c5) as f64;
            }
            let count = (n * n) as f64;
            table.push([(a / count) as f32, (b / count) as f32]);
        }
    }
    table
}

/// Berry's GTR1 (Burley 2012, the Disney clear coat; Cycles' `D_GTR1`):
/// `D(h) = (α² − 1) / (π·ln α²·(1 + (α² − 1)·cos² θh))`, for `α` in (0, 1).
fn gtr1_d(cos_h: f32, alpha: f32) -> f32 {
    if cos_h <= 0.0 {
        return 0.0;
    }
    let a2 = alpha * alpha;
    (a2 - 1.0) / (PI * a2.ln() * (1.0 + (a2 - 1.0) * cos_h * cos_h))
}

/// A GTR1 normal with density `D(h)·cos θh` (the inverse of its cumulative distribution in
/// `cos² θh`): `cos² θh = (1 − α^(2(1 − u)))/(1 − α²)`.
fn sample_gtr1(alpha: f32, u: Vec2) -> Vec3 {
    let a2 = alpha * alpha;
    let cos2 = ((1.0 - a2.powf(1.0 - u.x)) / (1.0 - a2)).clamp(0.0, 1.0);
    let sin = (1.0 - cos2).sqrt();
    let (sin_phi, cos_phi) = sin_cos_turn(u.y);
    Vec3::new(sin * cos_phi, sin * sin_phi, cos2.sqrt())
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
mod tests;
