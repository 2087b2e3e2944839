//! Portals: invisible convex polygons marking the opening through which a light is seen.

use glam::Vec3;

use super::antishadow::{
    AntishadowError, AntishadowPlanes, Region, classify_brute_force, classify_brute_force_hull,
};
use super::area::AreaLight;
use crate::asset::desc::PortalDesc;
use crate::sampling::polygon::{ConvexPolygon, Cut, Plane, PolygonError};

/// Why a portal node cannot be used; every message names the node.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PortalError {
    #[error("portal node '{portal}': portal_target '{target}' names no emissive mesh node")]
    TargetMissing { portal: String, target: String },
    #[error(
        "portal node '{portal}': portal_target '{target}' is a KHR_lights_punctual lamp; a \
         portal may only target an emissive mesh (a lamp is sampled exactly already, in one \
         direction)"
    )]
    TargetIsLamp { portal: String, target: String },
    #[error("portal node '{portal}': its mesh {error}")]
    BadPolygon { portal: String, error: PolygonError },
    #[error("portal node '{portal}': portal_light_probability {alpha} is not in [0, 1]")]
    BadAlpha { portal: String, alpha: f32 },
    #[error("portal node '{portal}': it lies in the plane of its light '{target}'")]
    Coplanar { portal: String, target: String },
    #[error("portal node '{portal}' and light '{target}': {error}")]
    Geometry {
        portal: String,
        target: String,
        error: AntishadowError,
    },
    /// A window portal onto the environment that cannot be used.
    #[error(transparent)]
    Window(#[from] super::window::WindowError),
}

/// A validated portal with its antishadow planes, ready to classify and sample.
#[derive(Clone, Debug)]
pub struct Portal {
    pub name: String,
    /// Index of the `PortalDesc` it was built from in the scene's description.
    pub desc_index: usize,
    /// Index of its light in the scene's lights.
    pub light: usize,
    /// Probability of sampling the light itself instead of the portal.
    pub alpha: f32,
    /// Whether `alpha` is still to be measured (`portal_light_probability: "auto"`, see
    /// `scene::portals::SourceCheck::auto_alpha`); until then it is the default.
    pub alpha_pending: bool,
    /// The portal, its normal pointing to its front (away from the light).
    pub polygon: ConvexPolygon,
    /// The light polygon, its normal pointing towards the portal's side; `None` for a light
    /// of any other shape, which its planes treat as a solid (`docs/method.md` §3.6).
    pub light_polygon: Option<ConvexPolygon>,
    pub planes: AntishadowPlanes,
}

impl Portal {
    /// Validates `desc`, the `desc_index`-th portal of its scene.
    pub fn new(
        desc: &PortalDesc,
        desc_index: usize,
        lights: &[AreaLight],
    ) -> Result<Portal, PortalError> {
        let portal = desc.name.clone();
        let target = desc.target.clone();
        if !(0.0..=1.0).contains(&desc.alpha) {
            return Err(PortalError::BadAlpha {
                portal,
                alpha: desc.alpha,
            });
        }
        let Some(light) = lights.iter().position(|l| l.name == desc.target) else {
            return Err(PortalError::TargetMissing { portal, target });
        };
        let polygon = ConvexPolygon::from_triangles(&desc.world_triangles()).map_err(|error| {
            PortalError::BadPolygon {
                portal: portal.clone(),
                error,
            }
        })?;
        let coplanar = || PortalError::Coplanar {
            portal: portal.clone(),
            target: target.clone(),
        };
        let geometry = |error| PortalError::Geometry {
            portal: portal.clone(),
            target: target.clone(),
            error,
        };
        let (polygon, light_polygon, planes) = match lights[light].polygon.clone() {
            Some(light_polygon) => {
                let (polygon, light_polygon) =
                    orient(polygon, light_polygon, lights[light].double_sided)
                        .ok_or_else(coplanar)?;
                let planes = AntishadowPlanes::new(&polygon, &light_polygon).map_err(geometry)?;
                (polygon, Some(light_polygon), planes)
            }
            None => {
                let polygon =
                    orient_to_solid(polygon, lights[light].centroid()).ok_or_else(coplanar)?;
                let points: Vec<Vec3> = lights[light].corners().collect();
                let planes = AntishadowPlanes::new_hull(&polygon, &points).map_err(geometry)?;
                (polygon, None, planes)
            }
        };
        Ok(Portal {
            name: portal,
            desc_index,
            light,
            alpha: desc.alpha,
            alpha_pending: desc.auto_alpha,
            polygon,
            light_polygon,
            planes,
        })
    }
}

impl Portal {
    /// The half-spaces whose intersection holds the points that `x` sees through the portal
    /// behind it: one plane through `x` and each edge, positive on the portal's side, and the
    /// portal's plane, positive behind it. `None` unless `x` lies in front of the portal and
    /// off the lines of its edges.
    #[inline(always)]
    pub fn seen_through_from(&self, x: Vec3) -> Option<Cut> {
        let plane = self.polygon.plane();
        if plane.signed_distance(x) <= 0.0 {
            return None;
        }
        let c = self.polygon.centroid();
        let mut cut = Cut::new();
        for (a, b) in self.polygon.edges() {
            let edge = Plane::through(x, a, b)?;
            let edge = if edge.signed_distance(c) < 0.0 {
                edge.flipped()
            } else {
                edge
            };
            cut.try_push(edge).ok()?;
        }
        cut.try_push(plane.flipped()).ok()?;
        Some(cut)
    }

    /// The region of `x` found without the planes, by projecting the light (or its solid)
    /// through the portal: a slow reference for tests and the overlay's debug mode.
    pub fn classify_brute_force(&self, x: Vec3) -> Region {
        match &self.light_polygon {
            Some(light) => classify_brute_force(&self.polygon, light, x),
            None => classify_brute_force_hull(&self.polygon, self.planes.light_behind_portal(), x),
        }
    }
}

/// A portal of a solid light faces away from the light's centroid; `None` when the centroid
/// lies in the portal's plane.
fn orient_to_solid(portal: ConvexPolygon, light_centroid: Vec3) -> Option<ConvexPolygon> {
    let eps = 1e-6 * portal.area().sqrt();
    let side = portal.plane().signed_distance(light_centroid);
    if side.abs() <= eps || side.is_nan() {
        return None;
    }
    Some(if side > 0.0 { portal.flipped() } else { portal })
}

/// Artists flip planes: the portal's front is the side away from the light's centroid, whatever
/// its winding; a two-sided light faces the portal. Returns `None` when either centroid lies in
/// the other's plane, so no side can be chosen.
fn orient(
    portal: ConvexPolygon,
    light: ConvexPolygon,
    light_double_sided: bool,
) -> Option<(ConvexPolygon, ConvexPolygon)> {
    let scale = portal.area().sqrt().max(light.area().sqrt());
    let eps = 1e-6 * scale;
    let light_side = portal.plane().signed_distance(light.centroid());
    if light_side.abs() <= eps {
        return None;
    }
    let portal = if light_side > 0.0 {
        portal.flipped()
    } else {
        portal
    };
    let portal_side = light.plane().signed_distance(portal.centroid());
    let light = if light_double_sided && portal_side < -eps {
        light.flipped()
    } else {
        light
    };
    Some((portal, light))
}
