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
    // Validate before writing, so an export always loads back.
    Scene::from_desc(desc.clone(), name)?;
    gltf::export_glb(&desc, out)?;
    println!("wrote {}", out.display());
    Ok(())
}
