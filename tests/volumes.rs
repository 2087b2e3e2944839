//! Thick glass (glTF `KHR_materials_volume`): a closed mesh filled with a refracting
//! dielectric. A glass block in a uniform sky returns exactly the light it receives (every
//! path's weight is 1: Fresnel choices, total internal reflection and `η²` both ways); light
//! crossing a volume is attenuated by Beer–Lambert as the extension defines it, on camera
//! rays and on shadow rays inside; and glass of the outside's IOR changes nothing, for every
//! strategy.

mod common;

use common::*;
use glam::{Quat, Vec2, Vec3};
use portalview::asset::desc::{MaterialDesc, SceneDesc, VolumeDesc};
use portalview::asset::environment::EnvironmentDesc;
use portalview::camera::Camera;
use portalview::light::Strategy;
use portalview::render::film::Film;
use portalview::render::integrator::Integrator;
use portalview::render::render;
use portalview::scene::Scene;

/// A closed box of half-extents `half` centred at `c`, turned by `rotation`, wound outwards.
fn cuboid(c: Vec3, half: Vec3, rotation: Quat) -> Vec<Vec<Vec3>> {
    let mut faces = vec![];
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let e = |k: usize| Vec3::AXES[k % 3] * half[k % 3];
            let f = Vec3::AXES[axis] * half[axis] * sign;
            // e(a + 1) × e(a + 2) points along +e(a): swapped on the negative face.
            let (u, v) = if sign > 0.0 {
                (e(axis + 1), e(axis + 2))
            } else {
                (e(axis + 2), e(axis + 1))
            };
            faces.push(
                [f - u - v, f + u - v, f + u + v, f - u + v]
                    .map(|p| c + rotation * p)
                    .to_vec(),
            );
        }
    }
    faces
}

/// Smooth glass of `ior` filling its mesh, absorbing to `attenuation` after `distance` metres.
fn thick_glass(ior: f32, attenuation: Vec3, distance: f32) -> MaterialDesc {
    MaterialDesc {
        ior,
        volume: Some(VolumeDesc {
            thickness: 0.1,
            attenuation_color: attenuation,
            attenuation_distance: distance,
        }),
        ..MaterialDesc::clear_glass("thick glass")
    }
}

/// A glass block in a sky of radiance 1.
fn block_in_the_sky(glass: MaterialDesc) -> Scene {
    let mut desc = SceneDesc {
        name: "block".into(),
        camera: camera(Vec3::new(0.0, 0.0, 2.0), Vec3::ZERO),
        environment: Some(EnvironmentDesc::constant(Vec3::ONE)),
        ..SceneDesc::default()
    };
    desc.materials.push(glass);
    let turn = Quat::from_rotation_y(0.5) * Quat::from_rotation_x(0.35);
    let faces = cuboid(Vec3::ZERO, Vec3::new(0.35, 0.3, 0.25), turn);
    desc.meshes.push(flat("block", 0, &faces));
    Scene::from_desc(desc, "block").unwrap()
}

/// Smooth glass in a uniform sky is a white furnace with no variance: each event is
/// reflection (weight 1) or refraction (`1/η²` in, `η²` out), so every path that leaves the
/// block carries exactly the sky's 1, at any depth (the boundary is not a path vertex).
/// Tolerance: float rounding. The negative case: the same block absorbing (attenuation 0.9
/// per 10 cm) darkens at least a fifth of the pixels by over 1%, so the camera does see the
/// glass in that many pixels; a renderer that dropped the `η²` on the way out would make them
/// `1/η²` or less.
#[test]
fn a_glass_block_in_a_uniform_sky_is_a_white_furnace() {
    for ior in [1.33f32, 1.5, 2.4] {
        for max_depth in [1, 3] {
            let scene = block_in_the_sky(thick_glass(ior, Vec3::ONE, f32::INFINITY));
            let integrator =
                Integrator::new(&scene, independent(Strategy::Antishadow, max_depth, 1));
            let (film, stats) = render(&integrator, 24, 24, 16);
            assert_eq!(stats.nonfinite, 0);
            for (i, c) in film.mean().iter().enumerate() {
                assert!(
                    (*c - Vec3::ONE).abs().max_element() < 1e-4,
                    "ior {ior} depth {max_depth} pixel {i}: {c}"
                );
            }
        }
        let scene = block_in_the_sky(thick_glass(ior, Vec3::splat(0.9), 0.1));
        let integrator = Integrator::new(&scene, independent(Strategy::Antishadow, 1, 1));
        let (film, _) = render(&integrator, 24, 24, 16);
        let darker = film.mean().iter().filter(|c| c.x < 0.99).count();
        assert!(
            darker > 24 * 24 / 5,
            "ior {ior}: {darker} pixels see the glass"
        );
    }
}

