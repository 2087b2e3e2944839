//! Time to an equal error: how long a render takes to reach a fixed relMSE against a
//! reference. This is what a viewer's user feels after a change, so a change that trades
//! speed for noise (or the reverse) is judged by it rather than by samples/s or MSE alone.

use std::sync::atomic::AtomicBool;
use std::time::Instant;

use super::metrics::{mse, relmse};
use super::reference::Reference;
use crate::render::film::Film;
use crate::render::integrator::{Integrator, RenderSettings};
use crate::render::render_pass;
use crate::scene::Scene;

/// When a render reached (or was given up short of) the target error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeToError {
    /// Pass render time until the relMSE first fell to the target, or until the cap.
    pub seconds: f64,
    pub spp: u32,
    /// The relMSE and MSE at that point.
    pub relmse: f64,
    pub mse: f64,
    /// Whether the target was reached within the cap.
    pub reached: bool,
}

impl TimeToError {
    /// The time to the target: measured, or (past the cap) extrapolated as `seconds ·
    /// relmse / target`, the law of a Monte Carlo error that falls as 1/time. A sampler that
    /// converges faster than that (Sobol') is then overestimated, never flattered.
    pub fn estimated_seconds(&self, target: f64) -> f64 {
        if self.reached {
            self.seconds
        } else {
            self.seconds * self.relmse / target
        }
    }
}

/// Renders `settings` at the reference's size, one pass at a time, until its relMSE against
/// `reference` is at most `target` or `cap_seconds` of pass time are spent. Only passes are
/// timed; the error is computed after each (a few ms, off the clock).
pub fn time_to_error(
    scene: &Scene,
    settings: RenderSettings,
    reference: &Reference,
    target: f64,
    cap_seconds: f64,
) -> TimeToError {
    let integrator = Integrator::new(scene, settings);
    let (width, height) = (reference.width, reference.height);
    let mut film = Film::new(width, height);
    let never = AtomicBool::new(false);
    let mut seconds = 0.0;
    loop {
        let start = Instant::now();
        let Ok((pass, _)) = render_pass(&integrator, width, height, film.spp, &never) else {
            // Never cancelled: `never` stays false.
            break;
        };
        seconds += start.elapsed().as_secs_f64();
        film.add_pass(&pass);
        let mean = film.mean();
        let rel = relmse(&mean, &reference.pixels);
        if rel <= target || seconds >= cap_seconds {
            return TimeToError {
                seconds,
                spp: film.spp,
                relmse: rel,
                mse: mse(&mean, &reference.pixels),
                reached: rel <= target,
            };
        }
    }
    TimeToError {
        seconds,
        spp: film.spp,
        relmse: f64::INFINITY,
        mse: f64::INFINITY,
        reached: false,
    }
}

/// MSE and relMSE of a render of exactly `spp` passes against `reference`.
pub fn error_at_spp(
    scene: &Scene,
    settings: RenderSettings,
    reference: &Reference,
    spp: u32,
) -> (f64, f64) {
    let integrator = Integrator::new(scene, settings);
    let (film, _) = crate::render::render(&integrator, reference.width, reference.height, spp);
    let mean = film.mean();
    (
        mse(&mean, &reference.pixels),
        relmse(&mean, &reference.pixels),
    )
}
