//! Scenes: what is authored (glTF, built-ins), validated and made ready to trace.

pub mod bvh;
pub mod enclosure;
pub mod opening;
pub mod portals;

use glam::{Vec2, Vec3, Vec4};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::asset::desc::{AlphaMode, MeshDesc};
use crate::asset::desc::{LampKind, PortalDesc, SceneDesc};
use crate::asset::environment::{
    EnvironmentDesc, EnvironmentError, EnvironmentOverrides, check_numbers,
};
use crate::asset::{builtin, gltf};
use crate::camera::Camera;
use crate::light::LightSet;
use crate::light::area::AreaLight;
use crate::light::environment::Environment;
use crate::light::portal::{Portal, PortalError};
use crate::light::punctual::Lamp;
use crate::light::window::Window;
use crate::material::Material;
use crate::surface::{MissingImage, SurfacePoint, SurfaceTextures};
use bvh::{Bvh, CutoutTriangle, Hit};

/// Why a scene cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error(transparent)]
    Gltf(#[from] gltf::GltfError),
    #[error("{file}: {error}")]
    Portal { file: String, error: PortalError },
    #[error("{file}: mesh node '{node}' references material {material}, which does not exist")]
    BadMaterial {
        file: String,
        node: String,
        material: usize,
    },
    #[error("{file}: mesh node '{node}': vertex index {index} is out of range")]
    BadIndex {
        file: String,
        node: String,
        index: u32,
    },
    #[error(
        "{file}: mesh node '{node}': vertex {index} at {position} is not within ±{MAX_COORDINATE:e} \
         on every axis"
    )]
    FarVertex {
        file: String,
        node: String,
        index: u32,
        position: Vec3,
    },
    #[error("{file}: {error}")]
    Bvh { file: String, error: bvh::BvhError },
    #[error("{file}: {error}")]
    Texture { file: String, error: MissingImage },
    #[error("unknown built-in scene '{0}' (built-ins: {names})", names = builtin::NAMES.join(", "))]
    UnknownBuiltin(String),
    #[error("{file}: {error}")]
    Environment {
        file: String,
        error: EnvironmentError,
    },
}

/// One triangle with its shading normals, material and light.
#[derive(Clone, Copy, Debug)]
pub struct SceneTriangle {
    pub p: [Vec3; 3],
    pub n: [Vec3; 3],
    pub material: u32,
    /// Index of its area light, or `NO_LIGHT`.
    pub light: u32,
    /// Index of its texture coordinates and tangents in `Geometry::attributes`, or
    /// `NO_ATTRIBUTES` (an untextured material needs none).
    pub attributes: u32,
}

pub const NO_LIGHT: u32 = u32::MAX;
pub const NO_ATTRIBUTES: u32 = u32::MAX;

/// The per-corner attributes of a triangle whose material is textured.
#[derive(Clone, Copy, Debug, Default)]
pub struct TriangleAttributes {
    /// `TEXCOORD_0` and `TEXCOORD_1` at the three corners.
    pub uvs: [[Vec2; 3]; 2],
    /// Tangents (w: the bitangent's sign) at the corners: the file's, or MikkTSpace's.
    pub tangents: [Vec4; 3],
}

impl TriangleAttributes {
    /// The attributes interpolated at barycentrics (u on corner 1, v on corner 2).
    pub fn at(&self, bary: Vec2) -> SurfacePoint {
        let w = 1.0 - bary.x - bary.y;
        let [t0, t1, t2] = self.tangents;
        SurfacePoint {
            uvs: self.uvs.map(|c| w * c[0] + bary.x * c[1] + bary.y * c[2]),
            tangent: (w * t0 + bary.x * t1 + bary.y * t2)
                .truncate()
                .extend(if t0.w < 0.0 { -1.0 } else { 1.0 }),
        }
    }
}

