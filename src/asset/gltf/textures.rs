//! Materials' textures: `textureInfo` objects (with `KHR_texture_transform`), samplers, and
//! images decoded from files next to the `.gltf`, data URIs or buffer views (`.glb`), PNG or
//! JPEG, with limits on their size. Every error names the file, the material and texture slot,
//! and the image (index, name, URI).

use std::io::Cursor;
use std::sync::Arc;

use glam::Vec2;

use super::*;
use crate::asset::texture::{
    Filter, Image, MAX_IMAGE_SIDE, MAX_IMAGE_TEXELS, MAX_SCENE_TEXELS, MAX_TEXELS_PER_FILE_BYTE,
    Sampler, TextureRef, TextureTransform, Wrap,
};

/// The most bytes an external image file or data URI may hold.
const MAX_IMAGE_BYTES: u64 = 256 << 20;
pub(super) const TEXTURE_TRANSFORM_EXTENSION: &str = "KHR_texture_transform";

/// Images decoded so far: each glTF image once, however many materials use it.
#[derive(Default)]
pub(super) struct Images {
    /// glTF image index → index in `decoded`.
    index: HashMap<usize, usize>,
    pub(super) decoded: Vec<Arc<Image>>,
    texels: u64,
}

impl<'a> Doc<'a> {
    /// The texture a `textureInfo` (as JSON) names, its image decoded; `at` names the material
    /// and the slot (`…, pbrMetallicRoughness.baseColorTexture`).
    pub(super) fn texture_ref(
        &self,
        info: &Value,
        at: &str,
        images: &mut Images,
    ) -> Result<TextureRef, GltfError> {
        let Some(index) = info.get("index").and_then(Value::as_u64) else {
            return Err(self.invalid(
                at,
                format!("must be a textureInfo with an integer index, found {info}"),
            ));
        };
        let Some(texture) = self.root.textures.get(index as usize) else {
            return Err(self.invalid(
                format!("{at}.index"),
                format!(
                    "texture {index} does not exist (the file has {})",
                    self.root.textures.len()
                ),
            ));
        };
        let texture_at = format!(
            "{at}, {}",
            label("texture", index as usize, texture.name.as_deref())
        );
        let mut tex_coord = match info.get("texCoord") {
            None => 0,
            Some(v) => self.set_index(v, &format!("{at}.texCoord"))?,
        };
        let extension = info
            .get("extensions")
            .and_then(|e| e.get(TEXTURE_TRANSFORM_EXTENSION));
        let transform = match extension {
            None => None,
            Some(t) => {
                let at = format!("{at}.extensions.{TEXTURE_TRANSFORM_EXTENSION}");
                if let Some(v) = t.get("texCoord") {
                    tex_coord = self.set_index(v, &format!("{at}.texCoord"))?;
                }
                Some(TextureTransform {
                    offset: self.vec2(t.get("offset"), &format!("{at}.offset"), Vec2::ZERO)?,
                    rotation: match t.get("rotation") {
                        None => 0.0,
                        Some(v) => number(self.file, &format!("{at}.rotation"), v)?,
                    },
                    scale: self.vec2(t.get("scale"), &format!("{at}.scale"), Vec2::ONE)?,
                })
            }
        };
        let sampler = match texture.sampler {
            None => Sampler::default(),
            Some(s) => self.sampler(s.value(), &texture_at)?,
        };
        let image = self.image(texture.source.value(), &texture_at, images)?;
        Ok(TextureRef {
            image,
            sampler,
            tex_coord,
            transform,
        })
    }

    /// A `texCoord`: 0 or 1 (the attribute sets read).
    fn set_index(&self, value: &Value, at: &str) -> Result<u32, GltfError> {
        match value.as_u64() {
            Some(n @ 0..=1) => Ok(n as u32),
            _ => Err(self.invalid(
                at,
                format!("must be 0 or 1 (TEXCOORD_0 or TEXCOORD_1 are read), found {value}"),
            )),
        }
    }

    fn vec2(&self, value: Option<&Value>, at: &str, default: Vec2) -> Result<Vec2, GltfError> {
        let Some(value) = value else {
            return Ok(default);
        };
        match value.as_array().map(Vec::as_slice) {
            Some([x, y]) => Ok(Vec2::new(
                number(self.file, at, x)?,
                number(self.file, at, y)?,
            )),
            _ => Err(self.invalid(at, format!("must be an array of 2 numbers, found {value}"))),
        }
    }

