//! The environment in a glTF scene's `extras` (where Blender writes scene custom properties):
//! `"environment"` (an image path relative to the file, or `[r, g, b]`),
//! `"environment_strength"`, `"environment_rotation"` (degrees about +Y) and
//! `"environment_interpolation"` (`"linear"`, the default, or `"closest"`).

use super::*;
use crate::asset::environment::{
    EnvImage, EnvMap, EnvironmentDesc, Interpolation, check_numbers, image_bytes, map_from_text,
};

pub const ENVIRONMENT_KEY: &str = "environment";
pub const ENVIRONMENT_STRENGTH_KEY: &str = "environment_strength";
pub const ENVIRONMENT_ROTATION_KEY: &str = "environment_rotation";
pub const ENVIRONMENT_INTERPOLATION_KEY: &str = "environment_interpolation";

/// The environment the used scene's extras describe, if they name one.
pub(super) fn scene_environment(
    file: &Path,
    root: &json::Root,
    warnings: &mut Vec<String>,
) -> Result<Option<EnvironmentDesc>, GltfError> {
    let Some(s) = used_scene(root) else {
        return Ok(None);
    };
    let Some(raw) = root.scenes.get(s).and_then(|scene| scene.extras.as_ref()) else {
        return Ok(None);
    };
    let at = format!("scene {s}, extras");
    let extras = match serde_json::from_str::<Value>(raw.get()) {
        Ok(Value::Object(map)) => map,
        Ok(_) => return Ok(None),
        Err(e) => return Err(invalid(file, at, e.to_string())),
    };
    let Some(value) = extras.get(ENVIRONMENT_KEY) else {
        return Ok(None);
    };
    let field = |key: &str| format!("{at}.{key}");
    let base = file.parent();
    let map = match value {
        Value::String(text) if !text.is_empty() => map_from_text(text, base, warnings)
            .map_err(|e| invalid(file, field(ENVIRONMENT_KEY), e.to_string()))?,
        Value::Array(items) if items.len() == 3 => {
            let c: Vec<f64> = items.iter().filter_map(Value::as_f64).collect();
            let colour = (c.len() == 3)
                .then(|| Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32))
                .filter(|c| c.is_finite() && c.min_element() >= 0.0);
            let Some(colour) = colour else {
                return Err(invalid(
                    file,
                    field(ENVIRONMENT_KEY),
                    format!("must be three non-negative numbers, found {value}"),
                ));
            };
            EnvMap::Constant(colour)
        }
        _ => {
            return Err(invalid(
                file,
                field(ENVIRONMENT_KEY),
                format!("must be an image path (.hdr or .exr) or [r, g, b], found {value}"),
            ));
        }
    };
    let number = |key: &str, default: f32| -> Result<f32, GltfError> {
        match extras.get(key) {
            None => Ok(default),
            Some(v) => v
                .as_f64()
                .map(|x| x as f32)
                .ok_or_else(|| invalid(file, field(key), format!("must be a number, found {v}"))),
        }
    };
    let strength = number(ENVIRONMENT_STRENGTH_KEY, 1.0)?;
    let rotation_degrees = number(ENVIRONMENT_ROTATION_KEY, 0.0)?;
    check_numbers(strength, rotation_degrees)
        .map_err(|e| invalid(file, at.clone(), e.to_string()))?;
    let interpolation = match extras.get(ENVIRONMENT_INTERPOLATION_KEY) {
        None => Interpolation::default(),
        Some(v) => v
            .as_str()
            .and_then(Interpolation::from_name)
            .ok_or_else(|| {
                invalid(
                    file,
                    field(ENVIRONMENT_INTERPOLATION_KEY),
                    format!("must be \"linear\" or \"closest\", found {v}"),
                )
            })?,
    };
    Ok(Some(EnvironmentDesc {
        map,
        strength,
        rotation_degrees,
        interpolation,
    }))
}

