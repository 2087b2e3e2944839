//! The BSDF's energy, its sampling against its pdf, and the extensions' Fresnel.

use super::*;
use crate::sampling::Rng;

/// F90 is continuous as F0 goes to 0: a specular-colour texel of 1/255 (sRGB) shades as one
/// of 0 to within 2% of the layer's weight, and glass's F0 keeps F90 = specularFactor.
#[test]
fn f90_fades_continuously_with_f0() {
    let params = |c: f32| MaterialParams {
        specular_color: Vec3::splat(c),
        specular_factor: 0.8,
        ..MaterialParams::from_desc(&MaterialDesc::diffuse("t", Vec3::splat(0.5)))
    };
    let f90 = |c: f32| Material::without_lobes(&params(c)).f90;
    let one_level = crate::asset::texture::srgb_to_linear(1.0 / 255.0);
    assert_eq!(f90(0.0), 0.0);
    assert!(f90(one_level) < 0.02 * 0.8, "{}", f90(one_level));
    assert!((f90(1.0) - 0.8).abs() < 1e-7);
    // Monotone and without jumps down to 0.
    let mut last = f90(1.0);
    for k in 1..500 {
        let c = 0.98f32.powi(k);
        let f = f90(c);
        assert!(f <= last && last - f < 0.05 * 0.8, "{c}: {f} after {last}");
        last = f;
    }
}

fn desc(metallic: f32, roughness: f32, base: Vec3) -> MaterialDesc {
    MaterialDesc {
        metallic,
        roughness,
        ..MaterialDesc::diffuse("t", base)
    }
}

/// Blender 3.4's export of a Principled BSDF with *Specular* 0 (a Lambertian base) and
/// *Clearcoat* `clearcoat` of roughness `roughness`.
fn coated(clearcoat: f32, roughness: f32, base: Vec3) -> MaterialDesc {
    MaterialDesc {
        clearcoat,
        clearcoat_roughness: roughness,
        ..blender_specular_zero(base)
    }
}

/// Blender 3.4's export of Principled *Specular* 0: `specularColorFactor` [0, 0, 0], no
/// `specularFactor` (so 1), and the Principled IOR.
fn blender_specular_zero(base: Vec3) -> MaterialDesc {
    MaterialDesc {
        specular_color: Vec3::ZERO,
        ior: 1.45,
        ..desc(0.0, 0.5, base)
    }
}

fn random_pair(rng: &mut Rng) -> (Vec3, Vec3) {
    let wo = sample_cosine_hemisphere(rng.uniform2());
    let wi = sample_cosine_hemisphere(rng.uniform2());
    (wo, wi)
}

#[test]
fn sample_pdf_matches_eval_pdf() {
    let mut rng = Rng::new(1, 2);
    let mut configurations: Vec<MaterialDesc> = [(0.0, 1.0), (0.0, 0.2), (1.0, 0.3), (0.5, 0.05)]
        .iter()
        .map(|&(m, r)| desc(m, r, Vec3::splat(0.7)))
        .collect();
    configurations.extend([
        blender_specular_zero(Vec3::splat(0.7)),
        MaterialDesc {
            specular_factor: 0.3,
            specular_color: Vec3::new(2.0, 0.5, 0.0),
            ior: 1.2,
            ..desc(0.2, 0.4, Vec3::new(0.9, 0.1, 0.3))
        },
        MaterialDesc {
            ior: 0.0,
            ..desc(0.0, 0.1, Vec3::ZERO)
        },
        MaterialDesc {
            roughness: 0.4,
            transmission: 0.8,
            base_color: Vec3::new(0.9, 0.7, 0.5),
            ..MaterialDesc::clear_glass("frosted")
        },
        MaterialDesc {
            roughness: 0.2,
            transmission: 1.0,
            ior: 1.0,
            ..MaterialDesc::clear_glass("frosted without a layer")
        },
        coated(0.6, 0.3, Vec3::new(0.5, 0.1, 0.1)),
        coated(1.0, 0.05, Vec3::ZERO),
    ]);
    for d in &configurations {
        let mat = Material::from_desc(d);
        let mut drawn = 0;
        for _ in 0..1000 {
            let wo = sample_cosine_hemisphere(rng.uniform2());
            if let Some(s) = mat.sample(wo, rng.uniform(), rng.uniform2()) {
                drawn += 1;
                let p = mat.eval_pdf(wo, s.wi).1;
                assert!((p - s.pdf).abs() <= 1e-4 * p.max(1.0), "{p} vs {}", s.pdf);
                assert!(s.f.is_finite() && s.pdf.is_finite());
                assert_eq!(s.f, mat.eval_pdf(wo, s.wi).0);
            }
        }
        assert!(drawn > 900, "{d:?}: only {drawn} samples");
    }
}

