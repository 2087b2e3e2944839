//! The scene as authored: what glTF files and the built-in scenes both produce, before any
//! validation or acceleration. World-space geometry, names kept for error messages.

use glam::{Mat4, Vec2, Vec3, Vec4};
use std::sync::Arc;

use crate::asset::environment::EnvironmentDesc;
use crate::asset::texture::{Image, TextureRef};
use crate::camera::Camera;

/// glTF `alphaMode`: what the base colour's alpha (factor times texture) does.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum AlphaMode {
    /// Alpha is ignored.
    #[default]
    Opaque,
    /// The surface is absent where alpha is below `cutoff` (`alphaCutoff`, 0.5 by default):
    /// rays pass through it.
    Mask { cutoff: f32 },
    /// glTF's blending, rendered as stochastic coverage: each ray passes through a point
    /// with probability `1 − alpha` (so a pixel averages to alpha blending, without tint).
    Blend,
}

/// A `normalTexture`: tangent-space normals, their x and y scaled by `scale`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NormalTexture {
    pub texture: TextureRef,
    pub scale: f32,
}

/// A material's textures (each multiplies its factor, as glTF says).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MaterialTextures {
    /// `baseColorTexture`: sRGB colour, linear alpha.
    pub base_color: Option<TextureRef>,
    /// `metallicRoughnessTexture`: roughness in G, metalness in B.
    pub metallic_roughness: Option<TextureRef>,
    pub normal: Option<NormalTexture>,
    /// `emissiveTexture`: sRGB colour.
    pub emissive: Option<TextureRef>,
    /// `KHR_materials_specular` `specularTexture`: the factor in A.
    pub specular: Option<TextureRef>,
    /// `KHR_materials_specular` `specularColorTexture`: sRGB colour.
    pub specular_color: Option<TextureRef>,
    /// `KHR_materials_transmission` `transmissionTexture`: the factor in R.
    pub transmission: Option<TextureRef>,
    /// `KHR_materials_clearcoat` `clearcoatTexture` (the factor in R) and
    /// `clearcoatRoughnessTexture` (the roughness in G).
    pub clearcoat: Option<TextureRef>,
    pub clearcoat_roughness: Option<TextureRef>,
}

impl MaterialTextures {
    pub fn any(&self) -> bool {
        self.refs().next().is_some()
    }

    /// Every texture reference, the normal map's included.
    pub fn refs(&self) -> impl Iterator<Item = &TextureRef> {
        [
            self.base_color.as_ref(),
            self.metallic_roughness.as_ref(),
            self.normal.as_ref().map(|n| &n.texture),
            self.emissive.as_ref(),
            self.specular.as_ref(),
            self.specular_color.as_ref(),
            self.transmission.as_ref(),
            self.clearcoat.as_ref(),
            self.clearcoat_roughness.as_ref(),
        ]
        .into_iter()
        .flatten()
    }
}

/// A glTF metallic-roughness material, reduced to what the renderer uses.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialDesc {
    pub name: String,
    pub base_color: Vec3,
    pub metallic: f32,
    pub roughness: f32,
    /// glTF `emissiveFactor`.
    pub emissive_factor: Vec3,
    /// `KHR_materials_emissive_strength` (1 when absent).
    pub emissive_strength: f32,
    /// `KHR_materials_specular` `specularFactor` in [0, 1] (1 when absent): the strength of the
    /// dielectric specular layer, its reflectance at grazing angles.
    pub specular_factor: f32,
    /// `KHR_materials_specular` `specularColorFactor`, each ≥ 0 ([1, 1, 1] when absent): scales
    /// the dielectric layer's reflectance at normal incidence (F0), not at grazing angles.
    pub specular_color: Vec3,
    /// `KHR_materials_ior` `ior` (1.5 when absent): 0 (infinite, F0 = 1) or ≥ 1.
    pub ior: f32,
    /// `KHR_materials_transmission` `transmissionFactor` in [0, 1] (0 when absent): the share
    /// of the dielectric base that transmits instead of scattering diffusely. Without
    /// `KHR_materials_volume` the surface is thin-walled: light goes straight through it.
    pub transmission: f32,
    /// `KHR_materials_volume` with `thicknessFactor` > 0: the mesh is closed and filled with
    /// the transmitting dielectric, which refracts (`None`: thin-walled).
    pub volume: Option<VolumeDesc>,
    /// `KHR_materials_clearcoat` `clearcoatFactor` in [0, 1] (0 when absent: no coat) and
    /// `clearcoatRoughnessFactor` in [0, 1]: Blender's Principled *Clearcoat* and *Clearcoat
    /// Roughness*, as its exporter writes them.
    pub clearcoat: f32,
    pub clearcoat_roughness: f32,
    pub double_sided: bool,
    /// `baseColorFactor`'s alpha.
    pub alpha: f32,
    pub alpha_mode: AlphaMode,
    pub textures: MaterialTextures,
}

