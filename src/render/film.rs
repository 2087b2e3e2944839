//! The film: per-pixel running sums of radiance and of its square, so that the mean and its
//! standard error are known at every pass. Sums are kept in f64: after thousands of passes f32
//! sums lose the low bits, and the variance (a difference of two large sums) with them.

use glam::{DVec3, Vec3};

#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    sum: Vec<DVec3>,
    sum_sq: Vec<DVec3>,
    /// Samples per pixel so far (every pass adds one to every pixel).
    pub spp: u32,
}

impl Film {
    pub fn new(width: u32, height: u32) -> Self {
        let n = (width * height) as usize;
        Film {
            width,
            height,
            sum: vec![DVec3::ZERO; n],
            sum_sq: vec![DVec3::ZERO; n],
            spp: 0,
        }
    }

    /// Adds one sample per pixel.
    pub fn add_pass(&mut self, pass: &[Vec3]) {
        debug_assert_eq!(pass.len(), self.sum.len());
        for ((s, q), &v) in self.sum.iter_mut().zip(&mut self.sum_sq).zip(pass) {
            let v = v.as_dvec3();
            *s += v;
            *q += v * v;
        }
        self.spp += 1;
    }

    /// The mean radiance of each pixel.
    pub fn mean(&self) -> Vec<Vec3> {
        let inv = 1.0 / self.spp.max(1) as f64;
        self.sum.iter().map(|&s| (s * inv).as_vec3()).collect()
    }

    /// The variance of each pixel's mean (sample variance over spp), per channel.
    pub fn variance_of_mean(&self) -> Vec<Vec3> {
        let n = self.spp as f64;
        if self.spp < 2 {
            return vec![Vec3::ZERO; self.sum.len()];
        }
        self.sum
            .iter()
            .zip(&self.sum_sq)
            .map(|(&s, &q)| {
                let mean = s / n;
                (((q / n - mean * mean) * (n / (n - 1.0))).max(DVec3::ZERO) / n).as_vec3()
            })
            .collect()
    }

    pub fn pixel_count(&self) -> usize {
        self.sum.len()
    }
}
