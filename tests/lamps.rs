//! `KHR_lights_punctual` lamps: irradiance against closed forms through the full renderer,
//! Blender's units, picking among area lights and lamps, a lamp inside a shade, and the
//! loader's errors.
//!
//! Radiance is estimated by `common::floor_radiance` on a pure Lambertian floor, so the exact
//! answer is `albedo/π · E`. For a scene lit by lamps only, every estimate is deterministic
//! per point (the lamp's one direction, and BSDF samples that find nothing): the standard
//! error is then zero and the tolerance is float round-off, 1e-3 relative (the shading point
//! is offset 2e-4 off the floor, and f32 sums). Where area lights add noise, the tolerance is
//! 4 standard errors on top.

mod common;

use std::f32::consts::PI;
use std::fs;
use std::path::PathBuf;

use glam::Vec3;
use portalview::asset::desc::{LampDesc, LampKind, MaterialDesc, SceneDesc};
use portalview::light::estimator::{LightSampler, PickedLight};
use portalview::light::punctual::LUMENS_PER_WATT;
use portalview::light::{Selection, Strategy};
use portalview::render::integrator::{Integrator, RenderSettings};
use portalview::render::stats::Stats;
use portalview::sampling::{Rng, Sampler};
use portalview::scene::Scene;
use serde_json::{Value, json};

use common::{
    camera, flat, floor_and_light, floor_radiance, lambert_irradiance, lambertian, plate, portal,
    square,
};

const ROUND_OFF: f64 = 1e-3;

/// A white floor at y = 0 (material 0) and nothing else.
fn floor_only() -> SceneDesc {
    SceneDesc {
        name: "lamps".into(),
        materials: vec![MaterialDesc::diffuse("floor", Vec3::ONE)],
        meshes: vec![flat(
            "floor",
            0,
            &[vec![
                Vec3::new(-50.0, 0.0, -50.0),
                Vec3::new(-50.0, 0.0, 50.0),
                Vec3::new(50.0, 0.0, 50.0),
                Vec3::new(50.0, 0.0, -50.0),
            ]],
        )],
        portals: vec![],
        lamps: vec![],
        warnings: Vec::new(),
        images: Vec::new(),
        camera: camera(Vec3::new(0.0, 3.0, 3.0), Vec3::ZERO),
        environment: None,
    }
}

/// A white lamp of `watts_per_sr` W/sr (stored in candela, as files hold it).
fn lamp(
    name: &str,
    kind: LampKind,
    watts_per_sr: f32,
    position: Vec3,
    direction: Vec3,
) -> LampDesc {
    LampDesc {
        name: name.into(),
        kind,
        color: Vec3::ONE,
        intensity: watts_per_sr * LUMENS_PER_WATT,
        range: None,
        position,
        direction: direction.normalize(),
    }
}

fn scene_of(desc: SceneDesc) -> Scene {
    lambertian(Scene::from_desc(desc, "lamps").unwrap(), 0, 1.0)
}

fn radiance(scene: &Scene, strategy: Strategy, x: Vec3, n: usize) -> (f64, f64) {
    floor_radiance(scene, (strategy, None), x, n, 7)
}

/// Whether an estimate matches `expected` within 4 standard errors plus round-off.
fn agrees((mean, se): (f64, f64), expected: f64) -> bool {
    (mean - expected).abs() <= 4.0 * se + ROUND_OFF * expected.abs().max(1e-3)
}

/// The shading point the renderer uses for floor point `x` seen by [`floor_radiance`]'s camera
/// ray (from `x + (0.3, 1, 0.2)`): lifted off the floor and back toward the eye by its ray
/// offset.
fn shading_point(scene: &Scene, x: Vec3) -> Vec3 {
    let wo = Vec3::new(0.3, 1.0, 0.2).normalize();
    Integrator::shading_origin(x, Vec3::Y, wo, scene.geometry.scale())
}

/// `I · cos θ / d²` at floor point `x` (normal +y) from a lamp at `p`, times `extra`; taken
/// at the shading point the renderer uses, `x` lifted off the floor by its ray offset (which
/// matters where the spot's falloff or the range window is steep).
fn inverse_square(scene: &Scene, i: f32, p: Vec3, x: Vec3, extra: f32) -> f64 {
    let v = p - shading_point(scene, x);
    f64::from(i * extra * (v.y / v.length()) / v.length_squared())
}

