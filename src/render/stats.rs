//! Counters the renderer keeps while it works: where shading points lie in the antishadow,
//! which technique drew each light sample, and how many rays were traced.

use glam::Vec3;
use std::ops::AddAssign;

use crate::light::Technique;
use crate::light::antishadow::Region;

/// Counts over one or more passes. Merging is a sum, so totals do not depend on threading.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stats {
    /// Shading points (at which a light was sampled) by region, indexed like `Region::ALL`,
    /// for the sampled light's portals.
    pub regions: [u64; 5],
    /// Shading points whose sampled light has no portal (or the strategy ignores portals).
    pub no_portal: u64,
    /// Light samples by the technique that drew them, indexed like `Technique::ALL`.
    pub techniques: [u64; 3],
    /// Light samples that drew nothing (the portal share at a point outside every antishadow).
    pub empty_samples: u64,
    pub camera_rays: u64,
    /// Closest-hit rays after the camera's.
    pub bounce_rays: u64,
    /// Occlusion rays: light samples' shadow rays, and the visibility tests of last-bounce
    /// directions that reach a light (see `Integrator::emission_along`).
    pub shadow_rays: u64,
    /// Time spent building contexts and drawing light samples, estimated from a timed
    /// subsample of shading points (one in `TIMING_STRIDE`).
    pub sampling_ns: u64,
    /// Samples per pixel accumulated in these counts.
    pub samples: u64,
    /// Paths whose first vertex was shaded in a packet's lanes (the staged schedule's,
    /// `Integrator::radiance_packet`); the others ran it one path at a time.
    pub lane_vertices: u64,
    /// Radiance samples that came out NaN or infinite and were replaced by zero: a symptom of
    /// a bug (or of a scene beyond f32), shown wherever statistics are, never silently lost.
    pub nonfinite: u64,
}

/// One shading point in this many is timed (timing each would cost more than sampling).
pub const TIMING_STRIDE: u64 = 16;

/// The cost of reading the clock twice (`Instant::now` and `elapsed`), measured once, so that
/// sampling times report the sampling and not the stopwatch.
pub fn timer_overhead() -> std::time::Duration {
    static OVERHEAD: std::sync::OnceLock<std::time::Duration> = std::sync::OnceLock::new();
    *OVERHEAD.get_or_init(|| {
        (0..5)
            .map(|_| {
                let start = std::time::Instant::now();
                for _ in 0..1000 {
                    std::hint::black_box(std::time::Instant::now().elapsed());
                }
                start.elapsed() / 1000
            })
            .min()
            .unwrap_or_default()
    })
}

impl Stats {
    pub fn count_region(&mut self, region: Region) {
        // `Region::ALL` lists the regions in declaration order.
        if let Some(count) = self.regions.get_mut(region as usize) {
            *count += 1;
        }
    }

    pub fn count_technique(&mut self, technique: Technique) {
        if let Some(i) = Technique::ALL.iter().position(|&t| t == technique) {
            self.techniques[i] += 1;
        }
    }

    /// `l` if it is finite, else zero, counted in `nonfinite`: a NaN or infinity would poison
    /// a pixel's mean for good.
    pub fn finite_or_counted(&mut self, l: Vec3) -> Vec3 {
        if l.is_finite() {
            l
        } else {
            self.nonfinite += 1;
            Vec3::ZERO
        }
    }

    pub fn shading_points(&self) -> u64 {
        self.regions.iter().sum::<u64>() + self.no_portal
    }

    /// Share of shading points in `region`, in [0, 1].
    pub fn region_share(&self, region: Region) -> f64 {
        let total = self.shading_points();
        match Region::ALL.iter().position(|&r| r == region) {
            Some(i) if total > 0 => self.regions[i] as f64 / total as f64,
            _ => 0.0,
        }
    }

    pub fn rays(&self) -> u64 {
        self.camera_rays + self.bounce_rays + self.shadow_rays
    }

    pub fn light_samples(&self) -> u64 {
        self.techniques.iter().sum::<u64>() + self.empty_samples
    }
}

impl AddAssign for Stats {
    fn add_assign(&mut self, o: Stats) {
        for (a, b) in self.regions.iter_mut().zip(o.regions) {
            *a += b;
        }
        for (a, b) in self.techniques.iter_mut().zip(o.techniques) {
            *a += b;
        }
        self.no_portal += o.no_portal;
        self.empty_samples += o.empty_samples;
        self.camera_rays += o.camera_rays;
        self.bounce_rays += o.bounce_rays;
        self.shadow_rays += o.shadow_rays;
        self.sampling_ns += o.sampling_ns;
        self.samples += o.samples;
        self.nonfinite += o.nonfinite;
        self.lane_vertices += o.lane_vertices;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn non_finite_radiance_is_zeroed_and_counted() {
        let mut stats = Stats::default();
        assert_eq!(stats.finite_or_counted(Vec3::ONE), Vec3::ONE);
        assert_eq!(stats.nonfinite, 0);
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            assert_eq!(
                stats.finite_or_counted(Vec3::new(1.0, bad, 0.0)),
                Vec3::ZERO
            );
        }
        assert_eq!(stats.nonfinite, 3);
        let mut total = Stats::default();
        total += stats;
        total += stats;
        assert_eq!(total.nonfinite, 6);
    }
}
