//! glTF 2.0 in and out: `.gltf` (external or embedded buffers) and `.glb` files to a
//! [`SceneDesc`] in world space, a `SceneDesc` back to `.glb`, and rewriting only the portal
//! nodes of an existing file after they were edited.
//!
//! A portal is a node whose `extras` hold `"portal_target": "<light node name>"` and optionally
//! `"portal_light_probability": <alpha in [0, 1]>` (how Blender exports custom properties).
//!
//! Every read is bounds-checked before it happens, so a malformed file is an error that names
//! the file and the node, mesh, accessor or field at fault, never a panic.

use std::borrow::Cow;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::fs;
use std::io::Write;
use std::ops::Range;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use glam::{Mat3, Mat4, Quat, Vec3};
use gltf::json;
use json::accessor::{ComponentType, GenericComponentType, IndexComponentType, Type};
use json::extras::RawValue;
use json::mesh::{Mode, Semantic};
use json::validation::{Checked, USize64, Validate};
use serde_json::{Map, Value};

use super::desc::{CameraDesc, MaterialDesc, MeshDesc, PortalDesc, SceneDesc};

/// The most vertices, or triangles, a file may hold (per accessor and over the whole scene).
pub const MAX_ELEMENTS: usize = 50_000_000;
/// `extras` key naming the emissive node a portal opens onto.
pub const PORTAL_TARGET_KEY: &str = "portal_target";
/// `extras` key holding the probability of sampling the light itself rather than the portal.
pub const PORTAL_ALPHA_KEY: &str = "portal_light_probability";
/// The portal's alpha when `portal_light_probability` is absent.
pub const DEFAULT_PORTAL_ALPHA: f32 = 0.1;
/// Camera-node `extras` key for the eye-to-target distance (glTF cameras have no target).
const CAMERA_TARGET_DISTANCE_KEY: &str = "portalview_target_distance";
const EMISSIVE_STRENGTH_EXTENSION: &str = "KHR_materials_emissive_strength";
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

/// Reads a `.gltf` or `.glb` file's default scene (else its first) into world space.
pub fn load_gltf(path: &Path) -> Result<SceneDesc, GltfError> {
    guarded(path, || {
        let source = read_source(path)?;
        let root = parse_document(path, source.json())?;
        let buffers = load_buffers(path, &root, source.bin())?;
        let doc = Doc {
            file: path,
            root: &root,
            buffers: &buffers,
        };
        let visits = walk_scene(path, &root)?;
        doc.scene(&visits)
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

/// Runs `work`, turning a panic (a bug: every input is checked before use) into an error.
fn guarded<T>(file: &Path, work: impl FnOnce() -> Result<T, GltfError>) -> Result<T, GltfError> {
    catch_unwind(AssertUnwindSafe(work)).unwrap_or_else(|payload| {
        let message = payload
            .downcast_ref::<&str>()
            .map(|s| (*s).to_owned())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "panic while processing the file".to_owned());
        Err(internal(file, message))
    })
}

// ---------------------------------------------------------------------------------------------
// Reading the container, the JSON and the buffers.

/// A file's bytes, with where its JSON and (for a `.glb`) its BIN chunk are.
struct Source {
    bytes: Vec<u8>,
    json: Range<usize>,
    bin: Option<Range<usize>>,
    is_glb: bool,
}

impl Source {
    fn json(&self) -> &[u8] {
        self.bytes.get(self.json.clone()).unwrap_or_default()
    }

    fn bin(&self) -> Option<&[u8]> {
        self.bin.clone().and_then(|r| self.bytes.get(r))
    }
}

fn read_source(file: &Path) -> Result<Source, GltfError> {
    let bytes = fs::read(file).map_err(|source| GltfError::Read {
        file: file.to_owned(),
        what: "the file".to_owned(),
        source,
    })?;
    let glb_extension = file
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("glb"));
    if bytes.starts_with(b"glTF") || glb_extension {
        let (json, bin) = split_glb(file, &bytes)?;
        Ok(Source {
            bytes,
            json,
            bin,
            is_glb: true,
        })
    } else {
        Ok(Source {
            json: 0..bytes.len(),
            bytes,
            bin: None,
            is_glb: false,
        })
    }
}

fn le_u32(bytes: &[u8], at: usize) -> Option<u32> {
    let b: [u8; 4] = bytes.get(at..at.checked_add(4)?)?.try_into().ok()?;
    Some(u32::from_le_bytes(b))
}

/// Where the JSON chunk and the BIN chunk (if any) of a GLB file are, every length checked.
fn split_glb(file: &Path, bytes: &[u8]) -> Result<(Range<usize>, Option<Range<usize>>), GltfError> {
    let err = |reason: String| GltfError::Glb {
        file: file.to_owned(),
        reason,
    };
    if bytes.len() < 12 {
        return Err(err(format!(
            "the file is {} bytes, shorter than the 12-byte GLB header",
            bytes.len()
        )));
    }
    if !bytes.starts_with(b"glTF") {
        return Err(err("it does not start with the magic \"glTF\"".to_owned()));
    }
    let version = le_u32(bytes, 4).unwrap_or(0);
    if version != 2 {
        return Err(err(format!(
            "GLB version {version} is not supported (only 2)"
        )));
    }
    let declared = le_u32(bytes, 8).unwrap_or(0) as usize;
    if declared > bytes.len() {
        return Err(err(format!(
            "the header declares {declared} bytes but the file has {} (truncated?)",
            bytes.len()
        )));
    }
    let Some(body) = bytes.get(12..declared) else {
        return Err(err(format!(
            "the header declares {declared} bytes, fewer than the header itself"
        )));
    };
    let (mut offset, mut chunk) = (0usize, 0usize);
    let (mut json, mut bin) = (None, None);
    while offset < body.len() {
        let (Some(length), Some(kind)) = (le_u32(body, offset), body.get(offset + 4..offset + 8))
        else {
            return Err(err(format!(
                "chunk {chunk}'s header at byte {} is cut off (truncated?)",
                12 + offset
            )));
        };
        let start = offset + 8;
        let Some(end) = start
            .checked_add(length as usize)
            .filter(|&end| end <= body.len())
        else {
            return Err(err(format!(
                "chunk {chunk} declares {length} bytes but only {} remain (truncated?)",
                body.len().saturating_sub(start)
            )));
        };
        // Ranges in the whole file, after its 12-byte header.
        let range = 12 + start..12 + end;
        match (chunk, kind) {
            (0, b"JSON") => json = Some(range),
            (0, _) => return Err(err("its first chunk is not JSON".to_owned())),
            (_, b"BIN\0") if bin.is_none() => bin = Some(range),
            // The spec asks readers to skip chunks they do not know.
            _ => {}
        }
        offset = end;
        chunk += 1;
    }
    let Some(json) = json else {
        return Err(err("it has no JSON chunk".to_owned()));
    };
    Ok((json, bin))
}

/// Parses and validates the JSON document.
fn parse_document(file: &Path, json_bytes: &[u8]) -> Result<json::Root, GltfError> {
    let root: json::Root =
        serde_json::from_slice(json_bytes).map_err(|source| GltfError::Json {
            file: file.to_owned(),
            source,
        })?;
    // The gltf crate's validation indexes the POSITION accessor without a bounds check.
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            for (semantic, accessor) in &primitive.attributes {
                if accessor.value() >= root.accessors.len() {
                    return Err(invalid(
                        file,
                        format!(
                            "{}, primitive {p}, attribute {}",
                            label("mesh", m, mesh.name.as_deref()),
                            semantic.to_string()
                        ),
                        format!(
                            "accessor {} does not exist (the file has {})",
                            accessor.value(),
                            root.accessors.len()
                        ),
                    ));
                }
            }
        }
    }
    let mut problems = Vec::new();
    root.validate(&root, json::Path::new, &mut |path, error| {
        let path = path().to_string();
        // The spec requires POSITION min/max, but they are unused here and often omitted;
        // required extensions are judged below.
        let ignored = path.ends_with("[\"POSITION\"].min")
            || path.ends_with("[\"POSITION\"].max")
            || path.starts_with("extensionsRequired");
        if !ignored {
            problems.push(format!("{path}: {error}"));
        }
    });
    for (i, extension) in root.extensions_required.iter().enumerate() {
        if !can_ignore_or_read(extension) {
            problems.push(format!(
                "extensionsRequired[{i}]: \"{extension}\" is not supported"
            ));
        }
    }
    if problems.is_empty() {
        return Ok(root);
    }
    let shown = problems.len().min(8);
    let mut listed = problems[..shown].join("; ");
    if problems.len() > shown {
        listed.push_str(&format!("; and {} more", problems.len() - shown));
    }
    Err(GltfError::Validation {
        file: file.to_owned(),
        problems: listed,
    })
}

