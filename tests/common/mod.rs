//! Scene building blocks shared by the integration tests.
#![allow(dead_code)]

use glam::{Mat4, Vec3};
use portalview::asset::desc::{MaterialDesc, PortalDesc, SceneDesc};
use portalview::camera::Camera;

pub use portalview::asset::builtin::flat_mesh as flat;

/// A portal from a convex polygon given in world space.
pub fn portal(name: &str, target: &str, alpha: f32, corners: &[Vec3]) -> PortalDesc {
    PortalDesc {
        name: name.to_owned(),
        target: target.to_owned(),
        alpha,
        local_triangles: (1..corners.len() - 1)
            .map(|i| [corners[0], corners[i], corners[i + 1]])
            .collect(),
        world_from_local: Mat4::IDENTITY,
        node_index: None,
    }
}

/// A square of half-size `h` centred at `c`, in the plane with normal `n` (its front).
pub fn square(c: Vec3, n: Vec3, h: f32) -> Vec<Vec3> {
    let n = n.normalize();
    let t = n.any_orthonormal_vector();
    let b = n.cross(t);
    vec![
        c - h * t - h * b,
        c + h * t - h * b,
        c + h * t + h * b,
        c - h * t + h * b,
    ]
}

pub fn camera(eye: Vec3, target: Vec3) -> Option<Camera> {
    Some(Camera {
        eye,
        target,
        up: Vec3::Y,
        yfov: 0.8,
        aspect: 1.0,
    })
}

/// A white diffuse floor at y = 0 and a polygon light `light` (front = its winding).
pub fn floor_and_light(albedo: f32, light: Vec<Vec3>, le: f32) -> SceneDesc {
    SceneDesc {
        name: "test".into(),
        materials: vec![
            MaterialDesc {
                ..MaterialDesc::diffuse("floor", Vec3::splat(albedo))
            },
            MaterialDesc::emitter("light", Vec3::splat(le), false),
        ],
        meshes: vec![
            flat(
                "floor",
                0,
                &[vec![
                    Vec3::new(-50.0, 0.0, -50.0),
                    Vec3::new(-50.0, 0.0, 50.0),
                    Vec3::new(50.0, 0.0, 50.0),
                    Vec3::new(50.0, 0.0, -50.0),
                ]],
            ),
            flat("light", 1, &[light]),
        ],
        portals: vec![],
        camera: camera(Vec3::new(0.0, 3.0, 3.0), Vec3::ZERO),
    }
}

/// Lambert's closed-form irradiance at `x` (normal `n`) from a polygon of radiance `le`:
/// `E = Le/2 · |Σ angle(v_i, v_{i+1}) · (n · unit(v_i × v_{i+1}))|`.
pub fn lambert_irradiance(x: Vec3, n: Vec3, polygon: &[Vec3], le: f32) -> f32 {
    let k = polygon.len();
    let sum: f32 = (0..k)
        .map(|i| {
            let a = (polygon[i] - x).normalize();
            let b = (polygon[(i + 1) % k] - x).normalize();
            let angle = a.dot(b).clamp(-1.0, 1.0).acos();
            angle * n.dot(a.cross(b).normalize())
        })
        .sum();
    0.5 * le * sum.abs()
}

/// Mean and standard error of a sample.
pub fn mean_and_se(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}