/// `∫ f(wi) dωi` over the upper hemisphere by a midpoint rule on an `n` × `n` grid in
/// (cos θi, φ).
fn over_hemisphere(n: usize, mut f: impl FnMut(Vec3) -> f64) -> f64 {
    let mut total = 0.0f64;
    for i in 0..n {
        let cos_i = (i as f32 + 0.5) / n as f32;
        let sin_i = (1.0 - cos_i * cos_i).sqrt();
        for j in 0..n {
            let phi = 2.0 * PI * (j as f32 + 0.5) / n as f32;
            total += f(Vec3::new(sin_i * phi.cos(), sin_i * phi.sin(), cos_i));
        }
    }
    total * 2.0 * PI as f64 / (n * n) as f64
}

/// The pdf is a density: its integral over the hemisphere, by a midpoint rule in
/// (cos θi, φ), is 1 less what visible-normal sampling sends below the horizon, and that
/// is measured by drawing: the share of 200 000 draws that succeed, within 4 of its
/// binomial standard errors plus the rule's error (2e-3). (It only had to be above 0.8.)
#[test]
fn pdf_integrates_to_at_most_one() {
    let n = 400;
    let mut rng = Rng::new(40, 13);
    for d in [
        desc(0.0, 1.0, Vec3::splat(0.5)),
        desc(0.0, 0.6, Vec3::splat(0.5)),
        desc(1.0, 0.7, Vec3::splat(0.5)),
        coated(1.0, 0.6, Vec3::ZERO),
    ] {
        let mat = Material::from_desc(&d);
        for cos_o in [1.0f32, 0.5, 0.1] {
            let wo = Vec3::new((1.0 - cos_o * cos_o).sqrt(), 0.0, cos_o);
            let total = over_hemisphere(n, |wi| mat.eval_pdf(wo, wi).1 as f64);
            let draws = 200_000;
            let drawn = (0..draws)
                .filter(|_| {
                    mat.sample_direction(wo, rng.uniform(), rng.uniform2())
                        .is_some()
                })
                .count() as f64
                / draws as f64;
            let se = (drawn * (1.0 - drawn) / draws as f64).sqrt();
            assert!(
                total <= 1.0 + 2e-3 && (total - drawn).abs() <= 4.0 * se + 2e-3,
                "{d:?} cos {cos_o}: {total} against {drawn} ± {se}"
            );
        }
    }
}

/// Rough glass's pdf is a density over the whole sphere: reflection above, transmission
/// below, integrated by a midpoint rule in (cos θi, φ) over each hemisphere, is the share of
/// draws that land there (the draws that visible-normal sampling sends past the horizon are
/// lost), within 4 binomial standard errors of 200 000 draws plus the rule's error (2e-3);
/// and the share below is at most the transmission's probability. (They only had to be above
/// 0.8 of it.)
#[test]
fn rough_glass_pdf_integrates_over_the_sphere() {
    let n = 400;
    let mut rng = Rng::new(41, 14);
    for roughness in [0.3f32, 0.7] {
        let glass = Material::from_desc(&MaterialDesc {
            roughness,
            ..MaterialDesc::clear_glass("frosted")
        });
        for cos_o in [1.0f32, 0.5, 0.1] {
            let wo = Vec3::new((1.0 - cos_o * cos_o).sqrt(), 0.0, cos_o);
            let above = over_hemisphere(n, |wi| glass.eval_pdf(wo, wi).1 as f64);
            let mirror = Vec3::new(1.0, 1.0, -1.0);
            let below = over_hemisphere(n, |wi| glass.eval_pdf(wo, wi * mirror).1 as f64);
            let (_, p_spec, p_trans) = glass.lobe_weights(cos_o);
            let draws = 200_000;
            let (mut up, mut down) = (0usize, 0usize);
            for _ in 0..draws {
                match glass.sample_direction(wo, rng.uniform(), rng.uniform2()) {
                    Some(wi) if wi.z > 0.0 => up += 1,
                    Some(wi) if wi.z < 0.0 => down += 1,
                    _ => {}
                }
            }
            for (what, integral, count) in [("above", above, up), ("below", below, down)] {
                let share = count as f64 / draws as f64;
                let se = (share * (1.0 - share) / draws as f64).sqrt();
                assert!(
                    (integral - share).abs() <= 4.0 * se + 2e-3,
                    "r {roughness} cos {cos_o} {what}: {integral} against {share} ± {se}"
                );
            }
            assert!(
                above + below <= 1.0 + 2e-3 && below <= p_trans as f64 + 2e-3,
                "r {roughness} cos {cos_o}: {above} + {below} vs {p_trans} ({p_spec})"
            );
        }
    }
}

