//! The film: per-pixel running sums of radiance and of its square, so that the mean and its
//! standard error are known at every pass.

use glam::Vec3;

#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    sum: Vec<Vec3>,
    sum_sq: Vec<Vec3>,
    /// Samples per pixel so far (every pass adds one to every pixel).
    pub spp: u32,
}

impl Film {
    pub fn new(width: u32, height: u32) -> Self {
        let n = (width * height) as usize;
        Film {
            width,
            height,
            sum: vec![Vec3::ZERO; n],
            sum_sq: vec![Vec3::ZERO; n],
            spp: 0,
        }
    }

    /// Adds one sample per pixel.
    pub fn add_pass(&mut self, pass: &[Vec3]) {
        debug_assert_eq!(pass.len(), self.sum.len());
        for ((s, q), &v) in self.sum.iter_mut().zip(&mut self.sum_sq).zip(pass) {
            *s += v;
            *q += v * v;
        }
        self.spp += 1;
    }

    /// The mean radiance of each pixel.
    pub fn mean(&self) -> Vec<Vec3> {
        let inv = 1.0 / self.spp.max(1) as f32;
        self.sum.iter().map(|&s| s * inv).collect()
    }

    /// The variance of each pixel's mean (sample variance over spp), per channel.
    pub fn variance_of_mean(&self) -> Vec<Vec3> {
        let n = self.spp as f32;
        if self.spp < 2 {
            return vec![Vec3::ZERO; self.sum.len()];
        }
        self.sum
            .iter()
            .zip(&self.sum_sq)
            .map(|(&s, &q)| {
                let mean = s / n;
                ((q / n - mean * mean) * (n / (n - 1.0))).max(Vec3::ZERO) / n
            })
            .collect()
    }

    pub fn pixel_count(&self) -> usize {
        self.sum.len()
    }
}