    fn sampler(&self, index: usize, at: &str) -> Result<Sampler, GltfError> {
        let Some(s) = self.root.samplers.get(index) else {
            return Err(self.invalid(at, format!("sampler {index} does not exist")));
        };
        let wrap = |mode: &Checked<json::texture::WrappingMode>, field: &str| match mode {
            Checked::Valid(json::texture::WrappingMode::Repeat) => Ok(Wrap::Repeat),
            Checked::Valid(json::texture::WrappingMode::ClampToEdge) => Ok(Wrap::ClampToEdge),
            Checked::Valid(json::texture::WrappingMode::MirroredRepeat) => Ok(Wrap::MirroredRepeat),
            Checked::Invalid => Err(self.invalid(
                format!("{at}, sampler {index}.{field}"),
                "is not a glTF wrap mode",
            )),
        };
        let filter = match s.mag_filter {
            Some(Checked::Valid(json::texture::MagFilter::Nearest)) => Filter::Nearest,
            _ => Filter::Bilinear,
        };
        Ok(Sampler {
            wrap_s: wrap(&s.wrap_s, "wrapS")?,
            wrap_t: wrap(&s.wrap_t, "wrapT")?,
            filter,
        })
    }

    /// Decodes glTF image `index` (once), returning its index among the scene's images.
    fn image(&self, index: usize, at: &str, images: &mut Images) -> Result<usize, GltfError> {
        if let Some(&k) = images.index.get(&index) {
            return Ok(k);
        }
        let Some(image) = self.root.images.get(index) else {
            return Err(self.invalid(at, format!("image {index} does not exist")));
        };
        let mut name = label("image", index, image.name.as_deref());
        if let Some(uri) = image.uri.as_deref().filter(|u| !u.starts_with("data:")) {
            name.push_str(&format!(" (uri \"{uri}\")"));
        }
        let at = format!("{at}, {name}");
        let bytes: Cow<[u8]> = match (&image.uri, image.buffer_view) {
            (Some(uri), _) => {
                let base = self.file.parent().unwrap_or(Path::new(""));
                Cow::Owned(read_uri(self.file, base, &at, uri, MAX_IMAGE_BYTES)?)
            }
            (None, Some(view)) => Cow::Borrowed(self.view_bytes(view.value(), &at)?.0),
            (None, None) => return Err(self.invalid(at, "has neither a uri nor a bufferView")),
        };
        let decoded = decode_image(&bytes, name).map_err(|reason| self.invalid(&at, reason))?;
        images.texels += decoded.width() as u64 * decoded.height() as u64;
        if images.texels > MAX_SCENE_TEXELS {
            return Err(self.invalid(
                at,
                format!("the scene's images exceed {MAX_SCENE_TEXELS} texels together"),
            ));
        }
        images.decoded.push(Arc::new(decoded));
        let k = images.decoded.len() - 1;
        images.index.insert(index, k);
        Ok(k)
    }
}

/// A PNG or JPEG image as 8-bit RGBA (16-bit channels are rounded to 8 bits), refused if
/// larger than [`MAX_IMAGE_SIDE`], [`MAX_IMAGE_TEXELS`] or [`MAX_TEXELS_PER_FILE_BYTE`] times
/// its file's size before any texel is allocated.
pub(super) fn decode_image(bytes: &[u8], name: String) -> Result<Image, String> {
    let reader = image::ImageReader::new(Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| format!("cannot be read: {e}"))?;
    match reader.format() {
        Some(image::ImageFormat::Png | image::ImageFormat::Jpeg) => {}
        Some(other) => {
            return Err(format!(
                "is {other:?}, but only PNG and JPEG images are read"
            ));
        }
        None => return Err("is neither a PNG nor a JPEG image".to_owned()),
    }
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_IMAGE_SIDE);
    limits.max_image_height = Some(MAX_IMAGE_SIDE);
    // The decoded image and the RGBA copy, at 16 bits per channel at most.
    limits.max_alloc = Some(MAX_IMAGE_TEXELS * 8 * 2);
    let mut reader = reader;
    reader.limits(limits);
    let (width, height) = reader
        .into_dimensions()
        .map_err(|e| format!("cannot be decoded: {e}"))?;
    if width as u64 * height as u64 > MAX_IMAGE_TEXELS {
        return Err(format!(
            "is {width}×{height}, more than the {MAX_IMAGE_TEXELS} texels an image may have"
        ));
    }
    crate::io::check_decoded_size(
        width as u64,
        height as u64,
        bytes.len() as u64,
        MAX_TEXELS_PER_FILE_BYTE,
    )?;
    let mut reader = image::ImageReader::new(Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| format!("cannot be read: {e}"))?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_IMAGE_SIDE);
    limits.max_image_height = Some(MAX_IMAGE_SIDE);
    limits.max_alloc = Some(MAX_IMAGE_TEXELS * 8 * 2);
    reader.limits(limits);
    let decoded = reader
        .decode()
        .map_err(|e| format!("cannot be decoded: {e}"))?;
    let rgba = decoded.into_rgba8();
    let (width, height) = rgba.dimensions();
    let texels = rgba
        .into_raw()
        .chunks_exact(4)
        .map(|c| [c[0], c[1], c[2], c[3]])
        .collect();
    Image::new(name, width, height, texels).ok_or_else(|| {
        format!("is {width}×{height}: empty, or larger than {MAX_IMAGE_SIDE} texels a side")
    })
}
