//! The Sobol' sampler: stratification of every draw over any power-of-two prefix of passes,
//! decorrelation across pixels and draws, and images that agree with independent sampling.

use glam::{Vec2, Vec3};
use portalview::light::Strategy;
use portalview::render::film::Film;
use portalview::render::integrator::{Integrator, RenderSettings};
use portalview::render::render;
use portalview::sampling::{Sampler, SamplerKind};
use portalview::scene::Scene;

/// A draw: one number or a pair.
#[derive(Clone, Copy, Debug)]
enum Draw {
    One(f32),
    Two(Vec2),
}

/// The draws of one path in the integrator's order: camera (2D); per vertex light pick,
/// technique pick, light direction (2D), lobe, BSDF direction (2D); two vertices.
fn path_draws(sampler: &mut Sampler) -> Vec<Draw> {
    let mut draws = vec![Draw::Two(sampler.uniform2())];
    for _ in 0..2 {
        draws.push(Draw::One(sampler.uniform()));
        draws.push(Draw::One(sampler.uniform()));
        draws.push(Draw::Two(sampler.uniform2()));
        draws.push(Draw::One(sampler.uniform()));
        draws.push(Draw::Two(sampler.uniform2()));
    }
    draws
}

/// The draws of passes `0..n` of pixel `(x, y)`, by draw slot.
fn slots(kind: SamplerKind, seed: u64, (x, y): (u32, u32), n: u32) -> Vec<Vec<Draw>> {
    let paths: Vec<Vec<Draw>> = (0..n)
        .map(|pass| path_draws(&mut kind.pass(seed, pass).start(x, y, 640)))
        .collect();
    (0..paths[0].len())
        .map(|slot| paths.iter().map(|p| p[slot]).collect())
        .collect()
}

/// `n = 2^k` numbers, one in each interval `[i/n, (i+1)/n)`.
fn stratified_1d(values: &[f32]) -> bool {
    let n = values.len();
    let mut seen = vec![false; n];
    for &v in values {
        let i = ((v as f64 * n as f64) as usize).min(n - 1);
        if std::mem::replace(&mut seen[i], true) {
            return false;
        }
    }
    true
}

/// `n = 2^k` points in `[0, 1)^s` forming a (t, k, s)-net: `2^t` points in every elementary
/// interval `2^-a_1 × … × 2^-a_s` with `a_1 + … + a_s = k − t` (every one when `k ≤ t`).
fn net(points: &[Vec<f32>], t: u32) -> bool {
    let n = points.len();
    let k = n.trailing_zeros();
    let s = points[0].len();
    if k <= t {
        return true;
    }
    // Every split of `k − t` digits among the `s` axes.
    let mut splits = vec![vec![]];
    for _ in 0..s {
        splits = splits
            .into_iter()
            .flat_map(|split: Vec<u32>| {
                let used: u32 = split.iter().sum();
                (0..=(k - t - used)).map(move |a| [split.clone(), vec![a]].concat())
            })
            .collect();
    }
    splits
        .into_iter()
        .filter(|split| split.iter().sum::<u32>() == k - t)
        .all(|split| {
            let mut counts = vec![0u32; 1 << (k - t)];
            for p in points {
                let cell = split.iter().zip(p).fold(0usize, |cell, (&a, &x)| {
                    let i = ((x as f64 * (1u64 << a) as f64) as usize).min((1 << a) - 1);
                    (cell << a) | i
                });
                counts[cell] += 1;
            }
            counts.iter().all(|&c| c == 1 << t)
        })
}

/// The slot of the first vertex's light direction, which shares the camera draw's index
/// (`sobol::JOINT_DRAW`); the camera takes Sobol' dimensions 2 and 3 of it, a (2, k, 2)-net in
/// the plane.
const JOINT_SLOT: usize = 3;
const CAMERA_SLOT: usize = 0;

/// A 1D slot's values one per interval, a 2D slot's points a (0, k, 2)-net.
fn slot_stratified(draws: &[Draw]) -> bool {
    match draws[0] {
        Draw::One(_) => stratified_1d(&points(draws).iter().map(|p| p[0]).collect::<Vec<_>>()),
        Draw::Two(_) => net(&points(draws), 0),
    }
}

/// Every draw of a pixel (camera, light pick, technique pick, light direction, lobe, BSDF
/// direction, at two vertices) is stratified over the first `2^k` passes for every `k` up to
/// 10: one value per `1/2^k` interval, and pairs a (0, k, 2)-net, but the camera's jitter,
/// which is a (2, k, 2)-net (with the first vertex's light direction it is one 4D net, the
/// next test). Negative case: independent numbers are not.
#[test]
fn sobol_draws_are_stratified_over_every_power_of_two_prefix() {
    for seed in [0u64, 7, 1 << 40] {
        for pixel in [(0, 0), (1, 0), (0, 1), (5, 9), (639, 479), (300, 200)] {
            let all = slots(SamplerKind::Sobol, seed, pixel, 1024);
            for k in 0..=10 {
                for (slot, draws) in all.iter().enumerate() {
                    let stratified = match slot {
                        CAMERA_SLOT => net(&points(&draws[..1 << k]), 2),
                        _ => slot_stratified(&draws[..1 << k]),
                    };
                    assert!(
                        stratified,
                        "seed {seed}, pixel {pixel:?}, slot {slot}: first 2^{k} passes not stratified"
                    );
                }
            }
        }
    }
    let independent = slots(SamplerKind::Independent, 0, (5, 9), 256);
    assert!(
        independent.iter().all(|draws| !slot_stratified(draws)),
        "independent numbers passed as stratified"
    );
}

