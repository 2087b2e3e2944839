//! glTF loading, exporting and portal saving, checked against hand-computed answers, plus a
//! corpus of broken files that must give errors naming the file (and the node or field), never
//! panics.

use std::f32::consts::FRAC_PI_2;
use std::fs;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use glam::{Mat4, Quat, Vec3};
use portalview::asset::desc::{LampDesc, LampKind, MaterialDesc, MeshDesc, PortalDesc, SceneDesc};
use portalview::asset::gltf::{export_glb, load_gltf, save_portals};
use portalview::camera::Camera;
use serde_json::{Value, json};

const EPS: f32 = 1e-5;

/// A fresh directory under the system's temporary directory.
fn temp_dir(test: &str) -> PathBuf {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let dir = std::env::temp_dir().join(format!(
        "portalview-gltf-{test}-{}-{}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    dir
}

/// Binary data with the bufferViews and accessors that describe it (buffer 0).
#[derive(Default)]
struct Bin {
    bytes: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Bin {
    fn view(&mut self, data: &[u8]) -> usize {
        while !self.bytes.len().is_multiple_of(4) {
            self.bytes.push(0);
        }
        self.views.push(json!({
            "buffer": 0, "byteOffset": self.bytes.len(), "byteLength": data.len()
        }));
        self.bytes.extend_from_slice(data);
        self.views.len() - 1
    }

    fn vec3s(&mut self, values: &[[f32; 3]]) -> usize {
        let data: Vec<u8> = values
            .iter()
            .flatten()
            .flat_map(|x| x.to_le_bytes())
            .collect();
        let view = self.view(&data);
        let lo = values
            .iter()
            .fold([f32::MAX; 3], |m, v| [0, 1, 2].map(|k| m[k].min(v[k])));
        let hi = values
            .iter()
            .fold([f32::MIN; 3], |m, v| [0, 1, 2].map(|k| m[k].max(v[k])));
        self.accessors.push(json!({
            "bufferView": view, "componentType": 5126, "count": values.len(), "type": "VEC3",
            "min": lo, "max": hi
        }));
        self.accessors.len() - 1
    }

    fn vec2s(&mut self, values: &[[f32; 2]]) -> usize {
        let data: Vec<u8> = values
            .iter()
            .flatten()
            .flat_map(|x| x.to_le_bytes())
            .collect();
        let view = self.view(&data);
        self.accessors.push(json!({
            "bufferView": view, "componentType": 5126, "count": values.len(), "type": "VEC2"
        }));
        self.accessors.len() - 1
    }

    fn indices(&mut self, values: &[u16]) -> usize {
        let data: Vec<u8> = values.iter().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&data);
        self.accessors.push(json!({
            "bufferView": view, "componentType": 5123, "count": values.len(), "type": "SCALAR"
        }));
        self.accessors.len() - 1
    }

    fn data_uri(&self) -> String {
        format!(
            "data:application/octet-stream;base64,{}",
            base64(&self.bytes)
        )
    }
}

fn base64(data: &[u8]) -> String {
    const ALPHABET: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for chunk in data.chunks(3) {
        let b = [0, 1, 2].map(|k| u32::from(*chunk.get(k).unwrap_or(&0)));
        let n = (b[0] << 16) | (b[1] << 8) | b[2];
        for k in 0..4 {
            out.push(if k <= chunk.len() {
                char::from(ALPHABET[(n >> (18 - 6 * k) & 63) as usize])
            } else {
                '='
            });
        }
    }
    out
}

fn write_json(path: &Path, doc: &Value) {
    fs::write(path, serde_json::to_vec_pretty(doc).unwrap()).unwrap();
}

fn close(a: Vec3, b: Vec3) -> bool {
    a.abs_diff_eq(b, EPS)
}

fn assert_portal_close(a: &PortalDesc, b: &PortalDesc) {
    assert_eq!(a.name, b.name);
    assert_eq!(a.target, b.target);
    assert!((a.alpha - b.alpha).abs() < EPS, "{} alpha", a.name);
    assert_eq!(
        a.local_triangles.len(),
        b.local_triangles.len(),
        "{}",
        a.name
    );
    for (s, t) in a.local_triangles.iter().zip(&b.local_triangles) {
        for (p, q) in s.iter().zip(t) {
            assert!(close(*p, *q), "{}: {p} vs {q}", a.name);
        }
    }
    assert!(
        a.world_from_local.abs_diff_eq(b.world_from_local, EPS),
        "{}: {} vs {}",
        a.name,
        a.world_from_local,
        b.world_from_local
    );
}

/// Equal up to float round-off, the scene's name and portal node indices.
fn assert_scenes_close(a: &SceneDesc, b: &SceneDesc) {
    assert_eq!(a.materials.len(), b.materials.len());
    for (m, n) in a.materials.iter().zip(&b.materials) {
        assert_eq!(m.name, n.name);
        assert!(close(m.base_color, n.base_color), "{}", m.name);
        assert!((m.metallic - n.metallic).abs() < EPS);
        assert!((m.roughness - n.roughness).abs() < EPS);
        assert!(close(m.emissive_factor, n.emissive_factor), "{}", m.name);
        assert!((m.emissive_strength - n.emissive_strength).abs() < EPS * m.emissive_strength);
        assert_eq!(m.specular_factor, n.specular_factor, "{}", m.name);
        assert_eq!(m.specular_color, n.specular_color, "{}", m.name);
        assert_eq!(m.ior, n.ior, "{}", m.name);
        assert_eq!(m.transmission, n.transmission, "{}", m.name);
        assert_eq!(m.volume, n.volume, "{}", m.name);
        assert_eq!(m.double_sided, n.double_sided, "{}", m.name);
    }
    assert_eq!(a.meshes.len(), b.meshes.len());
    for (m, n) in a.meshes.iter().zip(&b.meshes) {
        assert_eq!(m.node_name, n.node_name);
        assert_eq!(m.material, n.material);
        assert_eq!(m.indices, n.indices, "{}", m.node_name);
        assert_eq!(m.positions.len(), n.positions.len());
        assert!(
            m.positions
                .iter()
                .zip(&n.positions)
                .all(|(p, q)| close(*p, *q))
        );
        assert_eq!(m.normals.len(), n.normals.len());
        assert!(m.normals.iter().zip(&n.normals).all(|(p, q)| close(*p, *q)));
    }
    assert_eq!(a.portals.len(), b.portals.len());
    for (p, q) in a.portals.iter().zip(&b.portals) {
        assert_portal_close(p, q);
    }
    assert_eq!(a.lamps.len(), b.lamps.len());
    for (l, m) in a.lamps.iter().zip(&b.lamps) {
        assert_eq!((&l.name, l.kind, l.range), (&m.name, m.kind, m.range));
        assert!(close(l.color, m.color) && (l.intensity - m.intensity).abs() < EPS);
        assert!(close(l.position, m.position) && close(l.direction, m.direction));
    }
    match (&a.camera, &b.camera) {
        (None, None) => {}
        (Some(c), Some(d)) => {
            assert!(close(c.eye, d.eye) && close(c.target, d.target) && close(c.up, d.up));
            assert!((c.yfov - d.yfov).abs() < EPS && (c.aspect - d.aspect).abs() < EPS);
        }
        _ => panic!("one scene has a camera, the other not"),
    }
}

fn quad(name: &str, material: usize, corners: [Vec3; 4], normal: Vec3) -> MeshDesc {
    MeshDesc {
        node_name: name.to_owned(),
        material,
        positions: corners.to_vec(),
        normals: vec![normal; 4],
        indices: vec![[0, 1, 2], [0, 2, 3]],
        ..MeshDesc::default()
    }
}

fn unit_square() -> Vec<[Vec3; 3]> {
    let [a, b, c, d] = [
        Vec3::new(-0.5, -0.5, 0.0),
        Vec3::new(0.5, -0.5, 0.0),
        Vec3::new(0.5, 0.5, 0.0),
        Vec3::new(-0.5, 0.5, 0.0),
    ];
    vec![[a, b, c], [a, c, d]]
}

/// A floor, a one-sided emissive quad light facing down, a portal below it, a camera.
fn sample_scene() -> SceneDesc {
    let floor = quad(
        "floor",
        0,
        [
            Vec3::new(-2.0, 0.0, 2.0),
            Vec3::new(2.0, 0.0, 2.0),
            Vec3::new(2.0, 0.0, -2.0),
            Vec3::new(-2.0, 0.0, -2.0),
        ],
        Vec3::Y,
    );
    let light = quad(
        "light",
        1,
        [
            Vec3::new(-0.5, 3.0, -0.5),
            Vec3::new(0.5, 3.0, -0.5),
            Vec3::new(0.5, 3.0, 0.5),
            Vec3::new(-0.5, 3.0, 0.5),
        ],
        Vec3::NEG_Y,
    );
    SceneDesc {
        name: "sample".to_owned(),
        materials: vec![
            MaterialDesc::diffuse("floor", Vec3::new(0.7, 0.6, 0.5)),
            MaterialDesc::emitter("light", Vec3::new(20.0, 18.0, 15.0), false),
        ],
        meshes: vec![floor, light],
        portals: vec![PortalDesc {
            name: "window".to_owned(),
            target: "light".to_owned(),
            alpha: 0.25,
            auto_alpha: false,
            local_triangles: unit_square(),
            world_from_local: Mat4::from_rotation_translation(
                Quat::from_rotation_x(FRAC_PI_2),
                Vec3::new(0.0, 2.0, 0.0),
            ),
            node_index: None,
        }],
        lamps: vec![
            LampDesc {
                name: "bulb".to_owned(),
                kind: LampKind::Point,
                color: Vec3::new(1.0, 0.9, 0.7),
                intensity: 5435.2,
                range: None,
                position: Vec3::new(0.5, 1.5, -0.5),
                direction: Vec3::NEG_Z,
            },
            LampDesc {
                name: "spot".to_owned(),
                kind: LampKind::Spot {
                    inner_cone: 0.3,
                    outer_cone: 0.6,
                },
                color: Vec3::ONE,
                intensity: 800.0,
                range: Some(7.5),
                position: Vec3::new(-1.0, 2.5, 0.0),
                direction: Vec3::new(0.3, -1.0, 0.2).normalize(),
            },
            LampDesc {
                name: "sun".to_owned(),
                kind: LampKind::Directional,
                color: Vec3::new(1.0, 0.95, 0.9),
                intensity: 2049.0,
                range: None,
                position: Vec3::ZERO,
                direction: Vec3::new(-0.2, -1.0, -0.4).normalize(),
            },
        ],
        camera: Some(Camera {
            eye: Vec3::new(0.0, 1.0, 5.0),
            target: Vec3::new(0.0, 1.0, 0.0),
            up: Vec3::Y,
            yfov: 0.7,
            aspect: 1.5,
        }),
        environment: None,
        warnings: Vec::new(),
        images: Vec::new(),
    }
}

#[test]
fn export_then_load_round_trips() {
    let dir = temp_dir("round-trip");
    let path = dir.join("scene.glb");
    let desc = sample_scene();
    export_glb(&desc, &path).unwrap();

    let loaded = load_gltf(&path).unwrap();
    assert_eq!(loaded.name, "scene");
    assert_eq!(loaded.portals[0].node_index, Some(2));
    assert_scenes_close(&loaded, &desc);
    assert_eq!(loaded.materials[1].radiance(), desc.materials[1].radiance());

    // The strength extension is declared, and the file is one GLB with a BIN chunk.
    let bytes = fs::read(&path).unwrap();
    let glb = gltf::Glb::from_slice(&bytes).unwrap();
    assert!(glb.bin.is_some());
    let doc = gltf::Gltf::from_slice(&bytes).unwrap();
    assert!(
        doc.extensions_used()
            .any(|e| e == "KHR_materials_emissive_strength")
    );
    assert!(doc.extensions_used().any(|e| e == "KHR_lights_punctual"));
    // Exporting what was loaded gives the same scene again.
    let again = dir.join("again.glb");
    export_glb(&loaded, &again).unwrap();
    assert_scenes_close(&load_gltf(&again).unwrap(), &desc);
    let _ = fs::remove_dir_all(&dir);
}

/// A `.gltf` with an external buffer (whose name needs percent-encoding): a rotated and
/// translated parent with a scaled child, and a mirrored node whose mesh has no normals and
/// no indices.
fn write_nested(dir: &Path) -> PathBuf {
    let mut bin = Bin::default();
    let triangle = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let positions = bin.vec3s(&triangle);
    let normals = bin.vec3s(&[[0.0, 0.0, 1.0]; 3]);
    let indices = bin.indices(&[0, 1, 2]);
    let bare = bin.vec3s(&triangle);
    fs::write(dir.join("nested data.bin"), &bin.bytes).unwrap();
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let doc = json!({
        "asset": {"version": "2.0"},
        "buffers": [{"uri": "nested%20data.bin", "byteLength": bin.bytes.len()}],
        "bufferViews": bin.views,
        "accessors": bin.accessors,
        "meshes": [
            {"name": "Tri", "primitives": [{"attributes": {"POSITION": positions, "NORMAL": normals}, "indices": indices}]},
            {"name": "Bare", "primitives": [{"attributes": {"POSITION": bare}}]}
        ],
        "nodes": [
            {"name": "Parent", "translation": [1.0, 2.0, 3.0], "rotation": [0.0, s, 0.0, s], "children": [1]},
            {"name": "Child", "scale": [2.0, 2.0, 2.0], "mesh": 0},
            {"name": "Mirror", "scale": [-1.0, 1.0, 1.0], "translation": [0.0, 0.0, -5.0], "mesh": 1}
        ],
        "scenes": [{"nodes": [0, 2]}],
        "scene": 0
    });
    let path = dir.join("nested.gltf");
    write_json(&path, &doc);
    path
}

fn geometric_normal(mesh: &MeshDesc, t: usize) -> Vec3 {
    let [a, b, c] = mesh.indices[t].map(|i| mesh.positions[i as usize]);
    (b - a).cross(c - a).normalize()
}

#[test]
fn external_bin_and_nested_transforms_give_world_space() {
    let dir = temp_dir("nested");
    let scene = load_gltf(&write_nested(&dir)).unwrap();
    assert_eq!(scene.name, "nested");
    assert!(scene.portals.is_empty() && scene.camera.is_none());
    // Primitives without a material share one appended default material.
    assert_eq!(scene.materials.len(), 1);
    assert_eq!(scene.materials[0].name, "default");
    assert!(close(scene.materials[0].base_color, Vec3::splat(0.8)));
    assert!(!scene.materials[0].double_sided);
    assert_eq!(scene.meshes.len(), 2);

    // Child: scale 2, then a quarter turn about +Y ((x, y, z) -> (z, y, -x)), then (1, 2, 3).
    let child = &scene.meshes[0];
    assert_eq!(child.node_name, "Child");
    let expected = [
        Vec3::new(1.0, 2.0, 3.0),
        Vec3::new(1.0, 2.0, 1.0),
        Vec3::new(1.0, 4.0, 3.0),
    ];
    for (p, e) in child.positions.iter().zip(expected) {
        assert!(close(*p, e), "{p} vs {e}");
    }
    assert_eq!(child.indices, vec![[0, 1, 2]]);
    for n in &child.normals {
        assert!(close(*n, Vec3::X), "{n}");
    }
    assert!(close(geometric_normal(child, 0), Vec3::X));

    // Mirror: x negated, so the winding is flipped to keep the front face towards +Z.
    let mirror = &scene.meshes[1];
    assert_eq!(mirror.node_name, "Mirror");
    let expected = [
        Vec3::new(0.0, 0.0, -5.0),
        Vec3::new(-1.0, 0.0, -5.0),
        Vec3::new(0.0, 1.0, -5.0),
    ];
    for (p, e) in mirror.positions.iter().zip(expected) {
        assert!(close(*p, e), "{p} vs {e}");
    }
    assert_eq!(mirror.indices, vec![[0, 2, 1]]);
    assert!(close(geometric_normal(mirror, 0), Vec3::Z));
    for n in &mirror.normals {
        assert!(close(*n, Vec3::Z), "computed normal {n}");
    }
    let _ = fs::remove_dir_all(&dir);
}

/// Roughly what Blender writes: TRS nodes, custom properties as extras, the emissive strength
/// extension, a camera pitched down, a data-URI buffer.
fn write_blender_style(dir: &Path, name: &str) -> PathBuf {
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let mut bin = Bin::default();
    let square = [
        [-1.0, -1.0, 0.0],
        [1.0, -1.0, 0.0],
        [1.0, 1.0, 0.0],
        [-1.0, 1.0, 0.0],
    ];
    let square_positions = bin.vec3s(&square);
    let square_normals = bin.vec3s(&[[0.0, 0.0, 1.0]; 4]);
    let square_indices = bin.indices(&[0, 1, 2, 0, 2, 3]);
    let doc = json!({
        "asset": {"version": "2.0", "generator": "Khronos glTF Blender I/O v4.2.83"},
        "extensionsUsed": ["KHR_materials_emissive_strength", "KHR_texture_transform"],
        "extensionsRequired": ["KHR_texture_transform"],
        "scene": 0,
        "scenes": [{"name": "Scene", "nodes": [0, 1, 2, 3, 4]}],
        "nodes": [
            {"name": "Floor", "mesh": 0, "rotation": [-s, 0.0, 0.0, s], "scale": [5.0, 5.0, 1.0]},
            {"name": "Area Light", "mesh": 1, "translation": [0.0, 4.0, 0.0], "rotation": [s, 0.0, 0.0, s]},
            {"name": "Portal", "mesh": 2, "translation": [0.5, 2.0, -1.0],
             "rotation": [0.0, 0.3826834, 0.0, 0.9238795], "scale": [1.5, 0.5, 1.0],
             "extras": {"portal_target": "Area Light", "portal_light_probability": 0.3, "blender_note": "keep me"}},
            {"name": "Portal.001", "mesh": 2, "translation": [0.0, 1.0, 3.0],
             "extras": {"portal_target": "Area Light"}},
            {"name": "Camera", "camera": 0, "translation": [0.0, 3.0, 8.0],
             "rotation": [-0.2588190, 0.0, 0.0, 0.9659258]}
        ],
        "cameras": [{"name": "Camera", "type": "perspective",
                     "perspective": {"yfov": 0.6911112, "znear": 0.1, "zfar": 100.0}}],
        "materials": [
            {"name": "White", "doubleSided": true,
             "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.5}},
            {"name": "Emitter", "emissiveFactor": [1.0, 0.9, 0.8],
             "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 40.0}},
             "pbrMetallicRoughness": {"baseColorFactor": [0.0, 0.0, 0.0, 1.0]}}
        ],
        "meshes": [
            {"name": "Plane", "primitives": [{"attributes": {"POSITION": square_positions, "NORMAL": square_normals}, "indices": square_indices, "material": 0}]},
            {"name": "Plane.001", "primitives": [{"attributes": {"POSITION": square_positions, "NORMAL": square_normals}, "indices": square_indices, "material": 1}]},
            {"name": "PortalMesh", "primitives": [{"attributes": {"POSITION": square_positions}, "indices": square_indices}]}
        ],
        "accessors": bin.accessors,
        "bufferViews": bin.views,
        "buffers": [{"byteLength": bin.bytes.len(), "uri": bin.data_uri()}]
    });
    let path = dir.join(name);
    write_json(&path, &doc);
    path
}

#[test]
fn blender_style_portal_extras() {
    let dir = temp_dir("blender");
    let scene = load_gltf(&write_blender_style(&dir, "blender.gltf")).unwrap();
    let names: Vec<&str> = scene.meshes.iter().map(|m| m.node_name.as_str()).collect();
    assert_eq!(
        names,
        ["Floor", "Area Light"],
        "portal meshes are not geometry"
    );
    // The portal mesh has no material, but it is not geometry: no default material appears.
    assert_eq!(scene.materials.len(), 2);
    let emitter = &scene.materials[1];
    assert!((emitter.emissive_strength - 40.0).abs() < EPS);
    assert!(close(emitter.radiance(), Vec3::new(40.0, 36.0, 32.0)));
    assert!(scene.materials[0].double_sided && !emitter.double_sided);
    assert!((scene.materials[0].roughness - 0.5).abs() < EPS);

    // The floor's quad, rotated -90° about X and scaled 5, lies in y = 0 facing +Y.
    let floor = &scene.meshes[0];
    assert!(floor.positions.iter().all(|p| p.y.abs() < EPS));
    assert!(close(floor.positions[2], Vec3::new(5.0, 0.0, -5.0)));
    assert!(floor.normals.iter().all(|n| close(*n, Vec3::Y)));

    assert_eq!(scene.portals.len(), 2);
    let portal = &scene.portals[0];
    assert_eq!(portal.name, "Portal");
    assert_eq!(portal.target, "Area Light");
    assert!((portal.alpha - 0.3).abs() < EPS);
    assert_eq!(portal.node_index, Some(2));
    let [a, b, c, d] = [
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, -1.0, 0.0),
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(-1.0, 1.0, 0.0),
    ];
    assert_eq!(portal.local_triangles, vec![[a, b, c], [a, c, d]]);
    let expected = Mat4::from_scale_rotation_translation(
        Vec3::new(1.5, 0.5, 1.0),
        Quat::from_rotation_y(std::f32::consts::FRAC_PI_4),
        Vec3::new(0.5, 2.0, -1.0),
    );
    assert!(portal.world_from_local.abs_diff_eq(expected, 1e-5));
    let second = &scene.portals[1];
    assert_eq!(second.name, "Portal.001");
    assert!((second.alpha - 0.1).abs() < EPS, "default alpha");
    assert_eq!(second.node_index, Some(3));

    // Camera: pitched down 30°, aspect 4/3 when the file gives none.
    let Some(camera) = scene.camera else {
        panic!("the file has a camera");
    };
    let pitch = Quat::from_rotation_x(-30f32.to_radians());
    assert!(close(camera.eye, Vec3::new(0.0, 3.0, 8.0)));
    assert!(close(camera.target - camera.eye, pitch * Vec3::NEG_Z));
    assert!(close(camera.up, pitch * Vec3::Y));
    assert!((camera.yfov - 0.6911112).abs() < EPS);
    assert!((camera.aspect - 4.0 / 3.0).abs() < EPS);
    let _ = fs::remove_dir_all(&dir);
}

/// `portal_light_probability` as a scene extra is the alpha of the portals without their own;
/// `"auto"` (there or on a node) asks for the measured alpha; a bad value names the scene.
#[test]
fn scene_portal_alpha_and_auto() {
    let dir = temp_dir("scene_alpha");
    let path = write_blender_style(&dir, "blender.gltf");
    let mut doc: Value = serde_json::from_slice(&fs::read(&path).unwrap()).unwrap();
    doc["scenes"][0]["extras"] = json!({"portal_light_probability": "auto"});
    write_json(&path, &doc);
    let scene = load_gltf(&path).unwrap();
    let (own, default) = (&scene.portals[0], &scene.portals[1]);
    assert!(
        !own.auto_alpha && (own.alpha - 0.3).abs() < EPS,
        "its own alpha"
    );
    assert!(default.auto_alpha, "the scene's auto");

    doc["scenes"][0]["extras"] = json!({"portal_light_probability": 0.25});
    doc["nodes"][2]["extras"]["portal_light_probability"] = json!("auto");
    write_json(&path, &doc);
    let scene = load_gltf(&path).unwrap();
    assert!(scene.portals[0].auto_alpha, "the node's auto");
    assert!(!scene.portals[1].auto_alpha && (scene.portals[1].alpha - 0.25).abs() < EPS);

    doc["scenes"][0]["extras"] = json!({"portal_light_probability": "sometimes"});
    write_json(&path, &doc);
    let error = load_gltf(&path).unwrap_err().to_string();
    assert!(
        error.contains("blender.gltf")
            && error.contains("scene 0, extras.portal_light_probability"),
        "{error}"
    );
    let _ = fs::remove_dir_all(&dir);
}

#[test]
fn unread_extensions_and_textures_are_warnings_naming_the_file() {
    let dir = temp_dir("unread");
    let path = write_blender_style(&dir, "textured.gltf");
    // KHR_texture_transform is read: no warning.
    let scene = load_gltf(&path).unwrap();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    // An occlusion texture and an unread extension are.
    let mut doc: Value = serde_json::from_slice(&fs::read(&path).unwrap()).unwrap();
    doc["extensionsUsed"] = json!(["KHR_materials_emissive_strength", "KHR_materials_sheen"]);
    doc["materials"][0]["occlusionTexture"] = json!({"index": 0});
    doc["textures"] = json!([{"source": 0}]);
    fs::write(dir.join("ao.png"), png(1, 1, &[[255; 4]])).unwrap();
    doc["images"] = json!([{"uri": "ao.png"}]);
    // Vertex colours (the normals' accessor will do: a VEC3 of floats).
    let normals = doc["meshes"][0]["primitives"][0]["attributes"]["NORMAL"].clone();
    doc["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = normals;
    write_json(&path, &doc);
    let scene = load_gltf(&path).unwrap();
    assert_eq!(scene.warnings.len(), 3, "{:?}", scene.warnings);
    let all = scene.warnings.join("\n");
    for word in [
        "textured.gltf",
        "material 0 \"White\"",
        "occlusionTexture",
        "KHR_materials_sheen",
        "COLOR_0",
    ] {
        assert!(all.contains(word), "no \"{word}\" in {all}");
    }
    // A file that uses only what is read has no warnings.
    let plain = dir.join("plain.glb");
    export_glb(&sample_scene(), &plain).unwrap();
    assert!(load_gltf(&plain).unwrap().warnings.is_empty());
    let _ = fs::remove_dir_all(&dir);
}

/// An RGBA8 image of `width × height` texels as PNG bytes.
fn png(width: u32, height: u32, texels: &[[u8; 4]]) -> Vec<u8> {
    let raw: Vec<u8> = texels.iter().flatten().copied().collect();
    let image = image::RgbaImage::from_raw(width, height, raw).unwrap();
    let mut bytes = std::io::Cursor::new(Vec::new());
    image.write_to(&mut bytes, image::ImageFormat::Png).unwrap();
    bytes.into_inner()
}

/// An RGB image as JPEG bytes (quality 100).
fn jpeg(width: u32, height: u32, rgb: [u8; 3]) -> Vec<u8> {
    let raw: Vec<u8> = (0..width * height).flat_map(|_| rgb).collect();
    let image = image::RgbImage::from_raw(width, height, raw).unwrap();
    let mut bytes = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, 100)
        .encode_image(&image)
        .unwrap();
    bytes
}

/// A textured unit quad: POSITION, NORMAL, TEXCOORD_0 (u along x, v along −y) and
/// TEXCOORD_1 (swapped), material 0 "Painted" with `material` merged in, and these
/// `textures`, `images` and `samplers`; the binary data in `bin` (buffer 0).
fn textured_quad(
    mut bin: Bin,
    material: Value,
    textures: Value,
    images: Value,
    samplers: Value,
) -> (Value, Bin) {
    let square = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ];
    let p = bin.vec3s(&square);
    let n = bin.vec3s(&[[0.0, 0.0, 1.0]; 4]);
    let uv0 = bin.vec2s(&[[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]]);
    let uv1 = bin.vec2s(&[[1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 0.0]]);
    let i = bin.indices(&[0, 1, 2, 0, 2, 3]);
    let mut m = json!({"name": "Painted"});
    if let (Value::Object(m), Value::Object(extra)) = (&mut m, material) {
        m.extend(extra);
    }
    let doc = json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_texture_transform", "KHR_materials_specular"],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "Quad", "mesh": 0}],
        "meshes": [{"name": "QuadMesh", "primitives": [{"attributes":
            {"POSITION": p, "NORMAL": n, "TEXCOORD_0": uv0, "TEXCOORD_1": uv1},
            "indices": i, "material": 0}]}],
        "materials": [m],
        "textures": textures,
        "images": images,
        "samplers": samplers,
    });
    (doc, bin)
}