/// `KHR_materials_volume`: what fills a closed mesh of a transmitting material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumeDesc {
    /// `thicknessFactor` (> 0): only whether the volume is there matters to a path tracer,
    /// which meets the mesh's real thickness.
    pub thickness: f32,
    /// `attenuationColor`: the colour white light becomes after `attenuation_distance`.
    pub attenuation_color: Vec3,
    /// `attenuationDistance` in metres (infinite: no absorption).
    pub attenuation_distance: f32,
}

impl VolumeDesc {
    /// Beer–Lambert's absorption coefficient per metre, `−ln(attenuationColor) /
    /// attenuationDistance` per channel, as the extension defines it.
    pub fn sigma(&self) -> Vec3 {
        if !self.attenuation_distance.is_finite() {
            return Vec3::ZERO;
        }
        let c = self.attenuation_color.clamp(Vec3::splat(1e-6), Vec3::ONE);
        Vec3::new(-c.x.ln(), -c.y.ln(), -c.z.ln()) / self.attenuation_distance
    }
}

/// The glTF defaults of the specular layer: what a file without the extensions means.
pub const DEFAULT_SPECULAR_FACTOR: f32 = 1.0;
pub const DEFAULT_SPECULAR_COLOR: Vec3 = Vec3::ONE;
pub const DEFAULT_IOR: f32 = 1.5;
/// The perceptual roughness up to which transmission goes straight through (a smooth pane):
/// the roughness whose GGX alpha (its square) is the BSDF's smallest, 1e-3.
pub const SMOOTH_TRANSMISSION_ROUGHNESS: f32 = 0.032;

impl MaterialDesc {
    pub fn diffuse(name: &str, base_color: Vec3) -> Self {
        MaterialDesc {
            name: name.to_owned(),
            base_color,
            metallic: 0.0,
            roughness: 1.0,
            emissive_factor: Vec3::ZERO,
            emissive_strength: 1.0,
            specular_factor: DEFAULT_SPECULAR_FACTOR,
            specular_color: DEFAULT_SPECULAR_COLOR,
            ior: DEFAULT_IOR,
            transmission: 0.0,
            volume: None,
            clearcoat: 0.0,
            clearcoat_roughness: 0.0,
            double_sided: true,
            alpha: 1.0,
            alpha_mode: AlphaMode::Opaque,
            textures: MaterialTextures::default(),
        }
    }

    /// An emitter of radiance `radiance` W/(sr·m²), stored glTF-style as a factor in [0, 1]
    /// times a strength.
    pub fn emitter(name: &str, radiance: Vec3, double_sided: bool) -> Self {
        let strength = radiance.max_element().max(1.0);
        MaterialDesc {
            emissive_factor: radiance / strength,
            emissive_strength: strength,
            double_sided,
            ..MaterialDesc::diffuse(name, Vec3::ZERO)
        }
    }

    /// Emitted radiance in W/(sr·m²): `emissiveFactor × emissive_strength`.
    pub fn radiance(&self) -> Vec3 {
        self.emissive_factor * self.emissive_strength
    }

    pub fn is_emissive(&self) -> bool {
        self.radiance().max_element() > 0.0
    }

    /// Whether the specular layer differs from glTF's default (so a file must say it).
    pub fn has_specular_extension(&self) -> bool {
        self.specular_factor != DEFAULT_SPECULAR_FACTOR
            || self.specular_color != DEFAULT_SPECULAR_COLOR
    }

    /// Whether the IOR differs from glTF's default.
    pub fn has_ior_extension(&self) -> bool {
        self.ior != DEFAULT_IOR
    }

    /// Whether the material has a clear coat (so a file must say it with
    /// `KHR_materials_clearcoat`).
    pub fn has_clearcoat_extension(&self) -> bool {
        self.clearcoat > 0.0
    }

    /// Whether the material transmits (so a file must say it with `KHR_materials_transmission`).
    pub fn has_transmission_extension(&self) -> bool {
        self.transmission > 0.0 || self.textures.transmission.is_some()
    }

    /// Clear glass as glTF describes it: a white, smooth, fully transmitting dielectric of
    /// glTF's default IOR, thin-walled (a window pane's surfaces, a globe's shell).
    pub fn clear_glass(name: &str) -> Self {
        MaterialDesc {
            roughness: 0.0,
            transmission: 1.0,
            ..MaterialDesc::diffuse(name, Vec3::ONE)
        }
    }
}

/// One glTF primitive of one node, flattened into world space.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct MeshDesc {
    /// The name of the node it came from (portals name their light by it).
    pub node_name: String,
    pub material: usize,
    pub positions: Vec<Vec3>,
    /// Per-vertex shading normals, same length as `positions` (flat, with corners unshared,
    /// where the file has none).
    pub normals: Vec<Vec3>,
    pub indices: Vec<[u32; 3]>,
    /// `TEXCOORD_0` and `TEXCOORD_1`, each empty or one per position.
    pub texcoords: [Vec<Vec2>; 2],
    /// World-space `TANGENT`s (xyz, w = ±1 the bitangent's sign, `B = w·(N × T)`), empty or
    /// one per position; generated the MikkTSpace way when a normal map needs them.
    pub tangents: Vec<Vec4>,
}

