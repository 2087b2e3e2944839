//! The committed assets are the built-in scenes, exported: loading each gives the scene the
//! code builds (regenerate with `portalview export --scene NAME --out assets/NAME.glb`).

use glam::Vec3;
use portalview::asset::desc::SceneDesc;
use portalview::asset::environment::EnvMap;
use portalview::asset::{builtin, gltf};
use portalview::scene::Scene;
use std::path::Path;

fn close(a: Vec3, b: Vec3) -> bool {
    a.abs_diff_eq(b, 1e-5 * (1.0 + a.abs().max_element()))
}

fn assert_same(name: &str, file: &SceneDesc, code: &SceneDesc) {
    assert_eq!(
        file.materials.len(),
        code.materials.len(),
        "{name}: materials"
    );
    for (a, b) in file.materials.iter().zip(&code.materials) {
        assert_eq!(a.name, b.name);
        assert!(close(a.base_color, b.base_color), "{name}: {}", a.name);
        assert!((a.metallic - b.metallic).abs() < 1e-6 && (a.roughness - b.roughness).abs() < 1e-6);
        assert!(
            close(a.radiance(), b.radiance()),
            "{name}: {} emission",
            a.name
        );
        assert_eq!(a.double_sided, b.double_sided);
    }
    assert_eq!(file.meshes.len(), code.meshes.len(), "{name}: meshes");
    for (a, b) in file.meshes.iter().zip(&code.meshes) {
        assert_eq!(a.node_name, b.node_name);
        assert_eq!(a.material, b.material);
        assert_eq!(a.indices, b.indices, "{name}: {}", a.node_name);
        assert!(
            a.positions
                .iter()
                .zip(&b.positions)
                .all(|(p, q)| close(*p, *q))
        );
        assert!(a.normals.iter().zip(&b.normals).all(|(p, q)| close(*p, *q)));
    }
    assert_eq!(file.portals.len(), code.portals.len(), "{name}: portals");
    for (a, b) in file.portals.iter().zip(&code.portals) {
        assert_eq!((&a.name, &a.target, a.alpha), (&b.name, &b.target, b.alpha));
        let (ta, tb) = (a.world_triangles(), b.world_triangles());
        assert_eq!(ta.len(), tb.len());
        assert!(
            ta.iter()
                .flatten()
                .zip(tb.iter().flatten())
                .all(|(p, q)| close(*p, *q))
        );
    }
    match (&file.environment, &code.environment) {
        (None, None) => {}
        (Some(a), Some(b)) => {
            assert_eq!(
                (a.strength, a.rotation_degrees),
                (b.strength, b.rotation_degrees)
            );
            match (&a.map, &b.map) {
                (EnvMap::Constant(x), EnvMap::Constant(y)) => assert!(close(*x, *y)),
                (EnvMap::Image { image: x, .. }, EnvMap::Image { image: y, .. }) => {
                    assert_eq!((x.width, x.height), (y.width, y.height), "{name}");
                    // Written as Radiance RGBE: 8-bit mantissas.
                    assert!(x.pixels.iter().zip(&y.pixels).all(|(p, q)| {
                        (*p - *q).abs().max_element() <= 0.01 * q.max_element() + 1e-6
                    }));
                }
                _ => panic!("{name}: environment kinds differ"),
            }
        }
        _ => panic!("{name}: environment present in only one"),
    }
    let (ca, cb) = (file.camera.unwrap(), code.camera.unwrap());
    assert!(
        close(ca.eye, cb.eye) && close(ca.target, cb.target),
        "{name}: camera"
    );
    assert!((ca.yfov - cb.yfov).abs() < 1e-6 && (ca.aspect - cb.aspect).abs() < 1e-6);
}

#[test]
fn committed_assets_equal_the_builtin_scenes() {
    for name in builtin::NAMES {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("assets/{name}.glb"));
        let file = gltf::load_gltf(&path).unwrap();
        assert_same(name, &file, &builtin::desc(name).unwrap());
        // And the loaded file is a valid scene with its portals.
        let scene = Scene::load(&path).unwrap();
        assert_eq!(
            scene.portals.len() + scene.windows.len(),
            file.portals.len()
        );
    }
}
