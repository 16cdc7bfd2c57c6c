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

impl Loader<'_> {
    /// The surface model a material's extras ask for (see the module documentation); errors
    /// name the material.
    pub(super) fn surface_model(&mut self, document: &Document, extras: &::gltf::json::Extras, material: &str) -> Result<SurfaceModel> {
        let Some(map) = extras_object(extras) else {
            return Ok(SurfaceModel::MetallicRoughness);
        };
        let path = self.path;
        let bad = |reason: String| Error::invalid_file(path, format!("material '{material}' extras: {reason}"));
        let keys: Vec<&str> = ["bsdf", "brdf", "neural"].into_iter().filter(|k| map.contains_key(*k)).collect();
        if keys.len() > 1 {
            return Err(bad(format!("give only one of {}", keys.join(", "))));
        }
        let string = |key: &str| -> Result<&str> {
            match map[key].as_str() {
                Some("") => Err(bad(format!("'{key}' is empty"))),
                Some(s) => Ok(s),
                None => Err(bad(format!("'{key}' must be a string"))),
            }
        };
        match keys.first().copied() {
            Some("bsdf") => match string("bsdf")? {
                "diffuse" => Ok(SurfaceModel::Lambert),
                "metallic-roughness" => Ok(SurfaceModel::MetallicRoughness),
                other => Err(bad(format!("unknown bsdf '{other}' (expected diffuse or metallic-roughness)"))),
            },
            Some("brdf") => Binding::parse(string("brdf")?, self.base).map(SurfaceModel::Bound).map_err(|e| bad(e.to_string())),
            Some("neural") if map["neural"].is_object() => self.varying(document, &map["neural"], material).map(SurfaceModel::Varying),
            Some("neural") => Ok(SurfaceModel::Bound(Binding::Neural(string("neural")?.to_string()))),
            _ => Ok(SurfaceModel::MetallicRoughness),
        }
    }

    /// A `neural` object of a material's extras (the module documentation's forms).
    fn varying(&mut self, document: &Document, object: &Value, material: &str) -> Result<Varying> {
        const FORMS: &str = r#"{"code": NAME}, {"mix": [NAME, ...], "weights": TEXTURE} or {"blend": [A, B], "t": TEXTURE, "channel": 0-3}, each with an optional "tint": TEXTURE"#;
        let (path, base) = (self.path, self.base);
        let bad = |reason: String| Error::invalid_file(path, format!("material '{material}' extras: neural {reason}"));
        let map = object.as_object().expect("an object");
        let forms: Vec<&str> = ["code", "mix", "blend"].into_iter().filter(|k| map.contains_key(*k)).collect();
        let allowed: &[&str] = match forms[..] {
            ["code"] => &["code", "tint"],
            ["mix"] => &["mix", "weights", "tint"],
            ["blend"] => &["blend", "t", "channel", "tint"],
            _ => return Err(bad(format!("must be one of {FORMS}"))),
        };
        if let Some(key) = map.keys().find(|k| !allowed.contains(&k.as_str())) {
            return Err(bad(format!("has an unknown key '{key}' (the {} form takes {})", forms[0], allowed.join(", "))));
        }
        let binding = |value: &Value| -> Result<Binding> {
            match value.as_str() {
                Some("") | None => Err(bad(format!("names {value}, not a latent code or binding"))),
                Some(text) if text.contains(':') => Binding::parse(text, base).map_err(|e| bad(e.to_string())),
                Some(name) => Ok(Binding::Neural(name.to_string())),
            }
        };
        let names = |key: &str, range: std::ops::RangeInclusive<usize>| -> Result<Vec<Binding>> {
            let list = map[key].as_array().ok_or_else(|| bad(format!("'{key}' must be a list of codes")))?;
            if !range.contains(&list.len()) {
                return Err(bad(format!("'{key}' lists {} codes ({} to {} allowed)", list.len(), range.start(), range.end())));
            }
            list.iter().map(binding).collect()
        };
        let mut texture = |key: &str, encoding: Encoding| -> Result<TextureRef> {
            self.json_texture(document, object, key, encoding, material, &format!("neural {key}"))?
                .ok_or_else(|| Error::invalid_file(path, format!("material '{material}' extras: neural {key} is missing (a textureInfo object {{\"index\": i}})")))
        };
        let form = match forms[0] {
            "code" => VaryingForm::One(binding(&map["code"])?),
            "mix" => {
                let parts = names("mix", 2..=MAX_MIX_PARTS)?;
                VaryingForm::Mix { parts, weights: texture("weights", Encoding::Linear)? }
            }
            _ => {
                let ends = names("blend", 2..=2)?;
                let ends: Vec<String> = ends
                    .iter()
                    .map(|b| match b {
                        Binding::Neural(name) => Ok(name.clone()),
                        other => Err(bad(format!("blend interpolates latent codes, not {other} (mix tables or networks with \"mix\")"))),
                    })
                    .collect::<Result<_>>()?;
                let channel = match map.get("channel") {
                    None => 0,
                    Some(v) => v.as_u64().filter(|c| *c < 4).ok_or_else(|| bad(format!("channel {v} is out of range (0-3: R, G, B, A)")))? as usize,
                };
                VaryingForm::Blend { ends: [ends[0].clone(), ends[1].clone()], t: texture("t", Encoding::Linear)?, channel }
            }
        };
        let tint = match map.contains_key("tint") {
            true => Some(texture("tint", Encoding::Srgb)?),
            false => None,
        };
        Ok(Varying { form, tint })
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
