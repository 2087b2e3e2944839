//! Error metrics of an image against a reference, and how converged a film is.

use glam::{DVec3, Vec3};
use serde::{Deserialize, Serialize};

use crate::render::film::Film;

/// The ε of relMSE, in squared radiance units: `(x − r)² / (r² + ε)`. It keeps black and
/// near-black reference pixels (shadows, the unlit background) from dominating the mean; with
/// the built-in scenes' radiances of about 0.01 to 10, it weights pixels darker than 0.1 by
/// their absolute rather than relative error. 1e-2 is the usual choice (Rousselle et al.).
pub const RELMSE_EPSILON: f64 = 1e-2;

/// Mean squared error over pixels and channels. Both images are row-major and of equal size.
///
/// # Panics
/// If the lengths differ (a caller's bug: the sizes are checked where images are loaded).
pub fn mse(image: &[Vec3], reference: &[Vec3]) -> f64 {
    mean_channel_error(image, reference, |d, _| d * d)
}

/// Relative MSE: the mean over pixels and channels of `(x − r)² / (r² + ε)`, with
/// ε = [`RELMSE_EPSILON`].
///
/// # Panics
/// If the lengths differ.
pub fn relmse(image: &[Vec3], reference: &[Vec3]) -> f64 {
    mean_channel_error(image, reference, |d, r| d * d / (r * r + RELMSE_EPSILON))
}

/// The mean over pixels and channels of `error(x − r, r)`, in f64.
fn mean_channel_error(
    image: &[Vec3],
    reference: &[Vec3],
    error: impl Fn(DVec3, DVec3) -> DVec3,
) -> f64 {
    assert_eq!(image.len(), reference.len(), "images of different sizes");
    if image.is_empty() {
        return 0.0;
    }
    let sum: f64 = image
        .iter()
        .zip(reference)
        .map(|(&x, &r)| {
            let r = r.as_dvec3();
            let e = error(x.as_dvec3() - r, r);
            e.x + e.y + e.z
        })
        .sum();
    sum / (3 * image.len()) as f64
}

/// The share of the pixels that [`worst_pixels_share`] reports on: the worst 1 %.
pub const WORST_FRACTION: f64 = 0.01;

/// The share of the squared error (summed over a pixel's channels) that the worst `fraction`
/// of the pixels hold: about `fraction` where the error is spread evenly (noise the eye
/// averages), near 1 where a few fireflies carry it. 0 for an image equal to its reference.
///
/// # Panics
/// If the lengths differ.
pub fn worst_pixels_share(image: &[Vec3], reference: &[Vec3], fraction: f64) -> f64 {
    let errors = sorted_pixel_errors(image, reference);
    let total: f64 = errors.iter().sum();
    if !(total > 0.0 && total.is_finite()) {
        return 0.0;
    }
    let worst = ((errors.len() as f64 * fraction).ceil() as usize).min(errors.len());
    errors[errors.len() - worst..].iter().sum::<f64>() / total
}

/// The share of the pixels [`bulk_mse`] leaves out: the worst 0.1 %.
pub const BULK_DROPPED: f64 = 0.001;

/// The MSE of the image's bulk: over the pixels less the worst `dropped` fraction by squared
/// error (a handful of fireflies can carry the whole MSE while the rest of the image, what a
/// user looks at, is clean or grainy).
///
/// # Panics
/// If the lengths differ.
pub fn bulk_mse(image: &[Vec3], reference: &[Vec3], dropped: f64) -> f64 {
    let errors = sorted_pixel_errors(image, reference);
    let kept = errors.len() - ((errors.len() as f64 * dropped).floor() as usize).min(errors.len());
    if kept == 0 {
        return 0.0;
    }
    errors[..kept].iter().sum::<f64>() / (3 * kept) as f64
}

/// Each pixel's squared error summed over its channels, in increasing order.
///
/// # Panics
/// If the lengths differ.
fn sorted_pixel_errors(image: &[Vec3], reference: &[Vec3]) -> Vec<f64> {
    assert_eq!(image.len(), reference.len(), "images of different sizes");
    let mut errors: Vec<f64> = image
        .iter()
        .zip(reference)
        .map(|(&x, &r)| (x.as_dvec3() - r.as_dvec3()).length_squared())
        .collect();
    errors.sort_unstable_by(f64::total_cmp);
    errors
}

