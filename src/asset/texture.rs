//! Textures as glTF defines them: decoded 8-bit RGBA images, the sampler (wrap modes, bilinear
//! or nearest filtering; no mipmaps, so a texture seen from far away aliases rather than
//! blurs, which the path tracer's many samples per pixel average out), `KHR_texture_transform`,
//! and the colour decoding (sRGB to linear for colours, raw values for data).

use glam::{Vec2, Vec4};
use std::sync::{Arc, OnceLock};

/// The widest or tallest image read; larger ones are refused with an error.
pub const MAX_IMAGE_SIDE: u32 = 16384;
/// The most texels one image may have (256 MiB as RGBA8).
pub const MAX_IMAGE_TEXELS: u64 = 64 << 20;
/// The most texels a PNG or JPEG may decode to per byte of its file. A 1-bit PNG of one colour
/// packs 8 texels a byte and deflate compresses 1032:1 at most, so about 8,300; JPEG far less.
/// A header that claims more than this is damaged, and is refused before decoding.
pub const MAX_TEXELS_PER_FILE_BYTE: u64 = 16384;
/// The most texels all the images of a scene may have together (1 GiB as RGBA8).
pub const MAX_SCENE_TEXELS: u64 = 256 << 20;

/// A decoded image: row-major 8-bit RGBA texels, row 0 at the top (glTF's UV origin).
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// How errors and the UI name it (its glTF index, name or URI).
    pub name: String,
    width: u32,
    height: u32,
    texels: Vec<[u8; 4]>,
}

impl Image {
    /// An image of `width × height` texels; `None` unless there are exactly that many, at
    /// least one, and within [`MAX_IMAGE_SIDE`] and [`MAX_IMAGE_TEXELS`].
    pub fn new(name: String, width: u32, height: u32, texels: Vec<[u8; 4]>) -> Option<Self> {
        let count = width as u64 * height as u64;
        let fits = width > 0
            && height > 0
            && width <= MAX_IMAGE_SIDE
            && height <= MAX_IMAGE_SIDE
            && count <= MAX_IMAGE_TEXELS;
        (fits && texels.len() as u64 == count).then_some(Image {
            name,
            width,
            height,
            texels,
        })
    }

    pub fn width(&self) -> u32 {
        self.width
    }

    pub fn height(&self) -> u32 {
        self.height
    }

    pub fn texels(&self) -> &[[u8; 4]] {
        &self.texels
    }

    fn texel(&self, x: u32, y: u32) -> [u8; 4] {
        self.texels
            .get(y as usize * self.width as usize + x as usize)
            .copied()
            .unwrap_or([0; 4])
    }
}

/// glTF sampler wrap modes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Wrap {
    #[default]
    Repeat,
    ClampToEdge,
    MirroredRepeat,
}

impl Wrap {
    /// The texel index for index `i` (any integer) of a row or column of `n` texels.
    #[inline]
    pub fn index(self, i: i64, n: u32) -> u32 {
        let n = n as i64;
        // Lookups pass indices within a period or two of the image (coordinates are reduced
        // first): compare and shift there, and divide only beyond.
        let modulo = |i: i64, m: i64| {
            if (0..m).contains(&i) {
                i
            } else if (-m..0).contains(&i) {
                i + m
            } else if (m..2 * m).contains(&i) {
                i - m
            } else {
                i.rem_euclid(m)
            }
        };
        let j = match self {
            Wrap::Repeat => modulo(i, n),
            Wrap::ClampToEdge => i.clamp(0, n - 1),
            Wrap::MirroredRepeat => {
                let j = modulo(i, 2 * n);
                if j < n { j } else { 2 * n - 1 - j }
            }
        };
        j as u32
    }

    /// A coordinate equivalent to `u` under this mode but small (so that it converts to an
    /// integer texel index exactly): periodic modes drop whole periods, clamping clamps.
    fn reduce(self, u: f32) -> f32 {
        if !u.is_finite() {
            return 0.0;
        }
        match self {
            Wrap::Repeat => u - u.floor(),
            Wrap::MirroredRepeat => u - 2.0 * (0.5 * u).floor(),
            Wrap::ClampToEdge => u.clamp(-1.0, 2.0),
        }
    }
}

/// glTF magnification filters (minification uses the same: there are no mipmaps).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Filter {
    #[default]
    Bilinear,
    Nearest,
}

/// A glTF sampler.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Sampler {
    pub wrap_s: Wrap,
    pub wrap_t: Wrap,
    pub filter: Filter,
}

/// `KHR_texture_transform`: `uv' = offset + R(rotation) · (scale ⊙ uv)`, where R turns the
/// UVs counter-clockwise as the extension says: `u' = cos·u + sin·v`, `v' = −sin·u + cos·v`
/// (its example, "the lower left quadrant rotated clockwise 90°", fixes the sign).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TextureTransform {
    pub offset: Vec2,
    pub rotation: f32,
    pub scale: Vec2,
}

impl Default for TextureTransform {
    fn default() -> Self {
        TextureTransform {
            offset: Vec2::ZERO,
            rotation: 0.0,
            scale: Vec2::ONE,
        }
    }
}

impl TextureTransform {
    pub fn apply(&self, uv: Vec2) -> Vec2 {
        let s = uv * self.scale;
        let (sin, cos) = self.rotation.sin_cos();
        self.offset + Vec2::new(cos * s.x + sin * s.y, -sin * s.x + cos * s.y)
    }
}