/// Whether a file that requires `extension` still loads correctly here: it only changes
/// textures or material details that are not read, or it is understood (quantized attributes
/// are read as normalised integers, emissive strength is read).
fn can_ignore_or_read(extension: &str) -> bool {
    extension.starts_with("KHR_materials_")
        || matches!(
            extension,
            "KHR_mesh_quantization"
                | "KHR_texture_transform"
                | "KHR_texture_basisu"
                | "EXT_texture_webp"
                | "EXT_texture_avif"
                | "MSFT_texture_dds"
                | "KHR_lights_punctual"
        )
}

/// The bytes of every buffer, each at least as long as its `byteLength`.
fn load_buffers<'b>(
    file: &Path,
    root: &json::Root,
    bin: Option<&'b [u8]>,
) -> Result<Vec<Cow<'b, [u8]>>, GltfError> {
    let base = file.parent().unwrap_or(Path::new(""));
    let mut buffers = Vec::with_capacity(root.buffers.len());
    for (i, buffer) in root.buffers.iter().enumerate() {
        let at = label("buffer", i, buffer.name.as_deref());
        let data = match (buffer.uri.as_deref(), bin) {
            (Some(uri), _) => Cow::Owned(read_uri(file, base, &at, uri)?),
            (None, Some(bin)) if i == 0 => Cow::Borrowed(bin),
            (None, _) if i == 0 => {
                return Err(invalid(
                    file,
                    at,
                    "has no uri, and there is no GLB BIN chunk",
                ));
            }
            (None, _) => {
                return Err(invalid(
                    file,
                    at,
                    "has no uri (only buffer 0 may be the GLB BIN chunk)",
                ));
            }
        };
        let declared = buffer.byte_length.0;
        if (data.len() as u64) < declared {
            return Err(invalid(
                file,
                at,
                format!(
                    "holds {} bytes but declares byteLength {declared}",
                    data.len()
                ),
            ));
        }
        buffers.push(data);
    }
    Ok(buffers)
}

fn read_uri(file: &Path, base: &Path, at: &str, uri: &str) -> Result<Vec<u8>, GltfError> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let Some((_, payload)) = rest.split_once(";base64,") else {
            return Err(invalid(
                file,
                at,
                "its data URI is not base64 (data:…;base64,…)",
            ));
        };
        return base64_decode(payload)
            .ok_or_else(|| invalid(file, at, "its data URI holds invalid base64"));
    }
    if has_scheme(uri) {
        return Err(invalid(
            file,
            at,
            format!("URI \"{uri}\" is neither a relative path nor a data URI"),
        ));
    }
    let Some(relative) = percent_decode(uri) else {
        return Err(invalid(
            file,
            at,
            format!("URI \"{uri}\" is badly percent-encoded"),
        ));
    };
    let target = base.join(relative);
    fs::read(&target).map_err(|source| GltfError::Read {
        file: file.to_owned(),
        what: format!("{at} from \"{}\"", target.display()),
        source,
    })
}

/// Whether `uri` starts with a scheme such as `http:` (two letters or more, so that a Windows
/// drive letter is not one).
fn has_scheme(uri: &str) -> bool {
    uri.split_once(':').is_some_and(|(scheme, _)| {
        scheme.len() > 1
            && scheme.starts_with(|c: char| c.is_ascii_alphabetic())
            && scheme
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || "+.-".contains(c))
    })
}

fn percent_decode(s: &str) -> Option<String> {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while let Some(&b) = bytes.get(i) {
        if b == b'%' {
            let hex = std::str::from_utf8(bytes.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(b);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

const BASE64_ALPHABET: &[u8; 64] =
    b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

fn base64_encode(data: &[u8]) -> String {
    let mut out = String::with_capacity(data.len().div_ceil(3) * 4);
    for chunk in data.chunks(3) {
        let byte = |k: usize| u32::from(chunk.get(k).copied().unwrap_or(0));
        let n = (byte(0) << 16) | (byte(1) << 8) | byte(2);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(char::from(
                    BASE64_ALPHABET[(n >> (18 - 6 * k) & 63) as usize],
                ));
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// Standard or URL-safe base64, padding optional; `None` if malformed.
fn base64_decode(text: &str) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(text.len() / 4 * 3);
    let (mut acc, mut bits) = (0u32, 0u32);
    for c in text.trim_end_matches('=').bytes() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            _ => return None,
        };
        acc = (acc << 6) | u32::from(v);
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    // One character left over carries no whole byte.
    (bits < 6).then_some(out)
}

// ---------------------------------------------------------------------------------------------
// Walking the scene and reading geometry.

fn label(kind: &str, index: usize, name: Option<&str>) -> String {
    match name {
        Some(name) => format!("{kind} {index} \"{name}\""),
        None => format!("{kind} {index}"),
    }
}

fn node_label(index: usize, node: &json::Node) -> String {
    label("node", index, node.name.as_deref())
}

/// The name a node goes by in a `SceneDesc`.
fn node_name(index: usize, node: &json::Node) -> String {
    node.name.clone().unwrap_or_else(|| format!("node {index}"))
}

/// One node reached from the scene's roots, in depth-first order.
struct Visit {
    node: usize,
    world: Mat4,
    parent_world: Mat4,
}

/// The scene that is loaded: the default one, else the first.
fn used_scene(root: &json::Root) -> Option<usize> {
    match root.scene {
        Some(s) => Some(s.value()),
        None => (!root.scenes.is_empty()).then_some(0),
    }
}

/// The scene's root nodes; without scenes, every node that is nobody's child.
fn scene_roots(root: &json::Root) -> Vec<usize> {
    if let Some(scene) = used_scene(root).and_then(|s| root.scenes.get(s)) {
        return scene.nodes.iter().map(|n| n.value()).collect();
    }
    let mut is_child = vec![false; root.nodes.len()];
    for child in root.nodes.iter().flat_map(|n| n.children.iter().flatten()) {
        if let Some(flag) = is_child.get_mut(child.value()) {
            *flag = true;
        }
    }
    (0..root.nodes.len()).filter(|&i| !is_child[i]).collect()
}

/// Every node of the scene with its world transform (world = parent × local).
fn walk_scene(file: &Path, root: &json::Root) -> Result<Vec<Visit>, GltfError> {
    let mut visited = vec![false; root.nodes.len()];
    let mut visits = Vec::new();
    // An explicit stack: a deep hierarchy must not overflow the thread's stack.
    let mut stack: Vec<(usize, Mat4)> = scene_roots(root)
        .into_iter()
        .rev()
        .map(|i| (i, Mat4::IDENTITY))
        .collect();
    while let Some((i, parent_world)) = stack.pop() {
        let (Some(node), Some(seen)) = (root.nodes.get(i), visited.get_mut(i)) else {
            return Err(invalid(file, format!("node {i}"), "does not exist"));
        };
        let at = node_label(i, node);
        if *seen {
            return Err(invalid(
                file,
                at,
                "is reached twice in the scene (a node may have one parent, and no cycles)",
            ));
        }
        *seen = true;
        let world = parent_world * local_matrix(file, node, &at)?;
        if !world.is_finite() {
            return Err(invalid(file, at, "its world transform is not finite"));
        }
        if let Some(children) = &node.children {
            stack.extend(children.iter().rev().map(|c| (c.value(), world)));
        }
        visits.push(Visit {
            node: i,
            world,
            parent_world,
        });
    }
    Ok(visits)
}

fn local_matrix(file: &Path, node: &json::Node, at: &str) -> Result<Mat4, GltfError> {
    if let Some(m) = node.matrix {
        let m = Mat4::from_cols_array(&m);
        if !m.is_finite() {
            return Err(invalid(file, format!("{at}, matrix"), "is not finite"));
        }
        return Ok(m);
    }
    let translation = Vec3::from_array(node.translation.unwrap_or([0.0; 3]));
    let scale = Vec3::from_array(node.scale.unwrap_or([1.0; 3]));
    let rotation = Quat::from_array(node.rotation.map_or([0.0, 0.0, 0.0, 1.0], |q| q.0));
    if !translation.is_finite() {
        return Err(invalid(file, format!("{at}, translation"), "is not finite"));
    }
    if !scale.is_finite() {
        return Err(invalid(file, format!("{at}, scale"), "is not finite"));
    }
    if !rotation.is_finite() || rotation.length() < 1e-6 {
        return Err(invalid(
            file,
            format!("{at}, rotation"),
            "is not a unit quaternion",
        ));
    }
    Ok(Mat4::from_scale_rotation_translation(
        scale,
        rotation.normalize(),
        translation,
    ))
}

/// A primitive's vertices and triangles as stored (local space).
struct Geometry {
    positions: Vec<Vec3>,
    normals: Option<Vec<Vec3>>,
    triangles: Vec<[u32; 3]>,
}

/// Strided elements inside a buffer view, bounds already checked.
struct Elements<'b> {
    bytes: &'b [u8],
    stride: usize,
    size: usize,
}

impl<'b> Elements<'b> {
    fn get(&self, i: usize) -> Option<&'b [u8]> {
        let start = i.checked_mul(self.stride)?;
        self.bytes.get(start..start.checked_add(self.size)?)
    }
}

/// Where an accessor's values are, checked against its view and buffer.
struct AccessorData<'b> {
    count: usize,
    component: ComponentType,
    normalized: bool,
    base: Option<Elements<'b>>,
    /// Sparse substitutions: element indices and their values.
    sparse: Option<(Vec<usize>, Elements<'b>)>,
}

/// A parsed document with its buffers, and the file to name in errors.
struct Doc<'a> {
    file: &'a Path,
    root: &'a json::Root,
    buffers: &'a [Cow<'a, [u8]>],
}

