//! The environment light (`docs/method.md` §9): its sampler's pdf integrates to 1, sampled
//! pdf equals evaluated pdf, samples pass a chi-square test against the image (and a wrong
//! image is rejected), a constant environment gives irradiance π·L on an open plane through
//! the full renderer (and 1.03 × that is rejected); `.hdr` and `.exr` files load, broken ones
//! give errors naming the file; scene extras round-trip through glTF. Run in release.

mod common;

use glam::{Vec2, Vec3};
use portalview::asset::builtin;
use portalview::asset::desc::{MaterialDesc, SceneDesc};
use portalview::asset::environment::{
    EnvImage, EnvMap, EnvironmentDesc, Interpolation, hdr_bytes, load_image, map_from_text,
    with_overrides,
};
use portalview::asset::gltf;
use portalview::light::Strategy;
use portalview::light::environment::Environment;
use portalview::sampling::Rng;
use portalview::scene::Scene;
use std::f64::consts::PI;
use std::path::PathBuf;
use std::sync::Arc;

/// A small image with a bright spot, zeros and a gradient: every path of the sampler.
fn test_image() -> EnvImage {
    let (width, height) = (48u32, 24u32);
    let mut rng = Rng::new(5, 6);
    let pixels = (0..width * height)
        .map(|k| {
            let (i, j) = (k % width, k / width);
            if (i, j) == (30, 7) {
                Vec3::new(400.0, 300.0, 200.0)
            } else if j == 20 && i < 12 {
                Vec3::ZERO
            } else {
                Vec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * (1.0 + j as f32 / 8.0)
            }
        })
        .collect();
    EnvImage {
        width,
        height,
        pixels,
    }
}

fn image_env(image: EnvImage, rotation_degrees: f32) -> (EnvironmentDesc, Environment) {
    let desc = EnvironmentDesc {
        map: EnvMap::Image {
            file: None,
            image: Arc::new(image),
        },
        strength: 2.0,
        rotation_degrees,
        interpolation: Interpolation::Closest,
    };
    let env = Environment::new(&desc, 1.0);
    (desc, env)
}

fn uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (s, c) = (std::f32::consts::TAU * u.y).sin_cos();
    Vec3::new(r * c, z, r * s)
}

/// `∫ pdf dω` by uniform directions on the sphere, stratified (one jittered direction per cell
/// of a 2000 × 2000 grid over the sphere's equal-area parameters): 1 within 4 standard errors of
/// the mean, for the test image (turned by 37°), the built-in sky and a constant. The standard
/// error of a stratified mean comes from neighbouring cells taken in pairs, `Σ (a − b)² / 2`
/// over the pairs, over `n²` (conservative: it also counts the pdf's change between the two
/// cells). It must be below 0.005, so that a pdf 3% off (the negative case, 1.03 × the
/// integral) is rejected.
#[test]
fn environment_pdf_integrates_to_one() {
    let envs = [
        image_env(test_image(), 37.0).1,
        image_env(builtin::sky_image(), 0.0).1,
        Environment::new(&EnvironmentDesc::constant(Vec3::ONE), 1.0),
    ];
    const N: usize = 2000;
    for (k, env) in envs.iter().enumerate() {
        let mut rng = Rng::new(11, k as u64);
        let mut values = Vec::with_capacity(N * N);
        for i in 0..N {
            for j in 0..N {
                let u = Vec2::new(
                    (i as f32 + rng.uniform()) / N as f32,
                    (j as f32 + rng.uniform()) / N as f32,
                );
                values.push(4.0 * PI * f64::from(env.pdf(uniform_sphere(u))));
            }
        }
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let pairs: f64 = values.chunks(2).map(|p| (p[0] - p[1]).powi(2) / 2.0).sum();
        let se = pairs.sqrt() / n;
        // The constant's pdf is exact, so only f32 rounding is left.
        assert!(
            (mean - 1.0).abs() <= 4.0 * se + 1e-6,
            "env {k}: ∫pdf = {mean} ± {se}"
        );
        assert!(se < 0.005, "env {k}: too noisy to tell ({se})");
        assert!(
            (1.03 * mean - 1.0).abs() > 4.0 * se + 1e-6,
            "env {k}: a pdf 3% off would pass"
        );
    }
}

