//! glTF 2.0 in and out: `.gltf` (external or embedded buffers) and `.glb` files to a
//! [`SceneDesc`] in world space, a `SceneDesc` back to `.glb`, and rewriting only the portal
//! nodes of an existing file after they were edited.
//!
//! A portal is a node whose `extras` hold `"portal_target": "<light node name>"` and optionally
//! `"portal_light_probability": <alpha in [0, 1]>` (how Blender exports custom properties);
//! `"portal_target": "environment"` makes it a window onto the sky. The scene's `extras` may
//! hold the environment: `"environment"` (an image path or `[r, g, b]`),
//! `"environment_strength"`, `"environment_rotation"` (degrees about +Y).
//!
//! Every read is bounds-checked before it happens, so a malformed file is an error that names
//! the file and the node, mesh, accessor or field at fault, never a panic.

mod accessor;
mod container;
mod environment;
mod lamps;
mod read;
mod save_portals;
mod textures;
mod validate;
mod write;

use accessor::*;
use container::*;
use environment::*;
use lamps::*;
use read::*;
use save_portals::*;
use textures::*;
use validate::*;
use write::*;

use std::borrow::Cow;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::fs;
use std::ops::Range;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

use glam::{Mat3, Mat4, Quat, Vec2, Vec3, Vec4};
use gltf::json;
use json::accessor::{ComponentType, GenericComponentType, IndexComponentType, Type};
use json::extras::RawValue;
use json::mesh::{Mode, Semantic};
use json::validation::{Checked, USize64, Validate};
use serde_json::{Map, Value};

use crate::asset::desc::{
    AlphaMode, DEFAULT_IOR, DEFAULT_PORTAL_ALPHA, DEFAULT_SPECULAR_COLOR, DEFAULT_SPECULAR_FACTOR,
    MaterialDesc, MaterialTextures, MeshDesc, NormalTexture, PortalDesc, SceneDesc, VolumeDesc,
};
use crate::asset::texture::TextureRef;
use crate::camera::Camera;

/// The most vertices, or triangles, a file may hold (per accessor and over the whole scene).
pub const MAX_ELEMENTS: usize = 50_000_000;
/// `extras` key naming the emissive node a portal opens onto.
pub const PORTAL_TARGET_KEY: &str = "portal_target";
/// `extras` key holding the probability of sampling the light itself rather than the portal.
pub const PORTAL_ALPHA_KEY: &str = "portal_light_probability";
/// The value of [`PORTAL_ALPHA_KEY`] that asks for alpha from the portals' measured leak.
pub const AUTO_ALPHA: &str = "auto";
/// Camera-node `extras` key for the eye-to-target distance (glTF cameras have no target).
const CAMERA_TARGET_DISTANCE_KEY: &str = "portalview_target_distance";
const EMISSIVE_STRENGTH_EXTENSION: &str = "KHR_materials_emissive_strength";
const SPECULAR_EXTENSION: &str = "KHR_materials_specular";
const IOR_EXTENSION: &str = "KHR_materials_ior";
const TRANSMISSION_EXTENSION: &str = "KHR_materials_transmission";
const VOLUME_EXTENSION: &str = "KHR_materials_volume";
const CLEARCOAT_EXTENSION: &str = "KHR_materials_clearcoat";
/// Width over height of a perspective camera without `aspectRatio`.
const DEFAULT_ASPECT: f32 = 4.0 / 3.0;