/// Blender's Specular 0, a zero specular factor and ior = 1 all leave exactly Lambert: the
/// same value and pdf, bit for bit, at every pair of directions (grazing ones included).
#[test]
fn no_specular_layer_is_exactly_lambert() {
    let base = Vec3::new(0.8, 0.5, 0.2);
    let lambert = Material::lambertian(base);
    let mut rng = Rng::new(4, 4);
    for d in [
        blender_specular_zero(base),
        MaterialDesc {
            specular_factor: 0.0,
            ..desc(0.0, 0.2, base)
        },
        MaterialDesc {
            ior: 1.0,
            ..desc(0.0, 0.2, base)
        },
    ] {
        let mat = Material::from_desc(&d);
        assert_eq!((mat.f0, mat.f90), (Vec3::ZERO, 0.0), "{d:?}");
        for _ in 0..1000 {
            let (wo, wi) = random_pair(&mut rng);
            assert_eq!(mat.eval_pdf(wo, wi), lambert.eval_pdf(wo, wi));
        }
        let grazing = Vec3::new(0.9999, 0.0, 0.0141).normalize();
        assert_eq!(
            mat.eval_pdf(grazing, grazing * Vec3::new(-1.0, 1.0, 1.0)),
            lambert.eval_pdf(grazing, grazing * Vec3::new(-1.0, 1.0, 1.0))
        );
    }
    // A nonzero F0 in any channel keeps the layer, with the spec's F90 = specularFactor.
    let red = Material::from_desc(&MaterialDesc {
        specular_color: Vec3::new(1.0, 0.0, 0.0),
        specular_factor: 0.5,
        ..desc(0.0, 0.2, base)
    });
    assert_eq!(red.f90, 0.5);
    assert!((red.f0 - Vec3::new(0.02, 0.0, 0.0)).abs().max_element() < 1e-7);
}

#[test]
fn f0_follows_the_extension_texts() {
    let m = |specular_factor, specular_color, ior| {
        Material::from_desc(&MaterialDesc {
            specular_factor,
            specular_color,
            ior,
            ..desc(0.0, 0.5, Vec3::ONE)
        })
    };
    // glTF's default: 0.04 from ior 1.5.
    assert!(
        (m(1.0, Vec3::ONE, 1.5).f0 - Vec3::splat(0.04))
            .abs()
            .max_element()
            < 1e-7
    );
    // ior 0 is the "infinite" IOR: F0 = 1; the colour is clamped to 1 before the factor.
    assert_eq!(m(0.5, Vec3::splat(3.0), 0.0).f0, Vec3::splat(0.5));
    // Blender 3.4 exports Specular s as specularColorFactor 0.08·s / F0(ior).
    let s = 0.7;
    let color = Vec3::splat(0.08 * s / f0_from_ior(1.45));
    assert!(
        (m(1.0, color, 1.45).f0 - Vec3::splat(0.08 * s))
            .abs()
            .max_element()
            < 1e-6
    );
}

/// `(A, B)` by an independent quadrature: a midpoint rule over (cos θi, φ) of
/// `F·D·G2/(4 cos θo)` with the textbook GGX written out here in f64.
fn albedo_by_quadrature(cos_o: f64, alpha: f64, n: usize) -> (f64, f64) {
    let a2 = alpha * alpha;
    let lambda = |c: f64| {
        let tan2 = (1.0 - c * c).max(0.0) / (c * c);
        0.5 * ((1.0 + a2 * tan2).sqrt() - 1.0)
    };
    let wo = [(1.0 - cos_o * cos_o).sqrt(), 0.0, cos_o];
    let (mut a, mut b) = (0.0, 0.0);
    for i in 0..n {
        let cos_i = (i as f64 + 0.5) / n as f64;
        let sin_i = (1.0 - cos_i * cos_i).sqrt();
        for j in 0..n {
            // Symmetric in φ: integrate over [0, π] and double.
            let phi = std::f64::consts::PI * (j as f64 + 0.5) / n as f64;
            let wi = [sin_i * phi.cos(), sin_i * phi.sin(), cos_i];
            let h = [wo[0] + wi[0], wo[1] + wi[1], wo[2] + wi[2]];
            let len = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
            let (cos_h, wo_h) = (h[2] / len, (wo[0] * h[0] + wo[2] * h[2]) / len);
            let t = cos_h * cos_h * (a2 - 1.0) + 1.0;
            let d = a2 / (std::f64::consts::PI * t * t);
            let g2 = 1.0 / (1.0 + lambda(cos_o) + lambda(cos_i));
            // f·cos θi with the cosines cancelled: D·G2 / (4 cos θo).
            let f_cos = d * g2 / (4.0 * cos_o);
            let c5 = (1.0 - wo_h).powi(5);
            a += f_cos * (1.0 - c5);
            b += f_cos * c5;
        }
    }
    let cell = 2.0 * std::f64::consts::PI / (n * n) as f64;
    (a * cell, b * cell)
}

/// The largest difference allowed between the albedo table and the independent quadrature
/// (measured: under 8e-4, from interpolating between the table's rows of roughness).
const ALBEDO_TABLE_TOLERANCE: f64 = 1.5e-3;

