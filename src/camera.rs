//! A perspective pinhole camera (also what a scene description stores) that looks from `eye` at `target`, with the orbit, pan and zoom
//! a viewer needs and the projection that draws 3D lines over the image.

use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    pub eye: Vec3,
    pub target: Vec3,
    pub up: Vec3,
    /// Vertical field of view, radians.
    pub yfov: f32,
    /// Width over height that the scene was authored for.
    pub aspect: f32,
}

/// The camera's orthonormal basis: right, true up, and forward (towards the target).
#[derive(Clone, Copy, Debug)]
struct Basis {
    right: Vec3,
    up: Vec3,
    forward: Vec3,
}

/// Primary rays for one image size, with the camera's basis computed once.
#[derive(Clone, Copy, Debug)]
pub struct RayGenerator {
    eye: Vec3,
    forward: Vec3,
    /// Right and up, scaled to the image plane at unit distance.
    right: Vec3,
    up: Vec3,
}

impl RayGenerator {
    /// The ray through `ndc` (in [0, 1]², origin top-left): origin and unit direction.
    #[inline]
    pub fn ray(&self, ndc: Vec2) -> (Vec3, Vec3) {
        let d = self.forward + (2.0 * ndc.x - 1.0) * self.right + (1.0 - 2.0 * ndc.y) * self.up;
        (self.eye, d.normalize())
    }
}

impl Camera {
    /// The image height for `width` that keeps the camera's aspect ratio.
    pub fn height_for_width(&self, width: u32) -> u32 {
        ((width as f32 / self.aspect.max(1e-3)).round() as u32).max(1)
    }

    /// A camera that frames the box `[lo, hi]` from the front-right, slightly above.
    pub fn framing(lo: Vec3, hi: Vec3, aspect: f32) -> Self {
        let center = 0.5 * (lo + hi);
        let radius = (0.5 * (hi - lo).length()).max(1e-3);
        let yfov = 45f32.to_radians();
        let dir = Vec3::new(0.35, 0.35, 1.0).normalize();
        Camera {
            eye: center + dir * (radius / (0.5 * yfov).sin()),
            target: center,
            up: Vec3::Y,
            yfov,
            aspect,
        }
    }

    fn basis(&self) -> Basis {
        let forward = (self.target - self.eye).normalize_or(-Vec3::Z);
        let mut right = forward.cross(self.up).normalize_or_zero();
        if right == Vec3::ZERO {
            right = forward.any_orthonormal_vector();
        }
        Basis {
            right,
            up: right.cross(forward),
            forward,
        }
    }

    /// Primary rays for an image of aspect `aspect` (width over height).
    pub fn rays(&self, aspect: f32) -> RayGenerator {
        let b = self.basis();
        let tan_half = (0.5 * self.yfov).tan();
        RayGenerator {
            eye: self.eye,
            forward: b.forward,
            right: b.right * (tan_half * aspect),
            up: b.up * tan_half,
        }
    }

    /// The primary ray through `ndc` (in [0, 1]², origin top-left) for an image of aspect
    /// `aspect`: origin and unit direction.
    pub fn ray(&self, ndc: Vec2, aspect: f32) -> (Vec3, Vec3) {
        self.rays(aspect).ray(ndc)
    }

    /// Where the point `p` lands in normalised image coordinates, if it is in front of the camera.
    pub fn project(&self, p: Vec3, aspect: f32) -> Option<Vec2> {
        let b = self.basis();
        let v = p - self.eye;
        let z = v.dot(b.forward);
        if z <= 1e-6 {
            return None;
        }
        let tan_half = (0.5 * self.yfov).tan();
        let sx = v.dot(b.right) / (z * tan_half * aspect);
        let sy = v.dot(b.up) / (z * tan_half);
        Some(Vec2::new(0.5 * (sx + 1.0), 0.5 * (1.0 - sy)))
    }

    /// Clips the segment to the part in front of the camera (so lines through the eye can be
    /// drawn) and projects its ends.
    pub fn project_segment(&self, a: Vec3, b: Vec3, aspect: f32) -> Option<(Vec2, Vec2)> {
        let forward = self.basis().forward;
        let near = 1e-3 * (self.target - self.eye).length().max(1e-3);
        let (za, zb) = ((a - self.eye).dot(forward), (b - self.eye).dot(forward));
        if za < near && zb < near {
            return None;
        }
        let cut = |p: Vec3, q: Vec3, zp: f32, zq: f32| p + (q - p) * ((near - zp) / (zq - zp));
        let a2 = if za < near { cut(a, b, za, zb) } else { a };
        let b2 = if zb < near { cut(b, a, zb, za) } else { b };
        Some((self.project(a2, aspect)?, self.project(b2, aspect)?))
    }

    /// Turns the eye around the target: `yaw` about the up axis, `pitch` over it (radians).
    pub fn orbit(&mut self, yaw: f32, pitch: f32) {
        let offset = self.eye - self.target;
        let up = self.up.normalize_or(Vec3::Y);
        let yawed = glam::Quat::from_axis_angle(up, -yaw) * offset;
        let right = yawed.cross(up).normalize_or_zero();
        let pitched = glam::Quat::from_axis_angle(right, pitch) * yawed;
        // Stop short of the poles, where the basis would flip.
        if pitched.normalize_or_zero().dot(up).abs() < 0.995 {
            self.eye = self.target + pitched;
        } else {
            self.eye = self.target + yawed;
        }
    }

    /// Moves eye and target together by a fraction of the view distance (screen x right, y up).
    pub fn pan(&mut self, dx: f32, dy: f32) {
        let b = self.basis();
        let dist = (self.target - self.eye).length();
        let delta = (b.right * dx + b.up * dy) * dist;
        self.eye += delta;
        self.target += delta;
    }

    /// Moves the eye towards the target by `factor` of the distance (positive: closer).
    pub fn zoom(&mut self, factor: f32) {
        let offset = self.eye - self.target;
        let scaled = offset * (1.0 - factor).clamp(0.05, 20.0);
        if scaled.length() > 1e-4 {
            self.eye = self.target + scaled;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn project_inverts_ray() {
        let cam = Camera {
            eye: Vec3::new(1.0, 2.0, 5.0),
            target: Vec3::new(0.0, 0.5, 0.0),
            up: Vec3::Y,
            yfov: 0.8,
            aspect: 1.5,
        };
        for ndc in [
            Vec2::new(0.5, 0.5),
            Vec2::new(0.1, 0.9),
            Vec2::new(0.8, 0.2),
        ] {
            let (o, d) = cam.ray(ndc, 1.5);
            let back = cam.project(o + 3.0 * d, 1.5).unwrap();
            assert!(back.abs_diff_eq(ndc, 1e-5), "{back} vs {ndc}");
        }
    }
}
