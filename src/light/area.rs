//! Area lights: emissive triangle meshes, sampled uniformly by area (the thesis's baseline).

use glam::{Vec2, Vec3};

use crate::sampling::{Distribution1D, polygon::ConvexPolygon, sample_uniform_triangle};

/// A point drawn on a light, with its geometric normal (front side).
#[derive(Clone, Copy, Debug)]
pub struct LightPoint {
    pub p: Vec3,
    pub n: Vec3,
}

/// One emissive mesh primitive (one glTF node's emissive primitive).
#[derive(Clone, Debug)]
pub struct AreaLight {
    /// The node it came from: portals name their light by it.
    pub name: String,
    /// Emitted radiance, W/(sr·m²).
    pub radiance: Vec3,
    pub double_sided: bool,
    /// Scene triangles of the light, with their front-face normals and areas.
    triangles: Vec<([Vec3; 3], Vec3)>,
    by_area: Distribution1D,
    area: f32,
    /// The mesh as one planar convex polygon (front = winding), when it is one; only such
    /// lights may have portals.
    pub polygon: Option<ConvexPolygon>,
}

impl AreaLight {
    pub fn new(name: String, radiance: Vec3, double_sided: bool, triangles: &[[Vec3; 3]]) -> Self {
        let triangles: Vec<([Vec3; 3], Vec3)> = triangles
            .iter()
            .map(|t| (*t, (t[1] - t[0]).cross(t[2] - t[0])))
            .collect();
        let by_area = Distribution1D::new(triangles.iter().map(|(_, n)| 0.5 * n.length()));
        let area = by_area.total();
        let corners: Vec<[Vec3; 3]> = triangles.iter().map(|(t, _)| *t).collect();
        AreaLight {
            name,
            radiance,
            double_sided,
            polygon: ConvexPolygon::from_triangles(&corners).ok(),
            triangles: triangles
                .into_iter()
                .map(|(t, n)| (t, n.normalize_or_zero()))
                .collect(),
            by_area,
            area,
        }
    }

    pub fn area(&self) -> f32 {
        self.area
    }

    /// Emitted power, W: `π · Le · A`, twice for two-sided lights (luminance-weighted).
    pub fn power(&self) -> f32 {
        let sides = if self.double_sided { 2.0 } else { 1.0 };
        std::f32::consts::PI * luminance(self.radiance) * self.area * sides
    }

    /// A uniform point on the light's area (pdf `1 / area`). `u.x` picks the triangle and is
    /// reused inside it.
    pub fn sample_point(&self, u: Vec2) -> Option<LightPoint> {
        let (i, _, ux) = self.by_area.sample(u.x)?;
        let ([a, b, c], n) = self.triangles[i];
        let bary = sample_uniform_triangle(Vec2::new(ux, u.y));
        Some(LightPoint {
            p: bary.x * a + bary.y * b + (1.0 - bary.x - bary.y) * c,
            n,
        })
    }

    /// Radiance leaving a point with front normal `n` towards `w` (unit, from the light).
    pub fn emitted(&self, n: Vec3, w: Vec3) -> Vec3 {
        if self.double_sided || n.dot(w) > 0.0 {
            self.radiance
        } else {
            Vec3::ZERO
        }
    }

    /// Solid-angle pdf of uniform area sampling for a point at distance `dist` whose normal
    /// makes cosine `cos_light` with the direction.
    pub fn pdf_solid_angle(&self, dist: f32, cos_light: f32) -> f32 {
        let c = cos_light.abs();
        if c <= 0.0 || self.area <= 0.0 {
            return 0.0;
        }
        dist * dist / (self.area * c)
    }
}

/// Rec. 709 luminance.
pub fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}
