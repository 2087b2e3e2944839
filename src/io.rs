//! Files: the one atomic write every writer uses, and linear EXR / sRGB PNG encoding; and the
//! message of a caught panic, for reporting it as an error.

use std::fs;
use std::io::{Cursor, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use glam::Vec3;

/// Writes `bytes` to a uniquely named temporary file in `path`'s folder, flushes it to disk and
/// renames it over `path`: readers see the old file or the new one, never half of one, and two
/// writers never share a temporary file. An existing file's permissions are kept.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let temporary = temporary_sibling(path)?;
    let written = fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&temporary)
        .and_then(|mut f| {
            f.write_all(bytes)?;
            if let Ok(old) = fs::metadata(path) {
                f.set_permissions(old.permissions())?;
            }
            f.sync_all()
        })
        .and_then(|()| fs::rename(&temporary, path));
    if written.is_err() {
        // Best effort: the write error is the one worth reporting.
        let _ = fs::remove_file(&temporary);
    }
    written
}

/// `dir/.name.<pid>-<n>.tmp`, unique within this process and across processes.
fn temporary_sibling(path: &Path) -> std::io::Result<PathBuf> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let Some(name) = path.file_name() else {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "the path names no file",
        ));
    };
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    Ok(dir.join(format!(
        ".{}.{}-{}.tmp",
        name.to_string_lossy(),
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    )))
}

/// A linear RGB image as a 32-bit float OpenEXR file.
pub fn exr_bytes(width: u32, height: u32, pixels: &[Vec3]) -> Result<Vec<u8>, String> {
    use exr::prelude::*;
    let (w, h) = (width as usize, height as usize);
    if pixels.len() != w * h {
        return Err(format!("{} pixels for a {w}×{h} image", pixels.len()));
    }
    let channels = SpecificChannels::rgb(|p: Vec2<usize>| {
        let c = pixels[p.y() * w + p.x()];
        (c.x, c.y, c.z)
    });
    // Blocks in increasing order: the writer compresses them in parallel and would otherwise
    // store them as they finish, so one image could give files that differ byte for byte.
    let encoding = Encoding {
        line_order: LineOrder::Increasing,
        ..Encoding::default()
    };
    let mut bytes = Cursor::new(Vec::new());
    Image::from_encoded_channels((w, h), encoding, channels)
        .write()
        .to_buffered(&mut bytes)
        .map_err(|e| e.to_string())?;
    Ok(bytes.into_inner())
}

/// 8-bit sRGB pixels (3 bytes each) as a PNG file.
pub fn png_bytes(width: u32, height: u32, rgb8: &[u8]) -> Result<Vec<u8>, String> {
    let mut bytes = Cursor::new(Vec::new());
    image::write_buffer_with_format(
        &mut bytes,
        rgb8,
        width,
        height,
        image::ColorType::Rgb8,
        image::ImageFormat::Png,
    )
    .map_err(|e| e.to_string())?;
    Ok(bytes.into_inner())
}

/// The most pixels an image file may decode to, whatever its size: 2^28 (a 23k × 11.5k
/// panorama, 3 GiB as f32 RGB).
pub const MAX_DECODED_PIXELS: u64 = 1 << 28;

/// The most pixels an EXR or Radiance HDR file may decode to per byte of the file. Their
/// codecs compress at most about 1000:1 (deflate's limit is 1032:1, and a pixel is at least
/// two bytes of half floats; Radiance's run-length code at most 64:1), so a real file stays far
/// below this, while a damaged header that claims a huge image in a small file is refused
/// before anything is allocated.
pub const MAX_PIXELS_PER_FILE_BYTE: u64 = 1024;