/// Beer–Lambert as `KHR_materials_volume` defines it, `σ = −ln(attenuationColor) /
/// attenuationDistance`: through a 20 cm slab of glass of the outside's IOR (no reflection,
/// no refraction) whose attenuation colour is reached after 20 cm, a camera ray loses exactly
/// `1 − attenuationColor` (times `1/cos` of its angle to the slab, under 0.4% here: the
/// tolerance). The negative case: Cycles' Volume Absorption convention, `σ = density·(1 −
/// color)`, would give `exp(−(1 − c))`, far outside it.
#[test]
fn camera_rays_through_a_volume_follow_beer_lambert() {
    let attenuation = Vec3::new(0.25, 0.5, 1.0);
    let mut desc = SceneDesc {
        name: "slab".into(),
        camera: camera(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO),
        environment: Some(EnvironmentDesc::constant(Vec3::ONE)),
        ..SceneDesc::default()
    };
    desc.materials.push(thick_glass(1.0, attenuation, 0.2));
    let faces = cuboid(Vec3::ZERO, Vec3::new(0.4, 0.4, 0.1), Quat::IDENTITY);
    desc.meshes.push(flat("slab", 0, &faces));
    let scene = Scene::from_desc(desc, "slab").unwrap();
    let integrator = Integrator::new(&scene, independent(Strategy::Antishadow, 1, 2));
    let (film, stats) = render(&integrator, 32, 32, 8);
    assert_eq!(stats.nonfinite, 0);
    // Rays through the central 4 × 4 pixels cross both large faces (±0.4 at 4.9–5.1 m in a
    // field of ±0.4 rad covers pixels 13.03 to 18.97).
    let mean = film.mean();
    for y in 14..18 {
        for x in 14..18 {
            let c = mean[y * 32 + x];
            for k in 0..3 {
                let expected = attenuation[k];
                assert!(
                    (c[k] - expected).abs() <= 0.004 * (1.0 + 1.4),
                    "pixel ({x}, {y}) channel {k}: {} vs {expected}",
                    c[k]
                );
                let cycles = (-(1.0 - expected)).exp();
                assert!(k == 2 || (cycles - expected).abs() > 0.1);
            }
        }
    }
}

