//! `material-nn export`: a trained run → one self-contained `latent.bin`
//! ([`renderer::latent_file`]): the hypernetwork's weights, f_ref as f16, the latent codes of
//! the chosen materials and the names of the training materials.

use crate::dataset::MaterialTable;
use crate::error::{Error, Result};
use crate::inference::TrainedRun;
use half::f16;
use rayon::prelude::*;
use renderer::latent_file::{LatentFile, Mlp, NamedLatent, WeightType};
use std::path::Path;

/// Samples drawn per material to encode it (z is a mean over them).
pub const ENCODE_SAMPLES: usize = 65_536;

/// The decoder part of a latent file (no latent codes yet).
pub fn latent_file(run: &TrainedRun, weight_type: WeightType) -> LatentFile {
    let hypernetwork = run
        .model
        .heads
        .iter()
        .map(|h| Mlp {
            layers: h.to_dense(),
        })
        .collect();
    let f_ref = run
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
        f_ref,
        latents: Vec::new(),
        training_materials: run.split.train.clone(),
    }
}

/// Encodes the tables `names` of `data_dir` (`NAME.binary`) with a fixed seed per material.
pub fn encode_materials(
    run: &TrainedRun,
    data_dir: &Path,
    names: &[String],
    seed: u64,
) -> Result<Vec<NamedLatent>> {
    names
        .iter()
        .enumerate()
        .map(|(i, name)| {
            let path = data_dir.join(format!("{name}.{}", crate::tabulate::TABLE_EXTENSION));
            if !path.exists() {
                return Err(Error::invalid_file(
                    &path,
                    format!("no table for material '{name}'"),
                ));
            }
            let table = MaterialTable::read(&path)?;
            let z = run.encode_table(&table, ENCODE_SAMPLES, seed.wrapping_add(i as u64))?;
            Ok(NamedLatent {
                name: name.clone(),
                z,
            })
        })
        .collect()
}

/// Exports a run to `out`: the materials `names` (default: every material of the run's data
/// directory) encoded from `data_dir`.
pub fn export(
    run: &TrainedRun,
    data_dir: &Path,
    names: &[String],
    weight_type: WeightType,
    out: &Path,
) -> Result<LatentFile> {
    let mut file = latent_file(run, weight_type);
    file.latents = encode_materials(run, data_dir, names, run.config.seed)?;
    file.write(out)?;
    Ok(file)
}
