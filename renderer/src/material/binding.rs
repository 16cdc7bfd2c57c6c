//! Which BSDF each material of a scene gets: the one place that decides it.
//!
//! A material's surface is settled by the first of these rules that applies:
//!
//! 1. **The command line**, `render --bind MATERIAL=VALUE` ([`bind_scene`]): a VALUE with a
//!    `:` is a written [`Binding`] (`merl:`, `nbrdf:`, `neural:`; relative paths from the
//!    current directory), one without names a latent code of the latent files given
//!    (`render --material FILE`), which must hold it. It replaces whatever the scene says.
//! 2. **The scene file**: glTF material `extras` — `brdf` (a written [`Binding`], paths from
//!    the glTF file's directory), `neural` (a latent code), or `bsdf` (`diffuse`,
//!    `metallic-roughness`) — parsed where the file is read (`scene::gltf`) into the
//!    material's [`SurfaceModel`].
//! 3. **Equal names**: a material not bound by 1 or 2 whose name is that of a latent code of
//!    the latent files binds that code (the first file holding the name wins).
//! 4. **The latent-file fallback**: a material bound to a latent code while no latent file
//!    was given renders with its own glTF parameters (metallic-roughness), and
//!    [`super::SceneMaterials::unbound_neural`] names it, so the command line can say so.
//!
//! Everything else keeps the surface model it was loaded with (Lambert or
//! metallic-roughness). Rules 1 and 3 rewrite the scene description before it is prepared;
//! rule 4 is applied when it is prepared ([`surface`], called by
//! [`super::SceneMaterials::prepare`]).
//!
//! Outside a scene, for other renderers (the C and Python plugins), a material is one file
//! and [`file_binding`] says what that file binds.

use crate::neural::latent_library::LatentLibrary;
use crate::scene::{Binding, SceneDescription, SurfaceModel, Varying, VaryingForm};
use crate::{Error, Result};
use std::path::Path;

/// Applies rules 1 and 3 of the module documentation to `description`: `command_line` holds
/// the (MATERIAL, VALUE) pairs of `render --bind`, in order (a later pair for the same
/// material wins), and `latents` the latent files given. Returns the names of the materials
/// bound by equal names (rule 3).
///
/// Errors: a MATERIAL the scene lacks is [`Error::UnknownName`] listing the scene's
/// materials; a VALUE that does not parse is [`Binding::parse`]'s error; a latent name
/// without latent files is [`Error::InvalidArgument`] for `--bind`, one the files lack
/// [`Error::UnknownName`] listing their codes.
pub fn bind_scene(
    description: &mut SceneDescription,
    command_line: &[(String, String)],
    latents: &LatentLibrary,
) -> Result<Vec<String>> {
    for (material, value) in command_line {
        let Some(i) = description.materials.iter().position(|m| &m.name == material) else {
            return Err(Error::UnknownName {
                what: "material (in --bind)",
                name: material.clone(),
                available: description.materials.iter().map(|m| m.name.clone()).collect(),
            });
        };
        description.materials[i].model = SurfaceModel::Bound(command_line_binding(material, value, latents)?);
    }
    Ok(bind_equal_names(description, latents))
}

/// The binding VALUE of `--bind MATERIAL=VALUE` names (rule 1).
fn command_line_binding(material: &str, value: &str, latents: &LatentLibrary) -> Result<Binding> {
    if value.contains(':') {
        Binding::parse(value, Path::new(""))
    } else if latents.is_empty() {
        Err(Error::InvalidArgument {
            flag: "--bind".to_string(),
            reason: format!("{material}={value}: a latent name needs --material FILE"),
        })
    } else {
        latents.latent(value)?;
        Ok(Binding::Neural(value.to_string()))
    }
}

/// Rule 3: binds every material without a binding whose name is a latent name to that
/// latent; returns the names of the materials bound.
fn bind_equal_names(description: &mut SceneDescription, latents: &LatentLibrary) -> Vec<String> {
    let names = latents.names();
    let mut bound = Vec::new();
    for m in &mut description.materials {
        if !matches!(m.model, SurfaceModel::Bound(_) | SurfaceModel::Varying(_)) && names.contains(&m.name) {
            m.model = SurfaceModel::Bound(Binding::Neural(m.name.clone()));
            bound.push(m.name.clone());
        }
    }
    bound
}

/// The binding a material file names for a renderer of its own (the plugins,
/// [`super::MaterialBsdf::open`]): a MERL table (`.binary`), an NBRDF network (the prefix of
/// its six `.npy` files, or one of them), or else a latent file, whose code `name` it binds.
/// A latent file needs `name`; a table or network must not get one
/// ([`Error::InvalidArgument`] for the material name, naming the file).
pub fn file_binding(path: &Path, name: Option<&str>) -> Result<Binding> {
    let is_table = path.extension().is_some_and(|e| e == "binary");
    let is_network = path.to_string_lossy().ends_with(".npy") || crate::neural::nbrdf::tensor_paths(path)[0].is_file();
    let name_error = |reason: String| Error::InvalidArgument {
        flag: "material name".to_string(),
        reason,
    };
    match name {
        None if !is_table && !is_network => {
            Err(name_error(format!("{} is a latent file: name one of its codes", path.display())))
        }
        None if is_table => Ok(Binding::Merl(path.to_path_buf())),
        None => Ok(Binding::Nbrdf(path.to_path_buf())),
        Some(name) if !is_table && !is_network => Ok(Binding::Neural(name.to_string())),
        Some(name) => Err(name_error(format!("'{name}' given for {}, which holds one material", path.display()))),
    }
}