/// Shadow rays inside a volume are attenuated too: a floor and four small lights inside an
/// absorbing block of the outside's IOR, seen from above through its top. Each pixel is
/// `ρ/π · E(x) · exp(−σ·ℓ)`, with `ℓ` the camera ray's length inside and `E(x)` the
/// irradiance from the four lights through the medium, `Σ ∫ L cos θx cos θy e^{−σr} / r² dA`,
/// integrated here by a 40 × 40 midpoint rule per light (each pixel's centre; the lights are
/// symmetric under both image flips). Tolerance: 4 standard errors of each 4 × 4 block's mean
/// plus 1% for the centre and the quadrature. The negative case: shadow rays not attenuated
/// (E without `e^{−σr}`) are 20% brighter, far outside it.
#[test]
fn shadow_rays_inside_a_volume_follow_beer_lambert() {
    let (albedo, le, sigma) = (0.5f32, 8.0f32, 0.4f32);
    let attenuation = Vec3::splat((-sigma * 0.5).exp());
    let mut desc = SceneDesc {
        name: "medium".into(),
        camera: Some(Camera {
            eye: Vec3::new(0.0, 3.0, 0.0),
            target: Vec3::ZERO,
            up: Vec3::Z,
            yfov: 0.2,
            aspect: 1.0,
        }),
        ..SceneDesc::default()
    };
    desc.materials.push(thick_glass(1.0, attenuation, 0.5));
    desc.materials
        .push(MaterialDesc::diffuse("floor", Vec3::splat(albedo)));
    desc.materials
        .push(MaterialDesc::emitter("light", Vec3::splat(le), false));
    let faces = cuboid(
        Vec3::new(0.0, 0.5, 0.0),
        Vec3::new(1.0, 0.5, 1.0),
        Quat::IDENTITY,
    );
    desc.meshes.push(flat("medium", 0, &faces));
    desc.meshes.push(flat(
        "floor",
        1,
        &[square(Vec3::new(0.0, 0.01, 0.0), Vec3::Y, 0.9)],
    ));
    let lights: Vec<Vec<Vec3>> = [(0.5f32, 0.5f32), (-0.5, 0.5), (0.5, -0.5), (-0.5, -0.5)]
        .iter()
        .map(|&(x, z)| square(Vec3::new(x, 0.9, z), -Vec3::Y, 0.1))
        .collect();
    desc.meshes.push(flat("lights", 2, &lights));
    let camera = desc.camera.unwrap();
    let scene = Scene::from_desc(desc, "medium").unwrap();
    let integrator = Integrator::new(&scene, independent(Strategy::Light, 1, 3));
    let (width, spp) = (24u32, 256);
    let (film, stats) = render(&integrator, width, width, spp);
    assert_eq!(stats.nonfinite, 0);

    let irradiance = |x: Vec3, absorbing: bool| {
        let n = 40;
        let mut e = 0.0f64;
        for light in &lights {
            let (o, u, v) = (light[0], light[1] - light[0], light[3] - light[0]);
            let area = u.cross(v).length() as f64;
            for k in 0..n * n {
                let (a, b) = (
                    ((k % n) as f32 + 0.5) / n as f32,
                    ((k / n) as f32 + 0.5) / n as f32,
                );
                let y = o + a * u + b * v;
                let d = y - x;
                let r = d.length();
                let cos = (d.y / r) as f64;
                let absorbed = if absorbing { (-sigma * r).exp() } else { 1.0 };
                e += le as f64 * cos * cos * absorbed as f64 / (r * r) as f64 * area
                    / (n * n) as f64;
            }
        }
        e
    };
    let (mean, variance) = (film.mean(), film.variance_of_mean());
    let mut blocks = 0;
    for by in 0..width / 4 {
        for bx in 0..width / 4 {
            let (mut measured, mut var, mut expected, mut plain) = (0.0, 0.0, 0.0, 0.0);
            for k in 0..16 {
                let (x, y) = (bx * 4 + k % 4, by * 4 + k / 4);
                let ndc = Vec2::new(
                    (x as f32 + 0.5) / width as f32,
                    (y as f32 + 0.5) / width as f32,
                );
                let (eye, dir) = camera.ray(ndc, 1.0);
                let t_floor = (eye.y - 0.01) / -dir.y;
                let p = eye + t_floor * dir;
                // Inside the block from its top (y = 1) down to the floor.
                let inside = (1.0 - 0.01) / -dir.y;
                let camera_ray = (-sigma * inside).exp() as f64;
                let brdf = albedo as f64 / std::f64::consts::PI;
                expected += brdf * irradiance(p, true) * camera_ray / 16.0;
                plain += brdf * irradiance(p, false) * camera_ray / 16.0;
                let i = (y * width + x) as usize;
                measured += mean[i].x as f64 / 16.0;
                var += variance[i].x as f64 / 256.0;
            }
            let tolerance = 4.0 * var.sqrt() + 0.01 * expected;
            assert!(
                (measured - expected).abs() <= tolerance,
                "block ({bx}, {by}): {measured} vs {expected} ± {tolerance}"
            );
            assert!(
                (plain - expected).abs() > 3.0 * tolerance,
                "{plain} {expected}"
            );
            blocks += 1;
        }
    }
    assert_eq!(blocks, 36);
}

