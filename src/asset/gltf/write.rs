//! Writing a scene description as a glTF document (meshes, materials, portals, camera).

use super::*;

/// A JSON number that prints as the shortest decimal reading back to the same `f32`.
pub(super) fn json_f32(x: f32) -> Value {
    let shortest = x.to_string().parse::<f64>().unwrap_or(f64::from(x));
    serde_json::Number::from_f64(shortest).map_or(Value::Null, Value::Number)
}

pub(super) fn json_matrix(m: Mat4) -> Value {
    Value::Array(m.to_cols_array().into_iter().map(json_f32).collect())
}

pub(super) fn portal_extras_json(portal: &PortalDesc) -> Map<String, Value> {
    let mut extras = Map::new();
    extras.insert(
        PORTAL_TARGET_KEY.to_owned(),
        Value::from(portal.target.as_str()),
    );
    let alpha = if portal.auto_alpha {
        Value::from(AUTO_ALPHA)
    } else {
        json_f32(portal.alpha)
    };
    extras.insert(PORTAL_ALPHA_KEY.to_owned(), alpha);
    extras
}

pub(super) fn raw_json(
    file: &Path,
    value: &Map<String, Value>,
) -> Result<Box<RawValue>, GltfError> {
    serde_json::to_string(value)
        .and_then(RawValue::from_string)
        .map_err(|e| internal(file, e))
}

pub(super) fn json_index<T>(file: &Path, i: usize) -> Result<json::Index<T>, GltfError> {
    u32::try_from(i)
        .map(json::Index::new)
        .map_err(|_| invalid(file, "document", format!("index {i} exceeds glTF's limits")))
}

/// Binary data and the buffer views, accessors and meshes describing it, to be appended after
/// a document's existing ones (`*_base` counts those).
pub(super) struct GeometryWriter<'f> {
    pub(super) file: &'f Path,
    pub(super) bin: Vec<u8>,
    /// The index the buffer holding `bin` will have.
    pub(super) buffer: usize,
    pub(super) view_base: usize,
    pub(super) views: Vec<json::buffer::View>,
    pub(super) accessor_base: usize,
    pub(super) accessors: Vec<json::Accessor>,
    pub(super) mesh_base: usize,
    pub(super) meshes: Vec<json::Mesh>,
}

