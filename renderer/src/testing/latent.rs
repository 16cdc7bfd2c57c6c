//! Latent files for tests of the code around the decoder (plugins, fuzz targets), where
//! decoding the shipped 6-60-60-60-60-3 net and fitting its importance sampler (0.1 M
//! network evaluations) would cost most of the time.

use crate::formats::latent_file::{LatentFile, WeightType};
use crate::neural::mapping::MappingForm;
use std::path::Path;

/// The shipped latent file, `scenes/materials/latent.bin`.
pub fn shipped_latent_path() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/materials/latent.bin"))
}

/// Writes to `path` a latent file that decodes cheaply (a 6-4-3 target net, latent size 2)
/// with the codes `alum-bronze` and `chrome`: its net outputs y = ln 3 for every input, so
/// under the code mapping f = 2 f_ref + ε, twice the shipped file's reference BRDF (a glossy
/// median material, with the shipped file's f_ref and ε); chrome's offset scales it.
pub fn write_cheap_latent_file(path: &Path) -> crate::Result<()> {
    let shipped = LatentFile::read(shipped_latent_path())?;
    let mut file = LatentFile::synthetic(&[5], WeightType::F32);
    file.mapping = MappingForm::Code;
    file.epsilon = shipped.epsilon;
    file.f_ref = shipped.f_ref;
    let heads = file.hypernetwork.len();
    for (k, head) in file.hypernetwork.iter_mut().enumerate() {
        let last = head.layers.len() - 1;
        for (j, layer) in head.layers.iter_mut().enumerate() {
            layer.weight.fill(0.0);
            let output_bias = k == heads - 1 && j == last;
            layer.bias.fill(if output_bias { 3f32.ln() } else { 0.0 });
        }
    }
    file.latents[0].name = "alum-bronze".into();
    file.latents[1].name = "chrome".into();
    file.latents[1].offset = [0.1, 0.05, 0.0];
    file.latents[1].residual.clear();
    file.write(path)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::neural::latent_library::LatentLibrary;

    /// The cheap file loads and its codes decode to f = 2 f_ref + ε (chrome's scaled by its
    /// offset).
    #[test]
    fn the_cheap_latent_file_decodes_to_twice_the_reference() {
        let dir = std::env::temp_dir().join(format!("cheap-latent-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("cheap.bin");
        write_cheap_latent_file(&path).unwrap();
        let library = LatentLibrary::load(&[&path]).unwrap();
        let bronze = library.decode("alum-bronze").unwrap();
        let chrome = library.decode("chrome").unwrap();
        let (wo, wi) = (glam::Vec3::new(0.0, 0.6, 0.8), glam::Vec3::new(0.0, -0.6, 0.8));
        use crate::bsdf::Bxdf;
        let (a, b) = (bronze.eval(wo, wi), chrome.eval(wo, wi));
        assert!(a.min_element() > 0.0 && a.is_finite(), "{a}");
        assert!(b.x > a.x && b.z == a.z, "chrome {b}, alum-bronze {a}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