/// A light whose emission varies over its surface (an emissive texture or a cut-out): its
/// triangles and their attributes, to find the emission at any point of it.
pub struct LightSurface {
    triangles: Vec<([Vec3; 3], TriangleAttributes)>,
    pub surface: SurfaceTextures,
}

impl LightSurface {
    /// The factor on the light's radiance at its point `p`: the emissive texture's colour,
    /// times the coverage (zero where cut out, alpha for BLEND). The point's triangle is the
    /// one it lies in (closest to it, for round-off).
    pub fn emission_scale(&self, p: Vec3) -> Vec3 {
        let mut best = (f32::INFINITY, None);
        for (corners, attributes) in &self.triangles {
            let [a, b, c] = *corners;
            let (e1, e2, d) = (b - a, c - a, p - a);
            let n = e1.cross(e2);
            let n2 = n.length_squared();
            if n2 <= 0.0 {
                continue;
            }
            // Barycentrics of p's projection onto the triangle's plane.
            let u = d.cross(e2).dot(n) / n2;
            let v = e1.cross(d).dot(n) / n2;
            let outside = (-u).max(0.0) + (-v).max(0.0) + (u + v - 1.0).max(0.0);
            let off_plane = d.dot(n).abs() / n2.sqrt() / (e1.length() + e2.length());
            let error = outside + off_plane;
            if error < best.0 {
                best = (error, Some((Vec2::new(u, v), attributes)));
            }
        }
        let Some((bary, attributes)) = best.1 else {
            return Vec3::ZERO;
        };
        let point = attributes.at(bary);
        self.scale_at(&point.uvs)
    }

    /// The factor on the radiance at texture coordinates `uvs`.
    pub fn scale_at(&self, uvs: &[Vec2; 2]) -> Vec3 {
        let coverage = match self.surface.alpha_mode {
            AlphaMode::Opaque => 1.0,
            AlphaMode::Mask { .. } => {
                if self.surface.is_present(uvs, || 0.0) {
                    1.0
                } else {
                    0.0
                }
            }
            // Coverage on average: a BSDF ray meets the light with probability alpha.
            AlphaMode::Blend => self.surface.alpha(uvs).clamp(0.0, 1.0),
        };
        self.surface.emission_scale(uvs) * coverage
    }
}

/// The seed of the rays that measure `auto` alphas: a scene gets the same alphas every time.
const AUTO_ALPHA_SEED: u64 = 0x0a17;

/// The largest coordinate a vertex may have (NaN is refused too). The BVH build takes
/// differences of box centres and multiplies surface areas by triangle counts in f32: with
/// coordinates up to 10^12 these stay below 10^34, far from overflow, and the build cannot
/// meet an infinite or NaN cost (which made it panic).
pub const MAX_COORDINATE: f32 = 1e12;

impl SceneTriangle {
    /// Position and interpolated shading normal at barycentrics (u on vertex 1, v on vertex 2).
    pub fn point(&self, bary: Vec2) -> (Vec3, Vec3) {
        let w = 1.0 - bary.x - bary.y;
        let p = w * self.p[0] + bary.x * self.p[1] + bary.y * self.p[2];
        let n = (w * self.n[0] + bary.x * self.n[1] + bary.y * self.n[2]).normalize_or_zero();
        (p, n)
    }

    /// Unit geometric normal, front side by winding.
    pub fn geometric_normal(&self) -> Vec3 {
        (self.p[1] - self.p[0])
            .cross(self.p[2] - self.p[0])
            .normalize_or_zero()
    }
}