#[test]
fn albedo_table_matches_an_independent_quadrature() {
    let mut worst = 0.0f64;
    for &roughness in &[0.3f32, 0.5, 0.77, 1.0] {
        for &cos_o in &[0.05f32, 0.1, 0.3, 0.55, 0.8, 1.0] {
            let alpha = roughness * roughness;
            let (a, b) = ggx_albedo(cos_o, alpha);
            let (qa, qb) = albedo_by_quadrature(cos_o as f64, alpha as f64, 600);
            let error = (a as f64 - qa).abs().max((b as f64 - qb).abs());
            worst = worst.max(error);
            // The round-up covers the table's error for F = 1 and for glTF's default.
            for (f0, f90) in [(1.0, 1.0), (0.04, 1.0)] {
                let table = (f0 * a + f90 * b) as f64;
                let truth = f0 as f64 * qa + f90 as f64 * qb;
                assert!(
                    table * ALBEDO_ROUND_UP as f64 >= truth,
                    "r {roughness} cos {cos_o} F0 {f0}: {table} below {truth}"
                );
            }
            assert!(
                error <= ALBEDO_TABLE_TOLERANCE,
                "r {roughness} cos {cos_o}: table ({a}, {b}), quadrature ({qa}, {qb})"
            );
        }
    }
    eprintln!("albedo table: worst difference {worst:.2e}");
    // Where the lobe is too sharp for that quadrature, single scattering still loses
    // energy: A + B (the albedo with F = 1) never exceeds 1.
    for j in 0..=40 {
        for i in 0..=40 {
            let (a, b) = ggx_albedo(i as f32 / 40.0, (j as f32 / 40.0).powi(2));
            assert!(
                a + b <= 1.0 + 1e-4 && a >= 0.0 && b >= 0.0,
                "{i} {j}: {a} + {b}"
            );
        }
    }
}

/// A white furnace for thin glass: white, fully transmitting glass scatters its sampled
/// albedo (reflection, and for rough glass its transmission lobe) and passes
/// `straight_through` straight on (smooth glass), which add up to 1 at every angle, IOR and
/// roughness, less only what the albedo table's round-up gives the reflection beyond its
/// true energy. Tolerance: 4 standard errors of the sampled albedo, plus that round-up
/// (0.3% of E) and the table's error, on E and on the transmission lobe's normalisation
/// (relative to its albedo `A + B`). The negative case: a transmittance that ignored
/// Fresnel's rise towards grazing (`1 − F0`) would exceed 1 there.
#[test]
fn thin_glass_reflects_and_transmits_exactly_what_it_receives() {
    let mut rng = Rng::new(38, 1);
    for ior in [1.2f32, 1.5, 2.4] {
        for roughness in [0.0f32, 0.3, 0.7] {
            let glass = Material::from_desc(&MaterialDesc {
                ior,
                roughness,
                ..MaterialDesc::clear_glass("glass")
            });
            assert!(!glass.is_black());
            for cos_o in [1.0f32, 0.7, 0.3, 0.08] {
                let wo = Vec3::new((1.0 - cos_o * cos_o).sqrt(), 0.0, cos_o);
                let (reflected, se) = albedo(&glass, wo, &mut rng, 20_000);
                let transmitted = glass.straight_through(cos_o);
                assert_eq!(transmitted.x, transmitted.z, "white glass stays white");
                let total = reflected + transmitted.x as f64;
                let e = glass.specular_albedo(cos_o) as f64;
                let (a, b) = ggx_albedo(cos_o, glass.alpha);
                let tolerance = 4.0 * se
                    + e * (ALBEDO_ROUND_UP as f64 - 1.0)
                    + ALBEDO_TABLE_TOLERANCE * (1.0 + 1.0 / (a + b) as f64);
                // Smooth glass passes straight through; rough glass scatters through.
                assert_eq!(roughness == 0.0, glass.transmits());
                assert_eq!(roughness > 0.0, glass.transmits_rough());
                assert!(
                    (total - 1.0).abs() <= tolerance,
                    "ior {ior} r {roughness} cos {cos_o}: {reflected} + {transmitted} = {total}"
                );
                if cos_o < 0.1 && roughness == 0.0 {
                    let without_fresnel = reflected + (1.0 - glass.f0.x as f64);
                    assert!(
                        without_fresnel - 1.0 > 10.0 * tolerance,
                        "{without_fresnel}"
                    );
                }
            }
        }
    }
    // Transmission takes its share from the diffuse only: a smooth half-transmitting sheet
    // without a specular layer keeps half its Lambertian albedo, and passes the other half
    // straight through.
    let paint = Material::from_desc(&MaterialDesc {
        transmission: 0.5,
        specular_factor: 0.0,
        roughness: 0.0,
        ..MaterialDesc::diffuse("sheet", Vec3::splat(0.8))
    });
    let (f, _) = paint.eval_pdf(Vec3::Z, Vec3::Z);
    assert!((f.x - 0.4 * FRAC_1_PI).abs() < 1e-6);
    assert!((paint.straight_through(1.0).x - 0.4).abs() < 1e-6);
    // An opaque material passes nothing.
    assert_eq!(
        Material::from_desc(&desc(0.0, 0.5, Vec3::ONE)).straight_through(0.5),
        Vec3::ZERO
    );
}