/// Finishes `doc` with `bin` as its buffer: a data URI for a `.gltf`.
fn with_data_uri(mut doc: Value, bin: &Bin) -> Value {
    doc["accessors"] = json!(bin.accessors);
    doc["bufferViews"] = json!(bin.views);
    doc["buffers"] = json!([{"byteLength": bin.bytes.len(), "uri": bin.data_uri()}]);
    doc
}

/// `doc` and `bin` as a GLB file's bytes (the BIN chunk is buffer 0).
fn glb(mut doc: Value, bin: &Bin) -> Vec<u8> {
    doc["accessors"] = json!(bin.accessors);
    doc["bufferViews"] = json!(bin.views);
    doc["buffers"] = json!([{"byteLength": bin.bytes.len()}]);
    let mut json_bytes = serde_json::to_vec(&doc).unwrap();
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    let mut data = bin.bytes.clone();
    while !data.len().is_multiple_of(4) {
        data.push(0);
    }
    let total = 12 + 8 + json_bytes.len() + 8 + data.len();
    let mut out = b"glTF".to_vec();
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((json_bytes.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(json_bytes);
    out.extend((data.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(data);
    out
}

/// Every texture slot, from a file next to the `.gltf`, a data URI and a GLB buffer view,
/// PNG and JPEG, with samplers, `KHR_texture_transform` and its `texCoord` override.
#[test]
fn textures_are_read_from_files_data_uris_and_glb() {
    let dir = temp_dir("textures");
    let red_green = png(2, 1, &[[255, 0, 0, 255], [0, 255, 0, 128]]);
    fs::write(dir.join("base color.png"), &red_green).unwrap();
    let normal = png(1, 1, &[[128, 128, 255, 255]]);
    let material = json!({
        "alphaMode": "MASK", "alphaCutoff": 0.3,
        "pbrMetallicRoughness": {
            "baseColorFactor": [1.0, 1.0, 1.0, 0.9],
            "baseColorTexture": {"index": 0, "extensions": {"KHR_texture_transform":
                {"offset": [0.5, 0.0], "rotation": 0.25, "scale": [2.0, 3.0], "texCoord": 1}}},
            "metallicRoughnessTexture": {"index": 1, "texCoord": 1}
        },
        "normalTexture": {"index": 1, "scale": 0.5},
        "emissiveTexture": {"index": 2},
        "emissiveFactor": [1.0, 1.0, 1.0],
        "extensions": {"KHR_materials_specular": {
            "specularTexture": {"index": 0}, "specularColorTexture": {"index": 2}}}
    });
    let textures = json!([
        {"source": 0, "sampler": 0},
        {"source": 1},
        {"source": 2, "sampler": 1}
    ]);
    let samplers = json!([
        {"wrapS": 33071, "wrapT": 33648, "magFilter": 9728},
        {}
    ]);
    let jpeg_bytes = jpeg(4, 4, [200, 100, 50]);
    let data_uri = format!("data:image/png;base64,{}", base64(&normal));
    let (doc, bin) = textured_quad(
        Bin::default(),
        material.clone(),
        textures.clone(),
        json!([{"uri": "base%20color.png"}, {"uri": data_uri}, {"uri": "glow.jpg", "name": "Glow"}]),
        samplers.clone(),
    );
    fs::write(dir.join("glow.jpg"), &jpeg_bytes).unwrap();
    let path = dir.join("painted.gltf");
    write_json(&path, &with_data_uri(doc, &bin));
    let scene = load_gltf(&path).unwrap();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    check_textured(&scene);

    // The same in a GLB, every image in a buffer view of the BIN chunk.
    let mut bin = Bin::default();
    let views = [&red_green, &normal, &jpeg_bytes].map(|bytes| bin.view(bytes));
    let (doc, bin) = textured_quad(
        bin,
        material,
        textures,
        json!([
            {"bufferView": views[0], "mimeType": "image/png"},
            {"bufferView": views[1], "mimeType": "image/png"},
            {"bufferView": views[2], "mimeType": "image/jpeg", "name": "Glow"}
        ]),
        samplers,
    );
    let glb_path = dir.join("painted.glb");
    fs::write(&glb_path, glb(doc, &bin)).unwrap();
    let scene = load_gltf(&glb_path).unwrap();
    check_textured(&scene);
    let _ = fs::remove_dir_all(&dir);
}

fn check_textured(scene: &SceneDesc) {
    use portalview::asset::desc::AlphaMode;
    use portalview::asset::texture::{Filter, Wrap};
    assert_eq!(scene.images.len(), 3);
    let [base, normal, glow] = &scene.images[..] else {
        panic!("three images");
    };
    assert_eq!((base.width(), base.height()), (2, 1));
    assert_eq!(base.texels(), &[[255, 0, 0, 255], [0, 255, 0, 128]]);
    assert_eq!(normal.texels(), &[[128, 128, 255, 255]]);
    assert_eq!((glow.width(), glow.height()), (4, 4));
    // JPEG is lossy: within a few code values.
    for t in glow.texels() {
        let d = [200i32, 100, 50]
            .iter()
            .zip(t)
            .map(|(a, &b)| (a - b as i32).abs())
            .max()
            .unwrap();
        assert!(d <= 3, "{t:?}");
    }
    let m = &scene.materials[0];
    assert_eq!(m.alpha, 0.9);
    assert_eq!(m.alpha_mode, AlphaMode::Mask { cutoff: 0.3 });
    let t = &m.textures;
    let Some(base_ref) = t.base_color else {
        panic!("base colour texture");
    };
    assert_eq!(base_ref.image, 0);
    assert_eq!(
        base_ref.tex_coord, 1,
        "KHR_texture_transform's texCoord overrides"
    );
    assert_eq!(base_ref.sampler.wrap_s, Wrap::ClampToEdge);
    assert_eq!(base_ref.sampler.wrap_t, Wrap::MirroredRepeat);
    assert_eq!(base_ref.sampler.filter, Filter::Nearest);
    let transform = base_ref.transform.unwrap();
    assert_eq!(transform.offset, glam::Vec2::new(0.5, 0.0));
    assert_eq!(transform.rotation, 0.25);
    assert_eq!(transform.scale, glam::Vec2::new(2.0, 3.0));
    assert_eq!(t.metallic_roughness.unwrap().tex_coord, 1);
    assert_eq!(t.metallic_roughness.unwrap().image, 1);
    let n = t.normal.unwrap();
    assert_eq!((n.texture.image, n.scale), (1, 0.5));
    assert_eq!(n.texture.sampler.wrap_s, Wrap::Repeat);
    assert_eq!(t.emissive.unwrap().image, 2);
    assert_eq!(t.emissive.unwrap().sampler.filter, Filter::Bilinear);
    assert_eq!(t.specular.unwrap().image, 0);
    assert_eq!(t.specular_color.unwrap().image, 2);
    let mesh = &scene.meshes[0];
    assert_eq!(mesh.texcoords[0][0], glam::Vec2::new(0.0, 1.0));
    assert_eq!(mesh.texcoords[1][0], glam::Vec2::new(1.0, 0.0));
    // The scene builds, with its images.
    portalview::scene::Scene::from_desc(scene.clone(), "textured").unwrap();
}

/// A missing or undecodable image is an error naming the file, the image and the material.
#[test]
fn missing_and_corrupt_images_are_errors_naming_file_image_and_material() {
    let dir = temp_dir("bad-images");
    let material = json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}});
    // (file name, its bytes or none for a missing file, words the error must hold)
    type Case<'a> = (&'a str, Option<Vec<u8>>, &'a [&'a str]);
    let cases: [Case; 4] = [
        ("missing.png", None, &["missing.png", "cannot read"]),
        (
            "corrupt.png",
            Some(b"\x89PNG\r\n\x1a\n not really a png".to_vec()),
            &["corrupt.png", "decoded"],
        ),
        (
            "text.png",
            Some(b"hello".to_vec()),
            &["text.png", "neither a PNG nor a JPEG"],
        ),
        (
            "truncated.png",
            Some(png(64, 64, &[[9; 4]; 64 * 64])[..80].to_vec()),
            &["truncated.png", "decoded"],
        ),
    ];
    for (name, bytes, words) in cases {
        if let Some(bytes) = &bytes {
            fs::write(dir.join(name), bytes).unwrap();
        }
        let (doc, bin) = textured_quad(
            Bin::default(),
            material.clone(),
            json!([{"source": 0}]),
            json!([{"uri": name, "name": "Wood"}]),
            json!([]),
        );
        let path = dir.join("broken.gltf");
        write_json(&path, &with_data_uri(doc, &bin));
        let message = load_gltf(&path).unwrap_err().to_string();
        for word in [
            "broken.gltf",
            "image 0 \"Wood\"",
            "material 0 \"Painted\"",
            "baseColorTexture",
        ]
        .iter()
        .chain(words)
        {
            assert!(message.contains(word), "{name}: no \"{word}\" in {message}");
        }
    }
    // An image too large to hold is refused from its header, before any texel is decoded.
    let huge = png_header(20_000, 20_000);
    fs::write(dir.join("huge.png"), &huge).unwrap();
    let (doc, bin) = textured_quad(
        Bin::default(),
        material.clone(),
        json!([{"source": 0}]),
        json!([{"uri": "huge.png"}]),
        json!([]),
    );
    let path = dir.join("huge.gltf");
    write_json(&path, &with_data_uri(doc, &bin));
    let message = load_gltf(&path).unwrap_err().to_string();
    assert!(
        message.contains("huge.gltf") && message.contains("huge.png") && message.contains("limit"),
        "{message}"
    );
    // A texture on a texture coordinate set the primitive lacks.
    let (mut doc, bin) = textured_quad(
        Bin::default(),
        material,
        json!([{"source": 0}]),
        json!([{"uri": "ok.png"}]),
        json!([]),
    );
    fs::write(dir.join("ok.png"), png(1, 1, &[[1; 4]])).unwrap();
    doc["meshes"][0]["primitives"][0]["attributes"]
        .as_object_mut()
        .unwrap()
        .remove("TEXCOORD_0");
    let path = dir.join("no-uv.gltf");
    write_json(&path, &with_data_uri(doc, &bin));
    let message = load_gltf(&path).unwrap_err().to_string();
    assert!(
        message.contains("no-uv.gltf")
            && message.contains("TEXCOORD_0")
            && message.contains("Painted"),
        "{message}"
    );
    let _ = fs::remove_dir_all(&dir);
}

