//! Rewriting only the portal nodes of an existing `.gltf` or `.glb` after they were edited.

use super::*;

pub(super) fn save_portals_inner(file: &Path, portals: &[PortalDesc]) -> Result<(), GltfError> {
    let source = read_source(file)?;
    let root = parse_document(file, source.json())?;
    let buffers = load_buffers(file, &root, source.bin())?;
    let visits = walk_scene(file, &root)?;
    let doc = Doc {
        file,
        root: &root,
        buffers: &buffers,
    };
    // Saving portals reports nothing about the rest of the file: loading it did.
    let current = doc.scene(&visits, &mut Vec::new())?;
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
                    Value::Object(portal_extras_json(portal)),
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
            extras.extend(portal_extras_json(portal));
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
    rewrite_document(file, &source, &json)
}

/// Writes the edited document `json` over `file`, keeping a GLB's binary chunk as it was.
pub(super) fn rewrite_document(
    file: &Path,
    source: &Source,
    json: &Value,
) -> Result<(), GltfError> {
    let text = if source.is_glb {
        serde_json::to_vec(json)
    } else {
        serde_json::to_vec_pretty(json)
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
pub(super) fn parent_from_world(
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
pub(super) fn json_array<'v>(
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

pub(super) fn to_values<T: serde::Serialize>(
    file: &Path,
    items: &[T],
) -> Result<Vec<Value>, GltfError> {
    items
        .iter()
        .map(|item| serde_json::to_value(item).map_err(|e| internal(file, e)))
        .collect()
}
