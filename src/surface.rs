//! A textured material at a surface point: glTF's factors times its textures' values, the
//! normal map in the tangent frame, the emission and the alpha that cut-outs test.

use glam::{Vec2, Vec3, Vec4};
use std::sync::Arc;

use crate::asset::desc::{AlphaMode, MaterialDesc};
use crate::asset::texture::{Encoding, Image, Texture, TextureRef};
use crate::material::{Material, MaterialParams};

/// The interpolated vertex attributes at a point of a textured triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    /// `TEXCOORD_0` and `TEXCOORD_1` (zero where the mesh has none).
    pub uvs: [Vec2; 2],
    /// The tangent (xyz, not normalised) and the bitangent sign (w).
    pub tangent: Vec4,
}

/// Why a material's textures cannot be used.
#[derive(Debug, thiserror::Error)]
#[error("material \"{material}\": its {slot} names image {image}, which does not exist")]
pub struct MissingImage {
    pub material: String,
    pub slot: &'static str,
    pub image: usize,
}

/// A material's textures with their images in hand, and the factors they multiply.
#[derive(Clone, Debug)]
pub struct SurfaceTextures {
    params: MaterialParams,
    /// `baseColorFactor`'s alpha.
    alpha: f32,
    pub alpha_mode: AlphaMode,
    base_color: Option<Texture>,
    metallic_roughness: Option<Texture>,
    normal: Option<(Texture, f32)>,
    emissive: Option<Texture>,
    specular: Option<Texture>,
    specular_color: Option<Texture>,
    transmission: Option<Texture>,
    clearcoat: Option<Texture>,
    clearcoat_roughness: Option<Texture>,
}

impl SurfaceTextures {
    /// `None` for a material that needs no per-point work (no texture and no cut-out).
    pub fn new(desc: &MaterialDesc, images: &[Arc<Image>]) -> Result<Option<Self>, MissingImage> {
        let t = &desc.textures;
        if !t.any() && desc.alpha_mode == AlphaMode::Opaque {
            return Ok(None);
        }
        let resolve = |r: Option<&TextureRef>, slot| -> Result<Option<Texture>, MissingImage> {
            let Some(r) = r else {
                return Ok(None);
            };
            let Some(image) = images.get(r.image) else {
                return Err(MissingImage {
                    material: desc.name.clone(),
                    slot,
                    image: r.image,
                });
            };
            Ok(Some(Texture {
                image: image.clone(),
                sampler: r.sampler,
                tex_coord: r.tex_coord,
                transform: r.transform,
            }))
        };
        let normal = resolve(t.normal.as_ref().map(|n| &n.texture), "normalTexture")?;
        Ok(Some(SurfaceTextures {
            params: MaterialParams::from_desc(desc),
            alpha: desc.alpha,
            alpha_mode: desc.alpha_mode,
            base_color: resolve(t.base_color.as_ref(), "baseColorTexture")?,
            metallic_roughness: resolve(t.metallic_roughness.as_ref(), "metallicRoughnessTexture")?,
            normal: normal.zip(t.normal.map(|n| n.scale)),
            emissive: resolve(t.emissive.as_ref(), "emissiveTexture")?,
            specular: resolve(t.specular.as_ref(), "specularTexture")?,
            specular_color: resolve(t.specular_color.as_ref(), "specularColorTexture")?,
            transmission: resolve(t.transmission.as_ref(), "transmissionTexture")?,
            clearcoat: resolve(t.clearcoat.as_ref(), "clearcoatTexture")?,
            clearcoat_roughness: resolve(
                t.clearcoat_roughness.as_ref(),
                "clearcoatRoughnessTexture",
            )?,
        }))
    }

    /// Whether the surface has a normal map (and so needs tangents).
    pub fn normal_map(&self) -> Option<&Texture> {
        self.normal.as_ref().map(|(t, _)| t)
    }

    pub fn has_emission_texture(&self) -> bool {
        self.emissive.is_some()
    }

    /// Base colour alpha: the factor times the texture's alpha.
    pub fn alpha(&self, uvs: &[Vec2; 2]) -> f32 {
        match &self.base_color {
            Some(t) => self.alpha * t.sample(uvs, Encoding::Linear).w,
            None => self.alpha,
        }
    }

    /// Whether a ray meets the surface at this point: always unless it is cut out (MASK:
    /// alpha below the cutoff) or, for BLEND, unless `u` (uniform in [0, 1)) is not below
    /// alpha.
    pub fn is_present(&self, uvs: &[Vec2; 2], u: impl FnOnce() -> f32) -> bool {
        match self.alpha_mode {
            AlphaMode::Opaque => true,
            AlphaMode::Mask { cutoff } => self.alpha(uvs) >= cutoff,
            AlphaMode::Blend => u() < self.alpha(uvs),
        }
    }

    /// The emissive texture's factor on the material's emitted radiance (1 without one).
    pub fn emission_scale(&self, uvs: &[Vec2; 2]) -> Vec3 {
        match &self.emissive {
            Some(t) => t.sample(uvs, Encoding::Srgb).truncate(),
            None => Vec3::ONE,
        }
    }

    /// The normal-mapped shading normal from the interpolated normal `ns` and the point's
    /// tangent, or `None` without a normal map or where the tangent frame degenerates.
    pub fn mapped_normal(&self, point: &SurfacePoint, ns: Vec3) -> Option<Vec3> {
        let (texture, scale) = self.normal.as_ref()?;
        let tangent_space =
            tangent_space_normal(texture.sample(&point.uvs, Encoding::Linear), *scale);
        let t = point.tangent.truncate();
        let t = (t - ns * ns.dot(t)).normalize_or_zero();
        if t == Vec3::ZERO || ns == Vec3::ZERO {
            return None;
        }
        let sign = if point.tangent.w < 0.0 { -1.0 } else { 1.0 };
        let b = sign * ns.cross(t);
        let n =
            (tangent_space.x * t + tangent_space.y * b + tangent_space.z * ns).normalize_or_zero();
        (n != Vec3::ZERO).then_some(n)
    }

