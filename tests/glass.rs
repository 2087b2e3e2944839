//! Thin glass (glTF `KHR_materials_transmission` without a volume): shadow rays that cross
//! panes with their straight-through transmittance give the image that BSDF paths alone give
//! when glass stops shadow rays (as in Cycles), for every strategy, behind a window and around
//! a bulb; a pane in a uniform sky neither gains nor loses energy.

mod common;

use common::*;
use glam::Vec3;
use portalview::asset::builtin::{self, slab};
use portalview::asset::desc::{MaterialDesc, SceneDesc};
use portalview::asset::environment::{ENVIRONMENT_TARGET, EnvironmentDesc};
use portalview::light::Strategy;
use portalview::render::film::Film;
use portalview::render::integrator::{GlassShadows, Integrator, RenderSettings};
use portalview::render::render;
use portalview::sampling::SamplerKind;
use portalview::scene::Scene;

/// Renders `scene` at 48 × 36 with independent numbers (block z-scores rest on per-pixel
/// sample variances).
fn film(scene: &Scene, strategy: Strategy, glass: GlassShadows, spp: u32, seed: u64) -> Film {
    let settings = RenderSettings {
        strategy,
        seed,
        sampler: SamplerKind::Independent,
        glass,
        ..RenderSettings::default()
    };
    let integrator = Integrator::new(scene, settings);
    let (film, stats) = render(&integrator, 48, 36, spp);
    assert_eq!(stats.nonfinite, 0);
    film
}

/// Appends clear glass (`ior`) to `desc`: a 6 mm slab over `corners` between 1 cm and 1.6 cm
/// along `normal`, grown 2 cm past them.
fn add_pane(desc: &mut SceneDesc, corners: &[Vec3], normal: Vec3, ior: f32) {
    desc.materials.push(MaterialDesc {
        ior,
        ..MaterialDesc::clear_glass("glass")
    });
    let material = desc.materials.len() - 1;
    let faces = slab(corners, normal, (0.01, 0.016), 0.02);
    desc.meshes.push(flat("pane", material, &faces));
}

/// The bulb in a shade of `bulb_in_shade`, its opening closed by a pane just below its portal:
/// a lamp whose opening is glazed.
fn glazed_shade(ior: f32) -> Scene {
    let mut desc = bulb_in_shade();
    let opening = [
        Vec3::new(-0.3, 1.2, -0.3),
        Vec3::new(0.3, 1.2, -0.3),
        Vec3::new(0.3, 1.2, 0.3),
        Vec3::new(-0.3, 1.2, 0.3),
    ];
    add_pane(&mut desc, &opening, -Vec3::Y, ior);
    // The floor the opening lights, not the far floor at grazing angles, where light that
    // crosses glass at grazing incidence is so rare along BSDF paths that the stopped
    // render's per-pixel variances (and so the z-scores) are not yet trustworthy.
    desc.camera = camera(Vec3::new(0.0, 1.1, 1.0), Vec3::new(0.0, 0.0, -0.3));
    Scene::from_desc(desc, "glazed shade").unwrap()
}

/// A closed room 2 × 1.5 × 2 m with a square skylight in its ceiling, a window portal on it
/// facing down, a pane above it, under a uniform sky of radiance 1.
fn glazed_skylight() -> Scene {
    let (lo, hi) = (Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 1.5, 1.0));
    let faces = box_faces(lo, hi, &[], &[(0.6, 1.4, 0.6, 1.4)]);
    let skylight = square(Vec3::new(0.0, 1.5, 0.0), -Vec3::Y, 0.4);
    let mut desc = SceneDesc {
        name: "skylight".into(),
        materials: vec![MaterialDesc::diffuse("room", Vec3::splat(0.6))],
        meshes: vec![flat("room", 0, &faces)],
        portals: vec![portal("skylight", ENVIRONMENT_TARGET, 0.1, &skylight)],
        camera: camera(Vec3::new(0.0, 1.3, 0.95), Vec3::new(0.0, 0.0, -0.3)),
        environment: Some(EnvironmentDesc::constant(Vec3::ONE)),
        ..SceneDesc::default()
    };
    add_pane(&mut desc, &skylight, Vec3::Y, 1.5);
    Scene::from_desc(desc, "skylight").unwrap()
}