/// Everything that does not change while portals are edited: triangles, materials, lights, BVH.
pub struct Geometry {
    pub triangles: Vec<SceneTriangle>,
    pub materials: Vec<Material>,
    pub lights: Vec<AreaLight>,
    /// `KHR_lights_punctual` lamps: sampled with the lights, never hit by rays.
    pub lamps: Vec<Lamp>,
    pub bvh: Bvh,
    pub bounds: (Vec3, Vec3),
    /// Per material: its textures, if it has any (or a cut-out).
    pub surfaces: Vec<Option<SurfaceTextures>>,
    /// Corner attributes of the triangles of textured materials (see `SceneTriangle`).
    pub attributes: Vec<TriangleAttributes>,
    /// Per light: its emission over its surface, when a texture or a cut-out varies it.
    pub light_surfaces: Vec<Option<LightSurface>>,
    /// The radius of a sphere bounding the triangles and the lamps' positions (the
    /// environment's and directional lamps' power is the light falling on it).
    pub radius: f32,
    /// Whether any triangle other than a light's is thin glass ([`Material::transmits`]):
    /// rays then cross it (the integrator's panes).
    pub has_panes: bool,
}

impl Geometry {
    /// The scene's size, for ray offsets and tolerances.
    pub fn scale(&self) -> f32 {
        (self.bounds.1 - self.bounds.0).length().max(1e-3)
    }

    /// Whether triangle `triangle` is thin glass that rays cross ([`Material::transmits`];
    /// a light's triangles never are).
    pub fn is_pane(&self, triangle: u32) -> bool {
        self.triangles.get(triangle as usize).is_some_and(|t| {
            t.light == NO_LIGHT
                && self
                    .materials
                    .get(t.material as usize)
                    .is_some_and(Material::transmits)
        })
    }

    /// The closest hit of `origin + t·dir`, `t` in `(tmin, tmax)`, that is not thin glass:
    /// what a ray sees through the panes that the renderer's rays cross, as the portal finder,
    /// its check, the overlays and the tools see it. After [`MAX_PANES_SEEN_THROUGH`] panes,
    /// the last one.
    pub fn closest_hit_through_panes(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
    ) -> Option<Hit> {
        let mut hit = self.bvh.closest_hit(origin, dir, tmin, tmax)?;
        for _ in 0..MAX_PANES_SEEN_THROUGH {
            if !self.has_panes || !self.is_pane(hit.triangle) {
                break;
            }
            let tmin = hit.t * (1.0 + 1e-5) + 1e-7 * self.scale();
            hit = self.bvh.closest_hit(origin, dir, tmin, tmax)?;
        }
        Some(hit)
    }
}

/// The most panes [`Geometry::closest_hit_through_panes`] looks through.
pub const MAX_PANES_SEEN_THROUGH: usize = 32;

/// A validated scene: shared geometry plus its portals and camera.
#[derive(Clone)]
pub struct Scene {
    pub name: String,
    /// What it was built from; portal edits change `desc.portals` and rebuild `portals`.
    pub desc: Arc<SceneDesc>,
    pub geometry: Arc<Geometry>,
    pub portals: Vec<Portal>,
    /// The environment (from `desc.environment`), if any.
    pub environment: Option<Arc<Environment>>,
    /// Window portals onto the environment (portals whose target is `"environment"`).
    pub windows: Vec<Window>,
    pub camera: Camera,
    /// The glTF file it was loaded from, if any (where Save writes).
    pub source: Option<PathBuf>,
    /// Per area light, the box where it lights its enclosure ([`enclosure::enclosure_box`]);
    /// empty until measured (after a portal edit, [`Self::build_tables`]).
    enclosures: Vec<Option<(Vec3, Vec3)>>,
}

