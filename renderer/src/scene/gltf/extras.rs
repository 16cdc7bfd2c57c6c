//! What our renderer reads from glTF `extras`: a material's surface model (a BSDF kind or a
//! [`Binding`]) and the scene's environment.

use super::*;

/// Parses an `extras` object, or `None` when there are no extras.
pub(super) fn extras_object(extras: &::gltf::json::Extras) -> Option<serde_json::Map<String, Value>> {
    let raw = extras.as_ref()?;
    match serde_json::from_str(raw.get()) {
        Ok(Value::Object(map)) => Some(map),
        _ => None,
    }
}

/// The surface model a material's extras ask for (see the module documentation).
pub(super) fn surface_model(
    extras: &::gltf::json::Extras,
    material: &str,
    base: &Path,
) -> Result<SurfaceModel, String> {
    let Some(map) = extras_object(extras) else {
        return Ok(SurfaceModel::MetallicRoughness);
    };
    let keys: Vec<&str> = ["bsdf", "brdf", "neural"]
        .into_iter()
        .filter(|k| map.contains_key(*k))
        .collect();
    if keys.len() > 1 {
        return Err(format!(
            "material '{material}' extras give more than one of {}",
            keys.join(", ")
        ));
    }
    let string = |key: &str| -> Result<&str, String> {
        map[key]
            .as_str()
            .ok_or_else(|| format!("material '{material}' extras: '{key}' must be a string"))
    };
    match keys.first().copied() {
        Some("bsdf") => match string("bsdf")? {
            "diffuse" => Ok(SurfaceModel::Lambert),
            "metallic-roughness" => Ok(SurfaceModel::MetallicRoughness),
            other => Err(format!(
                "material '{material}' extras: unknown bsdf '{other}' (expected diffuse or metallic-roughness)"
            )),
        },
        Some("brdf") => {
            let text = string("brdf")?;
            if text.is_empty() {
                return Err(format!("material '{material}' extras: 'brdf' is empty"));
            }
            Binding::parse(text, base)
                .map(SurfaceModel::Bound)
                .map_err(|e| format!("material '{material}' extras: {e}"))
        }
        Some("neural") => {
            let name = string("neural")?;
            if name.is_empty() {
                return Err(format!("material '{material}' extras: 'neural' is empty"));
            }
            Ok(SurfaceModel::Bound(Binding::Neural(name.to_string())))
        }
        _ => Ok(SurfaceModel::MetallicRoughness),
    }
}

/// The environment named in `extras` (see [`EnvironmentSpec`]), `None` when there is none.
pub(super) fn environment_from_extras(
    extras: &::gltf::json::Extras,
    path: &Path,
    base: &Path,
) -> Result<Option<EnvironmentSpec>> {
    let Some(map) = extras_object(extras) else {
        return Ok(None);
    };
    let Some(env) = map.get("environment") else {
        return Ok(None);
    };
    let bad = |reason: &str| Error::invalid_file(path, format!("extras.environment: {reason}"));
    let env = env.as_object().ok_or_else(|| bad("must be an object"))?;
    let number = |key: &str, default: f32| -> Result<f32> {
        match env.get(key) {
            None => Ok(default),
            Some(v) => v
                .as_f64()
                .map(|x| x as f32)
                .filter(|x| x.is_finite())
                .ok_or_else(|| bad(&format!("'{key}' must be a number"))),
        }
    };
    let strength = number("strength", 1.0)?;
    if strength < 0.0 {
        return Err(bad("'strength' must not be negative"));
    }
    let rotation = number("rotation_degrees", 0.0)?.to_radians();
    let source = match (env.get("image"), env.get("color")) {
        (Some(image), None) => {
            let image = image
                .as_str()
                .filter(|s| !s.is_empty())
                .ok_or_else(|| bad("'image' must be a file name"))?;
            EnvironmentSource::Image(base.join(image))
        }
        (None, Some(color)) => {
            let rgb: Vec<f32> = color
                .as_array()
                .map(|a| {
                    a.iter()
                        .filter_map(Value::as_f64)
                        .map(|x| x as f32)
                        .collect()
                })
                .unwrap_or_default();
            match rgb[..] {
                [r, g, b] if rgb.iter().all(|c| c.is_finite() && *c >= 0.0) => {
                    EnvironmentSource::Constant(Rgb::new(r, g, b))
                }
                _ => return Err(bad("'color' must be three non-negative numbers")),
            }
        }
        (Some(_), Some(_)) => return Err(bad("give either 'image' or 'color', not both")),
        (None, None) => return Err(bad("needs 'image' or 'color'")),
    };
    Ok(Some(EnvironmentSpec {
        source,
        strength,
        rotation,
    }))
}