/// Shadow rays through glass against glass that stops them (only BSDF paths cross it, MIS
/// weight 1 past a pane): the same image for every strategy, by per-block z-scores whose
/// standard errors come from both films' per-pixel variances (`common::consistent`), with a
/// 3% scale error detected. The reference is rendered once with light sampling (with glass
/// stopping shadow rays, every strategy's light samples through the pane are lost alike).
fn passing_equals_stopping(scene: &Scene, spp_pass: u32, spp_stop: u32) {
    let stopped = film(scene, Strategy::Light, GlassShadows::Stop, spp_stop, 1);
    for strategy in Strategy::ALL {
        let passing = film(scene, strategy, GlassShadows::Pass, spp_pass, 2);
        assert_agrees(
            &format!("{}: {}", scene.name, strategy.name()),
            &passing,
            &stopped,
            strategy == Strategy::Antishadow,
        );
    }
}

#[test]
fn a_glazed_lamp_opening_passes_shadow_rays_without_bias() {
    passing_equals_stopping(&glazed_shade(1.5), 512, 16384);
}

#[test]
fn a_glazed_skylight_passes_shadow_rays_without_bias() {
    passing_equals_stopping(&glazed_skylight(), 128, 1024);
}

/// The negative case: shadow rays that cross the panes without their Fresnel weight (an IOR
/// of 1 reflects nothing: each crossing weighs 1 instead of about 0.96) brighten the image
/// under the glazed opening by about 8%, and the same comparison detects it.
#[test]
fn a_pane_without_its_fresnel_weight_is_detected() {
    let real = glazed_shade(1.5);
    let no_fresnel = glazed_shade(1.0);
    let stopped = film(&real, Strategy::Light, GlassShadows::Stop, 4096, 1);
    let wrong = film(
        &no_fresnel,
        Strategy::Antishadow,
        GlassShadows::Pass,
        256,
        2,
    );
    let blocks = block_differences(&wrong, &stopped, 6, 1.0);
    assert!(blocks.len() > 10);
    assert!(
        !consistent(&blocks),
        "a pane without Fresnel went undetected"
    );
}

/// A white furnace: a pane of white glass alone in a uniform sky of radiance 1, seen through
/// by the camera. Each surface reflects `E` and passes `1 − E` (up to the albedo table's
/// round-up), so every pixel is 1; the camera rays cross and trace the reflections beside
/// (`Integrator::cross_panes`), and losing those gives 0.979 at IOR 1.33. The mean over the
/// pane's pixels is within 4 standard errors (of the pixel means' spread) plus the table's
/// 0.3% round-up on E ≈ 0.1 of 1. The depth (8) leaves the inter-reflections between the
/// faces beyond it below 1e-6.
#[test]
fn a_pane_in_a_uniform_sky_is_a_white_furnace() {
    for ior in [1.33f32, 1.5, 2.4] {
        let mut desc = SceneDesc {
            name: "furnace".into(),
            camera: camera(Vec3::new(0.0, 0.0, 2.0), Vec3::ZERO),
            environment: Some(EnvironmentDesc::constant(Vec3::ONE)),
            ..SceneDesc::default()
        };
        // Turned 50° so the camera sees it at angles from 30° to 70°.
        let tilt = Vec3::new(50f32.to_radians().sin(), 0.0, 50f32.to_radians().cos());
        add_pane(&mut desc, &square(Vec3::ZERO, tilt, 0.6), tilt, ior);
        let scene = Scene::from_desc(desc, "furnace").unwrap();
        let settings = RenderSettings {
            strategy: Strategy::Antishadow,
            max_depth: 8,
            sampler: SamplerKind::Independent,
            ..RenderSettings::default()
        };
        let integrator = Integrator::new(&scene, settings);
        let (film, _) = render(&integrator, 24, 24, 256);
        let pixels: Vec<f64> = film.mean().iter().map(|c| c.x as f64).collect();
        let (mean, se) = mean_and_se(&pixels);
        let tolerance = 4.0 * se + 0.003 * 0.1;
        assert!((mean - 1.0).abs() <= tolerance, "ior {ior}: {mean} ± {se}");
        // The negative case: the glass's reflection alone is about 4·E ≈ 8–30% of the light
        // (both faces, both ways), far beyond the tolerance, so a pane that lost it (or
        // doubled it) would fail.
        let transmitted_only = scene.geometry.materials[0].straight_through(0.64).x as f64;
        assert!(
            (transmitted_only.powi(2) - 1.0).abs() > 5.0 * tolerance,
            "{transmitted_only}"
        );
    }
}