fn mean_and_se(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

/// Albedo `∫ f cos dωi` (red channel) estimated by sampling the BSDF, with its standard
/// error.
fn albedo(mat: &Material, wo: Vec3, rng: &mut Rng, n: usize) -> (f64, f64) {
    let values: Vec<f64> = (0..n)
        .map(|_| match mat.sample(wo, rng.uniform(), rng.uniform2()) {
            Some(s) => (s.f.x * s.wi.z.abs() / s.pdf) as f64,
            None => 0.0,
        })
        .collect();
    mean_and_se(&values)
}

/// glTF's default layer (F0 = 0.04, F90 = 1) against Blender's Specular 0 on a grey base
/// ρ: the albedos differ by the layer's energy less what the diffuse gave up,
/// `(1 − ρ)·E(wo)`, where `E = 0.04·A + B` comes from the independent quadrature above.
/// Tolerance: 4 standard errors of the sampled difference plus what the diffuse gives up
/// beyond the true E (the table's error and its round-up, times ρ·(F0 + F90)).
#[test]
fn default_specular_differs_from_specular_zero_by_the_fresnel_energy() {
    let rho = 0.5f32;
    let mut rng = Rng::new(21, 8);
    for roughness in [0.5f32, 1.0] {
        let default = Material::from_desc(&desc(0.0, roughness, Vec3::splat(rho)));
        let zero = Material::from_desc(&MaterialDesc {
            roughness,
            ..blender_specular_zero(Vec3::splat(rho))
        });
        // Normal incidence, and grazing (84°).
        for cos_o in [1.0f32, 0.1] {
            let wo = Vec3::new((1.0 - cos_o * cos_o).sqrt(), 0.0, cos_o);
            let (with_layer, se) = albedo(&default, wo, &mut rng, 400_000);
            let (without, se_zero) = albedo(&zero, wo, &mut rng, 1000);
            // Lambert sampled by its own cosine: every sample is exactly ρ.
            assert_eq!((without, se_zero), (rho as f64, 0.0));
            let (a, b) = albedo_by_quadrature(cos_o as f64, (roughness * roughness) as f64, 600);
            let energy = 0.04 * a + b;
            let expected = (1.0 - rho as f64) * energy;
            let measured = with_layer - without;
            let table_error = ALBEDO_TABLE_TOLERANCE + (ALBEDO_ROUND_UP as f64 - 1.0);
            let tolerance = 4.0 * se + rho as f64 * 1.04 * table_error;
            assert!(
                (measured - expected).abs() <= tolerance,
                "r {roughness} cos {cos_o}: {measured} vs {expected} ± {tolerance}"
            );
            // The negative case: at grazing incidence the Fresnel energy is far from
            // F0's, so a layer without Schlick's rise (E = 0.04·(A + B)) would fail.
            if cos_o < 0.5 {
                let without_fresnel = (1.0 - rho as f64) * 0.04 * (a + b);
                assert!((measured - without_fresnel).abs() > 3.0 * tolerance);
            }
        }
    }
}

/// The 0.999 quantile of χ² with `dof` degrees of freedom (Wilson–Hilferty).
fn chi_square_critical(dof: usize) -> f64 {
    let k = dof as f64;
    k * (1.0 - 2.0 / (9.0 * k) + 3.090 * (2.0 / (9.0 * k)).sqrt()).powi(3)
}

/// Pearson's χ² of `n` directions drawn by `draw` against the density `pdf` over the
/// sphere, in 24 bins of `cos θ` by 32 of `φ` (each integrated by a 64 × 64 midpoint
/// rule); bins expecting fewer than 5 draws are pooled, as is the mass of failed draws.
/// The statistic and the 0.999 critical value for its degrees of freedom.
fn chi_square(
    pdf: impl Fn(Vec3) -> f32,
    mut draw: impl FnMut() -> Option<Vec3>,
    n: usize,
) -> (f64, f64) {
    const NT: usize = 24;
    const NP: usize = 32;
    // Fine enough for the rough transmission's steep rise near the horizon, where 12 × 12
    // overestimated the integral by 3% at grazing incidence.
    const SUB: usize = 64;
    let bin = |w: Vec3| {
        let t = (((w.z + 1.0) * 0.5 * NT as f32) as usize).min(NT - 1);
        let phi = w.y.atan2(w.x).rem_euclid(std::f32::consts::TAU);
        let p = ((phi / std::f32::consts::TAU * NP as f32) as usize).min(NP - 1);
        t * NP + p
    };
    let mut observed = vec![0f64; NT * NP + 1];
    for _ in 0..n {
        match draw() {
            Some(w) => observed[bin(w)] += 1.0,
            None => observed[NT * NP] += 1.0,
        }
    }
    let mut expected = vec![0f64; NT * NP + 1];
    let cell = (2.0 / NT as f64) * (std::f64::consts::TAU / NP as f64) / (SUB * SUB) as f64;
    for t in 0..NT {
        for p in 0..NP {
            let mut sum = 0.0;
            for k in 0..SUB * SUB {
                let z = -1.0 + 2.0 * (t as f64 + ((k % SUB) as f64 + 0.5) / SUB as f64) / NT as f64;
                let phi = std::f64::consts::TAU
                    * (p as f64 + ((k / SUB) as f64 + 0.5) / SUB as f64)
                    / NP as f64;
                let r = (1.0 - z * z).max(0.0).sqrt();
                let w = Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
                sum += pdf(w) as f64 * cell;
            }
            expected[t * NP + p] = sum * n as f64;
        }
    }
    let drawn: f64 = expected[..NT * NP].iter().sum();
    expected[NT * NP] = (n as f64 - drawn).max(0.0);
    let (mut statistic, mut dof) = (0.0, 0usize);
    let (mut pooled_o, mut pooled_e) = (0.0, 0.0);
    for (o, e) in observed.iter().zip(&expected) {
        if *e < 5.0 {
            pooled_o += o;
            pooled_e += e;
        } else {
            statistic += (o - e) * (o - e) / e;
            dof += 1;
        }
    }
    if pooled_e > 0.0 {
        statistic += (pooled_o - pooled_e) * (pooled_o - pooled_e) / pooled_e.max(5.0);
        dof += 1;
    }
    (statistic, chi_square_critical(dof.saturating_sub(1).max(1)))
}

/// A direction `θo` from the normal.
fn at(cos_o: f32) -> Vec3 {
    Vec3::new((1.0 - cos_o * cos_o).sqrt(), 0.0, cos_o)
}

/// The sampling density is the evaluated pdf (issue 40: comparing `sample`'s pdf with
/// `eval_pdf` was circular, as `sample` returns `eval_pdf`): a χ² of drawn directions
/// against `eval_pdf` over the sphere, for the layered material (diffuse and GGX, metal,
/// rough thin transmission) and the rough dielectric (entering and leaving), at several
/// roughnesses and incidences. 200 000 draws each, at the 0.999 quantile: with about 40
/// tests, a chance failure has odds of about 1 in 25. The negative cases: the same draws
/// against the pdf of a wrong roughness (10% off) or a wrong IOR, which the test rejects.
#[test]
fn sampled_directions_follow_the_evaluated_pdf() {
    let mut rng = Rng::new(40, 11);
    let mut layered: Vec<MaterialDesc> = [(0.0, 0.4), (1.0, 0.5), (0.5, 0.3)]
        .iter()
        .map(|&(m, r)| desc(m, r, Vec3::splat(0.7)))
        .collect();
    layered.push(MaterialDesc {
        roughness: 0.5,
        transmission: 0.8,
        base_color: Vec3::new(0.9, 0.7, 0.5),
        ..MaterialDesc::clear_glass("frosted")
    });
    // Clear coats: over black (the coat draws nine in ten directions) and over a diffuse base.
    layered.extend([
        coated(1.0, 0.3, Vec3::ZERO),
        coated(1.0, 0.6, Vec3::ZERO),
        coated(0.5, 0.4, Vec3::splat(0.05)),
    ]);
    let mut materials: Vec<(String, Material)> = layered
        .iter()
        .map(|d| (format!("{d:?}"), Material::from_desc(d)))
        .collect();
    for roughness in [0.35f32, 0.6] {
        for (ior, inside) in [(1.5f32, false), (1.5, true), (1.33, false)] {
            let glass = thick_glass(roughness, ior);
            let name = format!("dielectric r {roughness} ior {ior} inside {inside}");
            materials.push((name, glass.dielectric(inside)));
        }
    }
    for (name, mat) in &materials {
        for cos_o in [0.9f32, 0.5, 0.15] {
            let wo = at(cos_o);
            let n = 200_000;
            let (stat, critical) = chi_square(
                |wi| mat.eval_pdf(wo, wi).1,
                || mat.sample_direction(wo, rng.uniform(), rng.uniform2()),
                n,
            );
            assert!(
                stat < critical,
                "{name} cos {cos_o}: χ² {stat} > {critical}"
            );
        }
    }
    // The negative cases: a roughness 10% off, a dielectric's IOR 1.5 for 1.33, and a coat's
    // roughness 10% off.
    let wo = at(0.5);
    for (what, mat, wrong) in [
        (
            "a roughness 10% off",
            Material::from_desc(&desc(0.0, 0.4, Vec3::splat(0.7))),
            Material::from_desc(&desc(0.0, 0.44, Vec3::splat(0.7))),
        ),
        (
            "a wrong IOR",
            thick_glass(0.35, 1.33).dielectric(false),
            thick_glass(0.35, 1.5).dielectric(false),
        ),
        (
            "a coat roughness 10% off",
            Material::from_desc(&coated(1.0, 0.3, Vec3::ZERO)),
            Material::from_desc(&coated(1.0, 0.33, Vec3::ZERO)),
        ),
    ] {
        let (stat, critical) = chi_square(
            |wi| wrong.eval_pdf(wo, wi).1,
            || mat.sample_direction(wo, rng.uniform(), rng.uniform2()),
            200_000,
        );
        assert!(stat > critical, "{what} passed: {stat} < {critical}");
    }
}

/// Cycles 3.4's clear coat closure, transcribed from `bsdf_microfacet_ggx_eval_reflect` for
/// `CLOSURE_BSDF_MICROFACET_GGX_CLEARCOAT_ID` (and `D_GTR1`, `fresnel_dielectric_cos`,
/// `interpolate_fresnel_color` with `cspec0` 0.04 at IOR 1.5, which is the exact Fresnel):
/// its `eval` over `cos θi`, so the BRDF.
fn cycles_clearcoat(wo: Vec3, wi: Vec3, clearcoat: f64, roughness: f64) -> f64 {
    let (cos_no, cos_ni) = (wo.z as f64, wi.z as f64);
    let m = (wo + wi).normalize();
    let alpha = (roughness * roughness).clamp(0.0, 1.0);
    let cos_m = m.z as f64;
    let a2 = alpha * alpha;
    let d = (a2 - 1.0) / (std::f64::consts::PI * a2.ln() * (1.0 + (a2 - 1.0) * cos_m * cos_m));
    let alpha2 = 0.0625;
    let g1 = |c: f64| 2.0 / (1.0 + (1.0 + alpha2 * (1.0 - c * c) / (c * c)).sqrt());
    let g = g1(cos_no) * g1(cos_ni);
    let fresnel = |cosi: f64, eta: f64| {
        let c = cosi.abs();
        let g = eta * eta - 1.0 + c * c;
        if g <= 0.0 {
            return 1.0;
        }
        let g = g.sqrt();
        let a = (g - c) / (g + c);
        let b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0);
        0.5 * a * a * (1.0 + b * b)
    };
    let f = 0.25 * clearcoat * fresnel(wi.dot(m) as f64, 1.5);
    let common = d * 0.25 / cos_no;
    f * g * common / cos_ni
}