/// A drawn direction's pdf is the pdf evaluated for it (up to f32 rounding of the direction
/// that moves it across a pixel edge, which must stay rare); a sample never has pdf 0.
#[test]
fn environment_sampled_pdf_equals_evaluated_pdf() {
    for (k, env) in [
        image_env(test_image(), 37.0).1,
        image_env(builtin::sky_image(), -20.0).1,
        Environment::new(&EnvironmentDesc::constant(Vec3::ONE), 1.0),
    ]
    .iter()
    .enumerate()
    {
        let mut rng = Rng::new(12, k as u64);
        let n = 200_000;
        let mut differing = 0;
        for _ in 0..n {
            let Some((w, pdf)) = env.sample(rng.uniform2()) else {
                continue;
            };
            assert!((w.length() - 1.0).abs() < 1e-5);
            let evaluated = env.pdf(w);
            assert!(evaluated > 0.0, "env {k}: a sample at {w} has pdf 0");
            if (pdf - evaluated).abs() > 1e-3 * evaluated {
                differing += 1;
            }
        }
        assert!(
            differing * 10_000 <= n,
            "env {k}: {differing} of {n} differ"
        );
    }
}

/// The pixel of direction `w` in an image turned by `rotation_degrees`, by Blender's mapping
/// (written out here independently of the renderer's code).
fn pixel(w: Vec3, rotation_degrees: f32, width: u32, height: u32) -> (u32, u32) {
    let (s, c) = rotation_degrees.to_radians().sin_cos();
    // A Mapping node's Z rotation in Blender turns the lookup vector by +rotation about the
    // up axis (glTF's +Y).
    let m = Vec3::new(c * w.x + s * w.z, w.y, -s * w.x + c * w.z);
    let u = 0.5 + m.z.atan2(m.x) / std::f32::consts::TAU;
    let v = m.y.clamp(-1.0, 1.0).acos() / std::f32::consts::PI;
    (
        ((u * width as f32) as u32).min(width - 1),
        ((v * height as f32) as u32).min(height - 1),
    )
}

/// Chi-square of `samples` against each pixel's probability taken from the image itself:
/// `mean channel × sin θ` at the row's centre, normalised (pixels with under 5 expected samples
/// are pooled). Returns the statistic and its critical value at significance 1e-3.
fn chi_square_against_image(
    image: &EnvImage,
    rotation_degrees: f32,
    samples: &[Vec3],
) -> (f64, f64) {
    let (w, h) = (image.width, image.height);
    let mut weights = vec![0.0f64; (w * h) as usize];
    for j in 0..h {
        let sin = (PI * (j as f64 + 0.5) / h as f64).sin();
        for i in 0..w {
            let p = image.pixels[(j * w + i) as usize];
            weights[(j * w + i) as usize] = f64::from(p.x + p.y + p.z) / 3.0 * sin;
        }
    }
    let total: f64 = weights.iter().sum();
    let mut counts = vec![0.0f64; weights.len()];
    for &s in samples {
        let (i, j) = pixel(s, rotation_degrees, w, h);
        counts[(j * w + i) as usize] += 1.0;
    }
    let n = samples.len() as f64;
    let (mut chi2, mut dof) = (0.0, 0usize);
    let (mut pooled_expected, mut pooled_count) = (0.0, 0.0);
    for (weight, count) in weights.iter().zip(&counts) {
        let expected = n * weight / total;
        if expected < 5.0 {
            pooled_expected += expected;
            pooled_count += count;
            continue;
        }
        chi2 += (count - expected).powi(2) / expected;
        dof += 1;
    }
    if pooled_expected > 0.0 {
        chi2 += (pooled_count - pooled_expected).powi(2) / pooled_expected.max(1.0);
        dof += 1;
    }
    let k = (dof - 1) as f64;
    let z = 3.090;
    (
        chi2,
        k * (1.0 - 2.0 / (9.0 * k) + z * (2.0 / (9.0 * k)).sqrt()).powi(3),
    )
}