/// The scene extras for `environment`, written for the glTF file `file`. An image made in code
/// is written beside it as `<stem>_environment.hdr`; an image file is named relative to the
/// glTF's folder when it lies in or below it, else by its absolute path.
pub(super) fn environment_extras(
    file: &Path,
    environment: &EnvironmentDesc,
) -> Result<Map<String, Value>, GltfError> {
    let mut extras = Map::new();
    let value = match &environment.map {
        EnvMap::Constant(c) => Value::Array(c.to_array().into_iter().map(json_f32).collect()),
        EnvMap::Image {
            file: source,
            image,
        } => Value::from(image_reference(file, source.as_deref(), image)?),
    };
    extras.insert(ENVIRONMENT_KEY.to_owned(), value);
    extras.insert(
        ENVIRONMENT_STRENGTH_KEY.to_owned(),
        json_f32(environment.strength),
    );
    extras.insert(
        ENVIRONMENT_ROTATION_KEY.to_owned(),
        json_f32(environment.rotation_degrees),
    );
    extras.insert(
        ENVIRONMENT_INTERPOLATION_KEY.to_owned(),
        Value::from(environment.interpolation.name()),
    );
    Ok(extras)
}

/// How the glTF `file` names the environment image: its source file, relative where it can
/// be, or a newly written EXR beside the glTF.
fn image_reference(
    file: &Path,
    source: Option<&Path>,
    image: &EnvImage,
) -> Result<String, GltfError> {
    let folder = file.parent().unwrap_or(Path::new(""));
    if let Some(source) = source.filter(|s| s.exists()) {
        let absolute = |p: &Path| fs::canonicalize(p).unwrap_or_else(|_| p.to_owned());
        let (source, folder) = (absolute(source), absolute(folder));
        return Ok(match source.strip_prefix(&folder) {
            Ok(relative) => relative.to_string_lossy().replace('\\', "/"),
            Err(_) => source.to_string_lossy().into_owned(),
        });
    }
    let stem = file
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".to_owned());
    let name = format!("{stem}_environment.hdr");
    let path = folder.join(&name);
    let bytes = image_bytes(&path, image).map_err(|e| internal(&path, e))?;
    crate::io::write_atomic(&path, &bytes).map_err(|source| GltfError::Write {
        file: path.clone(),
        source,
    })?;
    Ok(name)
}

/// Sets (or, for `None`, removes) the environment keys of the used scene's extras in the glTF
/// or GLB file at `file`, changing nothing else.
pub(super) fn save_environment_inner(
    file: &Path,
    environment: Option<&EnvironmentDesc>,
) -> Result<(), GltfError> {
    let source = read_source(file)?;
    let root = parse_document(file, source.json())?;
    let mut json: Value =
        serde_json::from_slice(source.json()).map_err(|source| GltfError::Json {
            file: file.to_owned(),
            source,
        })?;
    let new = environment
        .map(|e| environment_extras(file, e))
        .transpose()?;
    let Some(s) = used_scene(&root) else {
        return Err(invalid(
            file,
            "document",
            "has no scene to hold the environment",
        ));
    };
    let scenes = json_array(file, &mut json, "scenes")?;
    let Some(scene) = scenes.get_mut(s).and_then(Value::as_object_mut) else {
        return Err(invalid(file, format!("scene {s}"), "is not a JSON object"));
    };
    let extras = scene
        .entry("extras")
        .or_insert_with(|| Value::Object(Map::new()));
    if !extras.is_object() {
        *extras = Value::Object(Map::new());
    }
    if let Some(extras) = extras.as_object_mut() {
        for key in [
            ENVIRONMENT_KEY,
            ENVIRONMENT_STRENGTH_KEY,
            ENVIRONMENT_ROTATION_KEY,
        ] {
            extras.remove(key);
        }
        if let Some(new) = new {
            extras.extend(new);
        }
    }
    rewrite_document(file, &source, &json)
}