impl<'a> Doc<'a> {
    fn invalid(&self, at: impl Into<String>, reason: impl Into<String>) -> GltfError {
        invalid(self.file, at, reason)
    }

    /// The bytes of buffer view `view`, and its stride.
    fn view_bytes(&self, view: usize, at: &str) -> Result<(&'a [u8], Option<usize>), GltfError> {
        let Some(v) = self.root.buffer_views.get(view) else {
            return Err(self.invalid(at, format!("bufferView {view} does not exist")));
        };
        let b = v.buffer.value();
        let (Some(data), Some(buffer)) = (self.buffers.get(b), self.root.buffers.get(b)) else {
            return Err(self.invalid(at, format!("bufferView {view}: buffer {b} does not exist")));
        };
        let start = v.byte_offset.map_or(0, |o| o.0);
        let length = v.byte_length.0;
        let limit = buffer.byte_length.0.min(data.len() as u64);
        let bytes = start
            .checked_add(length)
            .filter(|&end| end <= limit)
            .and_then(|end| data.get(usize::try_from(start).ok()?..usize::try_from(end).ok()?));
        let Some(bytes) = bytes else {
            return Err(self.invalid(
                at,
                format!(
                    "bufferView {view} spans bytes {start}..{} but buffer {b} has {limit}",
                    start.saturating_add(length)
                ),
            ));
        };
        Ok((bytes, v.byte_stride.map(|s| s.0).filter(|&s| s > 0)))
    }