#[test]
fn point_lamp_irradiance_follows_the_inverse_square_law() {
    let i = 10.0;
    let p = Vec3::new(0.2, 1.5, -0.1);
    let mut desc = floor_only();
    desc.lamps
        .push(lamp("bulb", LampKind::Point, i, p, Vec3::NEG_Z));
    let scene = scene_of(desc);
    for x in [
        Vec3::ZERO,
        Vec3::new(1.0, 0.0, 0.5),
        Vec3::new(-2.0, 0.0, 1.5),
        Vec3::new(3.0, 0.0, -4.0),
    ] {
        let expected = inverse_square(&scene, i, p, x, 1.0) / f64::from(PI);
        let estimate = radiance(&scene, Strategy::Antishadow, x, 64);
        assert!(
            estimate.1 < 1e-6,
            "a point lamp alone is deterministic: {estimate:?}"
        );
        assert!(
            agrees(estimate, expected),
            "{x}: {estimate:?} vs {expected}"
        );
        // Negative cases: candela taken as W/sr (the 1/683 missing), or no cos θ.
        assert!(!agrees(estimate, expected * 683.0));
        let without_cos = expected / f64::from((p - x).normalize().y);
        assert!(!agrees(estimate, without_cos), "{x}");
    }
}

#[test]
fn point_lamp_range_applies_the_smooth_window() {
    let (i, p, range) = (10.0, Vec3::new(0.0, 1.0, 0.0), 2.0);
    let mut desc = floor_only();
    desc.lamps.push(LampDesc {
        range: Some(range),
        ..lamp("bulb", LampKind::Point, i, p, Vec3::NEG_Z)
    });
    let scene = scene_of(desc);
    for x in [
        Vec3::ZERO,
        Vec3::new(1.2, 0.0, 0.0),
        Vec3::new(1.5, 0.0, 0.5),
    ] {
        let d = (p - shading_point(&scene, x)).length();
        let window = (1.0 - (d / range).powi(4)).clamp(0.0, 1.0);
        let expected = inverse_square(&scene, i, p, x, window) / f64::from(PI);
        let estimate = radiance(&scene, Strategy::Antishadow, x, 16);
        assert!(
            agrees(estimate, expected),
            "{x}: {estimate:?} vs {expected}"
        );
        assert!(!agrees(
            estimate,
            inverse_square(&scene, i, p, x, 1.0) / f64::from(PI)
        ));
    }
    // Beyond the range: nothing.
    let far = radiance(&scene, Strategy::Antishadow, Vec3::new(3.0, 0.0, 0.0), 16);
    assert_eq!(far.0, 0.0);
}

#[test]
fn spot_lamp_irradiance_follows_the_extensions_falloff() {
    let (i, p) = (20.0, Vec3::new(0.0, 2.0, 0.0));
    let (inner, outer) = (0.3f32, 0.6f32);
    let mut desc = floor_only();
    desc.lamps.push(lamp(
        "spot",
        LampKind::Spot {
            inner_cone: inner,
            outer_cone: outer,
        },
        i,
        p,
        Vec3::NEG_Y,
    ));
    let scene = scene_of(desc);
    let falloff = |theta: f32| {
        let t = ((theta.cos() - outer.cos()) / (inner.cos() - outer.cos())).clamp(0.0, 1.0);
        t * t
    };
    let mut in_band = 0;
    // Offsets r from the axis: angles 0, 0.24 (inside), 0.38, 0.46, 0.54 (falloff), 0.64 (out).
    for r in [0.0f32, 0.5, 0.8, 1.0, 1.2, 1.5] {
        let x = Vec3::new(r * 0.6, 0.0, r * 0.8);
        let xs = shading_point(&scene, x);
        // The angle off the lamp's axis (straight down) at the shading point itself.
        let v = xs - p;
        let theta = (-v.y / v.length()).clamp(-1.0, 1.0).acos();
        let expected = inverse_square(&scene, i, p, x, falloff(theta)) / f64::from(PI);
        let estimate = radiance(&scene, Strategy::Antishadow, x, 16);
        assert!(
            agrees(estimate, expected),
            "r {r}: {estimate:?} vs {expected}"
        );
        // Negative case: without the falloff, points in the band disagree.
        let hard = inverse_square(&scene, i, p, x, if theta < outer { 1.0 } else { 0.0 });
        if theta > inner && theta < outer {
            in_band += 1;
            assert!(!agrees(estimate, hard / f64::from(PI)), "r {r}");
        }
    }
    assert_eq!(in_band, 3);
}

