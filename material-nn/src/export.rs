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
use std::path::{Path, PathBuf};

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

/// What [`export`] did.
#[derive(Debug)]
pub enum Exported {
    /// Every code made (`resumed` of them taken from an interrupted export's
    /// [`partial_dir`]) and the file written.
    Written { file: LatentFile, resumed: usize },
    /// Stopped before code `done` of `total`: the codes made are kept in [`partial_dir`], and
    /// the same export (same materials, data and settings) continues from them.
    Interrupted { done: usize, total: usize },
}

/// Where an export to `out` keeps the codes it has made until it writes `out`:
/// `OUT.partial/`, holding `codes.bin` (a latent file: the decoder and the codes so far,
/// rewritten after each) and `settings.txt` (the materials, data directory and encoding
/// settings they were made with). Removed once `out` is written.
pub fn partial_dir(out: &Path) -> PathBuf {
    let mut name = out.as_os_str().to_owned();
    name.push(".partial");
    PathBuf::from(name)
}

/// Which codes an [`export`] makes and where it writes them.
#[derive(Clone, Copy, Debug)]
pub struct ExportRequest<'a> {
    /// Directory of the tables (`NAME.binary`).
    pub data_dir: &'a Path,
    /// The materials, in the file's order.
    pub names: &'a [String],
    /// How each is encoded (the seed is offset by the material's position).
    pub settings: &'a EncodeSettings,
    /// The latent file written.
    pub out: &'a Path,
}

/// Writes `decoder` (a latent file's decoder part: [`latent_file`] of a run, or a latent file
/// read back) to `out` with the materials `names` encoded by `codec` from `data_dir`
/// with `settings` as its codes (any codes `decoder` held are replaced), the
/// seed offset by the material's position, so that a code does not depend on which codes were
/// made before it in this process. `progress(name)` after each code; `stop(done)` is asked
/// before each code and ends the export as [`Exported::Interrupted`]. Codes are kept in
/// [`partial_dir`] as they are made, and an export with the same materials, data and settings
/// takes them from there rather than making them again. Nothing is written to `out` unless
/// every code was made.
pub fn export(
    codec: &Codec,
    decoder: LatentFile,
    request: &ExportRequest,
    stop: &dyn Fn(usize) -> bool,
    progress: &mut dyn FnMut(&str),
) -> Result<Exported> {
    let ExportRequest { data_dir, names, settings, out } = *request;
    let tables: Vec<PathBuf> = names.iter().map(|name| crate::tables::table_path(data_dir, name)).collect();
    if let Some((path, name)) = tables.iter().zip(names).find(|(path, _)| !path.exists()) {
        return Err(Error::invalid_file(path, format!("no table for material '{name}'")));
    }
    let partial = partial_dir(out);
    let key = format!("materials {}\ndata {}\n{settings:?}\n", names.join(","), data_dir.display());
    let mut file = LatentFile {
        latents: resumed_codes(&partial, &key, &decoder, names),
        ..decoder
    };
    let resumed = file.latents.len();
    if resumed == 0 {
        if partial.exists() {
            std::fs::remove_dir_all(&partial).map_err(|e| Error::io(&partial, e))?;
        }
        std::fs::create_dir_all(&partial).map_err(|e| Error::io(&partial, e))?;
        let settings_path = partial.join("settings.txt");
        std::fs::write(&settings_path, &key).map_err(|e| Error::io(&settings_path, e))?;
    }
    for name in &names[..resumed] {
        progress(name);
    }
    for (i, (name, table)) in names.iter().zip(&tables).enumerate().skip(resumed) {
        if stop(i) {
            return Ok(Exported::Interrupted { done: i, total: names.len() });
        }
        let table = MaterialTable::read(table)?;
        let settings = EncodeSettings {
            seed: settings.seed.wrapping_add(i as u64),
            ..settings.clone()
        };
        file.latents.push(codec.encode(&table, &settings)?.into_named(name));
        file.write(partial.join("codes.bin"))?;
        progress(name);
    }
    file.write(out)?;
    std::fs::remove_dir_all(&partial).map_err(|e| Error::io(&partial, e))?;
    Ok(Exported::Written { file, resumed })
}

/// The codes an interrupted export left in `partial` (the first of `names`, in order) when
/// it was made with the same materials, data and settings (`key`) and for `decoder`; none
/// otherwise (also when the files are missing or unreadable: the export starts afresh).
fn resumed_codes(partial: &Path, key: &str, decoder: &LatentFile, names: &[String]) -> Vec<NamedLatent> {
    if std::fs::read_to_string(partial.join("settings.txt")).ok().as_deref() != Some(key) {
        return Vec::new();
    }
    let codes = partial.join("codes.bin");
    match LatentFile::read(&codes) {
        Ok(file) if check_same_decoder(&file, decoder, &codes).is_ok() => file
            .latents
            .into_iter()
            .zip(names)
            .take_while(|(code, name)| &code.name == *name)
            .map(|(code, _)| code)
            .collect(),
        _ => Vec::new(),
    }
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