    /// `count` elements of `size` bytes from `offset` in view `view`, every one in bounds.
    /// `packed` ignores the view's byteStride (sparse data is always tightly packed).
    fn elements(
        &self,
        view: usize,
        offset: u64,
        count: usize,
        size: usize,
        packed: bool,
        at: &str,
    ) -> Result<Elements<'a>, GltfError> {
        let (view_data, view_stride) = self.view_bytes(view, at)?;
        let stride = if packed {
            size
        } else {
            view_stride.unwrap_or(size)
        };
        if stride < size {
            return Err(self.invalid(
                at,
                format!(
                    "bufferView {view}'s byteStride {stride} is less than the element size {size}"
                ),
            ));
        }
        let offset_usize = usize::try_from(offset).ok();
        let end = match count.checked_sub(1) {
            None => offset_usize,
            Some(last) => last
                .checked_mul(stride)
                .and_then(|x| x.checked_add(size))
                .and_then(|x| x.checked_add(offset_usize?)),
        };
        let bytes = end
            .filter(|&end| end <= view_data.len())
            .and_then(|_| view_data.get(offset_usize?..));
        let Some(bytes) = bytes else {
            return Err(self.invalid(
                at,
                format!(
                    "{count} elements of {size} bytes (stride {stride}) from byte {offset} do not \
                     fit in bufferView {view} ({} bytes)",
                    view_data.len()
                ),
            ));
        };
        Ok(Elements {
            bytes,
            stride,
            size,
        })
    }

    /// Locates accessor `index`, which must be of type `expected` with at most `max_count`
    /// elements; nothing is read yet, but every element is known to be in bounds.
    fn accessor(
        &self,
        index: usize,
        at: &str,
        expected: Type,
        max_count: usize,
    ) -> Result<AccessorData<'a>, GltfError> {
        let at = format!("{at}, accessor {index}");
        let Some(accessor) = self.root.accessors.get(index) else {
            return Err(self.invalid(at, "does not exist"));
        };
        let Some(count) = usize::try_from(accessor.count.0)
            .ok()
            .filter(|&c| c <= max_count)
        else {
            return Err(self.invalid(
                at,
                format!(
                    "count {} exceeds the limit of {max_count}",
                    accessor.count.0
                ),
            ));
        };
        let Checked::Valid(GenericComponentType(component)) = accessor.component_type else {
            return Err(self.invalid(at, "componentType is invalid"));
        };
        let Checked::Valid(ty) = accessor.type_ else {
            return Err(self.invalid(at, "type is invalid"));
        };
        if ty != expected {
            return Err(self.invalid(
                at,
                format!(
                    "type is {}, expected {}",
                    type_name(ty),
                    type_name(expected)
                ),
            ));
        }
        let size = component.size() * ty.multiplicity();
        let base = match accessor.buffer_view {
            Some(view) => Some(self.elements(
                view.value(),
                accessor.byte_offset.map_or(0, |o| o.0),
                count,
                size,
                false,
                &at,
            )?),
            None => None,
        };
        let sparse = match &accessor.sparse {
            None => None,
            Some(sparse) => {
                let at = format!("{at}, sparse");
                let Some(n) = usize::try_from(sparse.count.0).ok().filter(|&n| n <= count) else {
                    return Err(self.invalid(
                        at,
                        format!("count {} exceeds the accessor's {count}", sparse.count.0),
                    ));
                };
                let Checked::Valid(IndexComponentType(index_type)) = sparse.indices.component_type
                else {
                    return Err(self.invalid(at, "indices.componentType is invalid"));
                };
                if !is_unsigned(index_type) {
                    return Err(self.invalid(at, "indices.componentType is not unsigned"));
                }
                let index_elements = self.elements(
                    sparse.indices.buffer_view.value(),
                    sparse.indices.byte_offset.0,
                    n,
                    index_type.size(),
                    true,
                    &format!("{at}.indices"),
                )?;
                let mut indices = Vec::with_capacity(n);
                for k in 0..n {
                    let i = index_elements
                        .get(k)
                        .map_or(u32::MAX, |b| read_uint(b, index_type))
                        as usize;
                    if i >= count {
                        return Err(self.invalid(
                            at,
                            format!("index {i} (entry {k}) is out of range for count {count}"),
                        ));
                    }
                    indices.push(i);
                }
                let values = self.elements(
                    sparse.values.buffer_view.value(),
                    sparse.values.byte_offset.0,
                    n,
                    size,
                    true,
                    &format!("{at}.values"),
                )?;
                Some((indices, values))
            }
        };
        Ok(AccessorData {
            count,
            component,
            normalized: accessor.normalized,
            base,
            sparse,
        })
    }

    /// Decodes every element of `data` (bounds were checked by `accessor`).
    fn read<T: Copy>(
        &self,
        data: &AccessorData<'a>,
        at: &str,
        zero: T,
        decode: impl Fn(&[u8]) -> T,
    ) -> Result<Vec<T>, GltfError> {
        let mut out = Vec::with_capacity(data.count);
        match &data.base {
            Some(elements) => {
                for i in 0..data.count {
                    let Some(bytes) = elements.get(i) else {
                        return Err(self.invalid(at, format!("element {i} is out of bounds")));
                    };
                    out.push(decode(bytes));
                }
            }
            None => out.resize(data.count, zero),
        }
        if let Some((indices, values)) = &data.sparse {
            for (k, &i) in indices.iter().enumerate() {
                let (Some(slot), Some(bytes)) = (out.get_mut(i), values.get(k)) else {
                    return Err(self.invalid(at, format!("sparse entry {k} is out of bounds")));
                };
                *slot = decode(bytes);
            }
        }
        Ok(out)
    }

    fn read_vec3s(&self, accessor: usize, at: &str) -> Result<Vec<Vec3>, GltfError> {
        let data = self.accessor(accessor, at, Type::Vec3, MAX_ELEMENTS)?;
        let (component, normalized) = (data.component, data.normalized);
        let size = component.size();
        let values = self.read(&data, at, Vec3::ZERO, |b| {
            Vec3::new(
                read_float(b, 0, component, normalized),
                read_float(b, size, component, normalized),
                read_float(b, 2 * size, component, normalized),
            )
        })?;
        if let Some((k, v)) = values.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(self.invalid(
                format!("{at}, accessor {accessor}"),
                format!("element {k} is not finite ({v})"),
            ));
        }
        Ok(values)
    }

    fn read_indices(&self, accessor: usize, at: &str) -> Result<Vec<u32>, GltfError> {
        let data = self.accessor(accessor, at, Type::Scalar, 3 * MAX_ELEMENTS)?;
        if !is_unsigned(data.component) || data.normalized {
            return Err(self.invalid(
                format!("{at}, accessor {accessor}"),
                "indices must be unsigned integers (UNSIGNED_BYTE, _SHORT or _INT)",
            ));
        }
        let component = data.component;
        self.read(&data, at, 0, |b| read_uint(b, component))
    }

    /// A triangle primitive's vertices and triangles, every index checked.
    fn geometry(&self, primitive: &json::mesh::Primitive, at: &str) -> Result<Geometry, GltfError> {
        let Checked::Valid(mode) = primitive.mode else {
            return Err(self.invalid(at, "mode is invalid"));
        };
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            return Err(self.invalid(
                at,
                format!(
                    "mode {} is not supported (only triangles, strips and fans)",
                    mode_name(mode)
                ),
            ));
        }
        let Some(position) = primitive
            .attributes
            .get(&Checked::Valid(Semantic::Positions))
        else {
            return Err(self.invalid(at, "has no POSITION attribute"));
        };
        let positions = self.read_vec3s(position.value(), &format!("{at}, POSITION"))?;
        let normals = match primitive.attributes.get(&Checked::Valid(Semantic::Normals)) {
            None => None,
            Some(normal) => {
                let normals = self.read_vec3s(normal.value(), &format!("{at}, NORMAL"))?;
                if normals.len() != positions.len() {
                    return Err(self.invalid(
                        format!("{at}, NORMAL"),
                        format!(
                            "has {} elements but POSITION has {}",
                            normals.len(),
                            positions.len()
                        ),
                    ));
                }
                Some(normals)
            }
        };
        // MAX_ELEMENTS keeps vertex numbers within u32.
        let corners = match primitive.indices {
            Some(indices) => self.read_indices(indices.value(), &format!("{at}, indices"))?,
            None => (0..positions.len() as u32).collect(),
        };
        if let Some((k, i)) = corners
            .iter()
            .enumerate()
            .find(|&(_, &i)| i as usize >= positions.len())
        {
            return Err(self.invalid(
                format!("{at}, indices"),
                format!(
                    "index {i} (entry {k}) is out of range for {} vertices",
                    positions.len()
                ),
            ));
        }
        if mode == Mode::Triangles && corners.len() % 3 != 0 {
            return Err(self.invalid(
                at,
                format!("{} indices do not make whole triangles", corners.len()),
            ));
        }
        Ok(Geometry {
            positions,
            normals,
            triangles: triangulate(mode, &corners),
        })
    }

    /// Everything the scene holds: materials, world-space meshes, portals and the camera.
    fn scene(&self, visits: &[Visit]) -> Result<SceneDesc, GltfError> {
        let mut materials = self
            .root
            .materials
            .iter()
            .enumerate()
            .map(|(i, m)| material_desc(self.file, i, m))
            .collect::<Result<Vec<_>, _>>()?;
        let mut default_material = None;
        let mut meshes = Vec::new();
        let mut portals = Vec::new();
        let mut camera = None;
        let mut budget = Budget::default();
        for visit in visits {
            let Some(node) = self.root.nodes.get(visit.node) else {
                return Err(self.invalid(format!("node {}", visit.node), "does not exist"));
            };
            let at = node_label(visit.node, node);
            let extras = node_extras(self.file, node, &at)?;
            if let Some(portal) = portal_extras(self.file, extras.as_ref(), &at)? {
                portals.push(self.portal(visit, node, &at, portal, &mut budget)?);
                continue;
            }
            if let Some(mesh_index) = node.mesh {
                let Some(mesh) = self.root.meshes.get(mesh_index.value()) else {
                    return Err(self.invalid(at, format!("mesh {} does not exist", mesh_index)));
                };
                let mesh_at = format!(
                    "{at}, {}",
                    label("mesh", mesh_index.value(), mesh.name.as_deref())
                );
                for (p, primitive) in mesh.primitives.iter().enumerate() {
                    let at = format!("{mesh_at}, primitive {p}");
                    let geometry = self.geometry(primitive, &at)?;
                    budget.spend(self.file, &at, &geometry)?;
                    let material = match primitive.material {
                        Some(m) if m.value() < materials.len() => m.value(),
                        Some(m) => {
                            return Err(self.invalid(at, format!("material {m} does not exist")));
                        }
                        None => *default_material.get_or_insert_with(|| {
                            materials.push(default_material_desc());
                            materials.len() - 1
                        }),
                    };
                    let name = node_name(visit.node, node);
                    let Some(mesh) = world_mesh(geometry, visit.world, name, material) else {
                        return Err(self.invalid(at, "a world-space position is not finite"));
                    };
                    meshes.push(mesh);
                }
            }
            if let (None, Some(c)) = (&camera, node.camera) {
                camera = self.camera(c.value(), visit.world, &at, extras.as_ref())?;
            }
        }
        Ok(SceneDesc {
            name: self
                .file
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default(),
            materials,
            meshes,
            portals,
            camera,
        })
    }

    fn portal(
        &self,
        visit: &Visit,
        node: &json::Node,
        at: &str,
        extras: PortalExtras,
        budget: &mut Budget,
    ) -> Result<PortalDesc, GltfError> {
        let Some(mesh_index) = node.mesh else {
            return Err(self.invalid(at, "is a portal (extras.portal_target) but has no mesh"));
        };
        let Some(mesh) = self.root.meshes.get(mesh_index.value()) else {
            return Err(self.invalid(at, format!("mesh {mesh_index} does not exist")));
        };
        let mut local_triangles = Vec::new();
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let at = format!(
                "{at}, {}, primitive {p}",
                label("mesh", mesh_index.value(), mesh.name.as_deref())
            );
            let geometry = self.geometry(primitive, &at)?;
            budget.spend(self.file, &at, &geometry)?;
            let corner = |i: u32| {
                geometry
                    .positions
                    .get(i as usize)
                    .copied()
                    .unwrap_or(Vec3::ZERO)
            };
            local_triangles.extend(geometry.triangles.iter().map(|t| t.map(corner)));
        }
        if local_triangles.is_empty() {
            return Err(self.invalid(at, "is a portal but its mesh has no triangles"));
        }
        Ok(PortalDesc {
            name: node_name(visit.node, node),
            target: extras.target,
            alpha: extras.alpha,
            local_triangles,
            world_from_local: visit.world,
            node_index: Some(visit.node),
        })
    }

    /// A perspective camera seen from its node; `None` for an orthographic one.
    fn camera(
        &self,
        index: usize,
        world: Mat4,
        node_at: &str,
        extras: Option<&Map<String, Value>>,
    ) -> Result<Option<CameraDesc>, GltfError> {
        let Some(camera) = self.root.cameras.get(index) else {
            return Err(self.invalid(node_at, format!("camera {index} does not exist")));
        };
        let at = format!(
            "{node_at}, {}",
            label("camera", index, camera.name.as_deref())
        );
        let (Checked::Valid(json::camera::Type::Perspective), Some(p)) =
            (camera.type_, &camera.perspective)
        else {
            return Ok(None);
        };
        if !(p.yfov.is_finite() && p.yfov > 0.0 && p.yfov < std::f32::consts::PI) {
            return Err(self.invalid(
                format!("{at}, perspective.yfov"),
                format!("must be in (0, π) radians, found {}", p.yfov),
            ));
        }
        let aspect = p.aspect_ratio.unwrap_or(DEFAULT_ASPECT);
        if !(aspect.is_finite() && aspect > 0.0) {
            return Err(self.invalid(
                format!("{at}, perspective.aspectRatio"),
                format!("must be positive, found {aspect}"),
            ));
        }
        let eye = world.w_axis.truncate();
        let forward = world.transform_vector3(Vec3::NEG_Z).normalize_or_zero();
        let up = world.transform_vector3(Vec3::Y).normalize_or_zero();
        if forward == Vec3::ZERO || up == Vec3::ZERO {
            return Err(self.invalid(at, "its node's transform is degenerate (zero scale)"));
        }
        let distance = extras
            .and_then(|e| e.get(CAMERA_TARGET_DISTANCE_KEY))
            .and_then(Value::as_f64)
            .map(|d| d as f32)
            .filter(|d| d.is_finite() && *d > 0.0)
            .unwrap_or(1.0);
        Ok(Some(CameraDesc {
            eye,
            target: eye + forward * distance,
            up,
            yfov: p.yfov,
            aspect,
        }))
    }
}

/// Counts vertices and triangles over the whole scene, so that instancing a mesh many times
/// cannot exhaust memory.
#[derive(Default)]
struct Budget {
    vertices: usize,
    triangles: usize,
}

impl Budget {
    fn spend(&mut self, file: &Path, at: &str, geometry: &Geometry) -> Result<(), GltfError> {
        self.vertices = self.vertices.saturating_add(geometry.positions.len());
        self.triangles = self.triangles.saturating_add(geometry.triangles.len());
        if self.vertices > MAX_ELEMENTS || self.triangles > MAX_ELEMENTS {
            return Err(invalid(
                file,
                at,
                format!(
                    "the scene exceeds {MAX_ELEMENTS} vertices or triangles ({} and {} so far)",
                    self.vertices, self.triangles
                ),
            ));
        }
        Ok(())
    }
}

fn is_unsigned(component: ComponentType) -> bool {
    matches!(
        component,
        ComponentType::U8 | ComponentType::U16 | ComponentType::U32
    )
}