/// A PNG signature and IHDR chunk (with its CRC) declaring `width × height` RGBA8, and no data.
fn png_header(width: u32, height: u32) -> Vec<u8> {
    fn crc32(bytes: &[u8]) -> u32 {
        let mut crc = !0u32;
        for &b in bytes {
            crc ^= b as u32;
            for _ in 0..8 {
                crc = if crc & 1 != 0 {
                    (crc >> 1) ^ 0xedb8_8320
                } else {
                    crc >> 1
                };
            }
        }
        !crc
    }
    let mut chunk = b"IHDR".to_vec();
    chunk.extend(width.to_be_bytes());
    chunk.extend(height.to_be_bytes());
    chunk.extend([8, 6, 0, 0, 0]);
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    out.extend(13u32.to_be_bytes());
    out.extend(&chunk);
    out.extend(crc32(&chunk).to_be_bytes());
    out
}

/// Saving portals into a textured `.gltf` keeps its textures working: the images, samplers
/// and texture references are untouched and load again.
#[test]
fn save_portals_keeps_textures() {
    let dir = temp_dir("save-textured");
    fs::write(
        dir.join("wood.png"),
        png(2, 1, &[[10, 20, 30, 255], [40, 50, 60, 255]]),
    )
    .unwrap();
    let (doc, bin) = textured_quad(
        Bin::default(),
        json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0,
            "extensions": {"KHR_texture_transform": {"scale": [2.0, 2.0]}}}},
            "normalTexture": {"index": 0}}),
        json!([{"source": 0, "sampler": 0}]),
        json!([{"uri": "wood.png"}]),
        json!([{"wrapS": 33648}]),
    );
    let mut doc = with_data_uri(doc, &bin);
    // An emitter for the portal to open onto.
    doc["nodes"]
        .as_array_mut()
        .unwrap()
        .push(json!({"name": "Light", "mesh": 0, "translation": [0.0, 0.0, 3.0]}));
    doc["scenes"][0]["nodes"] = json!([0, 1]);
    let path = dir.join("textured.gltf");
    write_json(&path, &doc);
    let before = load_gltf(&path).unwrap();
    let mut portal = new_portal("Window", Vec3::new(0.0, 0.0, 1.5));
    portal.target = "Light".into();
    save_portals(&path, &[portal]).unwrap();
    let after = load_gltf(&path).unwrap();
    assert_eq!(after.portals.len(), 1);
    assert_eq!(after.images, before.images);
    assert_eq!(after.materials, before.materials);
    assert_eq!(after.meshes, before.meshes);
    assert!(after.materials[0].textures.base_color.is_some());
    let _ = fs::remove_dir_all(&dir);
}