/// Scenes without glass are untouched: nothing there is a pane, and the built-ins with glass
/// have them.
#[test]
fn only_scenes_with_glass_have_panes() {
    for name in builtin::NAMES {
        let scene = Scene::from_desc(builtin::desc(name).unwrap(), name).unwrap();
        assert_eq!(
            scene.geometry.has_panes,
            matches!(name, "panes" | "pendant"),
            "{name}"
        );
    }
}

/// Rough glass is a vertex that scatters to both sides: a single frosted sheet in a uniform sky
/// of radiance 1, seen by the camera with one vertex (depth 1), reflects and transmits all of
/// it, so every pixel is 1: light samples of the sky on both sides (their shadow rays leave
/// from the side they go to), BSDF samples through the sheet, and their MIS weights must all
/// be right. Tolerance: 4 standard errors of the pixel means, plus the albedo table's error on
/// the transmission lobe's normalisation (1.5e-3 over an albedo above 0.5) and its round-up.
/// The negative case: the reflection alone (what a renderer that ignored light from behind
/// would give) is below 0.3, far outside it.
#[test]
fn a_frosted_sheet_in_a_uniform_sky_is_a_white_furnace() {
    for roughness in [0.3f32, 0.6] {
        let mut desc = SceneDesc {
            name: "frosted".into(),
            camera: camera(Vec3::new(0.0, 0.0, 2.0), Vec3::ZERO),
            environment: Some(EnvironmentDesc::constant(Vec3::ONE)),
            ..SceneDesc::default()
        };
        desc.materials.push(MaterialDesc {
            roughness,
            ..MaterialDesc::clear_glass("frosted")
        });
        let tilt = Vec3::new(40f32.to_radians().sin(), 0.0, 40f32.to_radians().cos());
        desc.meshes
            .push(flat("sheet", 0, &[square(Vec3::ZERO, tilt, 0.5)]));
        let scene = Scene::from_desc(desc, "frosted").unwrap();
        assert!(!scene.geometry.has_panes);
        let settings = RenderSettings {
            sampler: SamplerKind::Independent,
            ..RenderSettings::default()
        };
        let integrator = Integrator::new(&scene, settings);
        let (film, stats) = render(&integrator, 16, 16, 512);
        assert_eq!(stats.nonfinite, 0);
        let pixels: Vec<f64> = film.mean().iter().map(|c| c.x as f64).collect();
        let (mean, se) = mean_and_se(&pixels);
        let tolerance = 4.0 * se + 1.5e-3 / 0.5 + 0.003;
        assert!(
            (mean - 1.0).abs() <= tolerance,
            "r {roughness}: {mean} ± {se}"
        );
        let e = scene.geometry.materials[0].specular_albedo(0.77) as f64;
        assert!(1.0 - e > 10.0 * tolerance && e < 0.3, "{e}");
    }
}

/// With polygon lights and no sky, the last bounce finds the light it reaches by intersecting
/// the polygons and one shadow ray (`Integrator::emission_along`): through panes too. A square
/// light over a floor, a pane between them over half the floor, depth 2: passing equals
/// stopping, per block.
#[test]
fn a_pane_under_a_polygon_light_passes_its_light_without_bias() {
    let light = square(Vec3::new(0.0, 2.0, 0.0), -Vec3::Y, 0.6);
    let mut desc = floor_and_light(0.6, light, 10.0);
    let pane = [
        Vec3::new(-0.2, 1.0, -1.5),
        Vec3::new(1.5, 1.0, -1.5),
        Vec3::new(1.5, 1.0, 1.5),
        Vec3::new(-0.2, 1.0, 1.5),
    ];
    add_pane(&mut desc, &pane, Vec3::Y, 1.5);
    desc.camera = camera(Vec3::new(0.0, 1.6, 2.2), Vec3::new(0.0, 0.0, 0.0));
    let scene = Scene::from_desc(desc, "pane under a light").unwrap();
    let film = |glass, spp, seed| {
        let settings = RenderSettings {
            strategy: Strategy::Light,
            seed,
            max_depth: 2,
            sampler: SamplerKind::Independent,
            glass,
            ..RenderSettings::default()
        };
        render(&Integrator::new(&scene, settings), 48, 36, spp).0
    };
    let stopped = film(GlassShadows::Stop, 2048, 1);
    let passing = film(GlassShadows::Pass, 256, 2);
    assert_agrees("pane under a polygon light", &passing, &stopped, true);
}