/// Over a black base without a specular layer, the material is the coat alone: its BRDF is
/// Cycles 3.4's clear coat closure (transcribed above) at random directions, roughnesses and
/// weights, to 1e-4 of the larger. The coat adds to the base (as Cycles' does): over a white
/// Lambertian base the albedo is 1 plus the coat's own, which is at most a quarter of the
/// Fresnel's largest value over the lobe.
#[test]
fn the_clear_coat_is_cycles_closure() {
    let mut rng = Rng::new(7, 3);
    for _ in 0..2000 {
        let (wo, wi) = random_pair(&mut rng);
        let (clearcoat, roughness) = (rng.uniform(), 0.05 + 0.95 * rng.uniform());
        let mat = Material::from_desc(&coated(clearcoat, roughness, Vec3::ZERO));
        let ours = mat.eval_pdf(wo, wi).0;
        let cycles = cycles_clearcoat(wo, wi, clearcoat as f64, roughness as f64);
        assert!(ours.x == ours.y && ours.y == ours.z);
        assert!(
            (ours.x as f64 - cycles).abs() <= 1e-4 * cycles.max(1.0),
            "wo {wo} wi {wi} coat {clearcoat} r {roughness}: {} against Cycles' {cycles}",
            ours.x
        );
    }
    let white = Material::from_desc(&coated(1.0, 0.3, Vec3::ONE));
    let coat = Material::from_desc(&coated(1.0, 0.3, Vec3::ZERO));
    for cos_o in [1.0f32, 0.5, 0.1] {
        let wo = at(cos_o);
        let (total, se_total) = albedo(&white, wo, &mut rng, 200_000);
        let (alone, se_alone) = albedo(&coat, wo, &mut rng, 200_000);
        // Two independent estimates: 4 standard errors of their difference.
        let se = (se_total * se_total + se_alone * se_alone).sqrt();
        assert!(
            (total - 1.0 - alone).abs() < 4.0 * se && alone < 0.25,
            "cos {cos_o}: {total} ± {se_total}, the coat alone {alone} ± {se_alone}"
        );
    }
}