fn json_chunk(bytes: &[u8]) -> Value {
    let glb = gltf::Glb::from_slice(bytes).unwrap();
    serde_json::from_slice(&glb.json).unwrap()
}

fn portal_named<'a>(scene: &'a SceneDesc, name: &str) -> &'a PortalDesc {
    let found = scene.portals.iter().find(|p| p.name == name);
    found.unwrap_or_else(|| panic!("no portal {name}"))
}

/// Only `file` is left in its directory: the temporary file was renamed over it.
#[allow(unused_variables)]
fn assert_replaced(file: &Path, inode_before: u64) {
    let dir = file.parent().unwrap();
    let entries: Vec<_> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .filter(|n| !n.to_string_lossy().ends_with(".bin"))
        .collect();
    assert_eq!(entries, [file.file_name().unwrap()], "leftover files");
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        assert_ne!(
            fs::metadata(file).unwrap().ino(),
            inode_before,
            "replaced, not rewritten in place"
        );
    }
}

fn inode(file: &Path) -> u64 {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        fs::metadata(file).unwrap().ino()
    }
    #[cfg(not(unix))]
    {
        let _ = file;
        0
    }
}

fn new_portal(name: &str, at: Vec3) -> PortalDesc {
    PortalDesc {
        name: name.to_owned(),
        target: "light".to_owned(),
        alpha: 0.4,
        auto_alpha: false,
        local_triangles: vec![[Vec3::ZERO, Vec3::X, Vec3::Y]],
        world_from_local: Mat4::from_translation(at),
        node_index: None,
    }
}

#[test]
fn save_portals_round_trip_glb() {
    let dir = temp_dir("save-glb");
    let path = dir.join("room.glb");
    let mut desc = sample_scene();
    let mut door = desc.portals[0].clone();
    door.name = "door".to_owned();
    door.world_from_local = Mat4::from_translation(Vec3::new(3.0, 1.0, 0.0));
    desc.portals.push(door);
    export_glb(&desc, &path).unwrap();
    let before_bytes = fs::read(&path).unwrap();
    let before = json_chunk(&before_bytes);
    let loaded = load_gltf(&path).unwrap();
    assert_eq!(loaded.portals.len(), 2);

    // Move and retune the window, delete the door, add a skylight.
    let mut window = portal_named(&loaded, "window").clone();
    window.world_from_local =
        Mat4::from_translation(Vec3::new(0.0, 0.5, 0.25)) * window.world_from_local;
    window.alpha = 0.5;
    window.target = "light".to_owned();
    let skylight = new_portal("skylight", Vec3::new(0.0, 2.5, 0.0));
    let inode_before = inode(&path);
    save_portals(&path, &[window.clone(), skylight.clone()]).unwrap();
    assert_replaced(&path, inode_before);

    let after_bytes = fs::read(&path).unwrap();
    let after = json_chunk(&after_bytes);
    let reloaded = load_gltf(&path).unwrap();
    assert_eq!(reloaded.portals.len(), 2);
    assert_portal_close(portal_named(&reloaded, "window"), &window);
    let added = portal_named(&reloaded, "skylight");
    assert_portal_close(added, &skylight);
    assert_eq!(
        added.node_index,
        Some(8),
        "appended after the 8 exported nodes (2 meshes, 2 portals, 3 lamps, the camera)"
    );
    // Everything else reads back as before.
    let without_portals = |s: &SceneDesc| SceneDesc {
        portals: Vec::new(),
        ..s.clone()
    };
    assert_scenes_close(&without_portals(&reloaded), &without_portals(&loaded));

    // The BIN chunk is kept byte for byte; non-portal nodes and old arrays are unchanged.
    let bin = |bytes: &[u8]| {
        gltf::Glb::from_slice(bytes)
            .unwrap()
            .bin
            .unwrap()
            .into_owned()
    };
    assert_eq!(bin(&after_bytes), bin(&before_bytes));
    for i in [0, 1, 4, 5, 6, 7] {
        assert_eq!(after["nodes"][i], before["nodes"][i], "node {i}");
    }
    assert_eq!(
        after["nodes"][3], before["nodes"][3],
        "the deleted door's node stays, detached"
    );
    assert_eq!(after["scenes"][0]["nodes"], json!([0, 1, 2, 4, 5, 6, 7, 8]));
    for key in [
        "materials",
        "cameras",
        "extensionsUsed",
        "extensions",
        "asset",
    ] {
        assert_eq!(after[key], before[key], "{key}");
    }
    for key in ["accessors", "bufferViews", "meshes", "buffers"] {
        let old = before[key].as_array().unwrap();
        assert_eq!(
            after[key].as_array().unwrap()[..old.len()],
            old[..],
            "{key}"
        );
    }
    // Saving what was reloaded changes nothing that loads.
    save_portals(&path, &reloaded.portals).unwrap();
    let again = load_gltf(&path).unwrap();
    assert_scenes_close(&again, &reloaded);
    let _ = fs::remove_dir_all(&dir);
}