impl Scene {
    /// Validates `desc`; `file` names the source in error messages.
    pub fn from_desc(desc: SceneDesc, file: &str) -> Result<Scene, SceneError> {
        let mut triangles = Vec::new();
        let mut lights = Vec::new();
        let materials: Vec<Material> = desc.materials.iter().map(Material::from_desc).collect();
        let surfaces = desc
            .materials
            .iter()
            .map(|m| SurfaceTextures::new(m, &desc.images))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|error| SceneError::Texture {
                file: file.to_owned(),
                error,
            })?;
        let mut attributes = Vec::new();
        let mut light_surfaces = Vec::new();
        for mesh in &desc.meshes {
            let Some(material) = materials.get(mesh.material) else {
                return Err(SceneError::BadMaterial {
                    file: file.to_owned(),
                    node: mesh.node_name.clone(),
                    material: mesh.material,
                });
            };
            let light = if material.is_emissive() {
                lights.len() as u32
            } else {
                NO_LIGHT
            };
            let surface = surfaces.get(mesh.material).and_then(Option::as_ref);
            let mesh_attributes = surface.map(|s| triangle_attributes(mesh, s));
            let mut light_triangles = Vec::new();
            let mut corners = Vec::with_capacity(mesh.indices.len());
            for (k, tri) in mesh.indices.iter().enumerate() {
                let fetch = |i: u32| {
                    let k = i as usize;
                    match (mesh.positions.get(k), mesh.normals.get(k)) {
                        (Some(&p), Some(&n))
                            if p.abs().cmple(Vec3::splat(MAX_COORDINATE)).all() =>
                        {
                            Ok((p, n))
                        }
                        (Some(&p), Some(_)) => Err(SceneError::FarVertex {
                            file: file.to_owned(),
                            node: mesh.node_name.clone(),
                            index: i,
                            position: p,
                        }),
                        _ => Err(SceneError::BadIndex {
                            file: file.to_owned(),
                            node: mesh.node_name.clone(),
                            index: i,
                        }),
                    }
                };
                let [(p0, n0), (p1, n1), (p2, n2)] =
                    [fetch(tri[0])?, fetch(tri[1])?, fetch(tri[2])?];
                corners.push([p0, p1, p2]);
                let triangle_attributes = match &mesh_attributes {
                    Some(all) => {
                        let a = all.get(k).copied().unwrap_or_default();
                        if light != NO_LIGHT {
                            light_triangles.push(([p0, p1, p2], a));
                        }
                        attributes.push(a);
                        attributes.len() as u32 - 1
                    }
                    None => NO_ATTRIBUTES,
                };
                triangles.push(SceneTriangle {
                    p: [p0, p1, p2],
                    n: [n0, n1, n2],
                    material: mesh.material as u32,
                    light,
                    attributes: triangle_attributes,
                });
            }
            if light != NO_LIGHT {
                lights.push(AreaLight::new(
                    mesh.node_name.clone(),
                    material.emission,
                    material.double_sided,
                    &corners,
                ));
                let varies = surface
                    .filter(|s| s.has_emission_texture() || s.alpha_mode != AlphaMode::Opaque);
                light_surfaces.push(varies.map(|s| LightSurface {
                    triangles: light_triangles,
                    surface: s.clone(),
                }));
            }
        }
        let bounds = triangles
            .iter()
            .flat_map(|t| t.p)
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p), hi.max(p))
            });
        let bounds = if triangles.is_empty() {
            (Vec3::splat(-1.0), Vec3::splat(1.0))
        } else {
            bounds
        };
        // A directional lamp's power is the light falling on the disc of the sphere that
        // bounds the scene's triangles and its other lamps.
        let (lo, hi) = desc
            .lamps
            .iter()
            .filter(|l| l.kind != LampKind::Directional)
            .fold(bounds, |(lo, hi), l| {
                (lo.min(l.position), hi.max(l.position))
            });
        let radius = 0.5 * (hi - lo).length();
        let lamps = desc.lamps.iter().map(|l| Lamp::new(l, radius)).collect();
        let corners: Vec<[Vec3; 3]> = triangles.iter().map(|t| t.p).collect();
        let mut bvh = Bvh::build(&corners).map_err(|error| SceneError::Bvh {
            file: file.to_owned(),
            error,
        })?;
        // Alpha-tested materials: the BVH tests their triangles' coverage.
        let cutout_surfaces: Vec<SurfaceTextures> = surfaces
            .iter()
            .flatten()
            .filter(|s| s.alpha_mode != AlphaMode::Opaque)
            .cloned()
            .collect();
        if !cutout_surfaces.is_empty() {
            let mut slot = vec![u32::MAX; surfaces.len()];
            let mut next = 0;
            for (m, s) in surfaces.iter().enumerate() {
                if s.as_ref()
                    .is_some_and(|s| s.alpha_mode != AlphaMode::Opaque)
                {
                    slot[m] = next;
                    next += 1;
                }
            }
            bvh.set_cutouts(
                |i| {
                    let t = triangles.get(i as usize)?;
                    let surface = *slot.get(t.material as usize)?;
                    let a = attributes.get(t.attributes as usize)?;
                    (surface != u32::MAX).then_some(CutoutTriangle {
                        uvs: a.uvs,
                        surface,
                    })
                },
                cutout_surfaces,
            );
        }
        let has_panes = triangles
            .iter()
            .any(|t| t.light == NO_LIGHT && materials[t.material as usize].transmits());
        let geometry = Arc::new(Geometry {
            has_panes,
            bvh,
            triangles,
            materials,
            lights,
            lamps,
            bounds,
            surfaces,
            attributes,
            light_surfaces,
            radius,
        });
        let camera = match desc.camera {
            Some(c) => c,
            None => Camera::framing(bounds.0, bounds.1, 4.0 / 3.0),
        };
        let environment = build_environment(desc.environment.as_ref(), &geometry, file)?;
        let (portals, windows) =
            validate_portals(&desc.portals, &geometry, environment.as_deref(), file)?;
        let mut scene = Scene {
            name: desc.name.clone(),
            desc: Arc::new(desc),
            geometry,
            portals,
            environment,
            windows,
            camera,
            source: None,
            enclosures: Vec::new(),
        };
        scene.measure_portals();
        Ok(scene)
    }

    /// Loads a `.gltf`/`.glb` file.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let desc = gltf::load_gltf(path)?;
        let mut scene = Scene::from_desc(desc, &path.display().to_string())?;
        scene.source = Some(path.to_owned());
        Ok(scene)
    }

    /// A built-in scene by name, or a glTF file by path.
    pub fn open(name_or_path: &str) -> Result<Scene, SceneError> {
        match builtin::desc(name_or_path) {
            Some(desc) => Scene::from_desc(desc, name_or_path),
            None if Path::new(name_or_path).exists() || name_or_path.contains('.') => {
                Scene::load(Path::new(name_or_path))
            }
            None => Err(SceneError::UnknownBuiltin(name_or_path.to_owned())),
        }
    }

    /// [`Scene::open`], then the command line's replacements for its environment (CLI over
    /// the scene's extras); the same for every subcommand and the viewer.
    pub fn open_with_environment(
        name_or_path: &str,
        overrides: &EnvironmentOverrides,
    ) -> Result<Scene, SceneError> {
        let scene = Scene::open(name_or_path)?;
        if overrides.is_empty() {
            return Ok(scene);
        }
        let mut warnings = Vec::new();
        let environment = overrides
            .apply(scene.desc.environment.as_ref(), &mut warnings)
            .map_err(|error| SceneError::Environment {
                file: scene.file_label(),
                error,
            })?;
        let mut scene = scene.with_environment(environment)?;
        // The new scene's description is its own: extended in place, not copied again.
        Arc::make_mut(&mut scene.desc).warnings.extend(warnings);
        Ok(scene)
    }

    /// The same geometry with other portals (an edit); the BVH is shared, not rebuilt.
    pub fn with_portals(&self, portals: Vec<PortalDesc>) -> Result<Scene, SceneError> {
        let file = self.file_label();
        let (validated, windows) =
            validate_portals(&portals, &self.geometry, self.environment.as_deref(), &file)?;
        let desc = SceneDesc {
            portals,
            ..(*self.desc).clone()
        };
        let mut scene = Scene {
            desc: Arc::new(desc),
            portals: validated,
            windows,
            enclosures: Vec::new(),
            ..self.clone()
        };
        scene.measure_portals();
        Ok(scene)
    }

    /// The same geometry with the valid ones among `portals`; the others are left out and
    /// returned with their errors (an edit in progress must never stop the viewer).
    pub fn with_portals_lenient(
        &self,
        portals: Vec<PortalDesc>,
    ) -> (Scene, Vec<(usize, PortalError)>) {
        self.with_portals_reusing(portals, None)
    }

    /// [`Self::with_portals_lenient`], reusing the guided tables of `previous`'s windows (an
    /// earlier edit of this scene) where a window keeps its axes and the environment is the
    /// same: moving or resizing a window in the viewer then rebuilds no table.
    pub fn with_portals_reusing(
        &self,
        portals: Vec<PortalDesc>,
        previous: Option<&Scene>,
    ) -> (Scene, Vec<(usize, PortalError)>) {
        let (mut scene, errors) = self.with_portals_deferred(portals, previous);
        scene.build_tables();
        (scene, errors)
    }

    /// [`Self::with_portals_reusing`] without building the tables it cannot reuse (a turned
    /// or new window): cheap, so the viewer's UI thread makes it at once and renders it while
    /// [`Self::build_tables`] runs on another thread (a window without its table is sampled
    /// uniformly in its solid angle, which is exact).
    pub fn with_portals_deferred(
        &self,
        portals: Vec<PortalDesc>,
        previous: Option<&Scene>,
    ) -> (Scene, Vec<(usize, PortalError)>) {
        let same_environment = |p: &&Scene| match (&p.environment, &self.environment) {
            (Some(a), Some(b)) => Arc::ptr_eq(a, b),
            _ => false,
        };
        let built = previous
            .filter(same_environment)
            .map_or(&[][..], |p| &p.windows);
        let mut valid = Vec::new();
        let mut windows = Vec::new();
        let mut errors = Vec::new();
        for (i, d) in portals.iter().enumerate() {
            if d.is_window() {
                match Window::new_deferred(d, i, self.environment.as_deref(), built) {
                    Ok(w) => windows.push(w),
                    Err(e) => errors.push((i, e.into())),
                }
                continue;
            }
            match portal(d, i, &self.geometry) {
                Ok(p) => valid.push(p),
                Err(e) => errors.push((i, e)),
            }
        }
        let desc = SceneDesc {
            portals,
            ..(*self.desc).clone()
        };
        let scene = Scene {
            desc: Arc::new(desc),
            portals: valid,
            windows,
            enclosures: Vec::new(),
            ..self.clone()
        };
        (scene, errors)
    }

    /// Whether a window lacks the guided table the environment calls for (see
    /// [`Self::with_portals_deferred`]), or an `auto` alpha or the enclosures' boxes are not
    /// measured yet.
    pub fn lacks_tables(&self) -> bool {
        let environment = self.environment.as_deref();
        self.windows.iter().any(|w| w.lacks_table(environment))
            || self.alpha_pending()
            || self.enclosures.len() != self.geometry.lights.len()
    }

    /// Builds the guided tables the windows lack, measures the `auto` alphas and the
    /// enclosures.
    pub fn build_tables(&mut self) {
        let environment = self.environment.as_deref();
        for window in &mut self.windows {
            window.build_table(environment);
        }
        self.measure_portals();
    }

    /// Measures what the portals' rays show: the `auto` alphas, and each light's enclosure.
    fn measure_portals(&mut self) {
        self.resolve_auto_alpha(AUTO_ALPHA_SEED);
        if self.enclosures.len() != self.geometry.lights.len() {
            let scene = &*self;
            self.enclosures = (0..scene.geometry.lights.len())
                .into_par_iter()
                .map(|i| enclosure::enclosure_box(scene, i))
                .collect();
        }
    }

    /// The same scene under another environment (`None`: black). Windows are rebuilt for it
    /// (their guided tables follow the image); windows that were left out stay out.
    pub fn with_environment(
        &self,
        environment: Option<EnvironmentDesc>,
    ) -> Result<Scene, SceneError> {
        let mut scene = self.with_environment_deferred(environment)?;
        scene.build_tables();
        Ok(scene)
    }

    /// [`Self::with_environment`] without the windows' guided tables
    /// ([`Self::build_tables`] builds them).
    pub fn with_environment_deferred(
        &self,
        environment: Option<EnvironmentDesc>,
    ) -> Result<Scene, SceneError> {
        let file = self.file_label();
        let built = build_environment(environment.as_ref(), &self.geometry, &file)?;
        let windows = self
            .desc
            .portals
            .iter()
            .enumerate()
            .filter(|(_, d)| d.is_window())
            .filter_map(|(i, d)| Window::new_deferred(d, i, built.as_deref(), &[]).ok())
            .collect();
        let desc = SceneDesc {
            environment,
            ..(*self.desc).clone()
        };
        Ok(Scene {
            desc: Arc::new(desc),
            environment: built,
            windows,
            ..self.clone()
        })
    }

    /// The names of the portals, then the windows: what the overlay's per-portal regions
    /// are indexed by.
    pub fn overlay_portal_names(&self) -> Vec<String> {
        self.portals
            .iter()
            .map(|p| p.name.clone())
            .chain(self.windows.iter().map(|w| format!("{} (window)", w.name)))
            .collect()
    }

    /// How the scene is named in messages: its file, else its name.
    pub fn file_label(&self) -> String {
        match &self.source {
            Some(p) => p.display().to_string(),
            None => self.name.clone(),
        }
    }
}

