//! `KHR_lights_punctual` lamps: read from the nodes that carry one, written back as such.
//!
//! A lamp sits at its node's world position and points down its node's local −Z. Values are
//! kept in the extension's units (candela, lux); `light::punctual` converts them.

use super::*;
use crate::asset::desc::{LampDesc, LampKind};
use json::extensions::scene::khr_lights_punctual as punctual;

/// The extension's name, in `extensionsUsed` when lamps are written.
pub(super) const LIGHTS_EXTENSION: &str = "KHR_lights_punctual";

/// The lamp on node `index`, if it carries one; `world` is the node's world transform.
pub(super) fn node_lamp(
    file: &Path,
    root: &json::Root,
    index: usize,
    node: &json::Node,
    world: Mat4,
    at: &str,
) -> Result<Option<LampDesc>, GltfError> {
    let Some(reference) = node
        .extensions
        .as_ref()
        .and_then(|e| e.khr_lights_punctual.as_ref())
    else {
        return Ok(None);
    };
    let light_index = reference.light.value();
    let at = format!("{at}, KHR_lights_punctual light {light_index}");
    let Some(light) = root.get(reference.light) else {
        return Err(invalid(file, at, "does not exist"));
    };
    let bad = |what: &str, reason: String| invalid(file, format!("{at}, {what}"), reason);
    let Checked::Valid(ty) = light.type_ else {
        return Err(bad("type", "is not point, spot or directional".to_owned()));
    };
    let color = Vec3::from_array(light.color);
    if !color.is_finite() || color.min_element() < 0.0 {
        return Err(bad(
            "color",
            format!("{color} must be finite and not negative"),
        ));
    }
    if !light.intensity.is_finite() || light.intensity < 0.0 {
        return Err(bad(
            "intensity",
            format!("{} must be finite and not negative", light.intensity),
        ));
    }
    if let Some(range) = light.range
        && !(range.is_finite() && range > 0.0)
    {
        return Err(bad("range", format!("{range} must be finite and positive")));
    }
    let kind = match ty {
        punctual::Type::Point => LampKind::Point,
        punctual::Type::Directional => LampKind::Directional,
        punctual::Type::Spot => {
            let Some(spot) = &light.spot else {
                return Err(bad("spot", "is missing for a spot light".to_owned()));
            };
            let (inner, outer) = (spot.inner_cone_angle, spot.outer_cone_angle);
            // Blender writes inner = outer for a spot blend of 0: a hard-edged cone.
            let valid = inner.is_finite()
                && outer.is_finite()
                && inner >= 0.0
                && outer > 0.0
                && inner <= outer
                && outer <= std::f32::consts::FRAC_PI_2;
            if !valid {
                return Err(bad(
                    "spot",
                    format!(
                        "cone angles inner {inner}, outer {outer} must satisfy \
                         0 <= inner <= outer <= π/2 and outer > 0 (radians)"
                    ),
                ));
            }
            LampKind::Spot {
                inner_cone: inner,
                outer_cone: outer,
            }
        }
    };
    let position = world.transform_point3(Vec3::ZERO);
    let direction = world.transform_vector3(Vec3::NEG_Z).normalize_or_zero();
    if !position.is_finite() || direction == Vec3::ZERO || !direction.is_finite() {
        return Err(invalid(
            file,
            at,
            "its node's world transform gives no position or direction",
        ));
    }
    Ok(Some(LampDesc {
        name: node_name(index, node),
        kind,
        color,
        intensity: light.intensity,
        range: light.range,
        position,
        direction,
    }))
}

/// Checks what `export_glb` is given, so that it never writes a lamp `load_gltf` would refuse.
pub(super) fn check_lamp(file: &Path, lamp: &LampDesc) -> Result<(), GltfError> {
    let at = format!("lamp \"{}\"", lamp.name);
    let cones_ok = match lamp.kind {
        LampKind::Spot {
            inner_cone,
            outer_cone,
        } => {
            (0.0..=outer_cone).contains(&inner_cone)
                && outer_cone > 0.0
                && outer_cone <= std::f32::consts::FRAC_PI_2
        }
        _ => true,
    };
    let problem = if lamp.name.is_empty() {
        Some("has no name")
    } else if !lamp.color.is_finite() || lamp.color.min_element() < 0.0 {
        Some("colour is negative or not finite")
    } else if !lamp.intensity.is_finite() || lamp.intensity < 0.0 {
        Some("intensity is negative or not finite")
    } else if lamp.range.is_some_and(|r| !(r.is_finite() && r > 0.0)) {
        Some("range is not finite and positive")
    } else if !cones_ok {
        Some("spot cone angles are not 0 <= inner <= outer <= π/2 with outer > 0")
    } else if !lamp.position.is_finite()
        || !lamp.direction.is_finite()
        || lamp.direction.length() < 1e-6
    {
        Some("position or direction is not finite, or the direction is zero")
    } else {
        None
    };
    match problem {
        Some(reason) => Err(invalid(file, at, reason)),
        None => Ok(()),
    }
}

/// Appends one node per lamp to `nodes` and the lamps to the document's extension.
pub(super) fn export_lamps(
    file: &Path,
    lamps: &[LampDesc],
    root: &mut json::Root,
    nodes: &mut Vec<json::Node>,
) -> Result<(), GltfError> {
    if lamps.is_empty() {
        return Ok(());
    }
    let mut lights = Vec::with_capacity(lamps.len());
    for lamp in lamps {
        check_lamp(file, lamp)?;
        let (ty, spot) = match lamp.kind {
            LampKind::Point => (punctual::Type::Point, None),
            LampKind::Directional => (punctual::Type::Directional, None),
            LampKind::Spot {
                inner_cone,
                outer_cone,
            } => (
                punctual::Type::Spot,
                Some(punctual::Spot {
                    inner_cone_angle: inner_cone,
                    outer_cone_angle: outer_cone,
                }),
            ),
        };
        let light = json_index(file, lights.len())?;
        lights.push(punctual::Light {
            color: lamp.color.to_array(),
            extensions: None,
            extras: None,
            intensity: lamp.intensity,
            name: Some(lamp.name.clone()),
            range: lamp.range,
            spot,
            type_: Checked::Valid(ty),
        });
        let rotation = Quat::from_rotation_arc(Vec3::NEG_Z, lamp.direction.normalize());
        let world = Mat4::from_rotation_translation(rotation, lamp.position);
        nodes.push(json::Node {
            name: Some(lamp.name.clone()),
            matrix: Some(world.to_cols_array()),
            extensions: Some(json::extensions::scene::Node {
                khr_lights_punctual: Some(punctual::KhrLightsPunctual { light }),
                ..Default::default()
            }),
            ..Default::default()
        });
    }
    let extensions = root.extensions.get_or_insert_with(Default::default);
    extensions.khr_lights_punctual = Some(json::extensions::root::KhrLightsPunctual { lights });
    root.extensions_used.push(LIGHTS_EXTENSION.to_owned());
    Ok(())
}