/// Component `offset` bytes into `b` as a float, normalised integers mapped to [-1, 1].
fn read_float(b: &[u8], offset: usize, component: ComponentType, normalized: bool) -> f32 {
    let byte = |k: usize| b.get(offset + k).copied().unwrap_or(0);
    let (value, scale) = match component {
        ComponentType::F32 => return f32::from_le_bytes([byte(0), byte(1), byte(2), byte(3)]),
        ComponentType::I8 => (f32::from(byte(0) as i8), 127.0),
        ComponentType::U8 => (f32::from(byte(0)), 255.0),
        ComponentType::I16 => (f32::from(i16::from_le_bytes([byte(0), byte(1)])), 32767.0),
        ComponentType::U16 => (f32::from(u16::from_le_bytes([byte(0), byte(1)])), 65535.0),
        ComponentType::U32 => (
            u32::from_le_bytes([byte(0), byte(1), byte(2), byte(3)]) as f32,
            u32::MAX as f32,
        ),
    };
    if normalized {
        (value / scale).max(-1.0)
    } else {
        value
    }
}

/// An unsigned integer component (`u32::MAX` for other types, which callers reject first).
fn read_uint(b: &[u8], component: ComponentType) -> u32 {
    let byte = |k: usize| b.get(k).copied().unwrap_or(0);
    match component {
        ComponentType::U8 => u32::from(byte(0)),
        ComponentType::U16 => u32::from(u16::from_le_bytes([byte(0), byte(1)])),
        ComponentType::U32 => u32::from_le_bytes([byte(0), byte(1), byte(2), byte(3)]),
        _ => u32::MAX,
    }
}

fn type_name(ty: Type) -> &'static str {
    match ty {
        Type::Scalar => "SCALAR",
        Type::Vec2 => "VEC2",
        Type::Vec3 => "VEC3",
        Type::Vec4 => "VEC4",
        Type::Mat2 => "MAT2",
        Type::Mat3 => "MAT3",
        Type::Mat4 => "MAT4",
    }
}

fn mode_name(mode: Mode) -> &'static str {
    match mode {
        Mode::Points => "POINTS",
        Mode::Lines => "LINES",
        Mode::LineLoop => "LINE_LOOP",
        Mode::LineStrip => "LINE_STRIP",
        Mode::Triangles => "TRIANGLES",
        Mode::TriangleStrip => "TRIANGLE_STRIP",
        Mode::TriangleFan => "TRIANGLE_FAN",
    }
}

/// Triangles from a triangle list, strip or fan (strips alternate winding to keep it).
fn triangulate(mode: Mode, corners: &[u32]) -> Vec<[u32; 3]> {
    match mode {
        Mode::TriangleStrip => corners
            .windows(3)
            .enumerate()
            .map(|(i, w)| {
                if i % 2 == 0 {
                    [w[0], w[1], w[2]]
                } else {
                    [w[1], w[0], w[2]]
                }
            })
            .collect(),
        Mode::TriangleFan => match corners.split_first() {
            Some((&first, rest)) => rest.windows(2).map(|w| [first, w[0], w[1]]).collect(),
            None => Vec::new(),
        },
        _ => corners
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect(),
    }
}

/// The cofactor matrix of `m`, det(m) · m⁻ᵀ: it maps normals even when `m` is singular.
fn cofactor(m: Mat3) -> Mat3 {
    Mat3::from_cols(
        m.y_axis.cross(m.z_axis),
        m.z_axis.cross(m.x_axis),
        m.x_axis.cross(m.y_axis),
    )
}

/// A primitive moved to world space: positions by `world_from_local`, normals by its inverse
/// transpose, winding flipped when it mirrors. `None` if a position overflows.
fn world_mesh(
    geometry: Geometry,
    world_from_local: Mat4,
    node_name: String,
    material: usize,
) -> Option<MeshDesc> {
    let linear = Mat3::from_mat4(world_from_local);
    let mirrors = linear.determinant() < 0.0;
    let normal_from_local = if mirrors {
        -cofactor(linear)
    } else {
        cofactor(linear)
    };
    let positions: Vec<Vec3> = geometry
        .positions
        .iter()
        .map(|&p| world_from_local.transform_point3(p))
        .collect();
    if positions.iter().any(|p| !p.is_finite()) {
        return None;
    }
    let indices: Vec<[u32; 3]> = if mirrors {
        geometry
            .triangles
            .iter()
            .map(|&[a, b, c]| [a, c, b])
            .collect()
    } else {
        geometry.triangles
    };
    let mut normals: Vec<Vec3> = match geometry.normals {
        Some(normals) => normals
            .iter()
            .map(|&n| (normal_from_local * n).normalize_or_zero())
            .collect(),
        None => vec![Vec3::ZERO; positions.len()],
    };
    if normals.contains(&Vec3::ZERO) {
        let computed = vertex_normals(&positions, &indices);
        for (n, c) in normals.iter_mut().zip(computed) {
            if *n == Vec3::ZERO {
                *n = c;
            }
        }
    }
    Some(MeshDesc {
        node_name,
        material,
        positions,
        normals,
        indices,
    })
}

/// Area-weighted vertex normals from the faces (front by winding); +Z where undefined.
fn vertex_normals(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
    let mut sums = vec![Vec3::ZERO; positions.len()];
    let corner = |i: u32| positions.get(i as usize).copied().unwrap_or(Vec3::ZERO);
    for t in triangles {
        let [a, b, c] = t.map(corner);
        // Twice the triangle's area along its normal.
        let n = (b - a).cross(c - a);
        for &i in t {
            if let Some(sum) = sums.get_mut(i as usize) {
                *sum += n;
            }
        }
    }
    sums.into_iter().map(|s| s.normalize_or(Vec3::Z)).collect()
}

fn default_material_desc() -> MaterialDesc {
    MaterialDesc {
        double_sided: false,
        ..MaterialDesc::diffuse("default", Vec3::splat(0.8))
    }
}

fn material_desc(file: &Path, index: usize, m: &json::Material) -> Result<MaterialDesc, GltfError> {
    let at = label("material", index, m.name.as_deref());
    let pbr = &m.pbr_metallic_roughness;
    let [r, g, b, _] = pbr.base_color_factor.0;
    let base_color = Vec3::new(r, g, b);
    let metallic = pbr.metallic_factor.0;
    let roughness = pbr.roughness_factor.0;
    let emissive_factor = Vec3::from_array(m.emissive_factor.0);
    let emissive_strength = m
        .extensions
        .as_ref()
        .and_then(|e| e.emissive_strength.as_ref())
        .map_or(1.0, |s| s.emissive_strength.0);
    let fields = [
        (
            "pbrMetallicRoughness.baseColorFactor",
            base_color.is_finite(),
        ),
        ("pbrMetallicRoughness.metallicFactor", metallic.is_finite()),
        (
            "pbrMetallicRoughness.roughnessFactor",
            roughness.is_finite(),
        ),
        ("emissiveFactor", emissive_factor.is_finite()),
        (
            "extensions.KHR_materials_emissive_strength.emissiveStrength",
            emissive_strength.is_finite() && emissive_strength >= 0.0,
        ),
    ];
    if let Some((field, _)) = fields.iter().find(|(_, ok)| !ok) {
        return Err(invalid(
            file,
            format!("{at}, {field}"),
            "is not a finite (non-negative) number",
        ));
    }
    Ok(MaterialDesc {
        name: m
            .name
            .clone()
            .unwrap_or_else(|| format!("material {index}")),
        base_color,
        metallic,
        roughness,
        emissive_factor,
        emissive_strength,
        double_sided: m.double_sided,
    })
}

/// A node's `extras` if they are a JSON object.
fn node_extras(
    file: &Path,
    node: &json::Node,
    at: &str,
) -> Result<Option<Map<String, Value>>, GltfError> {
    let Some(raw) = &node.extras else {
        return Ok(None);
    };
    match serde_json::from_str::<Value>(raw.get()) {
        Ok(Value::Object(map)) => Ok(Some(map)),
        Ok(_) => Ok(None),
        Err(e) => Err(invalid(file, format!("{at}, extras"), e.to_string())),
    }
}

struct PortalExtras {
    target: String,
    alpha: f32,
}

/// The portal a node's extras describe, if they name a `portal_target`.
fn portal_extras(
    file: &Path,
    extras: Option<&Map<String, Value>>,
    at: &str,
) -> Result<Option<PortalExtras>, GltfError> {
    let Some(target) = extras.and_then(|e| e.get(PORTAL_TARGET_KEY)) else {
        return Ok(None);
    };
    let Some(target) = target.as_str().filter(|t| !t.is_empty()) else {
        return Err(invalid(
            file,
            format!("{at}, extras.{PORTAL_TARGET_KEY}"),
            format!("must be a non-empty string naming the light's node, found {target}"),
        ));
    };
    let alpha = match extras.and_then(|e| e.get(PORTAL_ALPHA_KEY)) {
        None => DEFAULT_PORTAL_ALPHA,
        Some(value) => match value.as_f64() {
            Some(a) if (0.0..=1.0).contains(&a) => a as f32,
            _ => {
                return Err(invalid(
                    file,
                    format!("{at}, extras.{PORTAL_ALPHA_KEY}"),
                    format!("must be a number in [0, 1], found {value}"),
                ));
            }
        },
    };
    Ok(Some(PortalExtras {
        target: target.to_owned(),
        alpha,
    }))
}