/// The corner attributes of every triangle of `mesh`, whose material is textured: texture
/// coordinates (zero where absent) and tangents, from the mesh or, for a normal map on a mesh
/// without them, generated by MikkTSpace on the normal map's texture coordinates.
fn triangle_attributes(mesh: &MeshDesc, surface: &SurfaceTextures) -> Vec<TriangleAttributes> {
    let uv = |set: usize, i: u32| {
        mesh.texcoords[set]
            .get(i as usize)
            .copied()
            .unwrap_or(Vec2::ZERO)
    };
    let mut out: Vec<TriangleAttributes> = mesh
        .indices
        .iter()
        .map(|t| TriangleAttributes {
            uvs: [0, 1].map(|set| t.map(|i| uv(set, i))),
            tangents: t.map(|i| mesh.tangents.get(i as usize).copied().unwrap_or(Vec4::ZERO)),
        })
        .collect();
    if let Some(normal_map) = surface.normal_map()
        && mesh.tangents.len() != mesh.positions.len()
    {
        let mut generator = Mikk {
            mesh,
            set: (normal_map.tex_coord as usize).min(1),
            out: &mut out,
        };
        // On failure (no usable faces) the tangents stay zero and the normal map is unused.
        let _ = bevy_mikktspace::generate_tangents(&mut generator);
    }
    out
}