#[test]
fn directional_lamp_gives_e_perp_times_cosine() {
    let e_perp = 3.0;
    let direction = Vec3::new(0.3, -1.0, 0.2).normalize();
    let mut desc = floor_only();
    desc.lamps.push(lamp(
        "sun",
        LampKind::Directional,
        e_perp,
        Vec3::new(0.0, 10.0, 0.0),
        direction,
    ));
    // A small roof over one point: the sun's shadow ray goes to infinity and meets it.
    desc.materials
        .push(MaterialDesc::diffuse("roof", Vec3::splat(0.5)));
    let roof_centre = Vec3::new(4.0, 0.0, 4.0) - direction * 2.0;
    desc.meshes
        .push(flat("roof", 1, &[square(roof_centre, Vec3::Y, 0.3)]));
    let scene = scene_of(desc);
    let cos = -direction.y;
    let expected = f64::from(e_perp * cos / PI);
    for x in [
        Vec3::ZERO,
        Vec3::new(-3.0, 0.0, 2.0),
        Vec3::new(7.0, 0.0, -9.0),
    ] {
        let estimate = radiance(&scene, Strategy::Antishadow, x, 16);
        assert!(
            agrees(estimate, expected),
            "{x}: {estimate:?} vs {expected}"
        );
        // Negative case: without cos θ.
        assert!(!agrees(estimate, f64::from(e_perp / PI)));
    }
    let shadowed = radiance(&scene, Strategy::Antishadow, Vec3::new(4.0, 0.0, 4.0), 16);
    assert_eq!(shadowed.0, 0.0, "under the roof");
}

/// A lamp-shade: a box around a point lamp, open at the bottom, with a portal on the opening.
fn lamp_in_shade(portal_target: Option<&str>) -> SceneDesc {
    let p = Vec3::new(0.0, 1.5, 0.0);
    let mut desc = floor_only();
    desc.lamps
        .push(lamp("bulb", LampKind::Point, 5.0, p, Vec3::NEG_Y));
    desc.materials
        .push(MaterialDesc::diffuse("shade", Vec3::splat(0.7)));
    let (h, y0, y1) = (0.3, 1.2, 1.8);
    let hole = (0.15, 0.45, 0.15, 0.45);
    let mut faces = plate(
        Vec3::new(-h, y0, -h),
        (Vec3::X, 2.0 * h),
        (Vec3::Z, 2.0 * h),
        &[hole],
    );
    faces.push(square(Vec3::new(0.0, y1, 0.0), -Vec3::Y, h));
    for n in [Vec3::X, -Vec3::X, Vec3::Z, -Vec3::Z] {
        let c = Vec3::new(0.0, 0.5 * (y0 + y1), 0.0) + n * h;
        faces.push(square(c, -n, h));
    }
    desc.meshes.push(flat("shade", 1, &faces));
    if let Some(target) = portal_target {
        let opening = square(Vec3::new(0.0, y0, 0.0), -Vec3::Y, 0.15);
        desc.portals.push(portal("opening", target, 0.1, &opening));
    }
    desc
}