#[test]
fn save_portals_round_trip_gltf() {
    let dir = temp_dir("save-gltf");
    let mut bin = Bin::default();
    let square = [
        [-1.0, -1.0, 0.0],
        [1.0, -1.0, 0.0],
        [1.0, 1.0, 0.0],
        [-1.0, 1.0, 0.0],
    ];
    let positions = bin.vec3s(&square);
    let indices = bin.indices(&[0, 1, 2, 0, 2, 3]);
    fs::write(dir.join("house.bin"), &bin.bytes).unwrap();
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let doc = json!({
        "asset": {"version": "2.0", "generator": "hand"},
        "extensionsUsed": ["EXT_made_up"],
        "scene": 0,
        "scenes": [{"nodes": [0, 2, 3]}],
        "nodes": [
            {"name": "Frame", "translation": [0.0, 1.0, 0.0], "rotation": [0.0, s, 0.0, s],
             "scale": [2.0, 2.0, 2.0], "children": [1], "extras": {"frame_id": 7}},
            {"name": "Window", "mesh": 1, "translation": [0.25, 0.0, 0.0],
             "extras": {"portal_target": "Sun", "portal_light_probability": 0.2, "blender_note": "keep"}},
            {"name": "Door", "mesh": 1, "translation": [5.0, 0.0, 0.0], "extras": {"portal_target": "Sun"}},
            {"name": "Sun", "mesh": 0, "translation": [0.0, 10.0, 0.0],
             "extensions": {"EXT_made_up": {"answer": 42}}, "extras": {"sun": [1, 2, 3]}}
        ],
        "materials": [{"name": "Hot", "emissiveFactor": [1.0, 1.0, 1.0]}],
        "meshes": [
            {"name": "SunMesh", "primitives": [{"attributes": {"POSITION": positions}, "indices": indices, "material": 0}]},
            {"name": "PortalMesh", "primitives": [{"attributes": {"POSITION": positions}, "indices": indices}]}
        ],
        "accessors": bin.accessors,
        "bufferViews": bin.views,
        "buffers": [{"byteLength": bin.bytes.len(), "uri": "house.bin"}]
    });
    let path = dir.join("house.gltf");
    write_json(&path, &doc);
    let loaded = load_gltf(&path).unwrap();
    assert_eq!(loaded.portals.len(), 2);
    let window = portal_named(&loaded, "Window");
    let frame_world = Mat4::from_scale_rotation_translation(
        Vec3::splat(2.0),
        Quat::from_rotation_y(FRAC_PI_2),
        Vec3::Y,
    );
    let expected = frame_world * Mat4::from_translation(Vec3::new(0.25, 0.0, 0.0));
    assert!(window.world_from_local.abs_diff_eq(expected, 1e-5));

    // Move the window (it stays under its parent), reshape nothing, delete the door, add one.
    let mut moved = window.clone();
    moved.world_from_local =
        Mat4::from_translation(Vec3::new(0.0, 0.0, 1.0)) * moved.world_from_local;
    moved.alpha = 0.6;
    let mut skylight = new_portal("Skylight", Vec3::new(0.0, 5.0, 0.0));
    skylight.target = "Sun".to_owned();
    // A reshaped portal gets a new mesh.
    let mut reshaped = moved.clone();
    reshaped.local_triangles = vec![[Vec3::ZERO, Vec3::X, Vec3::Y]];
    let bin_before = fs::read(dir.join("house.bin")).unwrap();
    let inode_before = inode(&path);
    save_portals(&path, &[reshaped.clone(), skylight.clone()]).unwrap();
    assert_replaced(&path, inode_before);

    let text = fs::read_to_string(&path).unwrap();
    assert!(text.contains("\n  "), "a .gltf stays pretty-printed JSON");
    let after: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(fs::read(dir.join("house.bin")).unwrap(), bin_before);
    let reloaded = load_gltf(&path).unwrap();
    assert_eq!(reloaded.portals.len(), 2);
    assert_portal_close(portal_named(&reloaded, "Window"), &reshaped);
    assert_portal_close(portal_named(&reloaded, "Skylight"), &skylight);

    // The window's node: a matrix relative to its parent, TRS gone, other extras kept.
    let node = &after["nodes"][1];
    assert!(node.get("translation").is_none() && node.get("rotation").is_none());
    assert_eq!(node["extras"]["blender_note"], "keep");
    assert_eq!(node["extras"]["portal_target"], "Sun");
    assert_eq!(node["mesh"], 2, "a new mesh for the new shape");
    let local: Vec<f32> = serde_json::from_value(node["matrix"].clone()).unwrap();
    let expected_local = frame_world.inverse() * reshaped.world_from_local;
    assert!(Mat4::from_cols_slice(&local).abs_diff_eq(expected_local, 1e-5));
    // Everything else is as it was.
    for i in [0, 2, 3] {
        assert_eq!(after["nodes"][i], doc["nodes"][i], "node {i}");
    }
    assert_eq!(after["scenes"][0]["nodes"], json!([0, 3, 4]));
    assert_eq!(after["buffers"][0], doc["buffers"][0]);
    let data_uri = after["buffers"][1]["uri"].as_str().unwrap();
    assert!(data_uri.starts_with("data:application/octet-stream;base64,"));
    for key in ["extensionsUsed", "materials", "asset"] {
        assert_eq!(after[key], doc[key], "{key}");
    }
    let _ = fs::remove_dir_all(&dir);
}

/// A one-triangle document with an external `.bin` named after `stem`, for breaking.
fn triangle_doc(dir: &Path, stem: &str, positions: &[[f32; 3]], indices: &[u16]) -> Value {
    let mut bin = Bin::default();
    let p = bin.vec3s(positions);
    let i = bin.indices(indices);
    fs::write(dir.join(format!("{stem}.bin")), &bin.bytes).unwrap();
    json!({
        "asset": {"version": "2.0"},
        "buffers": [{"uri": format!("{stem}.bin"), "byteLength": bin.bytes.len()}],
        "bufferViews": bin.views,
        "accessors": bin.accessors,
        "meshes": [{"name": "Tri", "primitives": [{"attributes": {"POSITION": p}, "indices": i}]}],
        "nodes": [{"name": "Tri Node", "mesh": 0}],
        "scenes": [{"nodes": [0]}],
        "scene": 0
    })
}

const TRIANGLE: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

/// Gives the triangle of `triangle_doc` a material "Paint" with these `extensions`.
/// Gives the triangle of `doc` a `TEXCOORD_0` (in a second buffer, `uv.bin` in `dir`).
fn with_uvs(dir: &Path, doc: &mut Value) {
    let uv = {
        let mut bin = Bin::default();
        bin.vec2s(&[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]);
        fs::write(dir.join("uv.bin"), &bin.bytes).unwrap();
        bin
    };
    doc["buffers"]
        .as_array_mut()
        .unwrap()
        .push(json!({"uri": "uv.bin", "byteLength": uv.bytes.len()}));
    let views = doc["bufferViews"].as_array().unwrap().len();
    doc["bufferViews"]
        .as_array_mut()
        .unwrap()
        .push(json!({"buffer": 1, "byteOffset": 0, "byteLength": uv.bytes.len()}));
    let accessors = doc["accessors"].as_array().unwrap().len();
    doc["accessors"]
        .as_array_mut()
        .unwrap()
        .push(json!({"bufferView": views, "componentType": 5126, "count": 3, "type": "VEC2"}));
    doc["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = json!(accessors);
}

fn with_material(doc: &mut Value, extensions: Value) {
    doc["materials"] = json!([{"name": "Paint", "extensions": extensions}]);
    doc["meshes"][0]["primitives"][0]["material"] = json!(0);
}

#[test]
fn sparse_accessors_substitute_values() {
    let dir = temp_dir("sparse");
    let mut bin = Bin::default();
    let base = bin.vec3s(&TRIANGLE);
    let sparse_indices = bin.view(&[2u8, 0, 0, 0]);
    let sparse_values = bin.view(
        &[0.0f32, 2.0, 0.0]
            .iter()
            .flat_map(|x| x.to_le_bytes())
            .collect::<Vec<u8>>(),
    );
    let sparse = json!({
        "count": 1,
        "indices": {"bufferView": sparse_indices, "componentType": 5121},
        "values": {"bufferView": sparse_values}
    });
    // One accessor over the base triangle, one over implicit zeros.
    let mut over_base = bin.accessors[base].clone();
    over_base["sparse"] = sparse.clone();
    let over_zeros = json!({"componentType": 5126, "count": 3, "type": "VEC3", "sparse": sparse});
    let doc = json!({
        "asset": {"version": "2.0"},
        "buffers": [{"uri": bin.data_uri(), "byteLength": bin.bytes.len()}],
        "bufferViews": bin.views,
        "accessors": [over_base, over_zeros],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]},
                   {"primitives": [{"attributes": {"POSITION": 1}}]}],
        "nodes": [{"mesh": 0}, {"mesh": 1}],
        "scenes": [{"nodes": [0, 1]}]
    });
    let path = dir.join("sparse.gltf");
    write_json(&path, &doc);
    let scene = load_gltf(&path).unwrap();
    let lifted = [Vec3::ZERO, Vec3::X, Vec3::new(0.0, 2.0, 0.0)];
    assert_eq!(scene.meshes[0].positions, lifted);
    assert_eq!(scene.meshes[0].node_name, "node 0");
    assert_eq!(
        scene.meshes[1].positions,
        [Vec3::ZERO, Vec3::ZERO, lifted[2]]
    );
    let _ = fs::remove_dir_all(&dir);
}