fn volume_desc() -> crate::asset::desc::VolumeDesc {
    crate::asset::desc::VolumeDesc {
        thickness: 0.01,
        attenuation_color: Vec3::ONE,
        attenuation_distance: f32::INFINITY,
    }
}

/// White glass of `roughness` and `ior` filling its mesh (a volume, not absorbing).
fn thick_glass(roughness: f32, ior: f32) -> Material {
    Material::from_desc(&MaterialDesc {
        roughness,
        ior,
        volume: Some(volume_desc()),
        ..MaterialDesc::clear_glass("thick")
    })
}

/// A rough dielectric boundary never creates energy: the weight `f·|cos θi|/pdf` of each
/// drawn direction, times `η²` for a refraction (radiance's compression, which conserves
/// power), is `G2/G1 ≤ 1`; they average above 0.7 (single scattering loses what bounces
/// between microfacets: a few percent outside, up to 26% inside near the critical angle
/// at roughness 0.6, as for other single-scattering GGX dielectrics). A smooth boundary conserves exactly: reflection with the exact
/// Fresnel's frequency, Snell's law, total internal reflection past the critical angle.
/// The negative case: without the `η²` the refracted power is off by half, far outside.
#[test]
fn a_dielectric_boundary_conserves_power() {
    let mut rng = Rng::new(40, 12);
    for roughness in [0.35f32, 0.6] {
        for (ior, inside) in [(1.5f32, false), (1.5, true), (2.4, false)] {
            let glass = thick_glass(roughness, ior).dielectric(inside);
            let eta = if inside { 1.0 / ior } else { ior };
            for cos_o in [0.9f32, 0.5, 0.15] {
                let wo = at(cos_o);
                let (mut power, mut without_eta) = (vec![], vec![]);
                for _ in 0..200_000 {
                    let s = glass.sample(wo, rng.uniform(), rng.uniform2());
                    let (p, q) = s.map_or((0.0, 0.0), |s| {
                        let w = (s.f.x * s.wi.z.abs() / s.pdf) as f64;
                        let scale = if s.wi.z < 0.0 { eta * eta } else { 1.0 };
                        assert!(w * scale as f64 <= 1.0 + 1e-4, "{w} {scale}");
                        (w * scale as f64, w)
                    });
                    power.push(p);
                    without_eta.push(q);
                }
                let (mean, se) = mean_and_se(&power);
                let label = format!("r {roughness} ior {ior} inside {inside} cos {cos_o}");
                assert!(
                    mean <= 1.0 + 4.0 * se && mean > 0.7,
                    "{label}: {mean} ± {se}"
                );
                // Where most of it refracts (near normal incidence), the η² matters.
                let (plain, _) = mean_and_se(&without_eta);
                if cos_o > 0.8 {
                    assert!((plain - mean).abs() > 0.2, "{label}: {plain} vs {mean}");
                }
            }
        }
    }
    // Smooth: the frequency of reflection is F, the weights 1 and 1/η², Snell's law.
    let smooth = thick_glass(0.0, 1.5);
    for inside in [false, true] {
        let glass = smooth.dielectric(inside);
        assert!(glass.is_smooth_dielectric());
        let eta = if inside { 1.0 / 1.5 } else { 1.5 };
        for cos_o in [1.0f32, 0.8, 0.5, 0.2] {
            let wo = at(cos_o);
            let f = fresnel_dielectric(cos_o, eta) as f64;
            let n = 100_000;
            let mut reflected = 0usize;
            for k in 0..n {
                let (wi, weight) = glass.sample_smooth_dielectric(wo, (k as f32 + 0.5) / n as f32);
                if wi.z > 0.0 {
                    reflected += 1;
                    assert_eq!(weight, Vec3::ONE);
                    assert!((wi - Vec3::new(-wo.x, 0.0, wo.z)).length() < 1e-6);
                } else {
                    assert!((weight.x - 1.0 / (eta * eta)).abs() < 1e-6);
                    // Snell: sin θt = sin θo / η, on the far side.
                    let sin_t = (1.0 - wi.z * wi.z).sqrt();
                    let sin_o = (1.0 - cos_o * cos_o).sqrt();
                    assert!((sin_t * eta - sin_o).abs() < 1e-5, "{sin_t} {sin_o}");
                    assert!(wi.x <= 0.0);
                }
            }
            let frequency = reflected as f64 / n as f64;
            assert!((frequency - f).abs() < 2.0 / n as f64, "{frequency} vs {f}");
            // Total internal reflection: inside, past the critical angle (41.8°).
            assert_eq!(inside && cos_o < 0.74, f == 1.0, "cos {cos_o}");
        }
    }
    // Normal incidence: ((η − 1)/(η + 1))², 0.04 for 1.5, from either side.
    assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
    assert!((fresnel_dielectric(1.0, 1.0 / 1.5) - 0.04).abs() < 1e-6);
}