impl<'f> GeometryWriter<'f> {
    pub(super) fn after(file: &'f Path, root: &json::Root) -> Self {
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

    pub(super) fn view(
        &mut self,
        bytes: &[u8],
        target: json::buffer::Target,
    ) -> Result<json::Index<json::buffer::View>, GltfError> {
        self.view_for(bytes, Some(target))
    }

    /// A buffer view of `bytes`; images have no `target`.
    pub(super) fn view_for(
        &mut self,
        bytes: &[u8],
        target: Option<json::buffer::Target>,
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
            target: target.map(Checked::Valid),
            extensions: None,
            extras: None,
        });
        Ok(index)
    }

    pub(super) fn accessor(
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

    pub(super) fn vec3s(
        &mut self,
        values: &[Vec3],
        min_max: bool,
    ) -> Result<json::Index<json::Accessor>, GltfError> {
        let bytes = le_bytes(
            values
                .iter()
                .flat_map(|v| v.to_array())
                .map(f32::to_le_bytes),
        );
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

    /// A VEC2 or VEC4 attribute (`N` floats per element).
    pub(super) fn floats<const N: usize>(
        &mut self,
        values: &[[f32; N]],
    ) -> Result<json::Index<json::Accessor>, GltfError> {
        let bytes = le_bytes(values.iter().flatten().map(|x| x.to_le_bytes()));
        let view = self.view(&bytes, json::buffer::Target::ArrayBuffer)?;
        let ty = if N == 2 { Type::Vec2 } else { Type::Vec4 };
        self.accessor(view, values.len(), ComponentType::F32, ty, None)
    }

    pub(super) fn indices(
        &mut self,
        triangles: &[[u32; 3]],
    ) -> Result<json::Index<json::Accessor>, GltfError> {
        let bytes = le_bytes(triangles.iter().flatten().map(|i| i.to_le_bytes()));
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
    pub(super) fn mesh(
        &mut self,
        name: &str,
        positions: &[Vec3],
        normals: Option<&[Vec3]>,
        triangles: &[[u32; 3]],
        material: Option<usize>,
    ) -> Result<json::Index<json::Mesh>, GltfError> {
        self.mesh_with(name, positions, normals, triangles, material, None)
    }

    /// [`Self::mesh`] with the texture coordinates and tangents of `textured`, if given.
    pub(super) fn mesh_with(
        &mut self,
        name: &str,
        positions: &[Vec3],
        normals: Option<&[Vec3]>,
        triangles: &[[u32; 3]],
        material: Option<usize>,
        textured: Option<&MeshDesc>,
    ) -> Result<json::Index<json::Mesh>, GltfError> {
        let mut attributes = BTreeMap::new();
        if let Some(mesh) = textured {
            for (set, uvs) in mesh.texcoords.iter().enumerate() {
                if !uvs.is_empty() {
                    let values: Vec<[f32; 2]> = uvs.iter().map(|v| v.to_array()).collect();
                    attributes.insert(
                        Checked::Valid(Semantic::TexCoords(set as u32)),
                        self.floats(&values)?,
                    );
                }
            }
            if !mesh.tangents.is_empty() {
                let values: Vec<[f32; 4]> = mesh.tangents.iter().map(|v| v.to_array()).collect();
                attributes.insert(Checked::Valid(Semantic::Tangents), self.floats(&values)?);
            }
        }
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
    pub(super) fn portal_mesh(
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

/// A material's texture references as glTF textures: one per distinct (image, sampler), each
/// image written once as PNG in the binary buffer.
#[derive(Default)]
pub(super) struct TextureWriter {
    textures: Vec<(usize, crate::asset::texture::Sampler)>,
}

impl TextureWriter {
    /// The glTF texture index for `r`.
    fn texture(&mut self, r: &TextureRef) -> u32 {
        let key = (r.image, r.sampler);
        let k = match self.textures.iter().position(|t| *t == key) {
            Some(k) => k,
            None => {
                self.textures.push(key);
                self.textures.len() - 1
            }
        };
        k as u32
    }

    /// `r` as a glTF textureInfo (with `KHR_texture_transform` when it has a transform).
    fn info(&mut self, r: &TextureRef, used: &mut Vec<&'static str>) -> json::texture::Info {
        json::texture::Info {
            index: json::Index::new(self.texture(r)),
            tex_coord: r.tex_coord,
            extensions: transform_extension(r, used)
                .map(|others| json::extensions::texture::Info { others }),
            extras: None,
        }
    }

    /// `r` as textureInfo JSON (for the specular extension, which is kept as JSON).
    fn info_json(&mut self, r: &TextureRef, used: &mut Vec<&'static str>) -> Value {
        serde_json::to_value(self.info(r, used)).unwrap_or(Value::Null)
    }

    /// Writes the images, samplers and textures into `root` and `geometry`'s buffer.
    fn finish(
        self,
        file: &Path,
        images: &[std::sync::Arc<crate::asset::texture::Image>],
        root: &mut json::Root,
        geometry: &mut GeometryWriter,
    ) -> Result<(), GltfError> {
        use crate::asset::texture::{Filter, Wrap};
        let mut written: HashMap<usize, usize> = HashMap::new();
        for (k, (image, sampler)) in self.textures.into_iter().enumerate() {
            let source = match written.get(&image) {
                Some(&i) => i,
                None => {
                    let Some(img) = images.get(image) else {
                        return Err(invalid(
                            file,
                            format!("texture {k}"),
                            format!("image {image} does not exist"),
                        ));
                    };
                    let png = encode_png(img).map_err(|e| internal(file, e))?;
                    let view = geometry.view_for(&png, None)?;
                    root.images.push(json::Image {
                        buffer_view: Some(view),
                        mime_type: Some(json::image::MimeType("image/png".to_owned())),
                        name: Some(img.name.clone()),
                        uri: None,
                        extensions: None,
                        extras: None,
                    });
                    written.insert(image, root.images.len() - 1);
                    root.images.len() - 1
                }
            };
            let wrap = |w: Wrap| {
                Checked::Valid(match w {
                    Wrap::Repeat => json::texture::WrappingMode::Repeat,
                    Wrap::ClampToEdge => json::texture::WrappingMode::ClampToEdge,
                    Wrap::MirroredRepeat => json::texture::WrappingMode::MirroredRepeat,
                })
            };
            root.samplers.push(json::texture::Sampler {
                mag_filter: Some(Checked::Valid(match sampler.filter {
                    Filter::Bilinear => json::texture::MagFilter::Linear,
                    Filter::Nearest => json::texture::MagFilter::Nearest,
                })),
                min_filter: None,
                name: None,
                wrap_s: wrap(sampler.wrap_s),
                wrap_t: wrap(sampler.wrap_t),
                extensions: None,
                extras: None,
            });
            root.textures.push(json::Texture {
                name: None,
                sampler: Some(json_index(file, root.samplers.len() - 1)?),
                source: json_index(file, source)?,
                extensions: None,
                extras: None,
            });
        }
        Ok(())
    }
}

/// The `KHR_texture_transform` extension object of `r`, if it has a transform.
fn transform_extension(r: &TextureRef, used: &mut Vec<&'static str>) -> Option<Map<String, Value>> {
    let t = r.transform?;
    if !used.contains(&TEXTURE_TRANSFORM_EXTENSION) {
        used.push(TEXTURE_TRANSFORM_EXTENSION);
    }
    let mut object = Map::new();
    object.insert(
        "offset".to_owned(),
        Value::Array(t.offset.to_array().map(json_f32).to_vec()),
    );
    object.insert("rotation".to_owned(), json_f32(t.rotation));
    object.insert(
        "scale".to_owned(),
        Value::Array(t.scale.to_array().map(json_f32).to_vec()),
    );
    let mut others = Map::new();
    others.insert(
        TEXTURE_TRANSFORM_EXTENSION.to_owned(),
        Value::Object(object),
    );
    Some(others)
}

/// `image` as PNG bytes (8-bit RGBA).
fn encode_png(image: &crate::asset::texture::Image) -> Result<Vec<u8>, String> {
    let raw: Vec<u8> = image.texels().iter().flatten().copied().collect();
    let buffer = image::RgbaImage::from_raw(image.width(), image.height(), raw)
        .ok_or_else(|| format!("image \"{}\" has the wrong number of texels", image.name))?;
    let mut bytes = std::io::Cursor::new(Vec::new());
    buffer
        .write_to(&mut bytes, image::ImageFormat::Png)
        .map_err(|e| format!("image \"{}\" cannot be encoded: {e}", image.name))?;
    Ok(bytes.into_inner())
}

/// `m` as a glTF material, and the material extensions it uses (each written only when its
/// values differ from glTF's defaults); its textures are numbered by `textures`.
pub(super) fn export_material(
    m: &MaterialDesc,
    textures: &mut TextureWriter,
) -> (json::Material, Vec<&'static str>) {
    // glTF keeps emissiveFactor in [0, 1]: fold any excess into the strength (same radiance).
    let peak = m.emissive_factor.max_element();
    let (factor, strength) = if peak > 1.0 {
        (m.emissive_factor / peak, m.emissive_strength * peak)
    } else {
        (m.emissive_factor, m.emissive_strength)
    };
    let mut used = Vec::new();
    let mut extensions = json::extensions::material::Material::default();
    if strength != 1.0 {
        used.push(EMISSIVE_STRENGTH_EXTENSION);
        extensions.emissive_strength = Some(json::extensions::material::EmissiveStrength {
            emissive_strength: json::extensions::material::EmissiveStrengthFactor(strength),
        });
    }
    let t = &m.textures;
    if m.has_specular_extension() || t.specular.is_some() || t.specular_color.is_some() {
        used.push(SPECULAR_EXTENSION);
        let mut specular = Map::new();
        specular.insert("specularFactor".to_owned(), json_f32(m.specular_factor));
        specular.insert(
            "specularColorFactor".to_owned(),
            Value::Array(m.specular_color.to_array().map(json_f32).to_vec()),
        );
        if let Some(r) = &t.specular {
            specular.insert(
                "specularTexture".to_owned(),
                textures.info_json(r, &mut used),
            );
        }
        if let Some(r) = &t.specular_color {
            specular.insert(
                "specularColorTexture".to_owned(),
                textures.info_json(r, &mut used),
            );
        }
        extensions
            .others
            .insert(SPECULAR_EXTENSION.to_owned(), Value::Object(specular));
    }
    if m.has_ior_extension() {
        used.push(IOR_EXTENSION);
        let mut ior = Map::new();
        ior.insert("ior".to_owned(), json_f32(m.ior));
        extensions
            .others
            .insert(IOR_EXTENSION.to_owned(), Value::Object(ior));
    }
    if m.has_transmission_extension() {
        used.push(TRANSMISSION_EXTENSION);
        let mut transmission = Map::new();
        transmission.insert("transmissionFactor".to_owned(), json_f32(m.transmission));
        if let Some(r) = &t.transmission {
            transmission.insert(
                "transmissionTexture".to_owned(),
                textures.info_json(r, &mut used),
            );
        }
        extensions.others.insert(
            TRANSMISSION_EXTENSION.to_owned(),
            Value::Object(transmission),
        );
    }
    if let Some(v) = &m.volume {
        used.push(VOLUME_EXTENSION);
        let mut volume = Map::new();
        volume.insert("thicknessFactor".to_owned(), json_f32(v.thickness));
        if v.attenuation_distance.is_finite() {
            let c = v.attenuation_color.to_array().map(json_f32);
            volume.insert("attenuationColor".to_owned(), Value::Array(c.to_vec()));
            volume.insert(
                "attenuationDistance".to_owned(),
                json_f32(v.attenuation_distance),
            );
        }
        extensions
            .others
            .insert(VOLUME_EXTENSION.to_owned(), Value::Object(volume));
    }
    if m.has_clearcoat_extension() {
        used.push(CLEARCOAT_EXTENSION);
        let mut coat = Map::new();
        coat.insert("clearcoatFactor".to_owned(), json_f32(m.clearcoat));
        coat.insert(
            "clearcoatRoughnessFactor".to_owned(),
            json_f32(m.clearcoat_roughness),
        );
        if let Some(r) = &t.clearcoat {
            coat.insert(
                "clearcoatTexture".to_owned(),
                textures.info_json(r, &mut used),
            );
        }
        if let Some(r) = &t.clearcoat_roughness {
            coat.insert(
                "clearcoatRoughnessTexture".to_owned(),
                textures.info_json(r, &mut used),
            );
        }
        extensions
            .others
            .insert(CLEARCOAT_EXTENSION.to_owned(), Value::Object(coat));
    }
    let has_material_extension =
        !extensions.others.is_empty() || extensions.emissive_strength.is_some();
    let (alpha_mode, alpha_cutoff) = match m.alpha_mode {
        AlphaMode::Opaque => (json::material::AlphaMode::Opaque, None),
        AlphaMode::Mask { cutoff } => (
            json::material::AlphaMode::Mask,
            Some(json::material::AlphaCutoff(cutoff)),
        ),
        AlphaMode::Blend => (json::material::AlphaMode::Blend, None),
    };
    let material = json::Material {
        name: Some(m.name.clone()),
        pbr_metallic_roughness: json::material::PbrMetallicRoughness {
            base_color_factor: json::material::PbrBaseColorFactor(
                m.base_color.extend(m.alpha).to_array(),
            ),
            base_color_texture: t.base_color.as_ref().map(|r| textures.info(r, &mut used)),
            metallic_factor: json::material::StrengthFactor(m.metallic),
            roughness_factor: json::material::StrengthFactor(m.roughness),
            metallic_roughness_texture: t
                .metallic_roughness
                .as_ref()
                .map(|r| textures.info(r, &mut used)),
            ..Default::default()
        },
        normal_texture: t.normal.as_ref().map(|n| {
            let info = textures.info(&n.texture, &mut used);
            json::material::NormalTexture {
                index: info.index,
                scale: n.scale,
                tex_coord: info.tex_coord,
                extensions: info
                    .extensions
                    .map(|e| json::extensions::material::NormalTexture { others: e.others }),
                extras: None,
            }
        }),
        emissive_texture: t.emissive.as_ref().map(|r| textures.info(r, &mut used)),
        emissive_factor: json::material::EmissiveFactor(factor.to_array()),
        alpha_mode: Checked::Valid(alpha_mode),
        alpha_cutoff,
        double_sided: m.double_sided,
        extensions: has_material_extension.then_some(extensions),
        ..Default::default()
    };
    (material, used)
}

/// The camera node's world matrix (looking down its −Z, +Y up) and the target distance.
pub(super) fn camera_transform(file: &Path, c: &Camera) -> Result<(Mat4, f32), GltfError> {
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
pub(super) fn export_document(
    file: &Path,
    desc: &SceneDesc,
) -> Result<(json::Root, Vec<u8>), GltfError> {
    for (k, m) in desc.materials.iter().enumerate() {
        check_material(file, k, m, desc.images.len())?;
    }
    for (k, mesh) in desc.meshes.iter().enumerate() {
        check_mesh(file, k, mesh, &desc.materials)?;
    }
    for portal in &desc.portals {
        check_portal(file, portal)?;
    }
    let mut root = json::Root::default();
    root.asset.generator = Some("portalview".to_owned());
    let mut extensions_used: Vec<&str> = Vec::new();
    let mut textures = TextureWriter::default();
    for m in &desc.materials {
        let (material, used) = export_material(m, &mut textures);
        for extension in used {
            if !extensions_used.contains(&extension) {
                extensions_used.push(extension);
            }
        }
        root.materials.push(material);
    }
    let mut geometry = GeometryWriter::after(file, &root);
    textures.finish(file, &desc.images, &mut root, &mut geometry)?;
    let mut nodes = Vec::new();
    for mesh in &desc.meshes {
        let normals = (!mesh.normals.is_empty()).then_some(mesh.normals.as_slice());
        let index = geometry.mesh_with(
            &mesh.node_name,
            &mesh.positions,
            normals,
            &mesh.indices,
            Some(mesh.material),
            Some(mesh),
        )?;
        nodes.push(json::Node {
            name: Some(mesh.node_name.clone()),
            mesh: Some(index),
            ..Default::default()
        });
    }
    for portal in &desc.portals {
        let index = geometry.portal_mesh(&portal.name, &portal.local_triangles)?;
        let extras = portal_extras_json(portal);
        nodes.push(json::Node {
            name: Some(portal.name.clone()),
            mesh: Some(index),
            matrix: Some(portal.world_from_local.to_cols_array()),
            extras: Some(raw_json(file, &extras)?),
            ..Default::default()
        });
    }
    export_lamps(file, &desc.lamps, &mut root, &mut nodes)?;
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
    let scene_extras = match &desc.environment {
        Some(environment) => Some(raw_json(file, &environment_extras(file, environment)?)?),
        None => None,
    };
    root.scenes.push(json::Scene {
        extensions: None,
        extras: scene_extras,
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
    // Appended: lamps declared theirs already.
    root.extensions_used
        .extend(extensions_used.into_iter().map(str::to_owned));
    Ok((root, bin))
}

/// Writes through [`crate::io::write_atomic`], as a glTF error naming the file.
pub(super) fn write_atomically(file: &Path, bytes: &[u8]) -> Result<(), GltfError> {
    crate::io::write_atomic(file, bytes).map_err(|source| GltfError::Write {
        file: file.to_owned(),
        source,
    })
}

/// 4-byte scalars laid end to end, as a glTF buffer stores them (little-endian).
fn le_bytes(words: impl IntoIterator<Item = [u8; 4]>) -> Vec<u8> {
    words.into_iter().flatten().collect()
}
