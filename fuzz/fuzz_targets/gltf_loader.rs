//! Feeds arbitrary bytes to the glTF loader as a `.glb` and as a `.gltf` (beside an external
//! `input.bin`, the BIN chunk of assets/lampshade.glb), then builds a renderable `Scene` from
//! whatever loads. A crash is: a panic (including one the loader caught and reported as an
//! internal error), an error that does not name the file, a timeout or running out of memory.
#![no_main]

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;
use portalview::asset::gltf::{GltfError, load_gltf};
use portalview::scene::Scene;

const LAMPSHADE: &[u8] = include_bytes!("../../assets/lampshade.glb");

/// The BIN chunk of a GLB file (the second chunk), for the external `.bin` of `.gltf` inputs.
fn bin_chunk(glb: &[u8]) -> &[u8] {
    let u32_at = |at: usize| {
        glb.get(at..at + 4)
            .and_then(|b| b.try_into().ok())
            .map_or(0, |b| u32::from_le_bytes(b) as usize)
    };
    let bin_header = 20 + u32_at(12);
    glb.get(bin_header + 8..bin_header + 8 + u32_at(bin_header))
        .unwrap_or_default()
}

/// A directory of this process's own, holding `input.bin`.
fn work_dir() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("portalview-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("create the fuzz work directory");
        std::fs::write(dir.join("input.bin"), bin_chunk(LAMPSHADE)).expect("write input.bin");
        dir
    })
}

fn check(path: &Path, data: &[u8]) {
    std::fs::write(path, data).expect("write the input file");
    let name = path.display().to_string();
    match load_gltf(path) {
        Ok(desc) => {
            if let Err(e) = Scene::from_desc(desc, &name) {
                let message = e.to_string();
                assert!(
                    message.contains(&name),
                    "scene error without the file: {message}"
                );
            }
        }
        Err(e @ GltfError::Internal { .. }) => panic!("the loader caught a panic: {e}"),
        Err(e) => {
            let message = e.to_string();
            assert!(
                message.contains(&name),
                "loader error without the file: {message}"
            );
        }
    }
}

fuzz_target!(|data: &[u8]| {
    let dir = work_dir();
    check(&dir.join("input.glb"), data);
    check(&dir.join("input.gltf"), data);
});