#[test]
fn point_lamp_inside_a_shade_lights_through_the_opening_only() {
    let scene = scene_of(lamp_in_shade(None));
    let p = Vec3::new(0.0, 1.5, 0.0);
    // Below the opening: the lamp's inverse-square light; beside the shade: its shadow.
    for x in [
        Vec3::ZERO,
        Vec3::new(0.2, 0.0, -0.1),
        Vec3::new(-0.3, 0.0, 0.2),
    ] {
        let expected = inverse_square(&scene, 5.0, p, x, 1.0) / f64::from(PI);
        let estimate = radiance(&scene, Strategy::Antishadow, x, 16);
        assert!(
            agrees(estimate, expected),
            "{x}: {estimate:?} vs {expected}"
        );
    }
    for x in [Vec3::new(2.0, 0.0, 0.0), Vec3::new(0.0, 0.0, -3.0)] {
        assert_eq!(radiance(&scene, Strategy::Antishadow, x, 16).0, 0.0, "{x}");
    }
    // With bounces, a point in the shade's shadow is lit by the floor below the opening
    // (the lamp is sampled again at every vertex): some light, all of it finite.
    let integrator = Integrator::new(
        &scene,
        RenderSettings {
            max_depth: 4,
            ..RenderSettings::default()
        },
    );
    let x = Vec3::new(2.0, 0.0, 0.0);
    let eye = x + Vec3::new(0.3, 1.0, 0.2);
    let mut stats = Stats::default();
    let total: f32 = (0..4000)
        .map(|k| {
            let mut rng = Sampler::from(Rng::keyed(3, &[k]));
            let l = integrator.radiance(eye, (x - eye).normalize(), &mut rng, &mut stats);
            assert!(l.is_finite());
            l.x
        })
        .sum();
    assert!(total > 0.0, "no indirect light reached the shadow");
    assert_eq!(stats.nonfinite, 0);
}

#[test]
fn a_portal_naming_a_lamp_is_an_error() {
    let Err(error) = Scene::from_desc(lamp_in_shade(Some("bulb")), "shade.gltf") else {
        panic!("a portal onto a lamp must be refused");
    };
    let message = error.to_string();
    assert!(
        message.contains("shade.gltf")
            && message.contains("'opening'")
            && message.contains("'bulb'")
            && message.contains("lamp"),
        "{message}"
    );
    // The same through an edit in the viewer: refused, the others kept.
    let scene = Scene::from_desc(lamp_in_shade(None), "shade.gltf").unwrap();
    let desc = lamp_in_shade(Some("bulb"));
    assert!(scene.with_portals(desc.portals.clone()).is_err());
    let (_, errors) = scene.with_portals_lenient(desc.portals);
    assert_eq!(errors.len(), 1);
}

/// An area light with a portal, and a point lamp: picked by power, and every strategy's
/// image agrees with the closed forms summed.
#[test]
fn lamps_and_area_lights_are_picked_by_power_and_strategies_agree() {
    let le = 8.0;
    let light = square(Vec3::new(0.0, 2.0, 0.0), -Vec3::Y, 0.4);
    let mut desc = floor_and_light(1.0, light.clone(), le);
    desc.portals.push(portal(
        "window",
        "light",
        0.1,
        &square(Vec3::new(0.0, 1.6, 0.0), -Vec3::Y, 0.3),
    ));
    let without_lamp = Scene::from_desc(desc.clone(), "mixed").unwrap();
    let sampler = LightSampler::new(&without_lamp, Strategy::Antishadow, None);
    let (x, n) = (Vec3::new(0.3, 0.0, 0.1), Vec3::Y);
    assert_eq!(sampler.light_probability(0, x, n), 1.0);

    let (i, p) = (1.5, Vec3::new(1.0, 1.0, 0.5));
    desc.lamps
        .push(lamp("bulb", LampKind::Point, i, p, Vec3::NEG_Z));
    let scene = lambertian(Scene::from_desc(desc, "mixed").unwrap(), 0, 1.0);
    let area_power = PI * le * 0.8 * 0.8;
    let lamp_power = 4.0 * PI * i;
    let sampler =
        LightSampler::with_selection(&scene, Strategy::Antishadow, None, Selection::Power);
    let expected_p = lamp_power / (lamp_power + area_power);
    let lamp_p = sampler.probability(PickedLight::Lamp(0), x, n);
    assert!((lamp_p - expected_p).abs() < 1e-5);
    assert!((sampler.light_probability(0, x, n) - (1.0 - expected_p)).abs() < 1e-5);

    for x in [Vec3::new(0.1, 0.0, 0.2), Vec3::new(1.2, 0.0, -0.6)] {
        let area = lambert_irradiance(x, Vec3::Y, &light, le);
        let expected =
            f64::from((area + i * (p - x).normalize().y / (p - x).length_squared()) / PI);
        let without = f64::from(area / PI);
        for strategy in Strategy::ALL {
            let estimate = radiance(&scene, strategy, x, 40_000);
            assert!(
                agrees(estimate, expected),
                "{} at {x}: {estimate:?} vs {expected}",
                strategy.name()
            );
            // Negative case: the lamp's share left out.
            assert!(!agrees(estimate, without), "{}", strategy.name());
        }
    }
}