// ---------------------------------------------------------------------------------------------
// Writing.

/// A JSON number that prints as the shortest decimal reading back to the same `f32`.
fn json_f32(x: f32) -> Value {
    let shortest = x.to_string().parse::<f64>().unwrap_or(f64::from(x));
    serde_json::Number::from_f64(shortest).map_or(Value::Null, Value::Number)
}

fn json_matrix(m: Mat4) -> Value {
    Value::Array(m.to_cols_array().into_iter().map(json_f32).collect())
}

fn portal_extras_json(target: &str, alpha: f32) -> Map<String, Value> {
    let mut extras = Map::new();
    extras.insert(PORTAL_TARGET_KEY.to_owned(), Value::from(target));
    extras.insert(PORTAL_ALPHA_KEY.to_owned(), json_f32(alpha));
    extras
}

fn raw_json(file: &Path, value: &Map<String, Value>) -> Result<Box<RawValue>, GltfError> {
    serde_json::to_string(value)
        .and_then(RawValue::from_string)
        .map_err(|e| internal(file, e))
}

fn json_index<T>(file: &Path, i: usize) -> Result<json::Index<T>, GltfError> {
    u32::try_from(i)
        .map(json::Index::new)
        .map_err(|_| invalid(file, "document", format!("index {i} exceeds glTF's limits")))
}

/// Binary data and the buffer views, accessors and meshes describing it, to be appended after
/// a document's existing ones (`*_base` counts those).
struct GeometryWriter<'f> {
    file: &'f Path,
    bin: Vec<u8>,
    /// The index the buffer holding `bin` will have.
    buffer: usize,
    view_base: usize,
    views: Vec<json::buffer::View>,
    accessor_base: usize,
    accessors: Vec<json::Accessor>,
    mesh_base: usize,
    meshes: Vec<json::Mesh>,
}

impl<'f> GeometryWriter<'f> {
    fn after(file: &'f Path, root: &json::Root) -> Self {
        GeometryWriter {
            file,
            bin: Vec::new(),
            buffer: root.buffers.len(),
            view_base: root.buffer_views.len(),
            views: Vec::new(),
            accessor_base: root.accessors.len(),
            accessors: Vec::new(),
            mesh_base: root.meshes.len(),
            meshes: Vec::new(),
        }
    }

    fn view(
        &mut self,
        bytes: &[u8],
        target: json::buffer::Target,
    ) -> Result<json::Index<json::buffer::View>, GltfError> {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        let index = json_index(self.file, self.view_base + self.views.len())?;
        self.views.push(json::buffer::View {
            buffer: json_index(self.file, self.buffer)?,
            byte_length: USize64::from(bytes.len()),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: None,
            name: None,
            target: Some(Checked::Valid(target)),
            extensions: None,
            extras: None,
        });
        Ok(index)
    }

    fn accessor(
        &mut self,
        view: json::Index<json::buffer::View>,
        count: usize,
        component: ComponentType,
        ty: Type,
        min_max: Option<(Vec3, Vec3)>,
    ) -> Result<json::Index<json::Accessor>, GltfError> {
        let index = json_index(self.file, self.accessor_base + self.accessors.len())?;
        let as_json = |v: Vec3| Value::Array(v.to_array().into_iter().map(json_f32).collect());
        self.accessors.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64::from(count),
            component_type: Checked::Valid(GenericComponentType(component)),
            extensions: None,
            extras: None,
            type_: Checked::Valid(ty),
            min: min_max.map(|(lo, _)| as_json(lo)),
            max: min_max.map(|(_, hi)| as_json(hi)),
            name: None,
            normalized: false,
            sparse: None,
        });
        Ok(index)
    }

    fn vec3s(
        &mut self,
        values: &[Vec3],
        min_max: bool,
    ) -> Result<json::Index<json::Accessor>, GltfError> {
        let bytes: Vec<u8> = values
            .iter()
            .flat_map(|v| v.to_array())
            .flat_map(f32::to_le_bytes)
            .collect();
        let view = self.view(&bytes, json::buffer::Target::ArrayBuffer)?;
        let bounds = min_max.then(|| {
            values
                .iter()
                .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| {
                    (lo.min(p), hi.max(p))
                })
        });
        self.accessor(view, values.len(), ComponentType::F32, Type::Vec3, bounds)
    }

    fn indices(
        &mut self,
        triangles: &[[u32; 3]],
    ) -> Result<json::Index<json::Accessor>, GltfError> {
        let bytes: Vec<u8> = triangles
            .iter()
            .flatten()
            .flat_map(|i| i.to_le_bytes())
            .collect();
        let view = self.view(&bytes, json::buffer::Target::ElementArrayBuffer)?;
        self.accessor(
            view,
            triangles.len() * 3,
            ComponentType::U32,
            Type::Scalar,
            None,
        )
    }

    /// A one-primitive triangle mesh.
    fn mesh(
        &mut self,
        name: &str,
        positions: &[Vec3],
        normals: Option<&[Vec3]>,
        triangles: &[[u32; 3]],
        material: Option<usize>,
    ) -> Result<json::Index<json::Mesh>, GltfError> {
        let mut attributes = BTreeMap::new();
        attributes.insert(
            Checked::Valid(Semantic::Positions),
            self.vec3s(positions, true)?,
        );
        if let Some(normals) = normals {
            attributes.insert(
                Checked::Valid(Semantic::Normals),
                self.vec3s(normals, false)?,
            );
        }
        let indices = self.indices(triangles)?;
        let material = material.map(|m| json_index(self.file, m)).transpose()?;
        let index = json_index(self.file, self.mesh_base + self.meshes.len())?;
        self.meshes.push(json::Mesh {
            extensions: None,
            extras: None,
            name: Some(name.to_owned()),
            primitives: vec![json::mesh::Primitive {
                attributes,
                extensions: None,
                extras: None,
                indices: Some(indices),
                material,
                mode: Checked::Valid(Mode::Triangles),
                targets: None,
            }],
            weights: None,
        });
        Ok(index)
    }

    /// A portal's local triangles as an indexed mesh without material.
    fn portal_mesh(
        &mut self,
        name: &str,
        triangles: &[[Vec3; 3]],
    ) -> Result<json::Index<json::Mesh>, GltfError> {
        let positions: Vec<Vec3> = triangles.iter().flatten().copied().collect();
        let indices: Vec<[u32; 3]> = (0..triangles.len() as u32)
            .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
            .collect();
        self.mesh(name, &positions, None, &indices, None)
    }
}

/// Checks what `export_glb` and `save_portals` are given, so that they never write a file
/// `load_gltf` would reject.
fn check_mesh(file: &Path, k: usize, mesh: &MeshDesc, materials: usize) -> Result<(), GltfError> {
    let at = format!("mesh {k} (node \"{}\")", mesh.node_name);
    let problem = if mesh.positions.is_empty() || mesh.indices.is_empty() {
        Some("has no triangles".to_owned())
    } else if mesh.positions.len() > MAX_ELEMENTS || mesh.indices.len() > MAX_ELEMENTS {
        Some(format!("exceeds {MAX_ELEMENTS} vertices or triangles"))
    } else if mesh.positions.iter().any(|p| !p.is_finite()) {
        Some("has a position that is not finite".to_owned())
    } else if !(mesh.normals.is_empty() || mesh.normals.len() == mesh.positions.len()) {
        Some(format!(
            "has {} normals for {} positions",
            mesh.normals.len(),
            mesh.positions.len()
        ))
    } else if mesh.normals.iter().any(|n| !n.is_finite()) {
        Some("has a normal that is not finite".to_owned())
    } else if let Some(i) = mesh
        .indices
        .iter()
        .flatten()
        .find(|&&i| i as usize >= mesh.positions.len())
    {
        Some(format!(
            "index {i} is out of range for {} vertices",
            mesh.positions.len()
        ))
    } else if mesh.material >= materials {
        Some(format!("material {} does not exist", mesh.material))
    } else {
        None
    };
    match problem {
        Some(reason) => Err(invalid(file, at, reason)),
        None => Ok(()),
    }
}

