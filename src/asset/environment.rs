//! The environment as authored: an equirectangular image (`.hdr` or `.exr`) or a constant
//! colour, a strength and a rotation about +Y. Plain data; `light::environment` samples it.

use glam::Vec3;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// `portal_target` of a window portal: it opens onto the environment, not onto a light.
pub const ENVIRONMENT_TARGET: &str = "environment";

/// An equirectangular image in linear RGB, row 0 at the top (+Y), `u` = 0.5 + atan2(z, x)/2π.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvImage {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Vec3>,
}

impl EnvImage {
    /// The pixel at column `i`, row `j`.
    pub fn pixel(&self, i: u32, j: u32) -> Vec3 {
        self.pixels[(j * self.width + i) as usize]
    }
}

/// What the environment's radiance comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum EnvMap {
    /// The same radiance from every direction.
    Constant(Vec3),
    /// An image; `file` is where it was read from (a glTF names it relative to itself when
    /// it is saved), `None` for an image made in code (a built-in sky), which saving writes
    /// beside the glTF.
    Image {
        file: Option<PathBuf>,
        image: Arc<EnvImage>,
    },
}

/// How an image is read between pixel centres: Blender's *Environment Texture* node's
/// *Interpolation* (scene extra `environment_interpolation`).
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    serde::Serialize,
    serde::Deserialize,
    clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum Interpolation {
    /// Bilinear between the four nearest pixel centres, wrapping in both directions as Cycles
    /// does (its environment images repeat: across a pole, the top row meets the bottom row).
    /// Blender's default.
    #[default]
    Linear,
    /// The pixel the direction falls in.
    Closest,
}

impl Interpolation {
    pub const ALL: [Interpolation; 2] = [Interpolation::Linear, Interpolation::Closest];

    /// The name in a scene's extras and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Interpolation::Linear => "linear",
            Interpolation::Closest => "closest",
        }
    }

    /// The interpolation named `text` (`"linear"` or `"closest"`, any case).
    pub fn from_name(text: &str) -> Option<Self> {
        Self::ALL
            .into_iter()
            .find(|i| i.name().eq_ignore_ascii_case(text))
    }
}

/// The environment of a scene: radiance = map × strength, the map turned by `rotation_degrees`
/// about +Y (counter-clockwise seen from above), read between pixels by `interpolation`.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentDesc {
    pub map: EnvMap,
    pub strength: f32,
    pub rotation_degrees: f32,
    pub interpolation: Interpolation,
}

impl EnvironmentDesc {
    pub fn constant(radiance: Vec3) -> Self {
        EnvironmentDesc {
            map: EnvMap::Constant(radiance),
            strength: 1.0,
            rotation_degrees: 0.0,
            interpolation: Interpolation::default(),
        }
    }
}

/// Why an environment cannot be used; every message names the file or the value.
#[derive(Debug, thiserror::Error)]
pub enum EnvironmentError {
    #[error("{}: cannot read the environment image: {reason}", file.display())]
    Read { file: PathBuf, reason: String },
    #[error("{}: the environment image is {width}×{height}; it must be at least 2×1 pixels \
             and at most 32768 on a side",
            file.display())]
    Size {
        file: PathBuf,
        width: u32,
        height: u32,
    },
    #[error("{}: environment files must be .hdr (Radiance RGBE) or .exr", file.display())]
    Format { file: PathBuf },
    #[error("environment colour '{0}': expected three non-negative numbers R,G,B")]
    BadColour(String),
    #[error(
        "an environment strength, rotation or interpolation was given, but no environment (give one with \
             --environment FILE|R,G,B, or in the scene's extras)"
    )]
    NoMap,
    #[error("environment {what} {value} must be a finite number{range}")]
    BadNumber {
        what: &'static str,
        value: f32,
        range: &'static str,
    },
}

/// The largest side of an environment image (a 32k × 16k map is 6 GB of f32 RGB already).
const MAX_SIDE: u32 = 32_768;

/// Reads an equirectangular `.hdr` or `.exr` image. Pixels that are negative or not finite
/// (photographic HDRIs have a few slightly negative ones) are read as 0, and one warning naming
/// the file, the count and the worst value is added to `warnings`; only an unreadable, empty or
/// mis-shaped image is an error.
pub fn load_image(file: &Path, warnings: &mut Vec<String>) -> Result<EnvImage, EnvironmentError> {
    let extension = file
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let read = |reason: String| EnvironmentError::Read {
        file: file.to_owned(),
        reason,
    };
    let (width, height, pixels) = match extension.as_str() {
        "exr" => {
            let (w, h, pixels) = crate::io::read_exr(file).map_err(|e| {
                // read_exr's message starts with the path already.
                read(
                    e.trim_start_matches(&format!("{}: ", file.display()))
                        .to_owned(),
                )
            })?;
            (w, h, pixels)
        }
        "hdr" => read_hdr(file).map_err(read)?,
        _ => {
            return Err(EnvironmentError::Format {
                file: file.to_owned(),
            });
        }
    };
    let mut image = EnvImage {
        width,
        height,
        pixels,
    };
    check_image(file, &image)?;
    if let Some(warning) = repair_pixels(file, &mut image) {
        warnings.push(warning);
    }
    Ok(image)
}