fn temp_file(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("portalview-lamps-{}", std::process::id()));
    fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// A glTF as Blender 3.4's exporter writes it: a 10 m white plane (Y-up) and lamp nodes.
fn blender_style(lights: Value, lamp_nodes: Vec<Value>) -> Value {
    let positions: [[f32; 3]; 4] = [
        [-5.0, 0.0, 5.0],
        [5.0, 0.0, 5.0],
        [5.0, 0.0, -5.0],
        [-5.0, 0.0, -5.0],
    ];
    let mut bytes: Vec<u8> = positions
        .iter()
        .flatten()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    let index_offset = bytes.len();
    bytes.extend([0u16, 1, 2, 0, 2, 3].iter().flat_map(|i| i.to_le_bytes()));
    let mut nodes = vec![json!({"name": "Plane", "mesh": 0})];
    nodes.extend(lamp_nodes);
    json!({
        "asset": {"version": "2.0", "generator": "Khronos glTF Blender I/O v3.4.50"},
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": lights}},
        "scene": 0,
        "scenes": [{"name": "Scene", "nodes": (0..nodes.len()).collect::<Vec<_>>()}],
        "nodes": nodes,
        "materials": [{"name": "White", "pbrMetallicRoughness":
            {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0}}],
        "meshes": [{"name": "Plane", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [-5.0, 0.0, -5.0], "max": [5.0, 0.0, 5.0]},
            {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": index_offset},
            {"buffer": 0, "byteOffset": index_offset, "byteLength": bytes.len() - index_offset}
        ],
        "buffers": [{"byteLength": bytes.len(),
                     "uri": format!("data:application/octet-stream;base64,{}", base64::encode(&bytes))}]
    })
}

/// Blender 3.4 exports a point lamp of P watts as `intensity = P · 683 / (4π)` cd, and Cycles
/// renders a white Lambertian plane 1 m below a 100 W lamp with radiance 100/(4π²) = 2.533.
#[test]
fn blender_100_watt_point_lamp_gives_cycles_radiance() {
    let watts = 100.0f32;
    let candela = watts * 683.0 / (4.0 * PI);
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let doc = blender_style(
        json!([{"name": "Point", "type": "point", "color": [1.0, 1.0, 1.0], "intensity": candela}]),
        vec![
            json!({"name": "Point", "translation": [0.0, 1.0, 0.0], "rotation": [-s, 0.0, 0.0, s],
                    "extensions": {"KHR_lights_punctual": {"light": 0}}}),
        ],
    );
    let path = temp_file("blender-point.gltf");
    fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let scene = lambertian(Scene::load(&path).unwrap(), 0, 1.0);
    assert_eq!(scene.geometry.lamps.len(), 1);
    let estimate = radiance(&scene, Strategy::Antishadow, Vec3::ZERO, 16);
    let cycles = f64::from(watts / (4.0 * PI * PI));
    assert!((cycles - 2.533).abs() < 1e-3);
    assert!(agrees(estimate, cycles), "{estimate:?} vs {cycles}");
    // Negative case: reading candela as W/sr would be 683 times too bright.
    assert!(!agrees(estimate, cycles * 683.0));
    let _ = fs::remove_file(&path);
}

/// Blender 3.4's spot and sun, written as its exporter does: a spot of P watts as a point lamp
/// of P watts (`P · 683 / (4π)` cd) with `outerConeAngle` = size/2 and `innerConeAngle` =
/// size/2 · (1 − blend); a sun of S W/m² as `S · 683` lx. On the spot's axis and under the sun,
/// portalview and Cycles agree: P/(4π) W/sr, and S W/m² on a surface facing the sun.
#[test]
fn blender_spot_and_sun_give_their_watts() {
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let down = json!([-s, 0.0, 0.0, s]);
    let (watts, size, blend) = (100.0f32, 1.2f32, 0.5f32);
    let spot = json!([{"name": "Spot", "type": "spot", "intensity": watts * 683.0 / (4.0 * PI),
        "spot": {"outerConeAngle": size / 2.0, "innerConeAngle": size / 2.0 * (1.0 - blend)}}]);
    let strength = 3.0f32;
    let sun = json!([{"name": "Sun", "type": "directional", "intensity": strength * 683.0}]);
    let cases = [
        (spot, [0.0, 1.0, 0.0], f64::from(watts / (4.0 * PI * PI))),
        (sun, [0.0, 4.0, 0.0], f64::from(strength / PI)),
    ];
    for (k, (lights, translation, expected)) in cases.into_iter().enumerate() {
        let node = json!({"name": "Lamp", "translation": translation, "rotation": down,
                          "extensions": {"KHR_lights_punctual": {"light": 0}}});
        let path = temp_file(&format!("blender-{k}.gltf"));
        fs::write(
            &path,
            serde_json::to_vec(&blender_style(lights, vec![node])).unwrap(),
        )
        .unwrap();
        let scene = lambertian(Scene::load(&path).unwrap(), 0, 1.0);
        let lamp = &scene.desc.lamps[0];
        assert!(lamp.direction.abs_diff_eq(Vec3::NEG_Y, 1e-6), "points down");
        if let LampKind::Spot {
            inner_cone,
            outer_cone,
        } = lamp.kind
        {
            assert!((outer_cone - 0.6).abs() < 1e-6 && (inner_cone - 0.3).abs() < 1e-6);
        }
        let estimate = radiance(&scene, Strategy::Antishadow, Vec3::ZERO, 16);
        assert!(
            agrees(estimate, expected),
            "case {k}: {estimate:?} vs {expected}"
        );
        assert!(!agrees(estimate, expected * 683.0), "case {k}");
        let _ = fs::remove_file(&path);
    }
}

#[test]
fn bad_lamps_are_errors_naming_the_file_and_node() {
    let node = |light: usize| {
        json!({"name": "Lamp.007", "translation": [0.0, 1.0, 0.0],
               "extensions": {"KHR_lights_punctual": {"light": light}}})
    };
    let cases = [
        (json!([{"type": "point", "intensity": -5.0}]), "intensity"),
        (json!([{"type": "point", "range": 0.0}]), "range"),
        (
            json!([{"type": "point", "color": [1.0, -1.0, 0.0]}]),
            "color",
        ),
        (
            json!([{"type": "spot", "spot": {"innerConeAngle": 0.7, "outerConeAngle": 0.5}}]),
            "spot",
        ),
        (
            json!([{"type": "spot", "spot": {"innerConeAngle": 0.1, "outerConeAngle": 2.0}}]),
            "spot",
        ),
    ];
    for (k, (lights, field)) in cases.into_iter().enumerate() {
        let path = temp_file(&format!("bad-{k}.gltf"));
        fs::write(
            &path,
            serde_json::to_vec(&blender_style(lights, vec![node(0)])).unwrap(),
        )
        .unwrap();
        let message = match Scene::load(&path) {
            Ok(_) => panic!("case {k} must be refused"),
            Err(e) => e.to_string(),
        };
        assert!(
            message.contains(&path.display().to_string())
                && message.contains("Lamp.007")
                && message.contains(field),
            "case {k}: {message}"
        );
        let _ = fs::remove_file(&path);
    }
    // A node naming a light that does not exist.
    let path = temp_file("missing.gltf");
    let doc = blender_style(json!([{"type": "point"}]), vec![node(3)]);
    fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let message = Scene::load(&path).map(|_| ()).unwrap_err().to_string();
    assert!(message.contains(&path.display().to_string()), "{message}");
    let _ = fs::remove_file(&path);
}