    /// The material at this point, seen from directions with `cos θo = cos_o` (see
    /// [`Material::at_incidence`]).
    pub fn material(&self, uvs: &[Vec2; 2], cos_o: f32) -> Material {
        let mut p = self.params;
        if let Some(t) = &self.base_color {
            p.base_color *= t.sample(uvs, Encoding::Srgb).truncate();
        }
        if let Some(t) = &self.metallic_roughness {
            let v = t.sample(uvs, Encoding::Linear);
            p.roughness *= v.y;
            p.metallic *= v.z;
        }
        if let Some(t) = &self.specular {
            p.specular_factor *= t.sample(uvs, Encoding::Linear).w;
        }
        if let Some(t) = &self.specular_color {
            p.specular_color *= t.sample(uvs, Encoding::Srgb).truncate();
        }
        if let Some(t) = &self.transmission {
            p.transmission *= t.sample(uvs, Encoding::Linear).x;
        }
        if let Some(t) = &self.clearcoat {
            p.clearcoat *= t.sample(uvs, Encoding::Linear).x;
        }
        if let Some(t) = &self.clearcoat_roughness {
            p.clearcoat_roughness *= t.sample(uvs, Encoding::Linear).y;
        }
        p.emission *= self.emission_scale(uvs);
        Material::at_incidence(&p, cos_o)
    }
}

/// Cycles' `ensure_valid_reflection` (Blender 3.4, `intern/cycles`), as its normal map node
/// applies it: a
/// shading normal `n` that would mirror the view direction `wo` below the surface (`ng`,
/// facing `wo`) is bent toward `ng`, in the plane of `n` and `ng`, just far enough that the
/// reflection of `wo` rises `min(0.9 · ng·wo, 0.01)` above it. Cycles applies it to every
/// normal-mapped normal; steep bumps seen from the side then shade brighter than the plain
/// rule (the mapped normal as is), as in Blender.
pub fn ensure_valid_reflection(ng: Vec3, wo: Vec3, n: Vec3) -> Vec3 {
    let r = 2.0 * n.dot(wo) * n - wo;
    let threshold = (0.9 * ng.dot(wo)).min(0.01);
    if ng.dot(r) >= threshold {
        return n;
    }
    // In the plane of n and ng: x along n's tangential part, z along ng.
    let x = (n - n.dot(ng) * ng).normalize_or_zero();
    let (ix, iz) = (wo.dot(x), wo.dot(ng));
    let (ix2, iz2) = (ix * ix, iz * iz);
    let a = ix2 + iz2;
    let b = (ix2 * (a - threshold * threshold)).max(0.0).sqrt();
    let c = iz * threshold + a;
    let fac = 0.5 / a;
    let (n1_z2, n2_z2) = (fac * (b + c), fac * (c - b));
    let valid = |z2: f32| z2 > 1e-5 && z2 <= 1.0 + 1e-5;
    let normal = |z2: f32| ((1.0 - z2).max(0.0).sqrt(), z2.max(0.0).sqrt());
    let (valid1, valid2) = (valid(n1_z2), valid(n2_z2));
    let (nx, nz) = match (valid1, valid2) {
        (true, true) => {
            let (a1, b1) = normal(n1_z2);
            let (a2, b2) = normal(n2_z2);
            let r1 = 2.0 * (a1 * ix + b1 * iz) * b1 - iz;
            let r2 = 2.0 * (a2 * ix + b2 * iz) * b2 - iz;
            let pick_first = if r1 >= 1e-5 && r2 >= 1e-5 {
                r1 < r2
            } else {
                r1 > r2
            };
            if pick_first { (a1, b1) } else { (a2, b2) }
        }
        (true, false) => normal(n1_z2),
        (false, true) => normal(n2_z2),
        (false, false) => return ng,
    };
    (nx * x + nz * ng).normalize_or(ng)
}

/// Cycles' `bump_shadowing_term(N, n, wi)` (Blender 3.4; Chiang, Li and Burley 2019, "Taming
/// the Shadow Terminator"), which Cycles multiplies into a diffuse closure's value (for light
/// samples and BSDF samples alike, not into its pdf) wherever its normal `n` differs from the
/// interpolated normal `ns`: light that the mapped normal faces but the smooth surface barely
/// does is faded smoothly, as a bump's shadow would fade it.
pub fn bump_shadowing_term(ns: Vec3, n: Vec3, wi: Vec3) -> f32 {
    let denominator = n.dot(wi) * ns.dot(n);
    let g = if denominator == 0.0 {
        0.0
    } else {
        ns.dot(wi) / denominator
    };
    if g >= 1.0 {
        1.0
    } else if g < 0.0 || g.is_nan() {
        0.0
    } else {
        let g2 = g * g;
        -g2 * g + g2 + g
    }
}

/// A normal texture's texel (linear RGB in [0, 1]) as a unit tangent-space normal, x and y
/// scaled by `normalTexture.scale` as the glTF specification says.
pub fn tangent_space_normal(texel: Vec4, scale: f32) -> Vec3 {
    let n = texel.truncate() * 2.0 - Vec3::ONE;
    Vec3::new(n.x * scale, n.y * scale, n.z).normalize_or(Vec3::Z)
}