/// The MSE with the reference's noise floor taken out: the reference's noise is independent of
/// the image's, so the measured MSE is the true MSE plus the floor and `mse − floor` is an
/// unbiased estimate of the true MSE. `None` where that is not positive (an image the reference
/// cannot tell from the truth), or without a floor.
pub fn mse_above_floor(mse: f64, floor: Option<f64>) -> Option<f64> {
    let floor = floor.filter(|f| f.is_finite() && *f >= 0.0)?;
    Some(mse - floor).filter(|e| e.is_finite() && *e > 0.0)
}

/// How converged a rendered image is, from its film's per-pixel variance of the mean.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Convergence {
    /// Mean over pixel channels of `sqrt(var / (r² + ε))`: the standard error relative to the
    /// pixel's value, with relMSE's ε. Exactly black channels with no variance (nothing was
    /// ever seen there) are left out.
    pub mean_relative_standard_error: f64,
    /// Mean variance of the pixel means: the expected MSE of this image against the true one,
    /// and what it adds to the MSE of any independent image measured against it.
    pub mse_floor: f64,
    /// The same floor for relMSE: mean of `var / (r² + ε)`.
    pub relmse_floor: f64,
}

impl Convergence {
    pub fn of(film: &Film) -> Convergence {
        let mean = film.mean();
        let variance = film.variance_of_mean();
        let (mut rse, mut counted) = (0.0f64, 0usize);
        let (mut floor, mut rel_floor) = (0.0f64, 0.0f64);
        for (m, v) in mean.iter().zip(&variance) {
            for (r, var) in [(m.x, v.x), (m.y, v.y), (m.z, v.z)] {
                let (r, var) = (r as f64, var as f64);
                floor += var;
                let rel = var / (r * r + RELMSE_EPSILON);
                rel_floor += rel;
                if r != 0.0 || var != 0.0 {
                    rse += rel.sqrt();
                    counted += 1;
                }
            }
        }
        let channels = (3 * mean.len()).max(1) as f64;
        Convergence {
            mean_relative_standard_error: rse / counted.max(1) as f64,
            mse_floor: floor / channels,
            relmse_floor: rel_floor / channels,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Evenly spread error puts 1 % of it in the worst 1 % of pixels; one firefly among
    /// otherwise exact pixels puts all of it there.
    #[test]
    fn the_worst_pixels_share_tells_fireflies_from_noise() {
        let reference = vec![Vec3::splat(0.5); 1000];
        let even: Vec<Vec3> = reference.iter().map(|r| *r + 0.1).collect();
        let share = worst_pixels_share(&even, &reference, WORST_FRACTION);
        assert!((share - 0.01).abs() < 1e-9, "{share}");
        let mut firefly = reference.clone();
        firefly[17] = Vec3::splat(50.0);
        assert_eq!(
            worst_pixels_share(&firefly, &reference, WORST_FRACTION),
            1.0
        );
        assert_eq!(
            worst_pixels_share(&reference, &reference, WORST_FRACTION),
            0.0
        );
        // The bulk leaves the firefly out, and is the MSE where the error is even.
        assert_eq!(bulk_mse(&firefly, &reference, BULK_DROPPED), 0.0);
        let even_mse = mse(&even, &reference);
        assert!((bulk_mse(&even, &reference, BULK_DROPPED) - even_mse).abs() < 1e-12);
    }

    #[test]
    fn the_floor_is_subtracted_only_when_known_and_below_the_mse() {
        let above = mse_above_floor(3e-5, Some(1e-5)).unwrap_or(0.0);
        assert!((above - 2e-5).abs() < 1e-18, "{above}");
        assert_eq!(mse_above_floor(3e-5, Some(0.0)), Some(3e-5));
        // Below the floor the reference cannot measure the error.
        assert_eq!(mse_above_floor(1e-5, Some(2e-5)), None);
        assert_eq!(mse_above_floor(1e-5, Some(1e-5)), None);
        assert_eq!(mse_above_floor(1e-5, None), None);
        assert_eq!(mse_above_floor(1e-5, Some(f64::NAN)), None);
    }
}