/// Glass of the outside's IOR, not absorbing, is not there: a square light closed in such a
/// block over a floor renders as the bare light, per 6 × 6 block, for every strategy at
/// depth 2. Shadow rays stop at the block (as at any refracting glass), so the light is
/// found by BSDF paths that cross its boundary without counting it as depth, and take the
/// full weight past it. The negative case (`assert_agrees`): a 3% error is detected.
#[test]
fn glass_of_the_outsides_ior_changes_nothing() {
    let bare = floor_and_light(0.5, square(Vec3::new(0.0, 1.0, 0.0), -Vec3::Y, 0.4), 4.0);
    let mut closed = bare.clone();
    closed
        .materials
        .push(thick_glass(1.0, Vec3::ONE, f32::INFINITY));
    let faces = cuboid(
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(0.5, 0.1, 0.5),
        Quat::IDENTITY,
    );
    closed.meshes.push(flat("block", 2, &faces));
    let bare = Scene::from_desc(bare, "bare").unwrap();
    let closed = Scene::from_desc(closed, "closed").unwrap();
    let reference = {
        let integrator = Integrator::new(&bare, independent(Strategy::Light, 2, 4));
        render(&integrator, 48, 36, 256).0
    };
    for strategy in Strategy::ALL {
        let integrator = Integrator::new(&closed, independent(strategy, 2, 5));
        let (image, stats): (Film, _) = render(&integrator, 48, 36, 1024);
        assert_eq!(stats.nonfinite, 0);
        assert_agrees(&format!("{strategy:?}"), &image, &reference, true);
    }
}

/// Rough glass is a vertex that refracts: a frosted block in a sky of radiance 1 neither
/// creates light nor loses more than single-scattering GGX does. Paths reach the sky by BSDF
/// samples and by light samples of the sky from both sides of the boundary (those from
/// inside stop at the glass), weighted by MIS. The mean over the pixels that see the block
/// is at most 1 (within 4 standard errors) and above 0.6: the boundary loses what single
/// scattering loses at each event (up to 26% inside near the critical angle at roughness
/// 0.6: `material::tests::a_dielectric_boundary_conserves_power`), and paths inside meet it
/// many times (measured: 0.93 at roughness 0.3, 0.69 at 0.6, seed 6). Radiance not divided
/// by `η²` on the way in, or kept on the way out, would leave 1 far behind either way.
#[test]
fn a_frosted_glass_block_in_a_uniform_sky_loses_only_what_single_scattering_loses() {
    // The pixels that see the block: those an absorbing smooth block darkens.
    let absorbing = block_in_the_sky(thick_glass(1.5, Vec3::splat(0.5), 0.1));
    let integrator = Integrator::new(&absorbing, independent(Strategy::Antishadow, 1, 1));
    let mask: Vec<bool> = render(&integrator, 24, 24, 16)
        .0
        .mean()
        .iter()
        .map(|c| c.x < 0.99)
        .collect();
    for roughness in [0.3f32, 0.6] {
        let scene = block_in_the_sky(MaterialDesc {
            roughness,
            ..thick_glass(1.5, Vec3::ONE, f32::INFINITY)
        });
        let integrator = Integrator::new(&scene, independent(Strategy::Antishadow, 12, 6));
        let (film, stats) = render(&integrator, 24, 24, 256);
        assert_eq!(stats.nonfinite, 0);
        let on_block: Vec<f64> = film
            .mean()
            .iter()
            .zip(&mask)
            .filter_map(|(c, &m)| m.then_some(c.x as f64))
            .collect();
        assert!(on_block.len() > 24 * 24 / 5, "{}", on_block.len());
        let (mean, se) = mean_and_se(&on_block);
        assert!(
            mean <= 1.0 + 4.0 * se && mean > 0.6,
            "roughness {roughness}: {mean} ± {se}"
        );
    }
}