/// A Radiance `.hdr` file's size and pixels, its header's size checked against the file's
/// before any pixel is allocated.
fn read_hdr(file: &Path) -> Result<(u32, u32, Vec<Vec3>), String> {
    let file_bytes = std::fs::metadata(file).map_err(|e| e.to_string())?.len();
    let open = || -> Result<image::ImageReader<_>, String> {
        let mut reader = image::ImageReader::open(file).map_err(|e| e.to_string())?;
        reader.set_format(image::ImageFormat::Hdr);
        let mut limits = image::Limits::default();
        limits.max_image_width = Some(MAX_SIDE);
        limits.max_image_height = Some(MAX_SIDE);
        reader.limits(limits);
        Ok(reader)
    };
    let (w, h) = open()?.into_dimensions().map_err(|e| e.to_string())?;
    crate::io::check_decoded_size(
        w as u64,
        h as u64,
        file_bytes,
        crate::io::MAX_PIXELS_PER_FILE_BYTE,
    )?;
    let rgb = open()?.decode().map_err(|e| e.to_string())?.to_rgb32f();
    let (w, h) = rgb.dimensions();
    Ok((w, h, rgb.pixels().map(|p| Vec3::from(p.0)).collect()))
}

/// An image is usable when it has pixels and a sane size.
pub fn check_image(file: &Path, image: &EnvImage) -> Result<(), EnvironmentError> {
    let (w, h) = (image.width, image.height);
    if w < 2
        || h < 1
        || w > MAX_SIDE
        || h > MAX_SIDE
        || image.pixels.len() != (w as usize) * (h as usize)
    {
        return Err(EnvironmentError::Size {
            file: file.to_owned(),
            width: w,
            height: h,
        });
    }
    Ok(())
}

/// Sets every channel that is negative or not finite to 0 (radiance is never negative; a
/// NaN or infinite pixel would make every pixel's sampling weight meaningless) and says so in
/// one line naming the file, how many pixels changed and the worst value, if any did.
pub fn repair_pixels(file: &Path, image: &mut EnvImage) -> Option<String> {
    let mut changed = 0usize;
    let mut lowest = 0.0f32;
    let mut not_finite = 0usize;
    for p in &mut image.pixels {
        if p.is_finite() && p.min_element() >= 0.0 {
            continue;
        }
        changed += 1;
        for c in p.as_mut() {
            if !c.is_finite() {
                not_finite += 1;
                *c = 0.0;
            } else if *c < 0.0 {
                lowest = lowest.min(*c);
                *c = 0.0;
            }
        }
    }
    (changed > 0).then(|| {
        let worst = match (lowest < 0.0, not_finite > 0) {
            (true, true) => {
                format!("the lowest {lowest}, and {not_finite} channels NaN or infinite")
            }
            (true, false) => format!("the lowest {lowest}"),
            _ => format!("{not_finite} channels NaN or infinite"),
        };
        format!(
            "{}: {changed} of the environment image's {} pixels were negative or not finite \
             ({worst}); they are read as 0",
            file.display(),
            image.pixels.len()
        )
    })
}

/// `R,G,B` (three non-negative numbers) as a colour, if the text is one; numbers separated
/// by commas that are not three (`1,2`) are a colour given wrong, not a file name.
pub fn parse_colour(text: &str) -> Option<Result<Vec3, EnvironmentError>> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if parts.len() < 2 || !parts.iter().all(|p| p.parse::<f32>().is_ok()) {
        return None;
    }
    if parts.len() != 3 {
        return Some(Err(EnvironmentError::BadColour(text.to_owned())));
    }
    let c: Vec<f32> = parts.iter().filter_map(|p| p.parse().ok()).collect();
    let colour = Vec3::new(c[0], c[1], c[2]);
    Some(if colour.is_finite() && colour.min_element() >= 0.0 {
        Ok(colour)
    } else {
        Err(EnvironmentError::BadColour(text.to_owned()))
    })
}

/// The map a `--environment` argument or a scene's `"environment"` string names: `R,G,B` or
/// an image file, resolved against `base` (the glTF's folder) when relative.
pub fn map_from_text(
    text: &str,
    base: Option<&Path>,
    warnings: &mut Vec<String>,
) -> Result<EnvMap, EnvironmentError> {
    if let Some(colour) = parse_colour(text) {
        return colour.map(EnvMap::Constant);
    }
    let path = resolve(text, base);
    let image = load_image(&path, warnings)?;
    Ok(EnvMap::Image {
        file: Some(path),
        image: Arc::new(image),
    })
}

