//! `portalview export`: a built-in scene as `.glb`.

use anyhow::{Context, Result};

use crate::asset::{builtin, gltf};
use crate::scene::Scene;

pub fn run(name: &str, out: &std::path::Path) -> Result<()> {
    let desc = builtin::desc(name).with_context(|| {
        format!(
            "unknown built-in scene '{name}' (built-ins: {})",
            builtin::NAMES.join(", ")
        )
    })?;
    let glb = out
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("glb"));
    anyhow::ensure!(
        glb,
        "{}: export writes a binary glTF: name it .glb",
        out.display()
    );
    // Validate before writing, so an export always loads back.
    Scene::from_desc(desc.clone(), name)?;
    gltf::export_glb(&desc, out)?;
    println!("wrote {}", out.display());
    Ok(())
}