fn check_portal(file: &Path, portal: &PortalDesc) -> Result<(), GltfError> {
    let at = format!("portal \"{}\"", portal.name);
    let problem = if portal.name.is_empty() {
        Some("has no name")
    } else if portal.target.is_empty() {
        Some("has no target")
    } else if !(0.0..=1.0).contains(&portal.alpha) {
        Some("alpha is not in [0, 1]")
    } else if portal.local_triangles.is_empty() {
        Some("has no triangles")
    } else if portal.local_triangles.len() > MAX_ELEMENTS {
        Some("has too many triangles")
    } else if portal
        .local_triangles
        .iter()
        .flatten()
        .any(|p| !p.is_finite())
    {
        Some("has a vertex that is not finite")
    } else if !portal.world_from_local.is_finite() {
        Some("world_from_local is not finite")
    } else {
        None
    };
    match problem {
        Some(reason) => Err(invalid(file, at, reason)),
        None => Ok(()),
    }
}

fn check_material(file: &Path, k: usize, m: &MaterialDesc) -> Result<(), GltfError> {
    let finite = m.base_color.is_finite()
        && m.metallic.is_finite()
        && m.roughness.is_finite()
        && m.emissive_factor.is_finite()
        && m.emissive_strength.is_finite();
    if !finite || m.emissive_factor.min_element() < 0.0 || m.emissive_strength < 0.0 {
        return Err(invalid(
            file,
            format!("material {k} \"{}\"", m.name),
            "has a factor that is negative or not finite",
        ));
    }
    Ok(())
}

fn export_material(m: &MaterialDesc) -> (json::Material, bool) {
    // glTF keeps emissiveFactor in [0, 1]: fold any excess into the strength (same radiance).
    let peak = m.emissive_factor.max_element();
    let (factor, strength) = if peak > 1.0 {
        (m.emissive_factor / peak, m.emissive_strength * peak)
    } else {
        (m.emissive_factor, m.emissive_strength)
    };
    let uses_strength = strength != 1.0;
    let extensions = uses_strength.then(|| json::extensions::material::Material {
        emissive_strength: Some(json::extensions::material::EmissiveStrength {
            emissive_strength: json::extensions::material::EmissiveStrengthFactor(strength),
        }),
        ..Default::default()
    });
    let material = json::Material {
        name: Some(m.name.clone()),
        pbr_metallic_roughness: json::material::PbrMetallicRoughness {
            base_color_factor: json::material::PbrBaseColorFactor(
                m.base_color.extend(1.0).to_array(),
            ),
            metallic_factor: json::material::StrengthFactor(m.metallic),
            roughness_factor: json::material::StrengthFactor(m.roughness),
            ..Default::default()
        },
        emissive_factor: json::material::EmissiveFactor(factor.to_array()),
        double_sided: m.double_sided,
        extensions,
        ..Default::default()
    };
    (material, uses_strength)
}

/// The camera node's world matrix (looking down its −Z, +Y up) and the target distance.
fn camera_transform(file: &Path, c: &CameraDesc) -> Result<(Mat4, f32), GltfError> {
    let to_target = c.target - c.eye;
    let forward = to_target.normalize_or_zero();
    let right = forward.cross(c.up).normalize_or_zero();
    if !c.eye.is_finite() || forward == Vec3::ZERO || right == Vec3::ZERO {
        return Err(invalid(
            file,
            "camera",
            "eye, target and up give no view direction (target at eye, or up along it)",
        ));
    }
    if !(c.yfov.is_finite() && c.yfov > 0.0 && c.yfov < std::f32::consts::PI) {
        return Err(invalid(file, "camera, yfov", "must be in (0, π) radians"));
    }
    if !(c.aspect.is_finite() && c.aspect > 0.0) {
        return Err(invalid(file, "camera, aspect", "must be positive"));
    }
    let up = right.cross(forward);
    let world_from_camera = Mat4::from_cols(
        right.extend(0.0),
        up.extend(0.0),
        (-forward).extend(0.0),
        c.eye.extend(1.0),
    );
    Ok((world_from_camera, to_target.length()))
}

/// `desc` as a glTF document and its binary buffer.
fn export_document(file: &Path, desc: &SceneDesc) -> Result<(json::Root, Vec<u8>), GltfError> {
    for (k, m) in desc.materials.iter().enumerate() {
        check_material(file, k, m)?;
    }
    for (k, mesh) in desc.meshes.iter().enumerate() {
        check_mesh(file, k, mesh, desc.materials.len())?;
    }
    for portal in &desc.portals {
        check_portal(file, portal)?;
    }
    let mut root = json::Root::default();
    root.asset.generator = Some("portalview".to_owned());
    let mut uses_strength = false;
    for m in &desc.materials {
        let (material, strength) = export_material(m);
        uses_strength |= strength;
        root.materials.push(material);
    }
    let mut geometry = GeometryWriter::after(file, &root);
    let mut nodes = Vec::new();
    for mesh in &desc.meshes {
        let normals = (!mesh.normals.is_empty()).then_some(mesh.normals.as_slice());
        let index = geometry.mesh(
            &mesh.node_name,
            &mesh.positions,
            normals,
            &mesh.indices,
            Some(mesh.material),
        )?;
        nodes.push(json::Node {
            name: Some(mesh.node_name.clone()),
            mesh: Some(index),
            ..Default::default()
        });
    }
    for portal in &desc.portals {
        let index = geometry.portal_mesh(&portal.name, &portal.local_triangles)?;
        let extras = portal_extras_json(&portal.target, portal.alpha);
        nodes.push(json::Node {
            name: Some(portal.name.clone()),
            mesh: Some(index),
            matrix: Some(portal.world_from_local.to_cols_array()),
            extras: Some(raw_json(file, &extras)?),
            ..Default::default()
        });
    }
    if let Some(camera) = &desc.camera {
        let (world_from_camera, distance) = camera_transform(file, camera)?;
        let camera_index = json_index(file, root.cameras.len())?;
        root.cameras.push(json::Camera {
            name: Some("camera".to_owned()),
            orthographic: None,
            perspective: Some(json::camera::Perspective {
                aspect_ratio: Some(camera.aspect),
                yfov: camera.yfov,
                zfar: None,
                znear: 0.01,
                extensions: None,
                extras: None,
            }),
            type_: Checked::Valid(json::camera::Type::Perspective),
            extensions: None,
            extras: None,
        });
        let mut extras = Map::new();
        extras.insert(CAMERA_TARGET_DISTANCE_KEY.to_owned(), json_f32(distance));
        nodes.push(json::Node {
            name: Some("camera".to_owned()),
            camera: Some(camera_index),
            matrix: Some(world_from_camera.to_cols_array()),
            extras: Some(raw_json(file, &extras)?),
            ..Default::default()
        });
    }
    root.scenes.push(json::Scene {
        extensions: None,
        extras: None,
        name: Some(desc.name.clone()),
        nodes: (0..nodes.len())
            .map(|i| json_index(file, i))
            .collect::<Result<_, _>>()?,
    });
    root.scene = Some(json_index(file, 0)?);
    root.nodes = nodes;
    let GeometryWriter {
        bin,
        views,
        accessors,
        meshes,
        ..
    } = geometry;
    if !bin.is_empty() {
        root.buffers.push(json::Buffer {
            byte_length: USize64::from(bin.len()),
            name: None,
            uri: None,
            extensions: None,
            extras: None,
        });
    }
    root.buffer_views = views;
    root.accessors = accessors;
    root.meshes = meshes;
    if uses_strength {
        root.extensions_used
            .push(EMISSIVE_STRENGTH_EXTENSION.to_owned());
    }
    Ok((root, bin))
}

fn glb_bytes(file: &Path, json: Vec<u8>, bin: Option<Vec<u8>>) -> Result<Vec<u8>, GltfError> {
    let total = 12 + 8 + json.len() + 3 + bin.as_ref().map_or(0, |b| 8 + b.len() + 3);
    if u32::try_from(total).is_err() {
        return Err(invalid(
            file,
            "GLB",
            "would exceed the format's 4 GiB limit",
        ));
    }
    let glb = gltf::binary::Glb {
        header: gltf::binary::Header {
            magic: *b"glTF",
            version: 2,
            length: 0, // `to_vec` computes it
        },
        json: Cow::Owned(json),
        bin: bin.map(Cow::Owned),
    };
    glb.to_vec().map_err(|e| internal(file, e))
}