/// A 2D slot's draws as points.
fn points(draws: &[Draw]) -> Vec<Vec<f32>> {
    draws
        .iter()
        .map(|d| match d {
            Draw::One(v) => vec![*v, *v],
            Draw::Two(p) => p.to_array().to_vec(),
        })
        .collect()
}

/// The camera's jitter and the first vertex's light direction together: over the first `2^k`
/// passes of a pixel, a (3, k, 4)-net (the first four Sobol' dimensions, each scrambled on its
/// own), so that where the light's visibility changes across a pixel its position and its
/// light direction are stratified together. Negative case: the camera with the second
/// vertex's light direction (scrambled as its own dimension) is not a (3, k, 4)-net, though
/// each of the two is a net on its own.
#[test]
fn the_camera_and_the_first_light_direction_form_one_net() {
    let joined = |all: &[Vec<Draw>], slot: usize, n: usize| -> Vec<Vec<f32>> {
        points(&all[0][..n])
            .into_iter()
            .zip(points(&all[slot][..n]))
            .map(|(a, b)| [a, b].concat())
            .collect()
    };
    for seed in [0u64, 7] {
        for pixel in [(0, 0), (5, 9), (300, 200)] {
            let all = slots(SamplerKind::Sobol, seed, pixel, 256);
            for k in 0..=8 {
                assert!(
                    net(&joined(&all, JOINT_SLOT, 1 << k), 3),
                    "seed {seed}, pixel {pixel:?}: the first 2^{k} passes are no 4D net"
                );
            }
            // Slot 8: the second vertex's light direction.
            assert!(
                !net(&joined(&all, 8, 256), 3),
                "seed {seed}, pixel {pixel:?}: an independently scrambled draw formed a net"
            );
        }
    }
}

/// Within one pass, across pixels, each draw is uniform and draws are uncorrelated with each
/// other (each is scrambled as a dimension of its own), and pixels do not repeat one pattern.
/// Tolerances: a chi-square over 16 bins at 1e-3 (critical value 37.7 for 15 degrees of
/// freedom), and correlations within 4 standard errors (1/√n for uncorrelated pairs).
/// Negative cases: the same statistics flag a dimension that collides with another in one pixel
/// of eight, and a slot drawn slightly off uniform.
#[test]
fn sobol_draws_are_uniform_and_uncorrelated_across_pixels() {
    let (w, h) = (64u32, 64u32);
    let samplers = SamplerKind::Sobol.pass(11, 3);
    let firsts: Vec<Vec<f32>> = (0..w * h)
        .map(|i| {
            let mut s = samplers.start(i % w, i / w, w);
            let camera = s.uniform2();
            let mut v = vec![camera.x, camera.y];
            v.extend((0..6).map(|_| s.uniform()));
            v
        })
        .collect();
    let n = firsts.len() as f64;
    let chi_square = |values: &[f32]| {
        let mut bins = [0.0f64; 16];
        values
            .iter()
            .for_each(|&v| bins[((v * 16.0) as usize).min(15)] += 1.0);
        let e = values.len() as f64 / 16.0;
        bins.iter().map(|b| (b - e) * (b - e) / e).sum::<f64>()
    };
    let correlation = |a: &[f32], b: &[f32]| {
        let m = |v: &[f32]| v.iter().map(|&x| x as f64).sum::<f64>() / v.len() as f64;
        let (ma, mb) = (m(a), m(b));
        let cov: f64 = a
            .iter()
            .zip(b)
            .map(|(&x, &y)| (x as f64 - ma) * (y as f64 - mb))
            .sum::<f64>();
        let va: f64 = a.iter().map(|&x| (x as f64 - ma).powi(2)).sum();
        let vb: f64 = b.iter().map(|&y| (y as f64 - mb).powi(2)).sum();
        cov / (va * vb).sqrt()
    };
    let slot = |k: usize| firsts.iter().map(|v| v[k]).collect::<Vec<f32>>();
    for k in 0..8 {
        let c = chi_square(&slot(k));
        assert!(c < 37.7, "slot {k}: chi-square {c}");
        for j in 0..k {
            let r = correlation(&slot(k), &slot(j));
            assert!(
                r.abs() < 4.0 / n.sqrt(),
                "slots {j} and {k}: correlation {r}"
            );
        }
    }
    // Negative cases of the failures the test exists for. A dimension that collides with
    // another in one pixel of eight (slot 5 reusing slot 2's number there): a correlation of
    // about 1/8, twice the tolerance, is flagged.
    let (two, five) = (slot(2), slot(5));
    let collided: Vec<f32> = five
        .iter()
        .zip(&two)
        .enumerate()
        .map(|(i, (&f, &t))| if i % 8 == 0 { t } else { f })
        .collect();
    assert!(correlation(&two, &collided).abs() > 4.0 / n.sqrt());
    // A slot drawn slightly off uniform (`u^1.1`, its lowest sixteenth 8% instead of 6.25%
    // likely) fails the chi-square.
    let warped: Vec<f32> = two.iter().map(|&x| x.powf(1.1)).collect();
    assert!(chi_square(&warped) > 37.7);
}

