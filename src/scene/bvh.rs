//! The acceleration structure: an obvhs CWBVH over every triangle, with triangles reordered
//! once into BVH order so traversal reads them sequentially.

use glam::{Vec2, Vec3, Vec3A};
use obvhs::{
    BvhBuildParams,
    cwbvh::{CwBvh, builder::build_cwbvh_from_tris},
    ray::{Ray, RayHit},
    triangle::Triangle,
};
use std::time::Duration;

/// A triangle laid out for intersection (obvhs's `RtTriangle` layout), with a Möller–Trumbore
/// test whose inside check accepts -0.0: obvhs's sign-bit test rejects it, so a ray exactly on
/// the shared diagonal of a quad would slip between its two triangles.
#[derive(Clone, Copy, Debug)]
struct RtTri {
    v0: Vec3A,
    e1: Vec3A,
    e2: Vec3A,
    ng: Vec3A,
}

impl RtTri {
    fn new(t: &Triangle) -> Self {
        let (e1, e2) = (t.v0 - t.v1, t.v2 - t.v0);
        RtTri {
            v0: t.v0,
            e1,
            e2,
            ng: e1.cross(e2),
        }
    }

    /// (u, v, t) of the hit, the hit point being `(1-u-v)·v0 + u·v1 + v·v2`.
    #[inline(always)]
    fn uvt(&self, ray: &Ray) -> (f32, f32, f32) {
        let c = self.v0 - ray.origin;
        let r = ray.direction.cross(c);
        let inv_det = 1.0 / self.ng.dot(ray.direction);
        (
            r.dot(self.e2) * inv_det,
            r.dot(self.e1) * inv_det,
            self.ng.dot(c) * inv_det,
        )
    }

    /// Distance along the ray, or infinity for a miss.
    #[inline(always)]
    fn intersect(&self, ray: &Ray) -> f32 {
        let (u, v, t) = self.uvt(ray);
        if u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t >= ray.tmin && t <= ray.tmax {
            t
        } else {
            f32::INFINITY
        }
    }
}

/// The closest intersection along a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    /// Index of the triangle in the scene's order.
    pub triangle: u32,
    /// Barycentric coordinates of the hit for vertices 1 and 2.
    pub bary: Vec2,
}

/// obvhs 0.4 misses every node when a direction component is -0.0 (its octant and inverse
/// direction disagree), so a ray straight down `-Y` would pass through the floor; adding +0.0
/// turns -0.0 into +0.0 and leaves every other value alone.
#[inline(always)]
fn make_ray(origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Ray {
    Ray::new(origin.into(), (dir + Vec3::ZERO).into(), tmin, tmax)
}

/// The two ray queries a renderer makes. The renderer traces through [`Bvh`]; the benchmark
/// traces through a recorder, to replay exactly the renderer's rays through raw traversal.
pub trait Tracer {
    /// The closest hit of `origin + t·dir` with `t` in `(tmin, tmax)`.
    fn closest_hit(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<Hit>;
    /// Whether anything lies on the open segment `origin + t·dir`, `t` in `(tmin, tmax)`.
    fn occluded(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> bool;
}

impl Tracer for Bvh {
    #[inline]
    fn closest_hit(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<Hit> {
        Bvh::closest_hit(self, origin, dir, tmin, tmax)
    }

    #[inline]
    fn occluded(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> bool {
        Bvh::occluded(self, origin, dir, tmin, tmax)
    }
}

pub struct Bvh {
    /// `None` for an empty scene, where every ray misses.
    cwbvh: Option<CwBvh>,
    /// Triangles in BVH order.
    triangles: Vec<RtTri>,
    /// Scene index of each triangle in BVH order.
    scene_index: Vec<u32>,
}

impl Bvh {
    pub fn build(triangles: &[[Vec3; 3]]) -> Self {
        let tris: Vec<Triangle> = triangles
            .iter()
            .map(|t| Triangle {
                v0: t[0].into(),
                v1: t[1].into(),
                v2: t[2].into(),
            })
            .collect();
        if tris.is_empty() {
            return Bvh {
                cwbvh: None,
                triangles: Vec::new(),
                scene_index: Vec::new(),
            };
        }
        let mut cwbvh = build_cwbvh_from_tris(
            &tris,
            BvhBuildParams::medium_build(),
            &mut Duration::default(),
        );
        let scene_index = std::mem::take(&mut cwbvh.primitive_indices);
        let triangles = scene_index
            .iter()
            .map(|&i| RtTri::new(&tris[i as usize]))
            .collect();
        // After reordering, BVH primitive i is triangle i of `triangles`.
        cwbvh.primitive_indices = (0..scene_index.len() as u32).collect();
        Bvh {
            cwbvh: Some(cwbvh),
            triangles,
            scene_index,
        }
    }

    /// The closest hit of `origin + t·dir` with `t` in `(tmin, tmax)`.
    #[inline]
    pub fn closest_hit(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<Hit> {
        let bvh = self.cwbvh.as_ref()?;
        let ray = make_ray(origin, dir, tmin, tmax);
        let mut hit = RayHit::none();
        if !bvh.ray_traverse(ray, &mut hit, |r, id| self.triangles[id].intersect(r)) {
            return None;
        }
        let (u, v, _) = self.triangles[hit.primitive_id as usize].uvt(&ray);
        Some(Hit {
            t: hit.t,
            triangle: self.scene_index[hit.primitive_id as usize],
            bary: Vec2::new(u, v),
        })
    }

    /// Whether anything lies on the open segment `origin + t·dir`, `t` in `(tmin, tmax)`.
    #[inline]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> bool {
        let Some(bvh) = self.cwbvh.as_ref() else {
            return false;
        };
        let ray = make_ray(origin, dir, tmin, tmax);
        !bvh.ray_traverse_miss(ray, |r, id| self.triangles[id].intersect(r))
    }

    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// The raw obvhs traversal with no shading work, for benchmarks: closest-hit distance.
    pub fn raw_closest_t(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> f32 {
        let Some(bvh) = self.cwbvh.as_ref() else {
            return f32::INFINITY;
        };
        let mut hit = RayHit::none();
        bvh.ray_traverse(make_ray(origin, dir, tmin, tmax), &mut hit, |r, id| {
            self.triangles[id].intersect(r)
        });
        hit.t
    }
}
