//! How a material names a BSDF made from data: a [`Binding`], parsed once where it is written
//! (glTF `extras`, `render --bind`, a report configuration), part of the scene description
//! ([`super::SurfaceModel::Bound`]) and opened when the scene is prepared for rendering
//! (`SharedBsdf::open`). Which binding a material ends up with is decided in one place,
//! `material::binding`.
//!
//! # Written form
//! `KIND:ARGUMENT`:
//! - `merl:PATH.binary` — a MERL-layout table (`.binary` may be left out when the file has it);
//! - `nbrdf:PREFIX` — the network in `PREFIX_fc1.npy`, `PREFIX_b1.npy`, … `PREFIX_b3.npy`,
//!   i.e. `nbrdf:DIR/MATERIAL` names material MATERIAL of a directory of networks such as
//!   `../shared/data/nbrdf/merl`; `PREFIX_fc1.npy` (any of the six file names) is accepted for
//!   PREFIX, and a directory that holds exactly one network may be named by itself;
//! - `neural:NAME` — latent code NAME of the latent files given at render time
//!   (`render --material FILE`).
//!
//! A relative path is resolved once, when the binding is parsed, against the directory the
//! text came from (the glTF file's for `extras`, the current directory for the command line).

use super::TextureRef;
use crate::{Error, Result};
use std::fmt;
use std::path::{Path, PathBuf};

/// The written forms [`Binding::parse`] understands.
pub const BINDING_FORMS: [&str; 3] = ["merl:PATH.binary", "nbrdf:PATH_PREFIX", "neural:LATENT_NAME"];

/// A BSDF made from data that a material is bound to.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum Binding {
    /// A MERL-layout table file.
    Merl(PathBuf),
    /// An NBRDF network: the prefix of its six `.npy` files (or one of them, or a directory
    /// holding exactly one network).
    Nbrdf(PathBuf),
    /// A latent code of the latent files given at render time, by name.
    Neural(String),
}

impl Binding {
    /// Parses the written form (module documentation); a relative path is joined to
    /// `base_dir` (pass `Path::new("")` for the current directory). Errors name the text: an
    /// unknown kind is [`Error::UnknownName`] listing [`BINDING_FORMS`], a missing `:` or
    /// argument [`Error::InvalidArgument`].
    pub fn parse(text: &str, base_dir: &Path) -> Result<Binding> {
        let invalid = |reason: String| Error::InvalidArgument {
            flag: format!("BRDF binding '{text}'"),
            reason,
        };
        let Some((kind, argument)) = text.split_once(':') else {
            return Err(invalid(format!("expected KIND:ARGUMENT, one of {}", BINDING_FORMS.join(", "))));
        };
        if !["merl", "nbrdf", "neural"].contains(&kind) {
            return Err(Error::UnknownName {
                what: "BRDF binding kind",
                name: text.to_string(),
                available: BINDING_FORMS.iter().map(|s| s.to_string()).collect(),
            });
        }
        if argument.is_empty() {
            return Err(invalid(format!("empty {}", if kind == "neural" { "name" } else { "path" })));
        }
        let path = || base_dir.join(argument);
        Ok(match kind {
            "merl" => Binding::Merl(path()),
            "nbrdf" => Binding::Nbrdf(path()),
            _ => Binding::Neural(argument.to_string()),
        })
    }

    /// The latent name of a [`Binding::Neural`].
    pub fn latent_name(&self) -> Option<&str> {
        match self {
            Binding::Neural(name) => Some(name),
            _ => None,
        }
    }
}

/// The written form, `KIND:ARGUMENT` (paths as resolved).
impl fmt::Display for Binding {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Binding::Merl(path) => write!(f, "merl:{}", path.display()),
            Binding::Nbrdf(path) => write!(f, "nbrdf:{}", path.display()),
            Binding::Neural(name) => write!(f, "neural:{name}"),
        }
    }
}

/// The most BSDFs a [`VaryingForm::Mix`] mixes: one per channel of an RGBA texture.
pub const MAX_MIX_PARTS: usize = 4;

/// A BSDF made from data that varies across a surface, driven by textures (glTF material
/// `extras`' object forms of `neural`, see [`super::gltf`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Varying {
    pub form: VaryingForm,
    /// A colour texture (sRGB-decoded, clamped to [0, 1]) multiplying f_r: a measured lobe
    /// with a painted colour.
    pub tint: Option<TextureRef>,
}

/// What a [`Varying`] material varies.
#[derive(Clone, Debug, PartialEq)]
pub enum VaryingForm {
    /// One binding everywhere (varied by the tint alone).
    One(Binding),
    /// The exact mixture f = Σ w_k f_k (pdf = Σ w_k pdf_k) of 2 to [`MAX_MIX_PARTS`]
    /// bindings; w_k is channel k (R, G, B, A; linear) of `weights`, normalised per texel
    /// (all zero: the first binding alone).
    Mix { parts: Vec<Binding>, weights: TextureRef },
    /// The latent interpolation z(t) from code `ends[0]` (t = 0) to `ends[1]` (t = 1) as
    /// `render --sweep` decodes it, t being channel `channel` (0–3: R, G, B, A; linear,
    /// clamped to [0, 1]) of `t`. Only latent codes have a latent space to interpolate in:
    /// the blend of two tables or networks is their [`VaryingForm::Mix`].
    Blend { ends: [String; 2], t: TextureRef, channel: usize },
}

impl Varying {
    /// The textures it reads.
    pub fn texture_refs(&self) -> Vec<&TextureRef> {
        let form = match &self.form {
            VaryingForm::One(_) => None,
            VaryingForm::Mix { weights, .. } => Some(weights),
            VaryingForm::Blend { t, .. } => Some(t),
        };
        form.into_iter().chain(self.tint.as_ref()).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_each_kind_and_resolves_relative_paths_once() {
        let base = Path::new("/scenes/a");
        assert_eq!(Binding::parse("merl:x.binary", base).unwrap(), Binding::Merl("/scenes/a/x.binary".into()));
        assert_eq!(Binding::parse("merl:/abs/x.binary", base).unwrap(), Binding::Merl("/abs/x.binary".into()));
        assert_eq!(Binding::parse("nbrdf:nets/chrome", base).unwrap(), Binding::Nbrdf("/scenes/a/nets/chrome".into()));
        assert_eq!(Binding::parse("neural:x/y", base).unwrap(), Binding::Neural("x/y".into()));
        assert_eq!(Binding::parse("merl:x.binary", Path::new("")).unwrap(), Binding::Merl("x.binary".into()));
        for text in ["merl:/abs/x.binary", "nbrdf:/n/chrome", "neural:gold"] {
            assert_eq!(Binding::parse(text, base).unwrap().to_string(), text);
        }
    }

    #[test]
    fn bad_text_is_named_in_the_error() {
        let e = Binding::parse("phong:foo.bin", Path::new("")).unwrap_err();
        assert!(matches!(e, Error::UnknownName { .. }));
        let msg = e.to_string();
        assert!(msg.contains("phong:foo.bin") && msg.contains("merl:PATH.binary"), "{msg}");
        let msg = Binding::parse("just-a-path.binary", Path::new("")).unwrap_err().to_string();
        assert!(msg.contains("just-a-path.binary") && msg.contains("KIND:ARGUMENT"), "{msg}");
        let msg = Binding::parse("merl:", Path::new("")).unwrap_err().to_string();
        assert!(msg.contains("'merl:'") && msg.contains("empty path"), "{msg}");
        let msg = Binding::parse("neural:", Path::new("")).unwrap_err().to_string();
        assert!(msg.contains("empty name"), "{msg}");
    }
}