/// Per-block means of an image `(mean, standard error)`, luminance, `b × b` blocks.
fn blocks(mean: &[Vec3], se2: &[f64], width: u32, height: u32, b: u32) -> Vec<(f64, f64)> {
    let lum = |c: Vec3| (c.x + c.y + c.z) as f64 / 3.0;
    let mut out = vec![];
    for by in 0..height / b {
        for bx in 0..width / b {
            let (mut m, mut v, mut n) = (0.0, 0.0, 0.0);
            for y in by * b..(by + 1) * b {
                for x in bx * b..(bx + 1) * b {
                    let i = (y * width + x) as usize;
                    m += lum(mean[i]);
                    v += se2[i];
                    n += 1.0;
                }
            }
            out.push((m / n, v.sqrt() / n));
        }
    }
    out
}

fn render_film(scene: &Scene, sampler: SamplerKind, seed: u64, spp: u32) -> Film {
    let integrator = Integrator::new(
        scene,
        RenderSettings {
            strategy: Strategy::Antishadow,
            alpha: None,
            max_depth: 1,
            seed,
            sampler,
            ..RenderSettings::default()
        },
    );
    render(&integrator, 48, 36, spp).0
}

/// Whether block differences `(difference, standard error)` look like noise: no block
/// beyond 5 standard errors, and the scale statistic `T = Σ z_i w_i / |w|` with `w_i = m_i /
/// se_i` (the most powerful test of a global scale error) within 4.
fn agree(diffs: &[(f64, f64, f64)]) -> bool {
    let z: Vec<f64> = diffs.iter().map(|d| d.0 / d.1).collect();
    let w: Vec<f64> = diffs.iter().map(|d| d.2 / d.1).collect();
    let norm = w.iter().map(|v| v * v).sum::<f64>().sqrt();
    let t = z.iter().zip(&w).map(|(a, b)| a * b).sum::<f64>() / norm;
    z.iter().all(|v| v.abs() < 5.0) && t.abs() <= 4.0
}

/// A Sobol'-sampled image is unbiased: the mean of 24 renders from independent seeds (32 spp
/// each) agrees with an independent-sampled render of 768 spp, per 6×6 block, on fig8c
/// (antipenumbra: projection sampling) and the lampshade (two portals). Sobol' samples are not
/// independent, so their standard error comes from the spread of the 24 replicates (which are
/// independent), not from the per-pixel sample variance; the independent render's from its
/// per-pixel sample variance. Negative case: the Sobol' mean scaled by 1.03 fails.
#[test]
fn sobol_images_agree_with_independent_sampling() {
    const REPLICATES: u64 = 24;
    for name in ["fig8c", "lampshade"] {
        let scene = Scene::open(name).unwrap();
        let (w, h) = (48, 36);
        let reference = render_film(&scene, SamplerKind::Independent, 1, 768);
        let ref_se2: Vec<f64> = reference
            .variance_of_mean()
            .iter()
            .map(|v| ((v.x + v.y + v.z) / 3.0) as f64)
            .collect();
        // Replicate block means (the variance of a luminance mean is not the mean of the
        // channel variances, so blocks are formed per replicate).
        let reps: Vec<Vec<(f64, f64)>> = (0..REPLICATES)
            .map(|r| {
                let film = render_film(&scene, SamplerKind::Sobol, 100 + r, 32);
                blocks(&film.mean(), &vec![0.0; film.pixel_count()], w, h, 6)
            })
            .collect();
        let ref_blocks = blocks(&reference.mean(), &ref_se2, w, h, 6);
        let brightest = ref_blocks.iter().map(|b| b.0).fold(0.0, f64::max);
        let diffs = |scale: f64| -> Vec<(f64, f64, f64)> {
            (0..ref_blocks.len())
                .filter_map(|b| {
                    let values: Vec<f64> = reps.iter().map(|r| scale * r[b].0).collect();
                    let n = values.len() as f64;
                    let mean = values.iter().sum::<f64>() / n;
                    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
                    let (rm, rse) = ref_blocks[b];
                    let se = (var / n + rse * rse).sqrt();
                    (se > 0.0 && rm > 1e-3 * brightest).then_some((mean - rm, se, rm))
                })
                .collect()
        };
        let d = diffs(1.0);
        assert!(d.len() > 10, "{name}: too few lit blocks");
        assert!(agree(&d), "{name}: (difference, se, mean) = {d:?}");
        assert!(!agree(&diffs(1.03)), "{name}: a 3% error went undetected");
    }
}
