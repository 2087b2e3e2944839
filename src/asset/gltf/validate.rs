//! Checks before use: the JSON against the glTF schema and the extensions we read or may
//! ignore; the element budget of a file; a scene description before it is written.

use super::*;

/// Parses and validates the JSON document.
pub(super) fn parse_document(file: &Path, json_bytes: &[u8]) -> Result<json::Root, GltfError> {
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

/// The extensions that are read: emissive strength, the specular layer's factors, IOR,
/// transmission, volume and clear coat change the materials, quantized attributes are read as
/// normalised integers.
pub(super) const READ_EXTENSIONS: [&str; 9] = [
    EMISSIVE_STRENGTH_EXTENSION,
    SPECULAR_EXTENSION,
    IOR_EXTENSION,
    TRANSMISSION_EXTENSION,
    VOLUME_EXTENSION,
    CLEARCOAT_EXTENSION,
    "KHR_mesh_quantization",
    "KHR_lights_punctual",
    TEXTURE_TRANSFORM_EXTENSION,
];

/// Whether a file that requires `extension` still loads correctly here: it is read, or it only
/// changes textures, material details or lights that are not read (so the file still loads,
/// with a warning from [`unread_extensions`]).
pub(super) fn can_ignore_or_read(extension: &str) -> bool {
    READ_EXTENSIONS.contains(&extension)
        || extension.starts_with("KHR_materials_")
        || matches!(
            extension,
            "KHR_texture_transform"
                | "KHR_texture_basisu"
                | "EXT_texture_webp"
                | "EXT_texture_avif"
                | "MSFT_texture_dds"
                | "KHR_lights_punctual"
        )
}

/// One warning naming the file's `extensionsUsed` that are not read (their effect is ignored),
/// if any: unread extensions are never silent.
pub(super) fn unread_extensions(file: &Path, root: &json::Root) -> Vec<String> {
    let unread: Vec<&str> = root
        .extensions_used
        .iter()
        .map(String::as_str)
        .filter(|e| !READ_EXTENSIONS.contains(e))
        .collect();
    if unread.is_empty() {
        return Vec::new();
    }
    vec![format!(
        "{}: extensionsUsed: {} not read; the file renders as if {} absent",
        file.display(),
        unread.join(", "),
        if unread.len() == 1 {
            "it were"
        } else {
            "they were"
        }
    )]
}

/// Counts vertices and triangles over the whole scene, so that instancing a mesh many times
/// cannot exhaust memory.
#[derive(Default)]
pub(super) struct Budget {
    pub(super) vertices: usize,
    pub(super) triangles: usize,
}

impl Budget {
    pub(super) fn spend(
        &mut self,
        file: &Path,
        at: &str,
        geometry: &Geometry,
    ) -> Result<(), GltfError> {
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

/// Checks what `export_glb` and `save_portals` are given, so that they never write a file
/// `load_gltf` would reject.
pub(super) fn check_mesh(
    file: &Path,
    k: usize,
    mesh: &MeshDesc,
    materials: &[MaterialDesc],
) -> Result<(), GltfError> {
    let at = format!("mesh {k} (node \"{}\")", mesh.node_name);
    let vertices = mesh.positions.len();
    let texture_sets = materials.get(mesh.material).map_or(Vec::new(), |m| {
        m.textures.refs().map(|t| t.tex_coord as usize).collect()
    });
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
    } else if mesh.material >= materials.len() {
        Some(format!("material {} does not exist", mesh.material))
    } else if let Some(set) = (0..2).find(|&set| {
        let n = mesh.texcoords[set].len();
        !(n == 0 || n == vertices) || mesh.texcoords[set].iter().any(|v| !v.is_finite())
    }) {
        Some(format!(
            "has {} TEXCOORD_{set} values for {vertices} positions, or one not finite",
            mesh.texcoords[set].len()
        ))
    } else if !(mesh.tangents.is_empty() || mesh.tangents.len() == vertices)
        || mesh.tangents.iter().any(|t| !t.is_finite())
    {
        Some(format!(
            "has {} tangents for {vertices} positions, or one not finite",
            mesh.tangents.len()
        ))
    } else {
        texture_sets
            .iter()
            .find(|&&set| mesh.texcoords.get(set).is_none_or(Vec::is_empty))
            .map(|set| format!("its material has a texture on TEXCOORD_{set}, which it lacks"))
    };
    match problem {
        Some(reason) => Err(invalid(file, at, reason)),
        None => Ok(()),
    }
}

pub(super) fn check_portal(file: &Path, portal: &PortalDesc) -> Result<(), GltfError> {
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

pub(super) fn check_material(
    file: &Path,
    k: usize,
    m: &MaterialDesc,
    images: usize,
) -> Result<(), GltfError> {
    let at = format!("material {k} \"{}\"", m.name);
    if let Some(t) = m
        .textures
        .refs()
        .find(|t| t.image >= images || t.tex_coord > 1)
    {
        return Err(invalid(
            file,
            at,
            format!(
                "a texture names image {} (of {images}) on TEXCOORD_{}",
                t.image, t.tex_coord
            ),
        ));
    }
    if !m.alpha.is_finite()
        || matches!(m.alpha_mode, AlphaMode::Mask { cutoff } if !(cutoff.is_finite() && cutoff >= 0.0))
    {
        return Err(invalid(
            file,
            at,
            "has an alpha or alpha cutoff that is not finite",
        ));
    }
    let finite = m.base_color.is_finite()
        && m.metallic.is_finite()
        && m.roughness.is_finite()
        && m.emissive_factor.is_finite()
        && m.emissive_strength.is_finite()
        && m.specular_factor.is_finite()
        && m.specular_color.is_finite()
        && m.ior.is_finite()
        && m.clearcoat.is_finite()
        && m.clearcoat_roughness.is_finite();
    let negative = m.emissive_factor.min_element() < 0.0
        || m.emissive_strength < 0.0
        || m.specular_color.min_element() < 0.0;
    if !finite || negative {
        return Err(invalid(
            file,
            at,
            "has a factor that is negative or not finite",
        ));
    }
    if !(0.0..=1.0).contains(&m.specular_factor) {
        return Err(invalid(file, at, "specular factor is not in [0, 1]"));
    }
    if !(m.ior == 0.0 || m.ior >= 1.0) {
        return Err(invalid(file, at, "ior is neither 0 nor at least 1"));
    }
    if !(0.0..=1.0).contains(&m.clearcoat) || !(0.0..=1.0).contains(&m.clearcoat_roughness) {
        return Err(invalid(
            file,
            at,
            "clear coat or its roughness is not in [0, 1]",
        ));
    }
    Ok(())
}
