//! Reading a document into a scene description: buffers, the node hierarchy, meshes in world
//! space, materials, portals (from node `extras`) and the camera.

use super::*;

/// The bytes of every buffer, each at least as long as its `byteLength`.
pub(super) fn load_buffers<'b>(
    file: &Path,
    root: &json::Root,
    bin: Option<&'b [u8]>,
) -> Result<Vec<Cow<'b, [u8]>>, GltfError> {
    let base = file.parent().unwrap_or(Path::new(""));
    let mut buffers = Vec::with_capacity(root.buffers.len());
    for (i, buffer) in root.buffers.iter().enumerate() {
        let at = label("buffer", i, buffer.name.as_deref());
        let declared = buffer.byte_length.0;
        let data = match (buffer.uri.as_deref(), bin) {
            (Some(uri), _) => Cow::Owned(read_uri(file, base, &at, uri, declared)?),
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

pub(super) fn label(kind: &str, index: usize, name: Option<&str>) -> String {
    match name {
        Some(name) => format!("{kind} {index} \"{name}\""),
        None => format!("{kind} {index}"),
    }
}

pub(super) fn node_label(index: usize, node: &json::Node) -> String {
    label("node", index, node.name.as_deref())
}

/// The name a node goes by in a `SceneDesc`.
pub(super) fn node_name(index: usize, node: &json::Node) -> String {
    node.name.clone().unwrap_or_else(|| format!("node {index}"))
}

/// One node reached from the scene's roots, in depth-first order.
pub(super) struct Visit {
    pub(super) node: usize,
    pub(super) world: Mat4,
    pub(super) parent_world: Mat4,
}

/// The scene that is loaded: the default one, else the first.
pub(super) fn used_scene(root: &json::Root) -> Option<usize> {
    match root.scene {
        Some(s) => Some(s.value()),
        None => (!root.scenes.is_empty()).then_some(0),
    }
}

/// The scene's root nodes; without scenes, every node that is nobody's child.
pub(super) fn scene_roots(root: &json::Root) -> Vec<usize> {
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
pub(super) fn walk_scene(file: &Path, root: &json::Root) -> Result<Vec<Visit>, GltfError> {
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

pub(super) fn local_matrix(file: &Path, node: &json::Node, at: &str) -> Result<Mat4, GltfError> {
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
pub(super) struct Geometry {
    pub(super) positions: Vec<Vec3>,
    pub(super) normals: Option<Vec<Vec3>>,
    pub(super) triangles: Vec<[u32; 3]>,
    /// `TEXCOORD_0` and `TEXCOORD_1`, when present.
    pub(super) texcoords: [Option<Vec<Vec2>>; 2],
    /// `TANGENT` (xyz and the bitangent sign w), when present.
    pub(super) tangents: Option<Vec<Vec4>>,
}

/// A parsed document with its buffers, and the file to name in errors.
pub(super) struct Doc<'a> {
    pub(super) file: &'a Path,
    pub(super) root: &'a json::Root,
    pub(super) buffers: &'a [Cow<'a, [u8]>],
}

impl<'a> Doc<'a> {
    /// A triangle primitive's vertices and triangles, every index checked.
    pub(super) fn geometry(
        &self,
        primitive: &json::mesh::Primitive,
        at: &str,
    ) -> Result<Geometry, GltfError> {
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
        let attribute_at = |name: &str| format!("{at}, {name}");
        let same_count = |n: usize, name: &str| {
            if n == positions.len() {
                Ok(())
            } else {
                Err(self.invalid(
                    attribute_at(name),
                    format!("has {n} elements but POSITION has {}", positions.len()),
                ))
            }
        };
        let mut texcoords = [None, None];
        for (set, slot) in texcoords.iter_mut().enumerate() {
            let semantic = Checked::Valid(Semantic::TexCoords(set as u32));
            if let Some(accessor) = primitive.attributes.get(&semantic) {
                let name = format!("TEXCOORD_{set}");
                let uvs = self.read_floats::<2>(accessor.value(), &attribute_at(&name))?;
                same_count(uvs.len(), &name)?;
                *slot = Some(uvs.into_iter().map(Vec2::from_array).collect());
            }
        }
        let tangents = match primitive
            .attributes
            .get(&Checked::Valid(Semantic::Tangents))
        {
            None => None,
            Some(accessor) => {
                let tangents = self.read_floats::<4>(accessor.value(), &attribute_at("TANGENT"))?;
                same_count(tangents.len(), "TANGENT")?;
                Some(tangents.into_iter().map(Vec4::from_array).collect())
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
            texcoords,
            tangents,
        })
    }

    /// Everything the scene holds: materials, world-space meshes, portals and the camera.
    /// What it uses but is not read is added to `warnings`.
    pub(super) fn scene(
        &self,
        visits: &[Visit],
        warnings: &mut Vec<String>,
    ) -> Result<SceneDesc, GltfError> {
        let mut images = Images::default();
        let mut materials = self
            .root
            .materials
            .iter()
            .enumerate()
            .map(|(i, m)| material_desc(self, i, m, &mut images, warnings))
            .collect::<Result<Vec<_>, _>>()?;
        let mut default_material = None;
        let mut meshes = Vec::new();
        let mut portals = Vec::new();
        let mut lamps = Vec::new();
        let mut camera = None;
        let mut budget = Budget::default();
        let mut warned_colors = false;
        let default_alpha = scene_portal_alpha(self.file, self.root)?;
        for visit in visits {
            let Some(node) = self.root.nodes.get(visit.node) else {
                return Err(self.invalid(format!("node {}", visit.node), "does not exist"));
            };
            let at = node_label(visit.node, node);
            let extras = node_extras(self.file, node, &at)?;
            if let Some(lamp) = node_lamp(self.file, self.root, visit.node, node, visit.world, &at)?
            {
                lamps.push(lamp);
            }
            if let Some(portal) = portal_extras(self.file, extras.as_ref(), &at, default_alpha)? {
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
                    let colors = Checked::Valid(Semantic::Colors(0));
                    if primitive.attributes.contains_key(&colors) && !warned_colors {
                        warned_colors = true;
                        warnings.push(format!(
                            "{}: {at}: vertex colours (COLOR_0) not read; the material's base \
                             colour is used alone",
                            self.file.display()
                        ));
                    }
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
                    if let Some(m) = materials.get(material) {
                        for texture in m.textures.refs() {
                            let set = texture.tex_coord as usize;
                            if geometry.texcoords.get(set).is_none_or(Option::is_none) {
                                return Err(self.invalid(
                                    at,
                                    format!(
                                        "material \"{}\" has a texture on TEXCOORD_{set}, \
                                         which the primitive does not have",
                                        m.name
                                    ),
                                ));
                            }
                        }
                    }
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
            lamps,
            camera,
            images: images.decoded,
            environment: None,
            warnings: Vec::new(),
        })
    }

    pub(super) fn portal(
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
            auto_alpha: extras.auto_alpha,
            local_triangles,
            world_from_local: visit.world,
            node_index: Some(visit.node),
        })
    }

    /// A perspective camera seen from its node; `None` for an orthographic one.
    pub(super) fn camera(
        &self,
        index: usize,
        world: Mat4,
        node_at: &str,
        extras: Option<&Map<String, Value>>,
    ) -> Result<Option<Camera>, GltfError> {
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
        Ok(Some(Camera {
            eye,
            target: eye + forward * distance,
            up,
            yfov: p.yfov,
            aspect,
        }))
    }
}

/// Triangles from a triangle list, strip or fan (strips alternate winding to keep it).
pub(super) fn triangulate(mode: Mode, corners: &[u32]) -> Vec<[u32; 3]> {
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
pub(super) fn cofactor(m: Mat3) -> Mat3 {
    Mat3::from_cols(
        m.y_axis.cross(m.z_axis),
        m.z_axis.cross(m.x_axis),
        m.x_axis.cross(m.y_axis),
    )
}

/// A primitive moved to world space: positions by `world_from_local`, normals by its inverse
/// transpose, winding flipped when it mirrors. `None` if a position overflows.
pub(super) fn world_mesh(
    geometry: Geometry,
    world_from_local: Mat4,
    node_name: String,
    material: usize,
) -> Option<MeshDesc> {
    let geometry = if geometry.normals.is_none() {
        flat(geometry)
    } else {
        geometry
    };
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
    // A tangent is a direction on the surface: it moves like a position's difference. The
    // bitangent `w·(N × T)` must move the same way; with the normal moved by the (mirror-
    // corrected) inverse transpose, that holds when a mirror flips the sign w.
    let handedness = if mirrors { -1.0 } else { 1.0 };
    let tangents = geometry.tangents.map_or_else(Vec::new, |tangents| {
        tangents
            .iter()
            .map(|t| {
                let sign = if t.w < 0.0 { -1.0 } else { 1.0 };
                (linear * t.truncate())
                    .normalize_or_zero()
                    .extend(sign * handedness)
            })
            .collect()
    });
    let [uv0, uv1] = geometry.texcoords;
    Some(MeshDesc {
        node_name,
        material,
        positions,
        normals,
        indices,
        texcoords: [uv0.unwrap_or_default(), uv1.unwrap_or_default()],
        tangents,
    })
}

/// Without `NORMAL`, glTF (3.7.2.1) asks for flat normals, and for `TANGENT` to be ignored:
/// every triangle gets corners of its own, with its face's normal (front by winding; zero
/// for a degenerate face, which [`world_mesh`] then fills in).
fn flat(geometry: Geometry) -> Geometry {
    let Geometry {
        positions,
        triangles,
        texcoords,
        ..
    } = geometry;
    let corner = |i: u32| positions.get(i as usize).copied().unwrap_or(Vec3::ZERO);
    let mut flat_positions = Vec::with_capacity(3 * triangles.len());
    let mut normals = Vec::with_capacity(3 * triangles.len());
    for t in &triangles {
        let [a, b, c] = t.map(corner);
        let n = (b - a).cross(c - a).normalize_or_zero();
        flat_positions.extend([a, b, c]);
        normals.extend([n; 3]);
    }
    let texcoords = texcoords.map(|uvs| {
        uvs.map(|uvs| {
            let uv = |i: u32| uvs.get(i as usize).copied().unwrap_or(Vec2::ZERO);
            triangles.iter().flat_map(|t| t.map(uv)).collect()
        })
    });
    Geometry {
        positions: flat_positions,
        normals: Some(normals),
        triangles: (0..triangles.len() as u32)
            .map(|k| [3 * k, 3 * k + 1, 3 * k + 2])
            .collect(),
        texcoords,
        tangents: None,
    }
}

/// Area-weighted vertex normals from the faces (front by winding); +Z where undefined.
pub(super) fn vertex_normals(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
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

pub(super) fn default_material_desc() -> MaterialDesc {
    MaterialDesc {
        double_sided: false,
        ..MaterialDesc::diffuse("default", Vec3::splat(0.8))
    }
}

/// The glTF material `m` (index `index`) as a description, its textures' images decoded into
/// `images`; what it uses but is not read (its occlusion texture) is added to `warnings`.
pub(super) fn material_desc(
    doc: &Doc,
    index: usize,
    m: &json::Material,
    images: &mut Images,
    warnings: &mut Vec<String>,
) -> Result<MaterialDesc, GltfError> {
    let file = doc.file;
    let at = label("material", index, m.name.as_deref());
    let pbr = &m.pbr_metallic_roughness;
    let [r, g, b, alpha] = pbr.base_color_factor.0;
    let base_color = Vec3::new(r, g, b);
    let metallic = pbr.metallic_factor.0;
    let roughness = pbr.roughness_factor.0;
    let emissive_factor = Vec3::from_array(m.emissive_factor.0);
    let extensions = m.extensions.as_ref();
    let emissive_strength = extensions
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
        ("pbrMetallicRoughness.baseColorFactor", alpha.is_finite()),
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
    let others = extensions.map(|e| &e.others);
    let extension = |name: &str| -> Result<Option<&Map<String, Value>>, GltfError> {
        match others.and_then(|o| o.get(name)) {
            None => Ok(None),
            Some(Value::Object(object)) => Ok(Some(object)),
            Some(other) => Err(invalid(
                file,
                format!("{at}, extensions.{name}"),
                format!("must be an object, found {other}"),
            )),
        }
    };
    let mut textures = core_textures(doc, m, &at, images, warnings)?;
    let alpha_mode = match m.alpha_mode {
        Checked::Valid(json::material::AlphaMode::Opaque) => AlphaMode::Opaque,
        Checked::Valid(json::material::AlphaMode::Mask) => {
            let cutoff = m.alpha_cutoff.map_or(0.5, |c| c.0);
            if !cutoff.is_finite() || cutoff < 0.0 {
                return Err(invalid(
                    file,
                    format!("{at}, alphaCutoff"),
                    format!("must be a non-negative number, found {cutoff}"),
                ));
            }
            AlphaMode::Mask { cutoff }
        }
        Checked::Valid(json::material::AlphaMode::Blend) => {
            warnings.push(format!(
                "{}: {at}: alphaMode BLEND is rendered as stochastic coverage (a ray passes \
                 with probability 1 − alpha): no refraction, no tint",
                file.display()
            ));
            AlphaMode::Blend
        }
        Checked::Invalid => {
            return Err(invalid(
                file,
                format!("{at}, alphaMode"),
                "is not a glTF alpha mode",
            ));
        }
    };
    let mut specular_factor = DEFAULT_SPECULAR_FACTOR;
    let mut specular_color = DEFAULT_SPECULAR_COLOR;
    if let Some(specular) = extension(SPECULAR_EXTENSION)? {
        let field = |key: &str| format!("{at}, extensions.{SPECULAR_EXTENSION}.{key}");
        if let Some(value) = specular.get("specularFactor") {
            specular_factor = unit_number(file, &field("specularFactor"), value)?;
        }
        if let Some(value) = specular.get("specularColorFactor") {
            let at = field("specularColorFactor");
            specular_color = vec3(file, &at, value)?;
            if specular_color.min_element() < 0.0 {
                return Err(invalid(
                    file,
                    at,
                    format!("must not be negative, found {value}"),
                ));
            }
        }
        if let Some(info) = specular.get("specularTexture") {
            textures.specular = Some(doc.texture_ref(info, &field("specularTexture"), images)?);
        }
        if let Some(info) = specular.get("specularColorTexture") {
            let at = field("specularColorTexture");
            textures.specular_color = Some(doc.texture_ref(info, &at, images)?);
        }
    }
    let mut ior = DEFAULT_IOR;
    if let Some(value) = extension(IOR_EXTENSION)?.and_then(|e| e.get("ior")) {
        let at = format!("{at}, extensions.{IOR_EXTENSION}.ior");
        ior = number(file, &at, value)?;
        if !(ior == 0.0 || ior >= 1.0) {
            return Err(invalid(
                file,
                at,
                format!("must be 0 (infinite) or at least 1, found {value}"),
            ));
        }
    }
    let mut transmission = 0.0;
    if let Some(extension) = extension(TRANSMISSION_EXTENSION)? {
        let field = |key: &str| format!("{at}, extensions.{TRANSMISSION_EXTENSION}.{key}");
        if let Some(value) = extension.get("transmissionFactor") {
            transmission = unit_number(file, &field("transmissionFactor"), value)?;
        }
        if let Some(info) = extension.get("transmissionTexture") {
            let at = field("transmissionTexture");
            textures.transmission = Some(doc.texture_ref(info, &at, images)?);
        }
    }
    let mut volume = None;
    if let Some(extension) = extension(VOLUME_EXTENSION)? {
        let field = |key: &str| format!("{at}, extensions.{VOLUME_EXTENSION}.{key}");
        let thickness = match extension.get("thicknessFactor") {
            Some(value) => number(file, &field("thicknessFactor"), value)?,
            None => 0.0,
        };
        if thickness < 0.0 {
            return Err(invalid(
                file,
                field("thicknessFactor"),
                "must not be negative",
            ));
        }
        let attenuation_color = match extension.get("attenuationColor") {
            Some(value) => {
                let c = vec3(file, &field("attenuationColor"), value)?;
                if !(c.min_element() >= 0.0 && c.max_element() <= 1.0) {
                    return Err(invalid(
                        file,
                        field("attenuationColor"),
                        format!("must be in [0, 1], found {value}"),
                    ));
                }
                c
            }
            None => Vec3::ONE,
        };
        let attenuation_distance = match extension.get("attenuationDistance") {
            Some(value) => {
                let d = number(file, &field("attenuationDistance"), value)?;
                if d <= 0.0 {
                    return Err(invalid(
                        file,
                        field("attenuationDistance"),
                        format!("must be positive, found {value}"),
                    ));
                }
                d
            }
            None => f32::INFINITY,
        };
        // The spec: thickness 0 is thin-walled. A path tracer meets the mesh's own thickness,
        // so the factor (and its texture) only says that the volume is there.
        if thickness > 0.0 && transmission > 0.0 {
            volume = Some(VolumeDesc {
                thickness,
                attenuation_color,
                attenuation_distance,
            });
            if ior == 0.0 {
                warnings.push(format!(
                    "{}: {at}: a volume of infinite IOR (ior 0) reflects everything: it is \
                     rendered as thin-walled glass",
                    file.display()
                ));
                volume = None;
            }
        }
    }
    let (mut clearcoat, mut clearcoat_roughness) = (0.0, 0.0);
    if let Some(extension) = extension(CLEARCOAT_EXTENSION)? {
        let field = |key: &str| format!("{at}, extensions.{CLEARCOAT_EXTENSION}.{key}");
        let unit = |key: &str| match extension.get(key) {
            Some(value) => unit_number(file, &field(key), value),
            None => Ok(0.0),
        };
        clearcoat = unit("clearcoatFactor")?;
        clearcoat_roughness = unit("clearcoatRoughnessFactor")?;
        if let Some(info) = extension.get("clearcoatTexture") {
            let at = field("clearcoatTexture");
            textures.clearcoat = Some(doc.texture_ref(info, &at, images)?);
        }
        if let Some(info) = extension.get("clearcoatRoughnessTexture") {
            let at = field("clearcoatRoughnessTexture");
            textures.clearcoat_roughness = Some(doc.texture_ref(info, &at, images)?);
        }
        let coated = clearcoat > 0.0;
        if coated && extension.contains_key("clearcoatNormalTexture") {
            warnings.push(format!(
                "{}: {at}: extensions.{CLEARCOAT_EXTENSION}.clearcoatNormalTexture is not read:                  the coat takes the surface's shading normal",
                file.display()
            ));
        } else if coated && textures.normal.is_some() {
            warnings.push(format!(
                "{}: {at}: the clear coat follows the normal map (Cycles' coat takes the                  unmapped normal unless its Clearcoat Normal is linked)",
                file.display()
            ));
        }
        if coated && volume.is_some() {
            warnings.push(format!(
                "{}: {at}: a clear coat over a refracting volume (KHR_materials_volume) is                  not rendered",
                file.display()
            ));
            clearcoat = 0.0;
            textures.clearcoat = None;
            textures.clearcoat_roughness = None;
        }
    }
    let emits = (emissive_factor * emissive_strength).max_element() > 0.0;
    if transmission > 0.0 && emits {
        warnings.push(format!(
            "{}: {at}: emits and transmits: a light's surface is rendered opaque, so its \
             transmission is not rendered",
            file.display()
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
        specular_factor,
        specular_color,
        ior,
        transmission,
        volume,
        clearcoat,
        clearcoat_roughness,
        double_sided: m.double_sided,
        alpha,
        alpha_mode,
        textures,
    })
}

/// The core glTF textures of material `m` (the specular layer's are read with its extension).
fn core_textures(
    doc: &Doc,
    m: &json::Material,
    at: &str,
    images: &mut Images,
    warnings: &mut Vec<String>,
) -> Result<MaterialTextures, GltfError> {
    // Every textureInfo is read as JSON, so that core and extension textures share one reader
    // (with `KHR_texture_transform`, which the json crate keeps as an unknown extension).
    let json = serde_json::to_value(m).map_err(|e| internal(doc.file, e))?;
    let info = |path: &[&str]| {
        path.iter()
            .try_fold(&json, |v, key| v.get(key))
            .filter(|v| !v.is_null())
    };
    let mut read = |path: &[&str]| -> Result<Option<TextureRef>, GltfError> {
        match info(path) {
            None => Ok(None),
            Some(v) => doc
                .texture_ref(v, &format!("{at}, {}", path.join(".")), images)
                .map(Some),
        }
    };
    let base_color = read(&["pbrMetallicRoughness", "baseColorTexture"])?;
    let metallic_roughness = read(&["pbrMetallicRoughness", "metallicRoughnessTexture"])?;
    let emissive = read(&["emissiveTexture"])?;
    let normal = match read(&["normalTexture"])? {
        None => None,
        Some(texture) => {
            let scale = m.normal_texture.as_ref().map_or(1.0, |n| n.scale);
            if !scale.is_finite() {
                return Err(invalid(
                    doc.file,
                    format!("{at}, normalTexture.scale"),
                    "is not a finite number",
                ));
            }
            Some(NormalTexture { texture, scale })
        }
    };
    if m.occlusion_texture.is_some() {
        warnings.push(format!(
            "{}: {at}: occlusionTexture not read (the path tracer computes occlusion itself)",
            doc.file.display()
        ));
    }
    Ok(MaterialTextures {
        base_color,
        metallic_roughness,
        normal,
        emissive,
        specular: None,
        specular_color: None,
        transmission: None,
        clearcoat: None,
        clearcoat_roughness: None,
    })
}

/// A JSON array of three finite numbers.
pub(super) fn vec3(file: &Path, at: &str, value: &Value) -> Result<Vec3, GltfError> {
    match value.as_array() {
        Some(items) if items.len() == 3 => Ok(Vec3::new(
            number(file, at, &items[0])?,
            number(file, at, &items[1])?,
            number(file, at, &items[2])?,
        )),
        _ => Err(invalid(
            file,
            at,
            format!("must be an array of 3 numbers, found {value}"),
        )),
    }
}

/// A JSON number that is finite as an `f32`.
pub(super) fn number(file: &Path, at: &str, value: &Value) -> Result<f32, GltfError> {
    match value.as_f64().map(|x| x as f32) {
        Some(x) if x.is_finite() => Ok(x),
        _ => Err(invalid(
            file,
            at,
            format!("must be a finite number, found {value}"),
        )),
    }
}

/// [`number`], and in [0, 1] (a factor of the material extensions).
fn unit_number(file: &Path, at: &str, value: &Value) -> Result<f32, GltfError> {
    let x = number(file, at, value)?;
    if !(0.0..=1.0).contains(&x) {
        return Err(invalid(
            file,
            at,
            format!("must be in [0, 1], found {value}"),
        ));
    }
    Ok(x)
}

/// A node's `extras` if they are a JSON object.
pub(super) fn node_extras(
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

pub(super) struct PortalExtras {
    pub(super) target: String,
    pub(super) alpha: f32,
    pub(super) auto_alpha: bool,
}

/// A `portal_light_probability` value at `at`: a number in [0, 1] (not auto), or `"auto"`.
fn portal_alpha(file: &Path, at: &str, value: &Value) -> Result<(f32, bool), GltfError> {
    if value.as_str() == Some(AUTO_ALPHA) {
        return Ok((DEFAULT_PORTAL_ALPHA, true));
    }
    match value.as_f64() {
        Some(a) if (0.0..=1.0).contains(&a) => Ok((a as f32, false)),
        _ => Err(invalid(
            file,
            format!("{at}.{PORTAL_ALPHA_KEY}"),
            format!("must be a number in [0, 1] or \"{AUTO_ALPHA}\", found {value}"),
        )),
    }
}

/// The alpha of portal nodes without their own `portal_light_probability`: the used scene's
/// `extras.portal_light_probability`, else the default.
pub(super) fn scene_portal_alpha(file: &Path, root: &json::Root) -> Result<(f32, bool), GltfError> {
    let default = (DEFAULT_PORTAL_ALPHA, false);
    let Some(s) = used_scene(root) else {
        return Ok(default);
    };
    let Some(raw) = root.scenes.get(s).and_then(|scene| scene.extras.as_ref()) else {
        return Ok(default);
    };
    let at = format!("scene {s}, extras");
    match serde_json::from_str::<Value>(raw.get()) {
        Ok(Value::Object(map)) => match map.get(PORTAL_ALPHA_KEY) {
            Some(value) => portal_alpha(file, &at, value),
            None => Ok(default),
        },
        Ok(_) => Ok(default),
        Err(e) => Err(invalid(file, at, e.to_string())),
    }
}

/// The portal a node's extras describe, if they name a `portal_target`; `default_alpha` for
/// one without its own `portal_light_probability`.
pub(super) fn portal_extras(
    file: &Path,
    extras: Option<&Map<String, Value>>,
    at: &str,
    default_alpha: (f32, bool),
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
    let (alpha, auto_alpha) = match extras.and_then(|e| e.get(PORTAL_ALPHA_KEY)) {
        None => default_alpha,
        Some(value) => portal_alpha(file, &format!("{at}, extras"), value)?,
    };
    Ok(Some(PortalExtras {
        target: target.to_owned(),
        alpha,
        auto_alpha,
    }))
}