/// Samples of the environment pass a chi-square test against the image they came from, and
/// fail it against the same image with one column's pixels doubled (the negative case).
#[test]
fn environment_samples_pass_chi_square_against_the_image() {
    let rotation = 37.0;
    let image = test_image();
    let (_, env) = image_env(image.clone(), rotation);
    let mut rng = Rng::new(13, 14);
    let samples: Vec<Vec3> = (0..300_000)
        .filter_map(|_| env.sample(rng.uniform2()).map(|s| s.0))
        .collect();
    let (chi2, critical) = chi_square_against_image(&image, rotation, &samples);
    assert!(chi2 <= critical, "chi² {chi2} > {critical}");
    let mut wrong = image.clone();
    for j in 0..wrong.height {
        let k = (j * wrong.width + 5) as usize;
        wrong.pixels[k] *= 2.0;
    }
    let (chi2, critical) = chi_square_against_image(&wrong, rotation, &samples);
    assert!(
        chi2 > critical,
        "a doubled column went undetected: {chi2} ≤ {critical}"
    );
    // And the rotation matters: the unturned image rejects these samples.
    let (chi2, critical) = chi_square_against_image(&image, 0.0, &samples);
    assert!(chi2 > critical, "the rotation went undetected");
}

/// A large white Lambertian floor under a constant environment of radiance L: irradiance π·L,
/// so the floor reflects albedo · L. The full renderer (environment sampling, MIS with BSDF
/// sampling, which finds the sky too) matches within 4 standard errors at several points, for
/// every strategy; 1.03 × the answer is rejected (negative case).
#[test]
fn constant_environment_gives_pi_l_on_an_open_plane() {
    let l = 0.8;
    let desc = SceneDesc {
        name: "open plane".into(),
        materials: vec![MaterialDesc::diffuse("floor", Vec3::ONE)],
        meshes: vec![common::flat(
            "floor",
            0,
            &[vec![
                Vec3::new(-500.0, 0.0, -500.0),
                Vec3::new(-500.0, 0.0, 500.0),
                Vec3::new(500.0, 0.0, 500.0),
                Vec3::new(500.0, 0.0, -500.0),
            ]],
        )],
        environment: Some(EnvironmentDesc {
            strength: 2.0,
            ..EnvironmentDesc::constant(Vec3::splat(l / 2.0))
        }),
        camera: common::camera(Vec3::new(0.0, 3.0, 3.0), Vec3::ZERO),
        ..SceneDesc::default()
    };
    let albedo = 0.7;
    let scene = common::lambertian(Scene::from_desc(desc, "open plane").unwrap(), 0, albedo);
    let expected = f64::from(albedo * l);
    let mut detects = false;
    for (k, strategy) in Strategy::ALL.into_iter().enumerate() {
        for (m, x) in [Vec3::ZERO, Vec3::new(3.0, 0.0, -7.0)]
            .into_iter()
            .enumerate()
        {
            let seed = 10 * k as u64 + m as u64;
            let (mean, se) = common::floor_radiance(&scene, (strategy, None), x, 20_000, seed);
            assert!(
                (mean - expected).abs() <= 4.0 * se,
                "{}: {mean} ± {se} vs {expected}",
                strategy.name()
            );
            detects |= (mean - 1.03 * expected).abs() > 4.0 * se;
        }
    }
    assert!(detects, "a 3% error is never detected");
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("portalview-env-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// An `.hdr` (RGBE: 8-bit mantissas, so within 1%) and an `.exr` (f32, exact) load as the
/// image written; broken, missing and unsupported files are errors that name the file.
#[test]
fn hdr_and_exr_load_and_broken_files_name_themselves() {
    let dir = temp_dir("load");
    let image = test_image();
    let hdr = dir.join("sky.hdr");
    std::fs::write(&hdr, hdr_bytes(&image).unwrap()).unwrap();
    let loaded = load_image(&hdr, &mut vec![]).unwrap();
    assert_eq!((loaded.width, loaded.height), (image.width, image.height));
    for (a, b) in loaded.pixels.iter().zip(&image.pixels) {
        assert!(
            (*a - *b).abs().max_element() <= 0.01 * b.max_element() + 1e-6,
            "{a} vs {b}"
        );
    }
    let exr = dir.join("sky.exr");
    let bytes = portalview::io::exr_bytes(image.width, image.height, &image.pixels).unwrap();
    std::fs::write(&exr, bytes).unwrap();
    assert_eq!(load_image(&exr, &mut vec![]).unwrap(), image);
    // Through the text a scene or the command line gives, relative to a folder.
    match map_from_text("sky.exr", Some(&dir), &mut vec![]).unwrap() {
        EnvMap::Image { image: loaded, .. } => assert_eq!(*loaded, image),
        other => panic!("{other:?}"),
    }
    assert_eq!(
        map_from_text("0.5, 1, 2", None, &mut vec![]).unwrap(),
        EnvMap::Constant(Vec3::new(0.5, 1.0, 2.0))
    );
    assert!(map_from_text("1,-1,2", None, &mut vec![]).is_err());

    let truncated_hdr = dir.join("truncated.hdr");
    let bytes = hdr_bytes(&image).unwrap();
    std::fs::write(&truncated_hdr, &bytes[..bytes.len() / 2]).unwrap();
    let garbage_exr = dir.join("garbage.exr");
    std::fs::write(&garbage_exr, b"not an exr at all").unwrap();
    let missing = dir.join("missing.hdr");
    let unsupported = dir.join("sky.png");
    std::fs::write(&unsupported, b"png").unwrap();
    for file in [&truncated_hdr, &garbage_exr, &missing, &unsupported] {
        let error = load_image(file, &mut vec![]).unwrap_err().to_string();
        assert!(
            error.contains(&file.display().to_string()),
            "error does not name the file: {error}"
        );
    }
    // Command-line overrides: numbers alone need an environment.
    let mut warnings = vec![];
    assert!(with_overrides(None, None, Some(2.0), None, None, &mut warnings).is_err());
    let closest = Some(Interpolation::Closest);
    assert!(with_overrides(None, None, None, None, closest, &mut warnings).is_err());
    let over = with_overrides(
        None,
        Some("1,1,1"),
        Some(3.0),
        Some(-45.0),
        closest,
        &mut warnings,
    )
    .unwrap()
    .unwrap();
    assert_eq!(
        (over.strength, over.rotation_degrees, over.interpolation),
        (3.0, -45.0, Interpolation::Closest)
    );
    assert!(warnings.is_empty());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A scene's environment survives export and load: a constant as `[r, g, b]`, the built-in
/// sky as an image written beside the `.glb`, with strength and rotation; extras that are not
/// an environment are errors naming the file and the field.
#[test]
fn environment_round_trips_through_gltf_scene_extras() {
    let dir = temp_dir("gltf");
    let mut desc = builtin::desc("window").unwrap();
    desc.environment = Some(EnvironmentDesc {
        strength: 1.5,
        rotation_degrees: 30.0,
        ..desc.environment.clone().unwrap()
    });
    let glb = dir.join("room.glb");
    gltf::export_glb(&desc, &glb).unwrap();
    assert!(dir.join("room_environment.hdr").exists());
    let loaded = gltf::load_gltf(&glb).unwrap();
    let env = loaded.environment.clone().unwrap();
    assert_eq!((env.strength, env.rotation_degrees), (1.5, 30.0));
    let EnvMap::Image { image, .. } = &env.map else {
        panic!("not an image: {:?}", env.map);
    };
    assert_eq!(image.width, builtin::sky_image().width);
    assert_eq!(loaded.portals.len(), 1);
    assert!(loaded.portals[0].is_window());
    Scene::load(&glb).unwrap();

    // Saving the environment rewrites only the scene's extras.
    gltf::save_environment(
        &glb,
        Some(&EnvironmentDesc::constant(Vec3::new(0.1, 0.2, 0.3))),
    )
    .unwrap();
    let saved = gltf::load_gltf(&glb).unwrap();
    assert_eq!(
        saved.environment.unwrap().map,
        EnvMap::Constant(Vec3::new(0.1, 0.2, 0.3))
    );
    assert_eq!(saved.meshes, loaded.meshes);
    gltf::save_environment(&glb, None).unwrap();
    assert!(gltf::load_gltf(&glb).unwrap().environment.is_none());

    // A broken reference: the file and the field are named.
    let bad = dir.join("bad.gltf");
    let text = r#"{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[],"extras":{"environment":"nowhere.hdr"}}]}"#;
    std::fs::write(&bad, text).unwrap();
    let error = gltf::load_gltf(&bad).unwrap_err().to_string();
    assert!(
        error.contains("bad.gltf") && error.contains("extras.environment"),
        "{error}"
    );
    assert!(error.contains("nowhere.hdr"), "{error}");
    let text = r#"{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[],"extras":{"environment":[1,2],"environment_strength":1}}]}"#;
    std::fs::write(&bad, text).unwrap();
    let error = gltf::load_gltf(&bad).unwrap_err().to_string();
    assert!(error.contains("extras.environment"), "{error}");
    let text = r#"{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[],"extras":{"environment":[1,2,3],"environment_strength":"x"}}]}"#;
    std::fs::write(&bad, text).unwrap();
    let error = gltf::load_gltf(&bad).unwrap_err().to_string();
    assert!(error.contains("extras.environment_strength"), "{error}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A sky of radiance 1 with a 2 × 2 block of hot pixels of different radiances: the hot spot
/// the window technique splits off, with its fill (the sky around it) exactly 1.
fn sun_block_image(values: [f32; 4]) -> EnvImage {
    let (width, height) = (64u32, 32u32);
    let mut pixels = vec![Vec3::ONE; (width * height) as usize];
    for (k, v) in values.into_iter().enumerate() {
        let (i, j) = (20 + k as u32 % 2, 9 + k as u32 / 2);
        pixels[(j * width + i) as usize] = Vec3::splat(v);
    }
    EnvImage {
        width,
        height,
        pixels,
    }
}

/// The sun split off for sampling within windows (`docs/method.md` §9.4). Its density
/// integrates to 1 (uniform directions, within 4 standard errors) for the built-in sky turned
/// by −20° and for a block of hot pixels; its draws stay inside the cap that holds it and have
/// positive density; its draws pass a chi-square test against `(L − fill) · solid angle` per
/// pixel, and fail it with two pixels' radiances swapped (the negative case); the sky without
/// the sun (`K`) is the fill there and the image elsewhere. A smooth image and one with two
/// suns 90° apart have no hot spot.
#[test]
fn the_sun_is_split_off_and_drawn_by_its_pixels() {
    let values = [2000.0, 2600.0, 3100.0, 3500.0];
    for (k, (image, rotation)) in [
        (builtin::sky_image(), -20.0),
        (sun_block_image(values), 0.0),
    ]
    .into_iter()
    .enumerate()
    {
        let (_, env) = image_env(image, rotation);
        let (power, centre, sin_radius) = env.hot_spot().expect("a hot spot");
        assert!(power > 0.0);
        let mut rng = Rng::new(17, k as u64);
        let values: Vec<f64> = (0..4_000_000)
            .map(|_| 4.0 * PI * f64::from(env.hot_pdf(uniform_sphere(rng.uniform2()))))
            .collect();
        let (mean, se) = common::mean_and_se(&values);
        assert!(
            (mean - 1.0).abs() <= 4.0 * se,
            "sun {k}: ∫pdf = {mean} ± {se}"
        );
        assert!(se < 0.05, "sun {k}: too noisy to tell ({se})");
        let cos_radius = (1.0 - sin_radius * sin_radius).sqrt();
        for _ in 0..20_000 {
            let w = env.sample_hot(rng.uniform2()).expect("a draw");
            assert!(
                w.dot(centre) >= cos_radius - 1e-6,
                "sun {k}: {w} outside the cap"
            );
            assert!(env.hot_pdf(w) > 0.0, "sun {k}: {w} drawn with density 0");
        }
    }
    // The built-in sun: K is the fill on it, the image elsewhere.
    let (_, env) = image_env(builtin::sky_image(), 0.0);
    let sun = builtin::sky_sun_direction();
    assert!(env.sky_weight(sun) < 0.01 * env.sampling_weight(sun));
    assert_eq!(env.sky_weight(Vec3::Y), env.sampling_weight(Vec3::Y));

    // Chi-square of the draws per hot pixel against (L − 1) times the pixel's solid angle.
    let chi_square = |values: [f32; 4], samples: &[Vec3]| {
        let image = sun_block_image(values);
        let (w, h) = (image.width, image.height);
        let (mut counts, mut outside) = ([0.0f64; 4], 0);
        for &s in samples {
            let (i, j) = pixel(s, 0.0, w, h);
            match (i.checked_sub(20), j.checked_sub(9)) {
                (Some(di @ 0..2), Some(dj @ 0..2)) => counts[(di + 2 * dj) as usize] += 1.0,
                // f32 rounding at a pixel's edge, which must stay rare.
                _ => outside += 1,
            }
        }
        assert!(
            outside * 10_000 < samples.len(),
            "{outside} draws outside the sun"
        );
        let weights: Vec<f64> = (0..4)
            .map(|k| {
                let j = 9 + k / 2;
                let omega =
                    (PI * j as f64 / h as f64).cos() - (PI * (j + 1) as f64 / h as f64).cos();
                (f64::from(values[k]) - 1.0) * omega
            })
            .collect();
        let total: f64 = weights.iter().sum();
        let n = samples.len() as f64;
        weights
            .iter()
            .zip(counts)
            .map(|(wt, c)| (c - n * wt / total).powi(2) / (n * wt / total))
            .sum::<f64>()
    };
    let (_, env) = image_env(sun_block_image(values), 0.0);
    let mut rng = Rng::new(19, 20);
    let samples: Vec<Vec3> = (0..200_000)
        .filter_map(|_| env.sample_hot(rng.uniform2()))
        .collect();
    // Three degrees of freedom: 16.27 is the 1e-3 critical value.
    let chi2 = chi_square(values, &samples);
    assert!(chi2 <= 16.27, "chi² {chi2}");
    let swapped = [values[3], values[1], values[2], values[0]];
    let chi2 = chi_square(swapped, &samples);
    assert!(chi2 > 16.27, "swapped pixels went undetected: chi² {chi2}");

    // No hot spot: a smooth image, and two suns too far apart for one cap.
    let smooth = EnvImage {
        width: 32,
        height: 16,
        pixels: (0..512)
            .map(|k| Vec3::splat(1.0 + (k / 32) as f32))
            .collect(),
    };
    assert!(image_env(smooth, 0.0).1.hot_spot().is_none());
    let mut two = sun_block_image([3000.0; 4]);
    for j in 9..11 {
        two.pixels[(j * 64 + 36) as usize] = Vec3::splat(3000.0);
    }
    assert!(image_env(two, 0.0).1.hot_spot().is_none());
}

/// An environment from `image` read by `interpolation`.
fn env_with(image: &EnvImage, interpolation: Interpolation) -> Environment {
    let desc = EnvironmentDesc {
        map: EnvMap::Image {
            file: None,
            image: Arc::new(image.clone()),
        },
        strength: 1.0,
        rotation_degrees: 23.0,
        interpolation,
    };
    Environment::new(&desc, 1.0)
}

/// Blender's *Linear* interpolation, sampled exactly: on a black image with one bright pixel
/// (the filter spreads it into its eight neighbours) and on the test image,
/// - the pdf integrates to 1 and a sample's pdf is the pdf evaluated for it;
/// - `L / pdf` over the sampler's directions estimates `∫ L dω`, which uniform directions
///   estimate independently: the two agree within 4 combined standard errors. The negative
///   case: the same estimate with the *Closest* table (which ignores the pixels the filter
///   spreads light into) falls short by far more, so the test fails for that reason;
/// - a constant image reads exactly its constant everywhere, the poles and the seam included.
#[test]
fn linear_interpolation_is_sampled_exactly() {
    let (width, height) = (16u32, 8u32);
    let mut spot = vec![Vec3::ZERO; (width * height) as usize];
    spot[(3 * width + 5) as usize] = Vec3::new(90.0, 100.0, 110.0);
    let spot = EnvImage {
        width,
        height,
        pixels: spot,
    };
    for (k, image) in [spot, test_image()].iter().enumerate() {
        let linear = env_with(image, Interpolation::Linear);
        let mut rng = Rng::new(21, k as u64);
        let n = 400_000;
        let pdfs: Vec<f64> = (0..n)
            .map(|_| 4.0 * PI * f64::from(linear.pdf(uniform_sphere(rng.uniform2()))))
            .collect();
        let (mean, se) = common::mean_and_se(&pdfs);
        assert!(
            (mean - 1.0).abs() <= 4.0 * se,
            "image {k}: ∫pdf = {mean} ± {se}"
        );
        let uniform: Vec<f64> = (0..n)
            .map(|_| {
                let w = uniform_sphere(rng.uniform2());
                4.0 * PI * f64::from(linear.radiance(w).y)
            })
            .collect();
        let (truth, truth_se) = common::mean_and_se(&uniform);
        let estimate = |table: &Environment, rng: &mut Rng| {
            let values: Vec<f64> = (0..n)
                .map(|_| match table.sample(rng.uniform2()) {
                    Some((w, pdf)) => {
                        let evaluated = table.pdf(w);
                        assert!(
                            (evaluated - pdf).abs() <= 1e-3 * pdf || k > 0,
                            "image {k}: sampled pdf {pdf}, evaluated {evaluated}"
                        );
                        f64::from(linear.radiance(w).y / pdf)
                    }
                    None => 0.0,
                })
                .collect();
            common::mean_and_se(&values)
        };
        let (mean, se) = estimate(&linear, &mut rng);
        let tolerance = 4.0 * (se * se + truth_se * truth_se).sqrt();
        assert!(
            (mean - truth).abs() <= tolerance,
            "image {k}: {mean} ± {se} vs ∫L = {truth} ± {truth_se}"
        );
        if k == 0 {
            let closest = env_with(image, Interpolation::Closest);
            let (short, short_se) = estimate(&closest, &mut rng);
            let tolerance = 4.0 * (short_se * short_se + truth_se * truth_se).sqrt();
            assert!(
                truth - short > tolerance,
                "the Closest table's {short} ± {short_se} should miss the spread light ({truth})"
            );
        }
    }
    let c = Vec3::new(0.25, 0.5, 2.0);
    let constant = EnvImage {
        width,
        height,
        pixels: vec![c; (width * height) as usize],
    };
    let env = env_with(&constant, Interpolation::Linear);
    let mut rng = Rng::new(22, 0);
    let mut directions: Vec<Vec3> = (0..10_000)
        .map(|_| uniform_sphere(rng.uniform2()))
        .collect();
    directions.extend([Vec3::Y, -Vec3::Y, -Vec3::X, Vec3::new(-1.0, 0.0, -1e-7)]);
    for w in directions {
        assert!(
            env.radiance(w).abs_diff_eq(c, 1e-6 * c.max_element()),
            "{w}: {}",
            env.radiance(w)
        );
    }
}

/// The sun of an image read with *Linear*: split off with the pixels its filter spreads into,
/// drawn by its pick table, whose own pmf gives `hot_pdf` (sampled equals evaluated, and it
/// integrates to 1); a direction drawn from it reads a positive excess there.
#[test]
fn a_linear_sun_is_drawn_by_its_pick_table() {
    let env = env_with(
        &sun_block_image([2000.0, 2600.0, 3100.0, 3500.0]),
        Interpolation::Linear,
    );
    assert!(env.hot_spot().is_some(), "the block of hot pixels is a sun");
    let mut rng = Rng::new(23, 0);
    for _ in 0..20_000 {
        let w = env.sample_hot(rng.uniform2()).unwrap();
        assert!(env.hot_pdf(w) > 0.0, "a drawn direction has density");
    }
    let values: Vec<f64> = (0..400_000)
        .map(|_| 4.0 * PI * f64::from(env.hot_pdf(uniform_sphere(rng.uniform2()))))
        .collect();
    let (mean, se) = common::mean_and_se(&values);
    assert!((mean - 1.0).abs() <= 4.0 * se, "∫hot_pdf = {mean} ± {se}");
}

/// Photographic HDRIs have a few slightly negative pixels; a damaged one may hold NaN or
/// infinite ones. They are read as 0, with one warning naming the file, how many pixels
/// changed and the worst value; the rest of the image is untouched. (Radiance `.hdr` cannot
/// store a negative, NaN or infinite value: RGBE's largest is 255·2¹¹⁹, finite; so `.exr`.)
#[test]
fn negative_and_non_finite_pixels_are_read_as_zero_with_a_warning() {
    let dir = temp_dir("repair");
    let mut image = test_image();
    image.pixels[3] = Vec3::new(-0.0039, 0.5, 0.25);
    image.pixels[10] = Vec3::new(f32::NAN, 1.0, 1.0);
    image.pixels[11] = Vec3::new(1.0, f32::INFINITY, -0.001);
    let exr = dir.join("photo.exr");
    let bytes = portalview::io::exr_bytes(image.width, image.height, &image.pixels).unwrap();
    std::fs::write(&exr, bytes).unwrap();
    let mut warnings = vec![];
    let loaded = load_image(&exr, &mut warnings).unwrap();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    let warning = &warnings[0];
    for part in [exr.display().to_string(), "3 of".into(), "-0.0039".into()] {
        assert!(warning.contains(&part), "'{warning}' lacks '{part}'");
    }
    assert_eq!(loaded.pixels[3], Vec3::new(0.0, 0.5, 0.25));
    assert_eq!(loaded.pixels[10], Vec3::new(0.0, 1.0, 1.0));
    assert_eq!(loaded.pixels[11], Vec3::new(1.0, 0.0, 0.0));
    for (k, (a, b)) in loaded.pixels.iter().zip(&image.pixels).enumerate() {
        if ![3, 10, 11].contains(&k) {
            assert_eq!(a, b, "pixel {k}");
        }
    }
    // A clean image gives no warning.
    let clean = dir.join("clean.exr");
    let t = test_image();
    std::fs::write(
        &clean,
        portalview::io::exr_bytes(t.width, t.height, &t.pixels).unwrap(),
    )
    .unwrap();
    let mut warnings = vec![];
    load_image(&clean, &mut warnings).unwrap();
    assert!(warnings.is_empty(), "{warnings:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A damaged header that claims a huge image in a small file is refused, by an error naming
/// the file, before any pixel is allocated: an `.exr` whose data window says 30000 × 30000,
/// and an `.hdr` whose resolution line says the same (9 · 10⁸ pixels, 11 GB as f32 RGB).
#[test]
fn a_header_claiming_a_huge_image_is_refused() {
    let dir = temp_dir("huge");
    let t = test_image();
    let mut exr = portalview::io::exr_bytes(t.width, t.height, &t.pixels).unwrap();
    let at = exr
        .windows(b"dataWindow\0box2i\0".len())
        .position(|w| w == b"dataWindow\0box2i\0")
        .expect("an EXR header has a data window");
    // After the name, the type and the 4-byte size: xMin, yMin, xMax, yMax.
    let values = at + b"dataWindow\0box2i\0".len() + 4;
    exr[values + 8..values + 12].copy_from_slice(&29_999i32.to_le_bytes());
    exr[values + 12..values + 16].copy_from_slice(&29_999i32.to_le_bytes());
    let exr_file = dir.join("huge.exr");
    std::fs::write(&exr_file, &exr).unwrap();
    let hdr = hdr_bytes(&t).unwrap();
    let text = String::from_utf8_lossy(&hdr);
    let line = format!("-Y {} +X {}", t.height, t.width);
    let at = text.find(&line).expect("an .hdr has a resolution line");
    let mut huge = hdr[..at].to_vec();
    huge.extend_from_slice(b"-Y 30000 +X 30000");
    huge.extend_from_slice(&hdr[at + line.len()..]);
    let hdr_file = dir.join("huge.hdr");
    std::fs::write(&hdr_file, &huge).unwrap();
    for file in [&exr_file, &hdr_file] {
        let error = load_image(file, &mut vec![]).unwrap_err().to_string();
        assert!(error.contains(&file.display().to_string()), "{error}");
        assert!(error.contains("30000"), "{error}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