#[test]
fn broken_files_give_errors_naming_the_file_and_field() {
    let dir = temp_dir("broken");
    // (file name, how to write it, words the message must contain)
    type Writer = Box<dyn Fn(&Path, &Path)>;
    let edited = |edit: fn(&mut Value)| -> Writer {
        Box::new(move |dir: &Path, path: &Path| {
            let stem = path.file_stem().unwrap().to_string_lossy().into_owned();
            let mut doc = triangle_doc(dir, &stem, &TRIANGLE, &[0, 1, 2]);
            edit(&mut doc);
            write_json(path, &doc);
        })
    };
    let cases: Vec<(&str, Writer, &[&str])> = vec![
        (
            "bad_json.gltf",
            Box::new(|_, p| fs::write(p, "{ \"asset\": ").unwrap()),
            &["JSON"],
        ),
        (
            "empty.glb",
            Box::new(|_, p| fs::write(p, b"").unwrap()),
            &["GLB"],
        ),
        (
            "truncated.glb",
            Box::new(|dir, p| {
                let whole = dir.join("whole.glb");
                export_glb(&sample_scene(), &whole).unwrap();
                let bytes = fs::read(&whole).unwrap();
                fs::write(p, &bytes[..bytes.len() / 2]).unwrap();
                fs::remove_file(whole).unwrap();
            }),
            &["truncated"],
        ),
        (
            "missing_bin.gltf",
            edited(|d| d["buffers"][0]["uri"] = json!("nowhere.bin")),
            &["buffer 0", "nowhere.bin"],
        ),
        (
            "short_buffer.gltf",
            edited(|d| d["buffers"][0]["byteLength"] = json!(1000)),
            &["buffer 0", "byteLength 1000"],
        ),
        (
            "view_out_of_buffer.gltf",
            edited(|d| d["bufferViews"][0]["byteOffset"] = json!(400)),
            &["bufferView 0", "Tri Node"],
        ),
        (
            "accessor_out_of_range.gltf",
            edited(|d| d["accessors"][0]["count"] = json!(100)),
            &["accessor 0", "Tri Node", "POSITION"],
        ),
        (
            "huge_count.gltf",
            edited(|d| d["accessors"][0]["count"] = json!(4_000_000_000u64)),
            &["accessor 0", "exceeds the limit"],
        ),
        (
            "index_out_of_range.gltf",
            Box::new(|dir, p| {
                write_json(
                    p,
                    &triangle_doc(dir, "index_out_of_range", &TRIANGLE, &[0, 1, 7]),
                )
            }),
            &["Tri Node", "index 7"],
        ),
        (
            "infinite_matrix.gltf",
            edited(|d| {
                d["nodes"][0]["matrix"] = json!([1e39, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1])
            }),
            &["Tri Node", "matrix", "not finite"],
        ),
        (
            "nan_matrix.gltf",
            Box::new(|dir, p| {
                let mut doc = triangle_doc(dir, "nan_matrix", &TRIANGLE, &[0, 1, 2]);
                doc["nodes"][0]["matrix"] = json!("@");
                let text = serde_json::to_string(&doc).unwrap().replace(
                    "\"@\"",
                    "[NaN, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]",
                );
                fs::write(p, text).unwrap();
            }),
            &["JSON"],
        ),
        (
            "nan_position.gltf",
            Box::new(|dir, p| {
                let nan = [[0.0, f32::NAN, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
                let mut doc = triangle_doc(dir, "nan_position", &nan, &[0, 1, 2]);
                doc["accessors"][0]["min"] = json!([0, 0, 0]);
                doc["accessors"][0]["max"] = json!([1, 1, 0]);
                write_json(p, &doc);
            }),
            &["Tri Node", "POSITION", "not finite"],
        ),
        (
            "lines.gltf",
            edited(|d| d["meshes"][0]["primitives"][0]["mode"] = json!(1)),
            &["Tri Node", "LINES"],
        ),
        (
            "no_positions.gltf",
            edited(|d| d["meshes"][0]["primitives"][0]["attributes"] = json!({"NORMAL": 0})),
            &["POSITION"],
        ),
        (
            "bad_accessor_index.gltf",
            edited(|d| d["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(9)),
            &["mesh 0", "accessor 9"],
        ),
        (
            "cycle.gltf",
            edited(|d| d["nodes"][0]["children"] = json!([0])),
            &["Tri Node", "twice"],
        ),
        (
            "bad_base64.gltf",
            edited(|d| d["buffers"][0]["uri"] = json!("data:application/octet-stream;base64,@@@")),
            &["buffer 0", "base64"],
        ),
        (
            "draco.gltf",
            edited(|d| d["extensionsRequired"] = json!(["KHR_draco_mesh_compression"])),
            &["extensionsRequired[0]", "KHR_draco_mesh_compression"],
        ),
        (
            "ior_below_one.gltf",
            edited(|d| with_material(d, json!({"KHR_materials_ior": {"ior": 0.5}}))),
            &["material 0 \"Paint\"", "KHR_materials_ior.ior", "0.5"],
        ),
        (
            "transmission_above_one.gltf",
            edited(|d| {
                with_material(
                    d,
                    json!({"KHR_materials_transmission": {"transmissionFactor": 1.5}}),
                )
            }),
            &[
                "material 0 \"Paint\"",
                "KHR_materials_transmission.transmissionFactor",
                "1.5",
            ],
        ),
        (
            "clearcoat_above_one.gltf",
            edited(|d| {
                with_material(
                    d,
                    json!({"KHR_materials_clearcoat": {"clearcoatFactor": 1.0, "clearcoatRoughnessFactor": 2.0}}),
                )
            }),
            &[
                "material 0 \"Paint\"",
                "KHR_materials_clearcoat.clearcoatRoughnessFactor",
                "2.0",
            ],
        ),
        (
            "negative_thickness.gltf",
            edited(|d| {
                with_material(
                    d,
                    json!({"KHR_materials_volume": {"thicknessFactor": -1.0}}),
                )
            }),
            &[
                "material 0 \"Paint\"",
                "KHR_materials_volume.thicknessFactor",
                "negative",
            ],
        ),
        (
            "attenuation_color_above_one.gltf",
            edited(|d| {
                with_material(
                    d,
                    json!({"KHR_materials_volume": {"thicknessFactor": 1.0, "attenuationColor": [1.0, 2.0, 0.5]}}),
                )
            }),
            &[
                "material 0 \"Paint\"",
                "KHR_materials_volume.attenuationColor",
                "[0, 1]",
            ],
        ),
        (
            "attenuation_distance_zero.gltf",
            edited(|d| {
                with_material(
                    d,
                    json!({"KHR_materials_volume": {"thicknessFactor": 1.0, "attenuationDistance": 0.0}}),
                )
            }),
            &[
                "material 0 \"Paint\"",
                "KHR_materials_volume.attenuationDistance",
                "positive",
            ],
        ),
        (
            "attenuation_color_short.gltf",
            edited(|d| {
                with_material(
                    d,
                    json!({"KHR_materials_volume": {"thicknessFactor": 1.0, "attenuationColor": [1.0, 0.5]}}),
                )
            }),
            &[
                "material 0 \"Paint\"",
                "KHR_materials_volume.attenuationColor",
                "3 numbers",
            ],
        ),
        (
            "ior_not_a_number.gltf",
            edited(|d| with_material(d, json!({"KHR_materials_ior": {"ior": "NaN"}}))),
            &[
                "material 0 \"Paint\"",
                "KHR_materials_ior.ior",
                "finite number",
            ],
        ),
        (
            "negative_specular.gltf",
            edited(|d| {
                with_material(
                    d,
                    json!({"KHR_materials_specular": {"specularFactor": -0.1}}),
                )
            }),
            &["material 0 \"Paint\"", "specularFactor", "[0, 1]"],
        ),
        (
            "specular_above_one.gltf",
            edited(|d| with_material(d, json!({"KHR_materials_specular": {"specularFactor": 2}}))),
            &["material 0 \"Paint\"", "specularFactor"],
        ),
        (
            "negative_specular_color.gltf",
            edited(|d| {
                with_material(
                    d,
                    json!({"KHR_materials_specular": {"specularColorFactor": [1, -1, 0]}}),
                )
            }),
            &["material 0 \"Paint\"", "specularColorFactor", "negative"],
        ),
        (
            "short_specular_color.gltf",
            edited(|d| {
                with_material(
                    d,
                    json!({"KHR_materials_specular": {"specularColorFactor": [1]}}),
                )
            }),
            &["material 0 \"Paint\"", "specularColorFactor", "3 numbers"],
        ),
        (
            "specular_color_not_a_number.gltf",
            edited(|d| {
                with_material(
                    d,
                    json!({"KHR_materials_specular": {"specularColorFactor": [1, null, 0]}}),
                )
            }),
            &[
                "material 0 \"Paint\"",
                "specularColorFactor",
                "finite number",
            ],
        ),
        (
            "specular_texture_missing.gltf",
            edited(|d| {
                with_material(
                    d,
                    json!({"KHR_materials_specular": {"specularTexture": {"index": 4}}}),
                )
            }),
            &["material 0 \"Paint\"", "specularTexture.index", "texture 4"],
        ),
        (
            "specular_not_an_object.gltf",
            edited(|d| with_material(d, json!({"KHR_materials_specular": 1}))),
            &["material 0 \"Paint\"", "KHR_materials_specular", "object"],
        ),
        (
            "portal_alpha.gltf",
            edited(|d| {
                d["nodes"][0]["extras"] =
                    json!({"portal_target": "Light", "portal_light_probability": "lots"})
            }),
            &["Tri Node", "portal_light_probability"],
        ),
        (
            "portal_without_mesh.gltf",
            edited(|d| {
                d["nodes"] = json!([{"name": "Hole", "extras": {"portal_target": "Light"}}])
            }),
            &["Hole", "no mesh"],
        ),
        (
            "bad_camera.gltf",
            edited(|d| {
                d["cameras"] =
                    json!([{"type": "perspective", "perspective": {"yfov": -1.0, "znear": 0.1}}]);
                d["nodes"][0]["camera"] = json!(0);
            }),
            &["Tri Node", "yfov"],
        ),
    ];
    for (name, write, words) in cases {
        let path = dir.join(name);
        write(&dir, &path);
        let Err(error) = load_gltf(&path) else {
            panic!("{name} loaded");
        };
        let message = error.to_string();
        assert!(message.contains(name), "{name}: {message}");
        for word in words {
            assert!(
                message.contains(word),
                "{name}: no \"{word}\" in: {message}"
            );
        }
        // Saving portals into a broken file fails the same way and leaves it untouched.
        let before = fs::read(&path).unwrap();
        assert!(save_portals(&path, &[]).is_err(), "{name}");
        assert_eq!(fs::read(&path).unwrap(), before, "{name}");
    }
    assert!(load_gltf(&dir.join("does_not_exist.glb")).is_err());
    let _ = fs::remove_dir_all(&dir);
}

#[test]
fn export_rejects_what_it_could_not_read_back() {
    let dir = temp_dir("export-bad");
    let path = dir.join("bad.glb");
    let mut desc = sample_scene();
    desc.meshes[0].indices[0] = [0, 1, 9];
    let message = export_glb(&desc, &path).unwrap_err().to_string();
    assert!(
        message.contains("bad.glb") && message.contains("floor"),
        "{message}"
    );
    assert!(!path.exists(), "nothing is written");
    let mut desc = sample_scene();
    desc.portals[0].alpha = 2.0;
    assert!(export_glb(&desc, &path).is_err());
    let mut desc = sample_scene();
    if let Some(camera) = &mut desc.camera {
        camera.target = camera.eye;
    }
    assert!(export_glb(&desc, &path).is_err());
    assert_eq!(
        fs::read_dir(&dir).unwrap().count(),
        0,
        "no temporary files left"
    );
    let _ = fs::remove_dir_all(&dir);
}

/// What Blender 3.4 writes for Principled *Specular* 0 (only `specularColorFactor`, no
/// `specularFactor`, and its IOR), other specular layers, and none: each lands in the right
/// fields, with glTF's defaults where absent, and without warnings since both are read.
#[test]
fn specular_and_ior_extensions_are_read() {
    let dir = temp_dir("specular");
    let mut doc = triangle_doc(&dir, "specular", &TRIANGLE, &[0, 1, 2]);
    doc["extensionsUsed"] = json!(["KHR_materials_specular", "KHR_materials_ior"]);
    doc["materials"] = json!([
        {"name": "Specular 0", "extensions": {
            "KHR_materials_specular": {"specularColorFactor": [0.0, 0.0, 0.0]},
            "KHR_materials_ior": {"ior": 1.45}}},
        {"name": "Tinted", "extensions": {
            "KHR_materials_specular": {"specularFactor": 0.5, "specularColorFactor": [2.5, 0.5, 0.0]},
            "KHR_materials_ior": {"ior": 0}}},
        {"name": "Plain"}
    ]);
    doc["meshes"][0]["primitives"][0]["material"] = json!(0);
    let path = dir.join("specular.gltf");
    write_json(&path, &doc);
    let scene = load_gltf(&path).unwrap();
    let warnings = &scene.warnings;
    assert!(warnings.is_empty(), "{warnings:?}");
    let [zero, tinted, plain] = &scene.materials[..] else {
        panic!("three materials");
    };
    assert_eq!(
        (zero.specular_factor, zero.specular_color, zero.ior),
        (1.0, Vec3::ZERO, 1.45)
    );
    assert_eq!(
        (tinted.specular_factor, tinted.specular_color, tinted.ior),
        (0.5, Vec3::new(2.5, 0.5, 0.0), 0.0)
    );
    assert_eq!(
        (plain.specular_factor, plain.specular_color, plain.ior),
        (1.0, Vec3::ONE, 1.5)
    );
    let _ = fs::remove_dir_all(&dir);
}

/// Glass as Blender 3.4 writes a Principled BSDF of Transmission 1 (`KHR_materials_transmission`
/// with its factor, the IOR only where it is not 1.5, no volume): thin-walled transmission,
/// read without a warning; rough transmission is read as such. A volume with a thickness is
/// read with its attenuation (Beer–Lambert's σ = −ln(colour)/distance), thickness 0 is
/// thin-walled, and a volume of infinite IOR warns that it is rendered thin, naming the file
/// and the material.
#[test]
fn transmission_and_volume_are_read_and_what_is_not_rendered_warns() {
    let dir = temp_dir("transmission");
    let mut doc = triangle_doc(&dir, "glass", &TRIANGLE, &[0, 1, 2]);
    doc["extensionsUsed"] = json!([
        "KHR_materials_transmission",
        "KHR_materials_ior",
        "KHR_materials_volume"
    ]);
    doc["materials"] = json!([
        {"name": "Pane", "pbrMetallicRoughness": {"roughnessFactor": 0.0},
         "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0}}},
        {"name": "Thick", "pbrMetallicRoughness": {"roughnessFactor": 0.0},
         "extensions": {"KHR_materials_transmission": {"transmissionFactor": 0.9},
                        "KHR_materials_ior": {"ior": 1.33},
                        "KHR_materials_volume": {"thicknessFactor": 0.02}}},
        {"name": "Frosted", "pbrMetallicRoughness": {"roughnessFactor": 0.4},
         "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0},
                        "KHR_materials_volume": {"thicknessFactor": 0.0}}},
        {"name": "Amber", "pbrMetallicRoughness": {"roughnessFactor": 0.0},
         "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0},
                        "KHR_materials_volume": {"thicknessFactor": 0.5,
                            "attenuationColor": [0.9, 0.6, 0.2], "attenuationDistance": 0.25}}},
        {"name": "Mirror glass", "pbrMetallicRoughness": {"roughnessFactor": 0.0},
         "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0},
                        "KHR_materials_ior": {"ior": 0.0},
                        "KHR_materials_volume": {"thicknessFactor": 0.1}}}
    ]);
    doc["meshes"][0]["primitives"][0]["material"] = json!(0);
    let path = dir.join("glass.gltf");
    write_json(&path, &doc);
    let scene = load_gltf(&path).unwrap();
    let [pane, thick, frosted, amber, mirror] = &scene.materials[..] else {
        panic!("five materials");
    };
    assert_eq!((pane.transmission, pane.ior, pane.volume), (1.0, 1.5, None));
    assert_eq!((thick.transmission, thick.ior), (0.9, 1.33));
    let volume = thick.volume.unwrap();
    assert_eq!(volume.thickness, 0.02);
    assert_eq!(volume.sigma(), Vec3::ZERO);
    assert_eq!((frosted.transmission, frosted.volume), (1.0, None));
    assert_eq!(frosted.roughness, 0.4);
    let sigma = amber.volume.unwrap().sigma();
    let expected = Vec3::new(0.9f32.ln(), 0.6f32.ln(), 0.2f32.ln()) / -0.25;
    assert!((sigma - expected).abs().max_element() < 1e-5, "{sigma}");
    assert_eq!(mirror.volume, None);
    let warnings = &scene.warnings;
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(
        warnings[0].contains("glass.gltf")
            && warnings[0].contains("\"Mirror glass\"")
            && warnings[0].contains("infinite IOR"),
        "{warnings:?}"
    );
    let _ = fs::remove_dir_all(&dir);
}

/// A clear coat as Blender 3.4 writes it (`clearcoatFactor`, `clearcoatRoughnessFactor`, and
/// one image with the coat in R and its roughness in G) is read without a warning, and at a
/// point the factors are multiplied by their channels. A coat over a normal map, and a
/// `clearcoatNormalTexture`, warn (the coat takes the shading normal); a coat over a
/// refracting volume warns that it is not rendered.
#[test]
fn clearcoat_is_read_with_its_textures_and_what_is_not_rendered_warns() {
    let dir = temp_dir("clearcoat");
    let mut doc = triangle_doc(&dir, "coat", &TRIANGLE, &[0, 1, 2]);
    doc["extensionsUsed"] = json!(["KHR_materials_clearcoat"]);
    with_uvs(&dir, &mut doc);
    fs::write(dir.join("coat.png"), png(1, 1, &[[128, 64, 0, 255]])).unwrap();
    doc["images"] = json!([{"uri": "coat.png"}]);
    doc["textures"] = json!([{"source": 0}]);
    with_material(
        &mut doc,
        json!({"KHR_materials_clearcoat": {"clearcoatFactor": 0.8, "clearcoatRoughnessFactor": 0.5,
            "clearcoatTexture": {"index": 0}, "clearcoatRoughnessTexture": {"index": 0}}}),
    );
    let path = dir.join("coat.gltf");
    write_json(&path, &doc);
    let scene = load_gltf(&path).unwrap();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let m = &scene.materials[0];
    assert_eq!((m.clearcoat, m.clearcoat_roughness), (0.8, 0.5));
    let images = scene.images.clone();
    let surface = portalview::surface::SurfaceTextures::new(m, &images)
        .unwrap()
        .unwrap();
    let at_point = surface.material(&[glam::Vec2::splat(0.5); 2], 1.0);
    let roughness = 0.5 * 64.0 / 255.0;
    assert!((at_point.clearcoat - 0.8 * 128.0 / 255.0).abs() < 1e-6);
    assert!((at_point.clearcoat_alpha - roughness * roughness).abs() < 1e-6);

    doc["materials"][0]["extensions"]["KHR_materials_clearcoat"]["clearcoatNormalTexture"] =
        json!({"index": 0});
    doc["materials"][0]["extensions"]["KHR_materials_transmission"] =
        json!({"transmissionFactor": 1.0});
    doc["materials"][0]["extensions"]["KHR_materials_volume"] = json!({"thicknessFactor": 0.1});
    write_json(&path, &doc);
    let scene = load_gltf(&path).unwrap();
    let warnings = scene.warnings.join("\n");
    assert!(
        warnings.contains("coat.gltf")
            && warnings.contains("clearcoatNormalTexture is not read")
            && warnings.contains("over a refracting volume"),
        "{warnings}"
    );
    assert_eq!(scene.materials[0].clearcoat, 0.0);
    let _ = fs::remove_dir_all(&dir);
}

/// The specular layer's textures are read; an extension the file uses but that is not read
/// is a warning naming the file and the extension.
#[test]
fn specular_textures_are_read_and_unread_extensions_warn() {
    let dir = temp_dir("specular-texture");
    let mut doc = triangle_doc(&dir, "textured", &TRIANGLE, &[0, 1, 2]);
    doc["extensionsUsed"] = json!(["KHR_materials_specular", "KHR_materials_sheen"]);
    fs::write(dir.join("spec.png"), png(1, 1, &[[255, 128, 0, 64]])).unwrap();
    doc["images"] = json!([{"uri": "spec.png"}]);
    doc["textures"] = json!([{"source": 0}]);
    with_uvs(&dir, &mut doc);
    with_material(
        &mut doc,
        json!({"KHR_materials_specular": {"specularColorTexture": {"index": 0}, "specularTexture": {"index": 0}, "specularFactor": 0.7}}),
    );
    let path = dir.join("textured.gltf");
    write_json(&path, &doc);
    let scene = load_gltf(&path).unwrap();
    let warnings = &scene.warnings;
    let m = &scene.materials[0];
    assert_eq!(m.specular_factor, 0.7);
    assert_eq!(m.textures.specular_color.map(|t| t.image), Some(0));
    assert_eq!(m.textures.specular.map(|t| t.image), Some(0));
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(
        warnings[0].contains("textured.gltf") && warnings[0].contains("KHR_materials_sheen"),
        "{warnings:?}"
    );
    // At a point: specularFactor × A (64/255), specularColor × sRGB-decoded RGB.
    let images = scene.images.clone();
    let surface = portalview::surface::SurfaceTextures::new(m, &images)
        .unwrap()
        .unwrap();
    let at_point = surface.material(&[glam::Vec2::splat(0.5); 2], 1.0);
    let plain = portalview::material::Material::from_desc(&MaterialDesc {
        specular_factor: 0.7 * 64.0 / 255.0,
        specular_color: Vec3::new(
            1.0,
            portalview::asset::texture::srgb_to_linear(128.0 / 255.0),
            0.0,
        ),
        ..m.clone()
    });
    assert!(
        (at_point.f0 - plain.f0).abs().max_element() < 1e-6,
        "{} vs {}",
        at_point.f0,
        plain.f0
    );
    assert!((at_point.f90 - plain.f90).abs() < 1e-6);
    let _ = fs::remove_dir_all(&dir);
}

/// Non-default specular layers, IORs, transmission and volumes are written as their extensions (declared in
/// `extensionsUsed`) and read back equal; defaults write neither.
#[test]
fn specular_and_ior_round_trip() {
    let dir = temp_dir("specular-round-trip");
    let path = dir.join("scene.glb");
    let mut desc = sample_scene();
    let plain = desc.clone();
    desc.materials[0].specular_color = Vec3::ZERO;
    desc.materials[0].ior = 1.45;
    desc.materials[1].specular_factor = 0.25;
    desc.materials[1].specular_color = Vec3::new(1.5, 0.1, 0.0);
    desc.materials[1].transmission = 0.75;
    desc.materials[1].volume = Some(portalview::asset::desc::VolumeDesc {
        thickness: 0.02,
        attenuation_color: Vec3::new(0.5, 0.75, 1.0),
        attenuation_distance: 0.3,
    });
    export_glb(&desc, &path).unwrap();
    assert_scenes_close(&load_gltf(&path).unwrap(), &desc);
    let used = |path: &Path| -> Vec<String> {
        let doc = gltf::Gltf::from_slice(&fs::read(path).unwrap()).unwrap();
        doc.extensions_used().map(str::to_owned).collect()
    };
    let extensions = used(&path);
    assert!(extensions.iter().any(|e| e == "KHR_materials_specular"));
    assert!(extensions.iter().any(|e| e == "KHR_materials_ior"));
    assert!(extensions.iter().any(|e| e == "KHR_materials_transmission"));
    assert!(extensions.iter().any(|e| e == "KHR_materials_volume"));
    export_glb(&plain, &path).unwrap();
    assert_scenes_close(&load_gltf(&path).unwrap(), &plain);
    let extensions = used(&path);
    // Default specular and IOR write neither extension (the sample scene's lamps declare theirs).
    assert!(
        extensions
            .iter()
            .all(|e| e == "KHR_materials_emissive_strength" || e == "KHR_lights_punctual"),
        "{extensions:?}"
    );
    // What a file could not hold is refused, naming the file and the material.
    for (field, edit) in [
        (
            "ior",
            (|m: &mut MaterialDesc| m.ior = 0.9) as fn(&mut MaterialDesc),
        ),
        ("ior", |m| m.ior = f32::NAN),
        ("specular factor", |m| m.specular_factor = 1.5),
        ("negative", |m| m.specular_color = Vec3::new(0.0, -1.0, 0.0)),
        ("not finite", |m| m.specular_factor = f32::NAN),
    ] {
        let mut bad = plain.clone();
        edit(&mut bad.materials[0]);
        let message = export_glb(&bad, &path).unwrap_err().to_string();
        assert!(
            message.contains("scene.glb") && message.contains("material 0 \"floor\""),
            "{message}"
        );
        assert!(
            message.contains(field) || field == "ior" && message.contains("finite"),
            "{message}"
        );
    }
    let _ = fs::remove_dir_all(&dir);
}

/// A textured scene exported as `.glb` reads back with the same images, texture references
/// (samplers, transforms, sets), alpha modes, texture coordinates and tangents.
#[test]
fn textured_export_round_trips() {
    use portalview::asset::desc::AlphaMode;
    use portalview::asset::texture::{Filter, TextureTransform, Wrap};
    let dir = temp_dir("textured-export");
    let mut desc = portalview::asset::builtin::with_test_textures(
        portalview::asset::builtin::desc("lampshade").unwrap(),
    );
    let m = &mut desc.materials[0];
    m.alpha = 0.7;
    m.alpha_mode = AlphaMode::Mask { cutoff: 0.25 };
    let base = m.textures.base_color.as_mut().unwrap();
    base.transform = Some(TextureTransform {
        offset: glam::Vec2::new(0.25, -0.5),
        rotation: 0.5,
        scale: glam::Vec2::new(2.0, 0.5),
    });
    base.sampler.wrap_s = Wrap::MirroredRepeat;
    base.sampler.filter = Filter::Nearest;
    m.textures.specular_color = m.textures.base_color;
    // A clear coat with its textures, on a material without a normal map (a coat over one
    // warns that it follows it).
    let coated = desc
        .materials
        .iter()
        .position(|m| m.textures.normal.is_none())
        .unwrap();
    let image = desc.materials[0].textures.base_color;
    let m = &mut desc.materials[coated];
    m.clearcoat = 0.6;
    m.clearcoat_roughness = 0.25;
    m.textures.clearcoat = image;
    m.textures.clearcoat_roughness = image;
    let mesh = &mut desc.meshes[0];
    mesh.tangents = vec![glam::Vec4::new(1.0, 0.0, 0.0, -1.0); mesh.positions.len()];
    let path = dir.join("textured.glb");
    export_glb(&desc, &path).unwrap();
    let back = load_gltf(&path).unwrap();
    assert!(back.warnings.is_empty(), "{:?}", back.warnings);
    for (a, b) in back.materials.iter().zip(&desc.materials) {
        assert_eq!(
            (a.alpha, a.alpha_mode),
            (b.alpha, b.alpha_mode),
            "{}",
            b.name
        );
        let (ra, rb): (Vec<_>, Vec<_>) = (a.textures.refs().collect(), b.textures.refs().collect());
        assert_eq!(ra.len(), rb.len(), "{}", b.name);
        for (x, y) in ra.iter().zip(&rb) {
            assert_eq!(back.images[x.image].texels(), desc.images[y.image].texels());
            assert_eq!(
                (x.sampler, x.tex_coord, x.transform),
                (y.sampler, y.tex_coord, y.transform)
            );
        }
        assert_eq!(
            a.textures.normal.map(|n| n.scale),
            b.textures.normal.map(|n| n.scale)
        );
        assert_eq!(
            (a.clearcoat, a.clearcoat_roughness),
            (b.clearcoat, b.clearcoat_roughness)
        );
    }
    assert!(back.materials[coated].textures.clearcoat.is_some());
    for (a, b) in back.meshes.iter().zip(&desc.meshes) {
        assert_eq!(a.texcoords, b.texcoords, "{}", b.node_name);
        assert_eq!(a.tangents, b.tangents, "{}", b.node_name);
    }
    // A texture on a set the mesh lacks could not be read back: refused.
    let mut bad = desc.clone();
    bad.meshes[0].texcoords[0].clear();
    let message = export_glb(&bad, &path).unwrap_err().to_string();
    assert!(
        message.contains("textured.glb") && message.contains("TEXCOORD_0"),
        "{message}"
    );
    let _ = fs::remove_dir_all(&dir);
}

/// A cube of 8 shared vertices without `NORMAL`: glTF (3.7.2.1) asks for flat normals, so
/// every triangle's corners carry its face's normal,
/// and each face shades as a flat Lambertian surface under a distant light, `ρ/π · E · cos θ`
/// at every point of it, its centre and its corners alike (averaged vertex normals tilt
/// toward the corners, which changes `cos θ` there).
#[test]
fn a_mesh_without_normals_is_shaded_flat() {
    use portalview::render::integrator::{Integrator, RenderSettings};
    use portalview::render::stats::Stats;
    use portalview::sampling::{Rng, Sampler};
    use portalview::scene::Scene;

    let dir = temp_dir("flat");
    let mut bin = Bin::default();
    let corners: Vec<[f32; 3]> = (0..8)
        .map(|k| [(k & 1) as f32, ((k >> 1) & 1) as f32, ((k >> 2) & 1) as f32])
        .collect();
    let positions = bin.vec3s(&corners);
    // Outward windings of the six faces (x = 0, x = 1, y = 0, y = 1, z = 0, z = 1).
    let faces: [[u16; 4]; 6] = [
        [0, 4, 6, 2],
        [1, 3, 7, 5],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 2, 3, 1],
        [4, 5, 7, 6],
    ];
    let triangles: Vec<u16> = faces
        .iter()
        .flat_map(|[a, b, c, d]| [*a, *b, *c, *a, *c, *d])
        .collect();
    let indices = bin.indices(&triangles);
    fs::write(dir.join("cube.bin"), &bin.bytes).unwrap();
    // The light arrives along (−1, −2, −0.5)/|…|: it falls on the top, the +x and the +z faces.
    let light_dir = Vec3::new(-1.0, -2.0, -0.5).normalize();
    let rotation = Quat::from_rotation_arc(Vec3::NEG_Z, light_dir);
    let doc = json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_specular"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"type": "directional", "intensity": 3.0}
        ]}},
        "buffers": [{"uri": "cube.bin", "byteLength": bin.bytes.len()}],
        "bufferViews": bin.views,
        "accessors": bin.accessors,
        // Blender's Lambertian material: Specular 0.
        "materials": [{
            "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0},
            "extensions": {"KHR_materials_specular": {"specularColorFactor": [0.0, 0.0, 0.0]}}
        }],
        "meshes": [{"name": "Cube", "primitives": [{
            "attributes": {"POSITION": positions},
            "indices": indices,
            "material": 0
        }]}],
        "nodes": [
            {"name": "Cube", "mesh": 0},
            {"name": "Sun", "rotation": rotation.to_array(), "extensions": {"KHR_lights_punctual": {"light": 0}}}
        ],
        "scenes": [{"nodes": [0, 1]}],
        "scene": 0
    });
    let path = dir.join("cube.gltf");
    write_json(&path, &doc);
    let desc = load_gltf(&path).unwrap();
    let mesh = &desc.meshes[0];
    assert_eq!(mesh.indices.len(), 12);
    assert!(
        mesh.tangents.is_empty(),
        "TANGENT is ignored without NORMAL"
    );
    for t in 0..12 {
        let face = geometric_normal(mesh, t);
        for &i in &mesh.indices[t] {
            assert!(close(mesh.normals[i as usize], face), "triangle {t}");
        }
    }

    // Lambert under the distant light, at the centre and near the corners of each lit face.
    let scene = Scene::from_desc(desc, "cube").unwrap();
    let integrator = Integrator::new(&scene, RenderSettings::default());
    // 3 lx is 3/683 W/m² (`light::punctual`); the albedo is 0.5.
    let (e, albedo) = (3.0 / 683.0, 0.5);
    for (normal, centre, u, v) in [
        (Vec3::Y, Vec3::new(0.5, 1.0, 0.5), Vec3::X, Vec3::Z),
        (Vec3::X, Vec3::new(1.0, 0.5, 0.5), Vec3::Y, Vec3::Z),
        (Vec3::Z, Vec3::new(0.5, 0.5, 1.0), Vec3::X, Vec3::Y),
    ] {
        let expected = albedo / std::f32::consts::PI * e * normal.dot(-light_dir);
        for (a, b) in [
            (0.0, 0.0),
            (0.45, 0.45),
            (-0.45, 0.45),
            (0.45, -0.45),
            (-0.45, -0.45),
        ] {
            let x = centre + a * u + b * v;
            let eye = x + normal * 2.0 + u * 0.3;
            let mut rng = Sampler::from(Rng::new(1, 0));
            let l =
                integrator.radiance(eye, (x - eye).normalize(), &mut rng, &mut Stats::default());
            assert!(
                (l.x - expected).abs() <= 1e-3 * expected,
                "face {normal} at ({a}, {b}): {} vs {expected}",
                l.x
            );
        }
    }
    fs::remove_dir_all(&dir).unwrap();
}
