//! Punctual lamps (`KHR_lights_punctual`): point, spot and directional lights. Each is a delta
//! light: from a shading point exactly one direction reaches it, so next-event estimation
//! draws that direction with a discrete probability (no solid-angle pdf), BSDF-sampled rays
//! never hit it, and its sample's MIS weight is 1.
//!
//! Units: the file gives candela (point, spot) or lux (directional). They are converted to
//! radiometric units at the luminous efficacy Blender's glTF add-on uses,
//! `PBR_WATTS_TO_LUMENS = 683` lm/W, so 1 cd is 1/683 W/sr and 1 lx is 1/683 W/m² (the
//! README says how a Blender lamp of P watts maps).

use glam::Vec3;

use super::area::luminance;
use crate::asset::desc::{LampDesc, LampKind};

/// Lumens per watt: the constant Blender's glTF add-on converts lamps with.
pub const LUMENS_PER_WATT: f32 = 683.0;

/// A lamp ready to sample, in radiometric units.
#[derive(Clone, Debug)]
pub struct Lamp {
    /// Its node's name.
    pub name: String,
    pub kind: LampKind,
    /// Radiant intensity (W/sr) on the axis for point and spot lamps; irradiance on a
    /// surface facing the light (W/m²) for directional ones.
    pub scale: Vec3,
    pub range: Option<f32>,
    pub position: Vec3,
    /// Unit direction the light travels along (spot axis; directional light's direction).
    pub direction: Vec3,
    /// `cos(outer)`, and `1 / max(0.001, cos(inner) − cos(outer))`: the extension's reference
    /// falloff (spot lamps only).
    cos_outer: f32,
    falloff_scale: f32,
    power: f32,
}

/// What a lamp sends to a shading point: the direction to it, how far it is, and the
/// irradiance it would give a surface facing it (W/m², the delta light's `Li / pdf`).
#[derive(Clone, Copy, Debug)]
pub struct LampSample {
    /// Unit direction from the shading point towards the lamp.
    pub wi: Vec3,
    /// Distance to the lamp; infinite for a directional lamp.
    pub dist: f32,
    /// `I · falloff · window / d²` (point, spot) or `E⊥` (directional).
    pub irradiance: Vec3,
}

impl Lamp {
    /// The lamp of `desc`; `scene_radius` is the radius of a sphere bounding the scene, which
    /// sets a directional lamp's power (the light that falls on the scene's disc).
    pub fn new(desc: &LampDesc, scene_radius: f32) -> Self {
        let scale = desc.color * desc.intensity / LUMENS_PER_WATT;
        let (cos_outer, falloff_scale) = match desc.kind {
            LampKind::Spot {
                inner_cone,
                outer_cone,
            } => {
                let (ci, co) = (inner_cone.cos(), outer_cone.cos());
                (co, 1.0 / (ci - co).max(0.001))
            }
            _ => (-1.0, 1.0),
        };
        let y = luminance(scale);
        let power = match desc.kind {
            LampKind::Point => 4.0 * std::f32::consts::PI * y,
            // The intensity integrated over the cone, the falloff counted as half-way between
            // the inner and outer cones: any positive weight keeps the estimate unbiased.
            LampKind::Spot {
                inner_cone,
                outer_cone,
            } => {
                let cos_mid = 0.5 * (inner_cone.cos() + outer_cone.cos());
                2.0 * std::f32::consts::PI * (1.0 - cos_mid) * y
            }
            LampKind::Directional => std::f32::consts::PI * scene_radius * scene_radius * y,
        };
        Lamp {
            name: desc.name.clone(),
            kind: desc.kind,
            scale,
            range: desc.range,
            position: desc.position,
            direction: desc.direction.normalize_or_zero(),
            cos_outer,
            falloff_scale,
            power,
        }
    }

    /// Power used to pick lights (W, luminance-weighted): `4π·I` for a point lamp, the cone's
    /// share of it for a spot, `E⊥ · π r²` over the scene's bounding sphere for a directional
    /// lamp.
    pub fn power(&self) -> f32 {
        self.power
    }

    /// `cos(outer)`: the spot's cone (−1 for other lamps).
    pub fn cos_outer(&self) -> f32 {
        self.cos_outer
    }

    /// The extension's spot falloff for a direction `w` leaving the lamp (unit):
    /// `clamp((cos θ − cos outer) / (cos inner − cos outer), 0, 1)²`; 1 for other lamps.
    pub fn falloff(&self, w: Vec3) -> f32 {
        match self.kind {
            LampKind::Spot { .. } => {
                let t =
                    ((self.direction.dot(w) - self.cos_outer) * self.falloff_scale).clamp(0.0, 1.0);
                t * t
            }
            _ => 1.0,
        }
    }

    /// The extension's recommended range window, `clamp(1 − (d / range)⁴, 0, 1)`.
    pub fn window(&self, dist: f32) -> f32 {
        match self.range {
            Some(range) => (1.0 - (dist / range).powi(4)).clamp(0.0, 1.0),
            None => 1.0,
        }
    }

    /// The light this lamp sends to `x`, or `None` when it sends none (outside the cone or
    /// the range, or at the lamp itself).
    pub fn sample(&self, x: Vec3) -> Option<LampSample> {
        let sample = match self.kind {
            LampKind::Directional => LampSample {
                wi: -self.direction,
                dist: f32::INFINITY,
                irradiance: self.scale,
            },
            LampKind::Point | LampKind::Spot { .. } => {
                let v = self.position - x;
                let dist = v.length();
                if dist <= 0.0 || !dist.is_finite() {
                    return None;
                }
                let wi = v / dist;
                let factor = self.falloff(-wi) * self.window(dist) / (dist * dist);
                LampSample {
                    wi,
                    dist,
                    irradiance: self.scale * factor,
                }
            }
        };
        (sample.irradiance.max_element() > 0.0).then_some(sample)
    }
}