/// Whether a `width`×`height` image may be decoded from a file of `file_bytes` bytes
/// ([`MAX_DECODED_PIXELS`], and `per_byte` pixels per byte of the file); the error says why not.
pub fn check_decoded_size(
    width: u64,
    height: u64,
    file_bytes: u64,
    per_byte: u64,
) -> Result<(), String> {
    let pixels = width.saturating_mul(height);
    let bound = MAX_DECODED_PIXELS.min(file_bytes.saturating_mul(per_byte));
    if pixels > bound {
        return Err(format!(
            "its header claims {width}×{height} pixels, more than a {file_bytes}-byte file can \
             hold (at most {bound}: {per_byte} per byte of the file, {MAX_DECODED_PIXELS} in all)"
        ));
    }
    Ok(())
}

/// Reads an `.exr` as linear RGB: width, height and pixels. Errors name the file. Every layer's
/// size is checked against the file's size ([`check_decoded_size`]) before any pixel is
/// allocated.
pub fn read_exr(path: &Path) -> Result<(u32, u32, Vec<Vec3>), String> {
    use exr::prelude::*;
    let failed = |e: &dyn std::fmt::Display| format!("{}: cannot read EXR: {e}", path.display());
    let file_bytes = fs::metadata(path).map_err(|e| failed(&e))?.len();
    let meta = exr::meta::MetaData::read_from_file(path, false).map_err(|e| failed(&e))?;
    for header in &meta.headers {
        let size = header.layer_size;
        check_decoded_size(
            size.width() as u64,
            size.height() as u64,
            file_bytes,
            MAX_PIXELS_PER_FILE_BYTE,
        )
        .map_err(|e| failed(&e))?;
    }
    let image = read_first_rgba_layer_from_file(
        path,
        |resolution, _| {
            (
                resolution.width(),
                vec![Vec3::ZERO; resolution.width() * resolution.height()],
            )
        },
        |(width, pixels), position, (r, g, b, _a): (f32, f32, f32, f32)| {
            if let Some(p) = pixels.get_mut(position.y() * *width + position.x()) {
                *p = Vec3::new(r, g, b);
            }
        },
    )
    .map_err(|e| failed(&e))?;
    let size = image.layer_data.size;
    let (_, pixels) = image.layer_data.channel_data.pixels;
    Ok((size.width() as u32, size.height() as u32, pixels))
}

/// A caught panic's message, for showing to the user.
pub fn panic_message(panic: &(dyn std::any::Any + Send)) -> String {
    panic
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn atomic_writes_replace_and_leave_no_temporary() {
        let dir = std::env::temp_dir().join(format!("portalview-io-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a.txt");
        write_atomic(&path, b"one").unwrap();
        write_atomic(&path, b"two").unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"two");
        let names: Vec<_> = fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 1, "{names:?}");
        assert!(write_atomic(&dir.join("missing").join("b.txt"), b"x").is_err());
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn exr_round_trips() {
        let dir = std::env::temp_dir().join(format!("portalview-exr-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let path = dir.join("i.exr");
        let pixels: Vec<Vec3> = (0..6).map(|i| Vec3::new(i as f32, 0.5, 1e-3)).collect();
        write_atomic(&path, &exr_bytes(3, 2, &pixels).unwrap()).unwrap();
        assert_eq!(read_exr(&path).unwrap(), (3, 2, pixels));
        assert!(exr_bytes(3, 3, &[Vec3::ZERO]).is_err());
        fs::remove_dir_all(&dir).unwrap();
    }

    /// 128 blocks, compressed in parallel: the same pixels must give the same file (with the
    /// writer's default, unspecified block order, this failed).
    #[test]
    fn exr_files_are_reproducible() {
        let (w, h) = (1024, 512);
        let pixels: Vec<Vec3> = (0..w * h)
            .map(|i| Vec3::new(i as f32, (i % 7) as f32, (i * 31 % 1000) as f32 / 3.0))
            .collect();
        let first = exr_bytes(w, h, &pixels).unwrap();
        for _ in 0..16 {
            assert_eq!(exr_bytes(w, h, &pixels).unwrap(), first);
        }
    }
}