/// A mesh as MikkTSpace reads it, writing tangents into per-triangle attributes.
struct Mikk<'a> {
    mesh: &'a MeshDesc,
    set: usize,
    out: &'a mut [TriangleAttributes],
}

impl Mikk<'_> {
    fn vertex(&self, face: usize, vert: usize) -> usize {
        self.mesh
            .indices
            .get(face)
            .and_then(|t| t.get(vert))
            .map_or(0, |&i| i as usize)
    }
}

impl bevy_mikktspace::Geometry for Mikk<'_> {
    fn num_faces(&self) -> usize {
        self.mesh.indices.len()
    }

    fn num_vertices_of_face(&self, _face: usize) -> usize {
        3
    }

    fn position(&self, face: usize, vert: usize) -> [f32; 3] {
        let i = self.vertex(face, vert);
        self.mesh
            .positions
            .get(i)
            .copied()
            .unwrap_or(Vec3::ZERO)
            .to_array()
    }

    fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
        let i = self.vertex(face, vert);
        self.mesh
            .normals
            .get(i)
            .copied()
            .unwrap_or(Vec3::ZERO)
            .to_array()
    }

    /// Blender's texture coordinates, `(u, 1 − v)`: glTF's `v` runs down the image, Blender's
    /// up, and a normal map's green (+Y) is up the image in both. MikkTSpace's bitangent
    /// follows increasing `v`; on Blender's `v` it points up the image, as Blender's (and
    /// Cycles') does for the same file.
    fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
        let i = self.vertex(face, vert);
        let uv = self.mesh.texcoords[self.set]
            .get(i)
            .copied()
            .unwrap_or(Vec2::ZERO);
        [uv.x, 1.0 - uv.y]
    }

    fn set_tangent(
        &mut self,
        tangent_space: Option<bevy_mikktspace::TangentSpace>,
        face: usize,
        vert: usize,
    ) {
        if let (Some(ts), Some(slot)) = (
            tangent_space,
            self.out
                .get_mut(face)
                .and_then(|a| a.tangents.get_mut(vert)),
        ) {
            *slot = Vec4::from_array(ts.tangent_encoded());
        }
    }
}

