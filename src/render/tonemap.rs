//! From linear radiance to display: exposure, sRGB encoding, a false-colour scale, and the
//! image files the CLI writes.

use glam::Vec3;
use std::path::Path;

/// Linear radiance times `2^exposure`, clamped and sRGB-encoded to 8 bits.
pub fn to_srgb8(c: Vec3, exposure: f32) -> [u8; 3] {
    let c = c * exposure.exp2();
    [c.x, c.y, c.z].map(srgb8)
}

/// Entries of the sRGB table, indexed by the square root of the linear value so that dark
/// values, where 8-bit sRGB steps are finest, get the most entries.
const SRGB_TABLE_SIZE: usize = 4096;

/// 8-bit sRGB of a linear value, from a table (a `powf` per channel per pixel made uploading a
/// frame the slowest thing the viewer does).
fn srgb8(v: f32) -> u8 {
    static TABLE: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    let table = TABLE.get_or_init(|| {
        (0..SRGB_TABLE_SIZE)
            .map(|i| {
                let u = i as f32 / (SRGB_TABLE_SIZE - 1) as f32;
                (encode_srgb(u * u) * 255.0 + 0.5) as u8
            })
            .collect()
    });
    let u = v.clamp(0.0, 1.0).sqrt();
    table[(u * (SRGB_TABLE_SIZE - 1) as f32 + 0.5) as usize]
}

fn encode_srgb(v: f32) -> f32 {
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// A perceptual blue–green–yellow–red ramp for `t` in [0, 1] (for luminance and error maps).
pub fn false_colour(t: f32) -> [u8; 3] {
    const STOPS: [[f32; 3]; 5] = [
        [0.05, 0.03, 0.25],
        [0.1, 0.35, 0.75],
        [0.15, 0.7, 0.45],
        [0.95, 0.85, 0.2],
        [0.85, 0.15, 0.1],
    ];
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    } * (STOPS.len() - 1) as f32;
    let i = (t.floor() as usize).min(STOPS.len() - 2);
    let f = t - i as f32;
    let (a, b) = (STOPS[i], STOPS[i + 1]);
    [0, 1, 2].map(|k| ((a[k] + (b[k] - a[k]) * f) * 255.0 + 0.5) as u8)
}

/// The image types [`write_image`] encodes.
enum ImageKind {
    Exr,
    Png,
}

/// The type of image `path` names by its extension, or an error naming the file.
fn image_kind(path: &Path) -> anyhow::Result<ImageKind> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("exr") => Ok(ImageKind::Exr),
        Some("png") => Ok(ImageKind::Png),
        _ => anyhow::bail!(
            "{}: unknown image type (use .exr for linear radiance or .png)",
            path.display()
        ),
    }
}

/// Whether an image can be written to `path`, before anything is rendered for it: its
/// extension is one [`write_image`] encodes, and its folder exists.
pub fn check_image_path(path: &Path) -> anyhow::Result<()> {
    image_kind(path)?;
    let folder = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !folder.is_dir() {
        anyhow::bail!(
            "{}: the folder {} does not exist",
            path.display(),
            folder.display()
        );
    }
    Ok(())
}

/// Writes `pixels` (row-major, linear radiance) to `.exr` (linear, 32-bit float) or `.png`
/// (tone-mapped sRGB), by the file's extension, atomically.
pub fn write_image(
    path: &Path,
    width: u32,
    height: u32,
    pixels: &[Vec3],
    exposure: f32,
) -> anyhow::Result<()> {
    let bytes = match image_kind(path)? {
        ImageKind::Exr => crate::io::exr_bytes(width, height, pixels)
            .map_err(|e| anyhow::anyhow!("{}: cannot encode EXR: {e}", path.display()))?,
        ImageKind::Png => {
            let rgb8: Vec<u8> = pixels.iter().flat_map(|&c| to_srgb8(c, exposure)).collect();
            crate::io::png_bytes(width, height, &rgb8)
                .map_err(|e| anyhow::anyhow!("{}: cannot encode PNG: {e}", path.display()))?
        }
    };
    crate::io::write_atomic(path, &bytes)
        .map_err(|e| anyhow::anyhow!("{}: cannot write: {e}", path.display()))
}

#[cfg(test)]
mod tests {
    #[test]
    fn image_paths_are_checked_before_rendering() {
        let dir = std::env::temp_dir();
        assert!(super::check_image_path(&dir.join("a.exr")).is_ok());
        assert!(super::check_image_path(&dir.join("a.PNG")).is_ok());
        let jpg = super::check_image_path(&dir.join("a.jpg")).unwrap_err();
        assert!(jpg.to_string().contains("unknown image type"), "{jpg}");
        let missing = dir.join("portalview-no-such-folder").join("a.exr");
        let error = super::check_image_path(&missing).unwrap_err().to_string();
        assert!(error.contains("does not exist"), "{error}");
    }

    #[test]
    fn table_matches_the_formula_within_one_level() {
        for i in 0..=10_000 {
            let v = i as f32 / 10_000.0;
            let exact = (super::encode_srgb(v) * 255.0 + 0.5) as i32;
            assert!((super::srgb8(v) as i32 - exact).abs() <= 1, "{v}");
        }
    }
}
