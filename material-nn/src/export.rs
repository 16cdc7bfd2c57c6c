//! `material-nn export`: a trained run → one self-contained `latent.bin`
//! ([`renderer::formats::latent_file`]): the hypernetwork's weights, the set encoder (so that
//! `material-nn encode --model latent.bin` needs no run directory), f_ref as f16, the latent
//! codes of the chosen materials (encoded and refined as `encode` does) and the names of the
//! training materials.

use crate::dataset::MaterialTable;
use crate::error::{Error, Result};
use crate::inference::{Codec, EncodeSettings, TrainedRun};
use half::f16;
use rayon::prelude::*;
use renderer::formats::latent_file::{LatentFile, NamedLatent, WeightType};
use renderer::neural::mlp::{Encoder, Mlp};
use std::path::Path;

/// The decoder part of a latent file (no latent codes yet).
pub fn latent_file(run: &TrainedRun, weight_type: WeightType) -> LatentFile {
    let codec = &run.codec;
    let hypernetwork = codec
        .model
        .heads
        .iter()
        .map(|h| Mlp {
            layers: h.to_dense(),
        })
        .collect();
    let f_ref = codec
        .sampler
        .reference
        .values
        .par_iter()
        .map(|v| {
            v.map(|c| {
                if c < 0.0 {
                    f16::from_f32(-1.0)
                } else {
                    f16::from_f32(c)
                }
            })
        })
        .collect();
    LatentFile {
        latent_dim: run.config.net.latent_dim,
        target_widths: run.config.net.target_widths.clone(),
        hyper_hidden: run.config.net.hyper_hidden.clone(),
        mapping: run.config.mapping,
        epsilon: run.config.epsilon,
        weight_type,
        hypernetwork,
        encoder: Some(Encoder {
            layers: codec.model.encoder.to_dense(),
            peak_share: codec.sampler.peak_share,
        }),
        f_ref,
        latents: Vec::new(),
        training_materials: run.split.train.clone(),
    }
}

/// Encodes the tables `names` of `data_dir` (`NAME.binary`) as `settings` say, the seed
/// offset by the material's position; `progress(name)` after each.
pub fn encode_materials(
    codec: &Codec,
    data_dir: &Path,
    names: &[String],
    settings: &EncodeSettings,
    progress: &mut dyn FnMut(&str),
) -> Result<Vec<NamedLatent>> {
    names
        .iter()
        .enumerate()
        .map(|(i, name)| {
            let path = crate::tables::table_path(data_dir, name);
            if !path.exists() {
                return Err(Error::invalid_file(
                    &path,
                    format!("no table for material '{name}'"),
                ));
            }
            let table = MaterialTable::read(&path)?;
            let settings = EncodeSettings {
                seed: settings.seed.wrapping_add(i as u64),
                ..settings.clone()
            };
            let refined = codec.encode(&table, &settings)?;
            progress(name);
            Ok(refined.into_named(name))
        })
        .collect()
}

/// Writes `decoder` (a latent file's decoder part: [`latent_file`] of a run, or a latent file
/// read back) to `out` with the materials `names` encoded by `codec` from `data_dir` with
/// `settings` as its codes (any codes `decoder` held are replaced). Nothing is written when a
/// material fails.
pub fn export(
    codec: &Codec,
    decoder: LatentFile,
    data_dir: &Path,
    names: &[String],
    settings: &EncodeSettings,
    out: &Path,
    progress: &mut dyn FnMut(&str),
) -> Result<LatentFile> {
    let file = LatentFile {
        latents: encode_materials(codec, data_dir, names, settings, progress)?,
        ..decoder
    };
    file.write(out)?;
    Ok(file)
}

/// Checks that `library` holds the decoder of `model` (same networks, mapping and f_ref up to
/// the f16 rounding either may be stored with): a latent code means something only with the
/// decoder it was encoded for. The error names `path` (the library).
pub fn check_same_decoder(library: &LatentFile, model: &LatentFile, path: &Path) -> Result<()> {
    let close = |a: &[f32], b: &[f32]| {
        a.len() == b.len()
            && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= 1e-3 * x.abs().max(y.abs()) + 1e-7)
    };
    let same = library.latent_dim == model.latent_dim
        && library.target_widths == model.target_widths
        && library.hyper_hidden == model.hyper_hidden
        && library.mapping == model.mapping
        && library.epsilon == model.epsilon
        && library.hypernetwork.len() == model.hypernetwork.len()
        && library.hypernetwork.iter().zip(&model.hypernetwork).all(|(a, b)| {
            a.layers.len() == b.layers.len()
                && a.layers.iter().zip(&b.layers).all(|(p, q)| {
                    close(&p.weight, &q.weight) && close(&p.bias, &q.bias)
                })
        })
        && library.f_ref == model.f_ref;
    if same {
        Ok(())
    } else {
        Err(Error::invalid_file(
            path,
            "holds another model's decoder; a code is only valid with the decoder it was \
             encoded for (use a new --add-to file)",
        ))
    }
}