/// A portal as authored: a node whose `extras` name its light, or `"environment"`
/// ([`crate::asset::environment::ENVIRONMENT_TARGET`]) for a window onto the sky.
#[derive(Clone, Debug, PartialEq)]
pub struct PortalDesc {
    pub name: String,
    /// Node name of the emissive mesh it opens onto (`extras.portal_target`).
    pub target: String,
    /// `extras.portal_light_probability`: the probability of sampling the light itself (for
    /// `auto_alpha`, the value used until the check has measured it).
    pub alpha: f32,
    /// `portal_light_probability: "auto"`: alpha follows from the measured leak of the portals
    /// (`scene::portals::SourceCheck::auto_alpha`), once per scene, before rendering.
    pub auto_alpha: bool,
    /// The portal mesh's triangles in the node's local space.
    pub local_triangles: Vec<[Vec3; 3]>,
    /// The node's world transform (its parents' times its own).
    pub world_from_local: Mat4,
    /// Where it came from in the file, so that saving rewrites only this node.
    pub node_index: Option<usize>,
}

/// A portal's alpha when the file does not give one: the thesis's value.
pub const DEFAULT_PORTAL_ALPHA: f32 = 0.1;

impl PortalDesc {
    /// Whether it is a window portal onto the environment.
    pub fn is_window(&self) -> bool {
        self.target == crate::asset::environment::ENVIRONMENT_TARGET
    }

    /// The same portal with its front turned over (its triangles' winding reversed).
    pub fn flipped(&self) -> Self {
        PortalDesc {
            local_triangles: self
                .local_triangles
                .iter()
                .map(|&[a, b, c]| [a, c, b])
                .collect(),
            ..self.clone()
        }
    }

    /// A new portal (not from a file) over the convex polygon `corners`, in world space, with
    /// the default alpha; its mesh is the polygon's fan.
    pub fn from_polygon(name: String, target: String, corners: &[Vec3]) -> Self {
        let local_triangles = corners
            .split_first()
            .map(|(&first, rest)| rest.windows(2).map(|w| [first, w[0], w[1]]).collect())
            .unwrap_or_default();
        PortalDesc {
            name,
            target,
            alpha: DEFAULT_PORTAL_ALPHA,
            auto_alpha: false,
            local_triangles,
            world_from_local: Mat4::IDENTITY,
            node_index: None,
        }
    }

    pub fn world_triangles(&self) -> Vec<[Vec3; 3]> {
        self.local_triangles
            .iter()
            .map(|t| t.map(|p| self.world_from_local.transform_point3(p)))
            .collect()
    }
}

/// The kind of a `KHR_lights_punctual` lamp.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LampKind {
    /// Emits equally in every direction from its position.
    Point,
    /// A point lamp limited to a cone around its direction: full intensity within
    /// `inner_cone` radians of the axis, none beyond `outer_cone`, the extension's smooth
    /// falloff between (`0 <= inner_cone <= outer_cone <= π/2`).
    Spot { inner_cone: f32, outer_cone: f32 },
    /// Parallel light arriving from infinitely far along `direction`.
    Directional,
}

/// A `KHR_lights_punctual` lamp as authored, in the extension's photometric units (what the
/// file holds; the renderer converts at 683 lm/W, see `light::punctual`).
#[derive(Clone, Debug, PartialEq)]
pub struct LampDesc {
    /// The name of its node (errors and portal targets name it).
    pub name: String,
    pub kind: LampKind,
    /// Linear RGB `color` (white when absent).
    pub color: Vec3,
    /// `intensity`: candela for point and spot lamps, lux for directional ones.
    pub intensity: f32,
    /// `range`: beyond it a point or spot lamp gives no light (`None`: unlimited).
    pub range: Option<f32>,
    /// World position of its node (unused by directional lamps).
    pub position: Vec3,
    /// Unit world direction the lamp points to: its node's local −Z.
    pub direction: Vec3,
}

/// A whole scene as authored.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct SceneDesc {
    pub name: String,
    pub materials: Vec<MaterialDesc>,
    pub meshes: Vec<MeshDesc>,
    pub portals: Vec<PortalDesc>,
    /// `KHR_lights_punctual` lamps.
    pub lamps: Vec<LampDesc>,
    /// The file's first camera, if any (else one is made to frame the scene).
    pub camera: Option<Camera>,
    /// Decoded images that materials' textures name by index (shared, not copied, when a
    /// description is cloned for a portal edit).
    pub images: Vec<Arc<Image>>,
    /// The sky: what rays leaving the scene see, sampled as a light (none: black).
    pub environment: Option<EnvironmentDesc>,
    /// What the file holds that is not read (an extension, a texture), each naming the file
    /// and what is left out: shown to the user, never dropped in silence.
    pub warnings: Vec<String>,
}
