//! Feeds arbitrary bytes to portalview's image decoders: as an environment image (`.exr` and
//! `.hdr`, through `load_image`, which repairs negative and non-finite pixels) and as a texture
//! (PNG or JPEG, through the glTF loader's decoder). A crash is a panic, an environment error
//! that does not name the file, a timeout or running out of memory: every decoder sizes what
//! it allocates by the file's size and a documented cap before decoding.
#![no_main]

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;
use portalview::asset::environment::load_image;
use portalview::asset::gltf::decode_texture;

/// A directory of this process's own for the input files.
fn work_dir() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir =
            std::env::temp_dir().join(format!("portalview-fuzz-images-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("create the fuzz work directory");
        dir
    })
}

fuzz_target!(|data: &[u8]| {
    for name in ["input.exr", "input.hdr"] {
        let path = work_dir().join(name);
        std::fs::write(&path, data).expect("write the input file");
        let mut warnings = Vec::new();
        if let Err(e) = load_image(&path, &mut warnings) {
            let message = e.to_string();
            assert!(message.contains(&path.display().to_string()), "{message}");
        }
    }
    let _ = decode_texture(data);
});