/// How a material of a prepared scene scatters, after every rule.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Surface<'a> {
    /// Lambertian, from the material's parameters.
    Lambert,
    /// glTF metallic-roughness, from the material's parameters.
    MetallicRoughness,
    /// The BSDF made from data that the binding names.
    Bound(&'a Binding),
    /// BSDFs made from data varied by textures.
    Varying(&'a Varying),
    /// Rule 4: bound to this latent code while no latent file was given; rendered as
    /// metallic-roughness.
    LatentWithoutFile(&'a str),
}

/// The surface of a material whose (bound) model is `model`, given the latent files
/// `latents` (rule 4).
pub(crate) fn surface<'a>(model: &'a SurfaceModel, latents: &LatentLibrary) -> Surface<'a> {
    match model {
        SurfaceModel::Lambert => Surface::Lambert,
        SurfaceModel::MetallicRoughness => Surface::MetallicRoughness,
        SurfaceModel::Bound(Binding::Neural(name)) if latents.is_empty() => Surface::LatentWithoutFile(name),
        SurfaceModel::Bound(binding) => Surface::Bound(binding),
        SurfaceModel::Varying(v) => match first_latent_name(v) {
            Some(name) if latents.is_empty() => Surface::LatentWithoutFile(name),
            _ => Surface::Varying(v),
        },
    }
}

/// The first latent code a varying material names, if any.
fn first_latent_name(v: &Varying) -> Option<&str> {
    match &v.form {
        VaryingForm::One(b) => b.latent_name(),
        VaryingForm::Mix { parts, .. } => parts.iter().find_map(Binding::latent_name),
        VaryingForm::Blend { ends, .. } => Some(ends[0].as_str()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::neural::latent_library::tests::library;
    use crate::scene::Material;

    fn scene(names: &[&str]) -> SceneDescription {
        SceneDescription {
            materials: names.iter().map(|n| Material::default_diffuse(n)).collect(),
            ..SceneDescription::default()
        }
    }

    fn pair(material: &str, value: &str) -> (String, String) {
        (material.to_string(), value.to_string())
    }

    /// The command line wins over the scene's own binding, which wins over equal names.
    #[test]
    fn command_line_over_scene_over_equal_names() {
        let (_dir, latents) = library();
        let [first, second] = [&latents.names()[0], &latents.names()[1]].map(|s| s.to_string());
        let mut description = scene(&[&first, &second, "plain"]);
        description.materials[1].model = SurfaceModel::Bound(Binding::Merl("scene.binary".into()));
        description.materials[2].model = SurfaceModel::Bound(Binding::Merl("scene.binary".into()));
        let bound = bind_scene(&mut description, &[pair("plain", &first)], &latents).unwrap();
        assert_eq!(bound, vec![first.clone()], "only the unbound material named like a code");
        let models: Vec<&SurfaceModel> = description.materials.iter().map(|m| &m.model).collect();
        assert_eq!(
            models,
            [
                &SurfaceModel::Bound(Binding::Neural(first.clone())),
                &SurfaceModel::Bound(Binding::Merl("scene.binary".into())),
                &SurfaceModel::Bound(Binding::Neural(first.clone())),
            ]
        );
    }

    #[test]
    fn bad_command_lines_name_what_is_wrong() {
        let (_dir, latents) = library();
        let msg = |binds: &[(String, String)], latents: &LatentLibrary| {
            bind_scene(&mut scene(&["preview"]), binds, latents).unwrap_err().to_string()
        };
        assert_eq!(
            msg(&[pair("preview", "gold")], &LatentLibrary::default()),
            "invalid value for --bind: preview=gold: a latent name needs --material FILE"
        );
        let m = msg(&[pair("nosuch", "merl:x.binary")], &latents);
        assert!(m.contains("material (in --bind) 'nosuch'") && m.contains("preview"), "{m}");
        let m = msg(&[pair("preview", "no-such-code")], &latents);
        assert!(m.contains("no-such-code") && m.contains(&latents.names()[0]), "{m}");
        let m = msg(&[pair("preview", "phong:x")], &latents);
        assert!(m.contains("phong:x"), "{m}");
    }

    /// Without latent files a latent binding falls back to the material's parameters.
    #[test]
    fn a_latent_without_a_file_falls_back() {
        let (_dir, latents) = library();
        let model = SurfaceModel::Bound(Binding::Neural("gold".into()));
        assert_eq!(surface(&model, &LatentLibrary::default()), Surface::LatentWithoutFile("gold"));
        assert_eq!(surface(&model, &latents), Surface::Bound(&Binding::Neural("gold".into())));
        let table = SurfaceModel::Bound(Binding::Merl("t.binary".into()));
        assert_eq!(surface(&table, &LatentLibrary::default()), Surface::Bound(&Binding::Merl("t.binary".into())));
        assert_eq!(surface(&SurfaceModel::Lambert, &latents), Surface::Lambert);
    }
}