/// Why a glTF file cannot be read or written. Every message starts with the file's path and
/// names the node, mesh, accessor or field at fault.
#[derive(Debug, thiserror::Error)]
pub enum GltfError {
    #[error("{}: cannot read {what}: {source}", file.display())]
    Read {
        file: PathBuf,
        what: String,
        source: std::io::Error,
    },
    #[error("{}: cannot write the file: {source}", file.display())]
    Write {
        file: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: invalid JSON: {source}", file.display())]
    Json {
        file: PathBuf,
        source: serde_json::Error,
    },
    #[error("{}: not a valid GLB container: {reason}", file.display())]
    Glb { file: PathBuf, reason: String },
    #[error("{}: invalid glTF document: {problems}", file.display())]
    Validation { file: PathBuf, problems: String },
    /// Well-formed glTF that cannot be used: `at` names the node, mesh, accessor or field.
    #[error("{}: {at}: {reason}", file.display())]
    Invalid {
        file: PathBuf,
        at: String,
        reason: String,
    },
    /// A bug, caught rather than allowed to take the application down.
    #[error("{}: internal error: {message}", file.display())]
    Internal { file: PathBuf, message: String },
}

fn invalid(file: &Path, at: impl Into<String>, reason: impl Into<String>) -> GltfError {
    GltfError::Invalid {
        file: file.to_owned(),
        at: at.into(),
        reason: reason.into(),
    }
}

fn internal(file: &Path, message: impl ToString) -> GltfError {
    GltfError::Internal {
        file: file.to_owned(),
        message: message.to_string(),
    }
}

/// Decodes a texture image as the loader does (PNG or JPEG, bounded before decoding): for the
/// image fuzzing target and tests. The error says why, without a file name.
pub fn decode_texture(bytes: &[u8]) -> Result<crate::asset::texture::Image, String> {
    decode_image(bytes, "texture".to_owned())
}

/// Reads a `.gltf` or `.glb` file's default scene (else its first) into world space. What the
/// file uses that is not read (extensions, textures) is in the description's `warnings`, each
/// naming the file and what is ignored.
pub fn load_gltf(path: &Path) -> Result<SceneDesc, GltfError> {
    guarded(path, || {
        let source = read_source(path)?;
        let root = parse_document(path, source.json())?;
        let mut warnings = unread_extensions(path, &root);
        let buffers = load_buffers(path, &root, source.bin())?;
        let doc = Doc {
            file: path,
            root: &root,
            buffers: &buffers,
        };
        let visits = walk_scene(path, &root)?;
        let mut desc = doc.scene(&visits, &mut warnings)?;
        desc.environment = scene_environment(path, &root, &mut warnings)?;
        desc.warnings = warnings;
        Ok(desc)
    })
}

/// Writes `desc` as a `.glb` that [`load_gltf`] reads back to an equal `SceneDesc` (up to
/// float round-off and the name, which comes from the file name). The file is replaced
/// atomically: it is written beside its destination and renamed over it.
pub fn export_glb(desc: &SceneDesc, path: &Path) -> Result<(), GltfError> {
    guarded(path, || {
        let (root, bin) = export_document(path, desc)?;
        let json = serde_json::to_vec(&root).map_err(|e| internal(path, e))?;
        let bytes = glb_bytes(path, json, (!bin.is_empty()).then_some(bin))?;
        write_atomically(path, &bytes)
    })
}

/// Rewrites the glTF or GLB file at `path` so that its portals are `portals`, changing nothing
/// but portal nodes (and appending meshes for new or reshaped portals):
/// - a portal with `node_index: Some(i)` sets node i's matrix (relative to its parent), its
///   portal extras (other keys are kept) and its name;
/// - a portal with `node_index: None` becomes a new root node with a new mesh, whose data is
///   embedded as a base64 data URI;
/// - portal nodes of the file absent from `portals` are detached from the hierarchy (nodes
///   are not renumbered).
///
/// A `.glb` keeps its BIN chunk byte for byte; a `.gltf` keeps its external buffers.
pub fn save_portals(path: &Path, portals: &[PortalDesc]) -> Result<(), GltfError> {
    guarded(path, || save_portals_inner(path, portals))
}

/// Sets the environment in the used scene's `extras` of the glTF or GLB file at `path` (or
/// removes it, for `None`), changing nothing else. An image made in code is written beside the
/// file as `<stem>_environment.hdr`.
pub fn save_environment(
    path: &Path,
    environment: Option<&crate::asset::environment::EnvironmentDesc>,
) -> Result<(), GltfError> {
    guarded(path, || save_environment_inner(path, environment))
}

/// Runs `work`, turning a panic (a bug: every input is checked before use) into an error.
fn guarded<T>(file: &Path, work: impl FnOnce() -> Result<T, GltfError>) -> Result<T, GltfError> {
    catch_unwind(AssertUnwindSafe(work))
        .unwrap_or_else(|payload| Err(internal(file, crate::io::panic_message(&*payload))))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn data_uris_decode_standard_and_url_safe_base64() {
        let (file, base) = (Path::new("x.gltf"), Path::new("."));
        for n in 0..40u8 {
            let data: Vec<u8> = (0..n).map(|i| i.wrapping_mul(37).wrapping_add(n)).collect();
            let uri = format!(
                "data:application/octet-stream;base64,{}",
                base64_encode(&data)
            );
            assert_eq!(
                read_uri(file, base, "buffer 0", &uri, u64::MAX).unwrap(),
                data
            );
        }
        let url_safe = "data:application/octet-stream;base64,-_-_";
        assert_eq!(
            read_uri(file, base, "b", url_safe, u64::MAX).unwrap(),
            vec![0xfb, 0xff, 0xbf]
        );
        let bad = read_uri(file, base, "buffer 3", "data:x;base64,TW*u", u64::MAX).unwrap_err();
        assert!(bad.to_string().contains("x.gltf") && bad.to_string().contains("buffer 3"));
    }

    #[test]
    fn percent_decoded_paths_and_schemes() {
        let dir = std::env::temp_dir().join(format!("portalview-uri-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        fs::write(dir.join("my scene.bin"), [1u8, 2]).unwrap();
        let file = dir.join("x.gltf");
        assert_eq!(
            read_uri(&file, &dir, "b", "my%20scene.bin", u64::MAX).unwrap(),
            vec![1, 2]
        );
        assert!(read_uri(&file, &dir, "b", "%FF", u64::MAX).is_err());
        fs::remove_dir_all(&dir).unwrap();
        assert!(has_scheme("http://x/y.bin"));
        assert!(!has_scheme("scene.bin"));
        assert!(!has_scheme("C:/scene.bin"));
    }

    #[test]
    fn cofactor_is_determinant_times_inverse_transpose() {
        let m = Mat3::from_cols_array(&[2.0, 0.3, -0.1, 0.5, -1.5, 0.2, 0.1, 0.4, 3.0]);
        let expected = m.inverse().transpose() * m.determinant();
        assert!(cofactor(m).abs_diff_eq(expected, 1e-5));
    }

    fn unit_triangle(normals: bool) -> Geometry {
        Geometry {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            normals: normals.then(|| vec![Vec3::Z; 3]),
            triangles: vec![[0, 1, 2]],
            texcoords: [None, None],
            tangents: None,
        }
    }

    #[test]
    fn mirroring_flips_winding_and_keeps_normals_in_front() {
        let mirror = Mat4::from_scale(Vec3::new(-2.0, 1.0, 1.0));
        for with_normals in [true, false] {
            let Some(mesh) = world_mesh(unit_triangle(with_normals), mirror, "m".into(), 0) else {
                panic!("finite input");
            };
            assert_eq!(mesh.indices, vec![[0, 2, 1]]);
            let [a, b, c] = mesh.indices[0].map(|i| mesh.positions[i as usize]);
            let geometric = (b - a).cross(c - a).normalize();
            for n in &mesh.normals {
                assert!(n.abs_diff_eq(geometric, 1e-6), "{n} vs {geometric}");
            }
        }
        // A tangent moves like a direction; the mirror flips its bitangent sign, so that
        // `w · (N × T)` is the mirrored bitangent (+Y here, as before the mirror).
        let geometry = Geometry {
            tangents: Some(vec![Vec4::new(1.0, 0.0, 0.0, 1.0); 3]),
            ..unit_triangle(true)
        };
        let Some(mesh) = world_mesh(geometry, mirror, "m".into(), 0) else {
            panic!("finite input");
        };
        for (t, n) in mesh.tangents.iter().zip(&mesh.normals) {
            assert!(t.abs_diff_eq(Vec4::new(-1.0, 0.0, 0.0, -1.0), 1e-6), "{t}");
            let bitangent = t.w * n.cross(t.truncate());
            assert!(bitangent.abs_diff_eq(Vec3::Y, 1e-6), "{bitangent}");
        }
    }

    #[test]
    fn normals_use_the_inverse_transpose() {
        // Under a non-uniform scale, transforming the normal like a position would be wrong.
        let scale = Mat4::from_scale(Vec3::new(1.0, 4.0, 1.0));
        let geometry = Geometry {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Z],
            normals: Some(vec![Vec3::new(1.0, 1.0, 0.0).normalize(); 3]),
            triangles: vec![[0, 1, 2]],
            texcoords: [None, None],
            tangents: None,
        };
        let Some(mesh) = world_mesh(geometry, scale, "s".into(), 0) else {
            panic!("finite input");
        };
        let expected = Vec3::new(1.0, 0.25, 0.0).normalize();
        assert!(mesh.normals[0].abs_diff_eq(expected, 1e-6));
    }

    #[test]
    fn computed_normals_are_area_weighted() {
        // Two faces sharing vertex 0: a big one facing +Z, a small one facing +X.
        let positions = vec![
            Vec3::ZERO,
            Vec3::new(4.0, 0.0, 0.0),
            Vec3::new(0.0, 4.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
        ];
        let normals = vertex_normals(&positions, &[[0, 1, 2], [0, 3, 4]]);
        let expected = Vec3::new(1.0, 0.0, 16.0).normalize();
        assert!(normals[0].abs_diff_eq(expected, 1e-6));
        assert!(normals[1].abs_diff_eq(Vec3::Z, 1e-6));
    }

    #[test]
    fn strips_and_fans_become_triangles_with_consistent_winding() {
        assert_eq!(
            triangulate(Mode::TriangleStrip, &[0, 1, 2, 3]),
            vec![[0, 1, 2], [2, 1, 3]]
        );
        assert_eq!(
            triangulate(Mode::TriangleFan, &[0, 1, 2, 3]),
            vec![[0, 1, 2], [0, 2, 3]]
        );
        assert_eq!(triangulate(Mode::Triangles, &[0, 1, 2]), vec![[0, 1, 2]]);
        assert!(triangulate(Mode::TriangleFan, &[]).is_empty());
    }

    #[test]
    fn glb_container_errors_are_reported() {
        let file = Path::new("x.glb");
        let mut glb = b"glTF".to_vec();
        glb.extend(2u32.to_le_bytes());
        glb.extend(40u32.to_le_bytes());
        glb.extend(8u32.to_le_bytes());
        glb.extend(b"JSON");
        glb.extend(b"{}      ");
        glb.extend(100u32.to_le_bytes());
        glb.extend(b"BIN\0");
        glb.extend([0u8; 4]);
        assert_eq!(glb.len(), 40);
        let message = split_glb(file, &glb).map(|_| ()).unwrap_err().to_string();
        assert!(
            message.contains("x.glb") && message.contains("chunk 1"),
            "{message}"
        );
        assert!(split_glb(file, &glb[..10]).is_err());
        assert!(
            split_glb(file, &glb[..30]).is_err(),
            "header length beyond the file"
        );
        let mut wrong_version = glb.clone();
        wrong_version[4] = 1;
        assert!(split_glb(file, &wrong_version).is_err());
        // A well-formed one: JSON chunk only.
        let mut ok = glb[..28].to_vec();
        ok[8..12].copy_from_slice(&28u32.to_le_bytes());
        let Ok((json, bin)) = split_glb(file, &ok) else {
            panic!("valid GLB");
        };
        assert_eq!(&ok[json], b"{}      ");
        assert!(bin.is_none());
    }

    #[test]
    fn camera_transform_round_trips_through_the_loader_convention() {
        let file = Path::new("c.glb");
        let desc = Camera {
            eye: Vec3::new(1.0, 2.0, 3.0),
            target: Vec3::new(4.0, 0.0, -1.0),
            up: Vec3::Y,
            yfov: 0.8,
            aspect: 1.5,
        };
        let Ok((world, distance)) = camera_transform(file, &desc) else {
            panic!("valid camera");
        };
        let forward = world.transform_vector3(Vec3::NEG_Z);
        let eye = world.w_axis.truncate();
        assert!(eye.abs_diff_eq(desc.eye, 1e-6));
        assert!((eye + forward * distance).abs_diff_eq(desc.target, 1e-5));
        let up = world.transform_vector3(Vec3::Y);
        assert!(up.dot(forward).abs() < 1e-6 && up.y > 0.0);
        let degenerate = Camera {
            up: desc.target - desc.eye,
            ..desc
        };
        assert!(camera_transform(file, &degenerate).is_err());
    }

    #[test]
    fn json_f32_prints_shortest_and_reads_back_exactly() {
        for x in [0.1f32, 1.0 / 3.0, -0.0, 1e-8, 123456.79, f32::MAX] {
            let text = json_f32(x).to_string();
            assert_eq!(text.parse::<f32>().ok(), Some(x), "{text}");
        }
        assert_eq!(json_f32(0.1).to_string(), "0.1");
    }

    #[test]
    fn portal_extras_are_validated() {
        let file = Path::new("p.gltf");
        let parse = |v: Value| {
            let Value::Object(map) = v else {
                panic!("object");
            };
            portal_extras(
                file,
                Some(&map),
                "node 3 \"P\"",
                (DEFAULT_PORTAL_ALPHA, false),
            )
        };
        let ok = parse(serde_json::json!({"portal_target": "L"}));
        assert!(
            matches!(ok, Ok(Some(PortalExtras { alpha, .. })) if alpha == DEFAULT_PORTAL_ALPHA)
        );
        assert!(matches!(parse(serde_json::json!({"other": 1})), Ok(None)));
        for bad in [
            serde_json::json!({"portal_target": 3}),
            serde_json::json!({"portal_target": ""}),
            serde_json::json!({"portal_target": "L", "portal_light_probability": "high"}),
            serde_json::json!({"portal_target": "L", "portal_light_probability": 1.5}),
        ] {
            let Err(e) = parse(bad) else {
                panic!("must be rejected");
            };
            let message = e.to_string();
            assert!(
                message.contains("p.gltf") && message.contains("node 3 \"P\""),
                "{message}"
            );
        }
    }
}