/// A material's reference to a texture, as authored: which image of the scene, how it is
/// sampled, which `TEXCOORD_n` it reads and its transform.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TextureRef {
    /// Index into `SceneDesc::images`.
    pub image: usize,
    pub sampler: Sampler,
    /// 0 or 1: `TEXCOORD_0` or `TEXCOORD_1` (after `KHR_texture_transform`'s override).
    pub tex_coord: u32,
    pub transform: Option<TextureTransform>,
}

/// A [`TextureRef`] with its image in hand, ready to sample.
#[derive(Clone, Debug)]
pub struct Texture {
    pub image: Arc<Image>,
    pub sampler: Sampler,
    pub tex_coord: u32,
    pub transform: Option<TextureTransform>,
}

/// sRGB-encoded 8-bit values to linear (the IEC 61966-2-1 curve).
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

fn srgb_table() -> &'static [f32; 256] {
    static TABLE: OnceLock<[f32; 256]> = OnceLock::new();
    TABLE.get_or_init(|| std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0)))
}

/// How a texel's channels become numbers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    /// RGB are sRGB-encoded colours (base colour, emission, specular colour); A is linear.
    Srgb,
    /// Every channel is a linear value in [0, 1] (metal/roughness, normals, specular).
    Linear,
}

/// Cells of [`srgb_to_linear_filtered`]'s table over [0, 1].
const FILTERED_CELLS: usize = 4096;

/// `srgb_to_linear` of an encoded value between texels (a filtered one), by a table of 4097
/// points and linear interpolation between them: within 2e-6 of the curve, without a `powf`
/// per channel per lookup.
fn srgb_to_linear_filtered(c: f32) -> f32 {
    static TABLE: OnceLock<Vec<f32>> = OnceLock::new();
    let table = TABLE.get_or_init(|| {
        (0..=FILTERED_CELLS)
            .map(|i| srgb_to_linear(i as f32 / FILTERED_CELLS as f32))
            .collect()
    });
    let x = c.clamp(0.0, 1.0) * FILTERED_CELLS as f32;
    let i = (x as usize).min(FILTERED_CELLS - 1);
    let t = x - i as f32;
    table[i] + (table[i + 1] - table[i]) * t
}

fn decode(t: [u8; 4], encoding: Encoding) -> Vec4 {
    let a = t[3] as f32 / 255.0;
    match encoding {
        Encoding::Srgb => {
            let lut = srgb_table();
            Vec4::new(
                lut[t[0] as usize],
                lut[t[1] as usize],
                lut[t[2] as usize],
                a,
            )
        }
        Encoding::Linear => Vec4::new(t[0] as f32, t[1] as f32, t[2] as f32, t[3] as f32) / 255.0,
    }
}

impl Image {
    /// The filtered value at `uv` (glTF convention: (0, 0) is the top-left corner of the
    /// image, texel centres at half-integers times the texel size). Bilinear filtering of sRGB
    /// colours interpolates the encoded values and decodes the result, as Cycles does for an
    /// 8-bit sRGB image (`svm_image_texture`, `NODE_IMAGE_COMPRESS_AS_SRGB`): artists judge by
    /// Blender. (GPUs, and the glTF viewers on them, decode each texel first: between a black
    /// and a white texel that is 0.5 where Cycles gives 0.214; on a checkerboard floor Cycles
    /// is 2–3% darker.)
    pub fn sample(&self, uv: Vec2, sampler: Sampler, encoding: Encoding) -> Vec4 {
        let (u, v) = (sampler.wrap_s.reduce(uv.x), sampler.wrap_t.reduce(uv.y));
        let (w, h) = (self.width, self.height);
        match sampler.filter {
            Filter::Nearest => {
                let x = sampler.wrap_s.index((u * w as f32).floor() as i64, w);
                let y = sampler.wrap_t.index((v * h as f32).floor() as i64, h);
                decode(self.texel(x, y), encoding)
            }
            Filter::Bilinear => {
                let (x, y) = (u * w as f32 - 0.5, v * h as f32 - 0.5);
                let (x0, y0) = (x.floor(), y.floor());
                let (fx, fy) = (x - x0, y - y0);
                let (x0, y0) = (x0 as i64, y0 as i64);
                let xs = [sampler.wrap_s.index(x0, w), sampler.wrap_s.index(x0 + 1, w)];
                let ys = [sampler.wrap_t.index(y0, h), sampler.wrap_t.index(y0 + 1, h)];
                let at = |i: usize, j: usize| decode(self.texel(xs[i], ys[j]), Encoding::Linear);
                let top = at(0, 0).lerp(at(1, 0), fx);
                let bottom = at(0, 1).lerp(at(1, 1), fx);
                let filtered = top.lerp(bottom, fy);
                match encoding {
                    Encoding::Linear => filtered,
                    Encoding::Srgb => Vec4::new(
                        srgb_to_linear_filtered(filtered.x),
                        srgb_to_linear_filtered(filtered.y),
                        srgb_to_linear_filtered(filtered.z),
                        filtered.w,
                    ),
                }
            }
        }
    }
}

impl Texture {
    /// The texture coordinate this texture reads at a point whose interpolated `TEXCOORD_0`
    /// and `TEXCOORD_1` are `uvs`, transformed.
    #[inline]
    pub fn coordinate(&self, uvs: &[Vec2; 2]) -> Vec2 {
        let uv = uvs[(self.tex_coord as usize).min(1)];
        match &self.transform {
            Some(t) => t.apply(uv),
            None => uv,
        }
    }

    #[inline]
    pub fn sample(&self, uvs: &[Vec2; 2], encoding: Encoding) -> Vec4 {
        self.image
            .sample(self.coordinate(uvs), self.sampler, encoding)
    }
}