/// Writes `bytes` beside `file`, then renames it over `file`: readers see the old file or the
/// new one, never half of one.
fn write_atomically(file: &Path, bytes: &[u8]) -> Result<(), GltfError> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let Some(name) = file.file_name() else {
        return Err(invalid(file, "path", "names no file"));
    };
    let dir = file
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let temporary = dir.join(format!(
        ".{}.{}-{}.tmp",
        name.to_string_lossy(),
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let written = fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&temporary)
        .and_then(|mut f| {
            f.write_all(bytes)?;
            if let Ok(old) = fs::metadata(file) {
                f.set_permissions(old.permissions())?;
            }
            f.sync_all()
        })
        .and_then(|()| fs::rename(&temporary, file));
    if let Err(source) = written {
        // Best effort: the write error is the one worth reporting.
        let _ = fs::remove_file(&temporary);
        return Err(GltfError::Write {
            file: file.to_owned(),
            source,
        });
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Saving edited portals.

fn save_portals_inner(file: &Path, portals: &[PortalDesc]) -> Result<(), GltfError> {
    let source = read_source(file)?;
    let root = parse_document(file, source.json())?;
    let buffers = load_buffers(file, &root, source.bin())?;
    let visits = walk_scene(file, &root)?;
    let doc = Doc {
        file,
        root: &root,
        buffers: &buffers,
    };
    let current = doc.scene(&visits)?;
    let in_file: HashMap<usize, &PortalDesc> = current
        .portals
        .iter()
        .filter_map(|p| Some((p.node_index?, p)))
        .collect();
    let parent_world: HashMap<usize, Mat4> =
        visits.iter().map(|v| (v.node, v.parent_world)).collect();

    let mut kept = HashSet::new();
    for portal in portals {
        check_portal(file, portal)?;
        if let Some(i) = portal.node_index {
            if !in_file.contains_key(&i) {
                return Err(invalid(
                    file,
                    format!("portal \"{}\"", portal.name),
                    format!("node {i} is not a portal node of the file's scene"),
                ));
            }
            if !kept.insert(i) {
                return Err(invalid(
                    file,
                    format!("portal \"{}\"", portal.name),
                    format!("node {i} is given to two portals"),
                ));
            }
        }
    }

    let mut json: Value =
        serde_json::from_slice(source.json()).map_err(|source| GltfError::Json {
            file: file.to_owned(),
            source,
        })?;
    let mut geometry = GeometryWriter::after(file, &root);
    let mut new_nodes = Vec::new();
    let mut edits = Vec::new();
    for portal in portals {
        match portal.node_index {
            Some(i) => {
                let old = in_file.get(&i).copied();
                let reshaped = old.is_none_or(|old| old.local_triangles != portal.local_triangles);
                let mesh = if reshaped {
                    Some(geometry.portal_mesh(&portal.name, &portal.local_triangles)?)
                } else {
                    None
                };
                let parent = parent_world.get(&i).copied().unwrap_or(Mat4::IDENTITY);
                let local = parent_from_world(file, parent, portal)? * portal.world_from_local;
                let rename = old.is_none_or(|old| old.name != portal.name);
                edits.push((i, portal, local, mesh, rename));
            }
            None => {
                let mesh = geometry.portal_mesh(&portal.name, &portal.local_triangles)?;
                let mut node = Map::new();
                node.insert("name".to_owned(), Value::from(portal.name.as_str()));
                node.insert("mesh".to_owned(), Value::from(mesh.value()));
                node.insert("matrix".to_owned(), json_matrix(portal.world_from_local));
                node.insert(
                    "extras".to_owned(),
                    Value::Object(portal_extras_json(&portal.target, portal.alpha)),
                );
                new_nodes.push(Value::Object(node));
            }
        }
    }

    let nodes = json_array(file, &mut json, "nodes")?;
    for (i, portal, local, mesh, rename) in edits {
        let Some(node) = nodes.get_mut(i).and_then(Value::as_object_mut) else {
            return Err(invalid(file, format!("node {i}"), "is not a JSON object"));
        };
        for key in ["translation", "rotation", "scale"] {
            node.remove(key);
        }
        node.insert("matrix".to_owned(), json_matrix(local));
        if let Some(mesh) = mesh {
            node.insert("mesh".to_owned(), Value::from(mesh.value()));
        }
        if rename {
            node.insert("name".to_owned(), Value::from(portal.name.as_str()));
        }
        let extras = node
            .entry("extras")
            .or_insert_with(|| Value::Object(Map::new()));
        if !extras.is_object() {
            *extras = Value::Object(Map::new());
        }
        if let Some(extras) = extras.as_object_mut() {
            extras.extend(portal_extras_json(&portal.target, portal.alpha));
        }
    }
    // Deleted portals: detach from every parent and scene; indices stay as they are.
    let deleted: HashSet<usize> = in_file
        .keys()
        .copied()
        .filter(|i| !kept.contains(i))
        .collect();
    for node in nodes.iter_mut().filter_map(Value::as_object_mut) {
        let emptied = match node.get_mut("children").and_then(Value::as_array_mut) {
            Some(children) => {
                children.retain(|c| !c.as_u64().is_some_and(|c| deleted.contains(&(c as usize))));
                children.is_empty()
            }
            None => false,
        };
        if emptied {
            node.remove("children");
        }
    }
    let first_new = nodes.len();
    let added = new_nodes.len();
    nodes.extend(new_nodes);
    if let Some(scenes) = json.get_mut("scenes").and_then(Value::as_array_mut) {
        let used = used_scene(&root);
        for (s, scene) in scenes.iter_mut().enumerate() {
            let Some(roots) = scene.get_mut("nodes").and_then(Value::as_array_mut) else {
                continue;
            };
            roots.retain(|c| !c.as_u64().is_some_and(|c| deleted.contains(&(c as usize))));
            if Some(s) == used {
                roots.extend((first_new..first_new + added).map(Value::from));
            }
        }
    }

    let GeometryWriter {
        bin,
        views,
        accessors,
        meshes,
        ..
    } = geometry;
    if !bin.is_empty() {
        let mut buffer = Map::new();
        buffer.insert("byteLength".to_owned(), Value::from(bin.len()));
        buffer.insert(
            "uri".to_owned(),
            Value::from(format!(
                "data:application/octet-stream;base64,{}",
                base64_encode(&bin)
            )),
        );
        json_array(file, &mut json, "buffers")?.push(Value::Object(buffer));
        for (key, values) in [
            ("bufferViews", to_values(file, &views)?),
            ("accessors", to_values(file, &accessors)?),
            ("meshes", to_values(file, &meshes)?),
        ] {
            json_array(file, &mut json, key)?.extend(values);
        }
    }

    let text = if source.is_glb {
        serde_json::to_vec(&json)
    } else {
        serde_json::to_vec_pretty(&json)
    }
    .map_err(|e| internal(file, e))?;
    // What is written must read back.
    parse_document(file, &text)?;
    let bytes = if source.is_glb {
        glb_bytes(file, text, source.bin().map(<[u8]>::to_vec))?
    } else {
        text
    };
    write_atomically(file, &bytes)
}

/// The inverse of a portal's parent's world transform.
fn parent_from_world(
    file: &Path,
    parent_world: Mat4,
    portal: &PortalDesc,
) -> Result<Mat4, GltfError> {
    let inverse = parent_world.inverse();
    if parent_world.determinant() == 0.0 || !inverse.is_finite() {
        return Err(invalid(
            file,
            format!("portal \"{}\"", portal.name),
            "its parent node's transform is singular, so it cannot be placed",
        ));
    }
    Ok(inverse)
}

/// The top-level array `key` of the document, created if absent.
fn json_array<'v>(
    file: &Path,
    json: &'v mut Value,
    key: &str,
) -> Result<&'v mut Vec<Value>, GltfError> {
    let Some(object) = json.as_object_mut() else {
        return Err(invalid(file, "document", "is not a JSON object"));
    };
    object
        .entry(key)
        .or_insert_with(|| Value::Array(Vec::new()))
        .as_array_mut()
        .ok_or_else(|| invalid(file, key, "is not an array"))
}

fn to_values<T: serde::Serialize>(file: &Path, items: &[T]) -> Result<Vec<Value>, GltfError> {
    items
        .iter()
        .map(|item| serde_json::to_value(item).map_err(|e| internal(file, e)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_round_trips_and_matches_known_vectors() {
        assert_eq!(base64_encode(b"Man"), "TWFu");
        assert_eq!(base64_encode(b"Ma"), "TWE=");
        assert_eq!(base64_encode(b"M"), "TQ==");
        assert_eq!(base64_encode(b""), "");
        for n in 0..40u8 {
            let data: Vec<u8> = (0..n).map(|i| i.wrapping_mul(37).wrapping_add(n)).collect();
            assert_eq!(base64_decode(&base64_encode(&data)), Some(data));
        }
        assert_eq!(base64_decode("TWE"), Some(b"Ma".to_vec()));
        assert_eq!(base64_decode("TW=E"), None);
        assert_eq!(base64_decode("T"), None);
        assert_eq!(base64_decode("TW*u"), None);
    }

    #[test]
    fn percent_decoding_and_schemes() {
        assert_eq!(
            percent_decode("my%20scene.bin").as_deref(),
            Some("my scene.bin")
        );
        assert_eq!(percent_decode("a%2"), None);
        assert_eq!(percent_decode("%FF"), None);
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
    }

    #[test]
    fn normals_use_the_inverse_transpose() {
        // Under a non-uniform scale, transforming the normal like a position would be wrong.
        let scale = Mat4::from_scale(Vec3::new(1.0, 4.0, 1.0));
        let geometry = Geometry {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Z],
            normals: Some(vec![Vec3::new(1.0, 1.0, 0.0).normalize(); 3]),
            triangles: vec![[0, 1, 2]],
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
        let desc = CameraDesc {
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
        let degenerate = CameraDesc {
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
            portal_extras(file, Some(&map), "node 3 \"P\"")
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
