//! Scenes: what is authored (glTF, built-ins), validated and made ready to trace.

pub mod bvh;

use glam::{Vec2, Vec3};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::asset::desc::{LampKind, PortalDesc, SceneDesc};
use crate::asset::environment::{EnvironmentDesc, EnvironmentError, check_numbers};
use crate::asset::{builtin, gltf};
use crate::camera::Camera;
use crate::light::LightSet;
use crate::light::area::AreaLight;
use crate::light::environment::Environment;
use crate::light::portal::{Portal, PortalError};
use crate::light::punctual::Lamp;
use crate::light::window::Window;
use crate::material::Material;
use bvh::Bvh;

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
}

pub const NO_LIGHT: u32 = u32::MAX;

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
    /// The radius of a sphere bounding the triangles and the lamps' positions (the
    /// environment's and directional lamps' power is the light falling on it).
    pub radius: f32,
}

impl Geometry {
    /// The scene's size, for ray offsets and tolerances.
    pub fn scale(&self) -> f32 {
        (self.bounds.1 - self.bounds.0).length().max(1e-3)
    }
}

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
}

impl Scene {
    /// Validates `desc`; `file` names the source in error messages.
    pub fn from_desc(desc: SceneDesc, file: &str) -> Result<Scene, SceneError> {
        let mut triangles = Vec::new();
        let mut lights = Vec::new();
        let materials: Vec<Material> = desc.materials.iter().map(Material::from_desc).collect();
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
            let mut corners = Vec::with_capacity(mesh.indices.len());
            for tri in &mesh.indices {
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
                triangles.push(SceneTriangle {
                    p: [p0, p1, p2],
                    n: [n0, n1, n2],
                    material: mesh.material as u32,
                    light,
                });
            }
            if light != NO_LIGHT {
                lights.push(AreaLight::new(
                    mesh.node_name.clone(),
                    material.emission,
                    material.double_sided,
                    &corners,
                ));
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
        let geometry = Arc::new(Geometry {
            bvh: Bvh::build(&corners).map_err(|error| SceneError::Bvh {
                file: file.to_owned(),
                error,
            })?,
            triangles,
            materials,
            lights,
            lamps,
            bounds,
            radius,
        });
        let camera = match desc.camera {
            Some(c) => c,
            None => Camera::framing(bounds.0, bounds.1, 4.0 / 3.0),
        };
        let environment = build_environment(desc.environment.as_ref(), &geometry, file)?;
        let (portals, windows) =
            validate_portals(&desc.portals, &geometry, environment.as_deref(), file)?;
        Ok(Scene {
            name: desc.name.clone(),
            desc: Arc::new(desc),
            geometry,
            portals,
            environment,
            windows,
            camera,
            source: None,
        })
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

    /// The same geometry with other portals (an edit); the BVH is shared, not rebuilt.
    pub fn with_portals(&self, portals: Vec<PortalDesc>) -> Result<Scene, SceneError> {
        let file = self.file_label();
        let (validated, windows) =
            validate_portals(&portals, &self.geometry, self.environment.as_deref(), &file)?;
        let desc = SceneDesc {
            portals,
            ..(*self.desc).clone()
        };
        Ok(Scene {
            desc: Arc::new(desc),
            portals: validated,
            windows,
            ..self.clone()
        })
    }

    /// The same geometry with the valid ones among `portals`; the others are left out and
    /// returned with their errors (an edit in progress must never stop the viewer).
    pub fn with_portals_lenient(
        &self,
        portals: Vec<PortalDesc>,
    ) -> (Scene, Vec<(usize, PortalError)>) {
        let mut valid = Vec::new();
        let mut windows = Vec::new();
        let mut errors = Vec::new();
        for (i, d) in portals.iter().enumerate() {
            if d.is_window() {
                match Window::new(d, i, self.environment.as_deref()) {
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
            ..self.clone()
        };
        (scene, errors)
    }

    /// The same scene under another environment (`None`: black). Windows are rebuilt for it
    /// (their guided tables follow the image); windows that were left out stay out.
    pub fn with_environment(
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
            .filter_map(|(i, d)| Window::new(d, i, built.as_deref()).ok())
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
