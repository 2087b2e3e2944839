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
    /// The mesh as one planar convex polygon (front = winding), when it is one. A portal of
    /// such a light uses the polygon's exact planes; any other light is a solid for its
    /// portals (`docs/method.md` §3.6).
    pub polygon: Option<ConvexPolygon>,
    /// Centre and radius of a sphere holding every triangle: rays that miss it skip them all.
    bounds: (Vec3, f32),
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
        let (lo, hi) = corners
            .iter()
            .flatten()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| {
                (lo.min(p), hi.max(p))
            });
        let centre = 0.5 * (lo + hi);
        let radius = corners
            .iter()
            .flatten()
            .map(|p| p.distance(centre))
            .fold(0.0, f32::max);
        AreaLight {
            bounds: (centre, radius * (1.0 + 1e-5)),
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

    /// The light's triangles.
    pub fn triangles(&self) -> impl Iterator<Item = [Vec3; 3]> + '_ {
        self.triangles.iter().map(|(t, _)| *t)
    }

    /// The corners of every triangle (shared vertices repeated).
    pub fn corners(&self) -> impl Iterator<Item = Vec3> + '_ {
        self.triangles.iter().flat_map(|(t, _)| t.iter().copied())
    }

    /// The area-weighted centroid of the triangles.
    pub fn centroid(&self) -> Vec3 {
        let weighted: Vec3 = self
            .triangles
            .iter()
            .enumerate()
            .map(|(i, ([a, b, c], _))| (*a + *b + *c) / 3.0 * self.by_area.pmf(i))
            .sum();
        weighted
    }

    /// The nearest point where the ray `o + t·d` (`t > 0`) meets the light, whichever side, and
    /// `t`; the normal returned is the front of the triangle (or polygon) it meets. Occluders
    /// are ignored: this is where a direction drawn towards the light lands on it.
    #[inline(always)]
    pub fn intersect(&self, o: Vec3, d: Vec3) -> Option<(LightPoint, f32)> {
        if let Some(polygon) = &self.polygon {
            let t = polygon.intersect(o, d)?;
            return Some((
                LightPoint {
                    p: o + t * d,
                    n: polygon.normal(),
                },
                t,
            ));
        }
        // Ray–sphere rejection first: most lights with portals are seen through a small part
        // of the sky.
        let (centre, radius) = self.bounds;
        let oc = centre - o;
        let along = oc.dot(d);
        if oc.length_squared() > radius * radius
            && (along < 0.0 || (oc - along * d).length_squared() > radius * radius)
        {
            return None;
        }
        self.crossings(o, d).min_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// Every point where the ray `o + t·d` (`t > 0`) crosses the light's triangles, and its `t`.
    fn crossings(&self, o: Vec3, d: Vec3) -> impl Iterator<Item = (LightPoint, f32)> + '_ {
        self.triangles.iter().filter_map(move |&([a, b, c], n)| {
            let t = intersect_triangle(o, d, a, b, c)?;
            Some((LightPoint { p: o + t * d, n }, t))
        })
    }

    /// The solid-angle density of the directions from `x` that [`Self::sample_point`] produces:
    /// the sum of [`Self::pdf_solid_angle`] over every crossing of the ray, since a ray may cross
    /// a bulb or a folded panel more than once. The estimator does not need it (it weights the
    /// point it drew, in area measure: a point behind another part of the light is occluded and
    /// contributes nothing); tests integrate it over directions.
    pub fn direction_pdf(&self, x: Vec3, w: Vec3) -> f32 {
        if let Some(polygon) = &self.polygon {
            return polygon
                .intersect(x, w)
                .map_or(0.0, |t| self.pdf_solid_angle(t, polygon.normal().dot(w)));
        }
        self.crossings(x, w)
            .map(|(y, t)| self.pdf_solid_angle(t, y.n.dot(w)))
            .sum()
    }

    /// Emitted power, W: `π · Le · A`, twice for two-sided lights (luminance-weighted).
    pub fn power(&self) -> f32 {
        let sides = if self.double_sided { 2.0 } else { 1.0 };
        std::f32::consts::PI * luminance(self.radiance) * self.area * sides
    }

    /// A uniform point on the light's area (pdf `1 / area`). `u.x` picks the triangle and is
    /// reused inside it.
    #[inline(always)]
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
    #[inline(always)]
    pub fn emitted(&self, n: Vec3, w: Vec3) -> Vec3 {
        if self.double_sided || n.dot(w) > 0.0 {
            self.radiance
        } else {
            Vec3::ZERO
        }
    }

    /// Solid-angle pdf of uniform area sampling for a point at distance `dist` whose normal
    /// makes cosine `cos_light` with the direction.
    #[inline(always)]
    pub fn pdf_solid_angle(&self, dist: f32, cos_light: f32) -> f32 {
        let c = cos_light.abs();
        if c <= 0.0 || self.area <= 0.0 {
            return 0.0;
        }
        dist * dist / (self.area * c)
    }
}

/// Möller–Trumbore: the ray parameter `t > 0` where `o + t·d` meets triangle `abc`, either side.
fn intersect_triangle(o: Vec3, d: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Option<f32> {
    let (e1, e2) = (b - a, c - a);
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - a;
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = d.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(q) * inv;
    (t > 0.0 && t.is_finite()).then_some(t)
}

/// Rec. 709 luminance.
pub fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}