/// `file` relative to `base` (the glTF's folder), unless it is absolute.
pub fn resolve(file: &str, base: Option<&Path>) -> PathBuf {
    let path = Path::new(file);
    match base {
        Some(base) if path.is_relative() => base.join(path),
        _ => path.to_owned(),
    }
}

/// Checks a strength (≥ 0) and a rotation (finite).
pub fn check_numbers(strength: f32, rotation_degrees: f32) -> Result<(), EnvironmentError> {
    if !(strength.is_finite() && strength >= 0.0) {
        return Err(EnvironmentError::BadNumber {
            what: "strength",
            value: strength,
            range: " ≥ 0",
        });
    }
    if !rotation_degrees.is_finite() {
        return Err(EnvironmentError::BadNumber {
            what: "rotation",
            value: rotation_degrees,
            range: "",
        });
    }
    Ok(())
}

/// A `.hdr` (Radiance RGBE) file of `image`.
pub fn hdr_bytes(image: &EnvImage) -> Result<Vec<u8>, String> {
    let rgb: Vec<image::Rgb<f32>> = image
        .pixels
        .iter()
        .map(|p| image::Rgb(p.to_array()))
        .collect();
    let mut bytes = Vec::new();
    image::codecs::hdr::HdrEncoder::new(&mut bytes)
        .encode(&rgb, image.width as usize, image.height as usize)
        .map_err(|e| e.to_string())?;
    Ok(bytes)
}

/// The bytes of `image` as a file of `path`'s kind (`.hdr` or `.exr`; EXR keeps f32 exactly).
pub fn image_bytes(path: &Path, image: &EnvImage) -> Result<Vec<u8>, String> {
    let is_hdr = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("hdr"));
    if is_hdr {
        hdr_bytes(image)
    } else {
        crate::io::exr_bytes(image.width, image.height, &image.pixels)
    }
}

/// What the command line's `--environment FILE|R,G,B`, `--environment-strength S`,
/// `--environment-rotation DEG` and `--environment-interpolation linear|closest` (of `render`,
/// `compare` and `view`) replace in a scene's
/// environment; each `None` keeps the scene's.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct EnvironmentOverrides {
    /// `R,G,B` or an image file, relative to the working folder.
    pub source: Option<String>,
    pub strength: Option<f32>,
    pub rotation_degrees: Option<f32>,
    pub interpolation: Option<Interpolation>,
}

impl EnvironmentOverrides {
    /// Whether nothing is replaced.
    pub fn is_empty(&self) -> bool {
        self.source.is_none()
            && self.strength.is_none()
            && self.rotation_degrees.is_none()
            && self.interpolation.is_none()
    }

    /// `current` with these replacements (see [`with_overrides`]).
    pub fn apply(
        &self,
        current: Option<&EnvironmentDesc>,
        warnings: &mut Vec<String>,
    ) -> Result<Option<EnvironmentDesc>, EnvironmentError> {
        with_overrides(
            current,
            self.source.as_deref(),
            self.strength,
            self.rotation_degrees,
            self.interpolation,
            warnings,
        )
    }
}

/// The environment after command-line overrides: `source` (`R,G,B` or an image file, relative
/// to the working folder) replaces the scene's map, `strength` and `rotation_degrees` its
/// numbers. Without a map from either, numbers alone are an error.
pub fn with_overrides(
    current: Option<&EnvironmentDesc>,
    source: Option<&str>,
    strength: Option<f32>,
    rotation_degrees: Option<f32>,
    interpolation: Option<Interpolation>,
    warnings: &mut Vec<String>,
) -> Result<Option<EnvironmentDesc>, EnvironmentError> {
    let map = match source {
        Some(text) => Some(map_from_text(text, None, warnings)?),
        None => current.map(|c| c.map.clone()),
    };
    let Some(map) = map else {
        return match (strength, rotation_degrees, interpolation) {
            (None, None, None) => Ok(None),
            _ => Err(EnvironmentError::NoMap),
        };
    };
    let strength = strength.unwrap_or(current.map_or(1.0, |c| c.strength));
    let rotation_degrees = rotation_degrees.unwrap_or(current.map_or(0.0, |c| c.rotation_degrees));
    let interpolation =
        interpolation.unwrap_or(current.map_or_else(Default::default, |c| c.interpolation));
    check_numbers(strength, rotation_degrees)?;
    Ok(Some(EnvironmentDesc {
        map,
        strength,
        rotation_degrees,
        interpolation,
    }))
}