impl LightSet for Scene {
    fn lights(&self) -> &[AreaLight] {
        &self.geometry.lights
    }

    fn portals(&self) -> &[Portal] {
        &self.portals
    }

    fn lamps(&self) -> &[Lamp] {
        &self.geometry.lamps
    }

    fn environment(&self) -> Option<&Environment> {
        self.environment.as_deref()
    }

    fn windows(&self) -> &[Window] {
        &self.windows
    }

    fn enclosure(&self, light: usize) -> Option<(Vec3, Vec3)> {
        self.enclosures.get(light).copied().flatten()
    }
}

/// The environment of `desc`, checked.
fn build_environment(
    desc: Option<&EnvironmentDesc>,
    geometry: &Geometry,
    file: &str,
) -> Result<Option<Arc<Environment>>, SceneError> {
    let Some(desc) = desc else {
        return Ok(None);
    };
    check_numbers(desc.strength, desc.rotation_degrees).map_err(|error| {
        SceneError::Environment {
            file: file.to_owned(),
            error,
        }
    })?;
    Ok(Some(Arc::new(Environment::new(desc, geometry.radius))))
}

/// The portal of `desc`, the `i`-th of its scene; a portal naming a lamp is refused (a lamp
/// is a point or a direction: there is no area for a portal to open onto).
fn portal(desc: &PortalDesc, i: usize, geometry: &Geometry) -> Result<Portal, PortalError> {
    if geometry.lamps.iter().any(|l| l.name == desc.target) {
        return Err(PortalError::TargetIsLamp {
            portal: desc.name.clone(),
            target: desc.target.clone(),
        });
    }
    Portal::new(desc, i, &geometry.lights)
}

/// The area-light portals and the window portals of `descs`; the first error stops.
fn validate_portals(
    descs: &[PortalDesc],
    geometry: &Geometry,
    environment: Option<&Environment>,
    file: &str,
) -> Result<(Vec<Portal>, Vec<Window>), SceneError> {
    let mut portals = Vec::new();
    let mut windows = Vec::new();
    let error = |error: PortalError| SceneError::Portal {
        file: file.to_owned(),
        error,
    };
    for (i, d) in descs.iter().enumerate() {
        if d.is_window() {
            windows.push(Window::new(d, i, environment).map_err(|e| error(e.into()))?);
        } else {
            portals.push(portal(d, i, geometry).map_err(error)?);
        }
    }
    Ok((portals, windows))
}
