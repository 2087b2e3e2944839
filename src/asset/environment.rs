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

/// The environment of a scene: radiance = map × strength, the map turned by `rotation_degrees`
/// about +Y (counter-clockwise seen from above).
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentDesc {
    pub map: EnvMap,
    pub strength: f32,
    pub rotation_degrees: f32,
}

impl EnvironmentDesc {
    pub fn constant(radiance: Vec3) -> Self {
        EnvironmentDesc {
            map: EnvMap::Constant(radiance),
            strength: 1.0,
            rotation_degrees: 0.0,
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
    #[error("{}: the environment image has a pixel that is negative or not finite at \
             ({x}, {y})", file.display())]
    BadPixel { file: PathBuf, x: u32, y: u32 },
    #[error("{}: environment files must be .hdr (Radiance RGBE) or .exr", file.display())]
    Format { file: PathBuf },
    #[error("environment colour '{0}': expected three non-negative numbers R,G,B")]
    BadColour(String),
    #[error(
        "an environment strength or rotation was given, but no environment (give one with \
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

/// Reads an equirectangular `.hdr` or `.exr` image.
pub fn load_image(file: &Path) -> Result<EnvImage, EnvironmentError> {
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
        "hdr" => {
            let mut reader = image::ImageReader::open(file).map_err(|e| read(e.to_string()))?;
            reader.set_format(image::ImageFormat::Hdr);
            let decoded = reader.decode().map_err(|e| read(e.to_string()))?;
            let rgb = decoded.to_rgb32f();
            let (w, h) = rgb.dimensions();
            let pixels = rgb.pixels().map(|p| Vec3::from(p.0)).collect();
            (w, h, pixels)
        }
        _ => {
            return Err(EnvironmentError::Format {
                file: file.to_owned(),
            });
        }
    };
    let image = EnvImage {
        width,
        height,
        pixels,
    };
    check_image(file, &image)?;
    Ok(image)
}

/// An image is usable when it has pixels, a sane size and finite non-negative radiance.
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
    if let Some(k) = image
        .pixels
        .iter()
        .position(|p| !p.is_finite() || p.min_element() < 0.0)
    {
        return Err(EnvironmentError::BadPixel {
            file: file.to_owned(),
            x: k as u32 % w,
            y: k as u32 / w,
        });
    }
    Ok(())
}

/// `R,G,B` (three non-negative numbers) as a colour, if the text is one.
pub fn parse_colour(text: &str) -> Option<Result<Vec3, EnvironmentError>> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if parts.len() != 3 || !parts.iter().all(|p| p.parse::<f32>().is_ok()) {
        return None;
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
pub fn map_from_text(text: &str, base: Option<&Path>) -> Result<EnvMap, EnvironmentError> {
    if let Some(colour) = parse_colour(text) {
        return colour.map(EnvMap::Constant);
    }
    let path = resolve(text, base);
    let image = load_image(&path)?;
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

/// What the command line's `--environment FILE|R,G,B`, `--environment-strength S` and
/// `--environment-rotation DEG` (of `render`, `compare` and `view`) replace in a scene's
/// environment; each `None` keeps the scene's.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct EnvironmentOverrides {
    /// `R,G,B` or an image file, relative to the working folder.
    pub source: Option<String>,
    pub strength: Option<f32>,
    pub rotation_degrees: Option<f32>,
}

impl EnvironmentOverrides {
    /// Whether nothing is replaced.
    pub fn is_empty(&self) -> bool {
        self.source.is_none() && self.strength.is_none() && self.rotation_degrees.is_none()
    }

    /// `current` with these replacements (see [`with_overrides`]).
    pub fn apply(
        &self,
        current: Option<&EnvironmentDesc>,
    ) -> Result<Option<EnvironmentDesc>, EnvironmentError> {
        with_overrides(
            current,
            self.source.as_deref(),
            self.strength,
            self.rotation_degrees,
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
) -> Result<Option<EnvironmentDesc>, EnvironmentError> {
    let map = match source {
        Some(text) => Some(map_from_text(text, None)?),
        None => current.map(|c| c.map.clone()),
    };
    let Some(map) = map else {
        return match (strength, rotation_degrees) {
            (None, None) => Ok(None),
            _ => Err(EnvironmentError::NoMap),
        };
    };
    let strength = strength.unwrap_or(current.map_or(1.0, |c| c.strength));
    let rotation_degrees = rotation_degrees.unwrap_or(current.map_or(0.0, |c| c.rotation_degrees));
    check_numbers(strength, rotation_degrees)?;
    Ok(Some(EnvironmentDesc {
        map,
        strength,
        rotation_degrees,
    }))
}
