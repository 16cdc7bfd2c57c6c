//! A run directory: where `material-nn train` keeps a run and where inference, export and
//! evaluation read it back.
//!
//! Files: `config.json`, `split.json`, `run.json` (data directory and materials),
//! `reference.binary` (f_ref, MERL layout), `checkpoint.bin` (latest), `best.bin` (the
//! checkpoint of the best epoch); model weights inside checkpoints as burnpack bytes.

use crate::config::TrainConfig;
use crate::error::{Error, Result};
use crate::model::HyperBrdf;
use burn::module::Module;
use burn::store::ModuleRecord;
use burn::tensor::{Bytes, Device};
use rand::SeedableRng;
use renderer::support::write_bytes_atomically;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Where a run keeps its files.
#[derive(Clone, Debug)]
pub struct RunDir(pub PathBuf);

impl RunDir {
    /// `config.json`.
    pub fn config(&self) -> PathBuf {
        self.0.join("config.json")
    }
    /// `split.json`.
    pub fn split(&self) -> PathBuf {
        self.0.join("split.json")
    }
    /// `run.json`.
    pub fn info(&self) -> PathBuf {
        self.0.join("run.json")
    }
    /// `reference.binary`: f_ref as a MERL table.
    pub fn reference(&self) -> PathBuf {
        self.0.join("reference.binary")
    }
    /// `checkpoint.bin`: the latest checkpoint.
    pub fn checkpoint(&self) -> PathBuf {
        self.0.join("checkpoint.bin")
    }
    /// `best.bin`: the checkpoint of the best epoch.
    pub fn best(&self) -> PathBuf {
        self.0.join("best.bin")
    }
}

/// `run.json`: what the run was trained on.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunInfo {
    /// The data directory given to `train`.
    pub data_dir: PathBuf,
    /// Every material of the data directory at the start of the run.
    pub materials: Vec<String>,
}

/// Reads a JSON file of the run directory.
pub fn read_json<T: for<'de> Deserialize<'de>>(path: &Path) -> Result<T> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    serde_json::from_str(&text).map_err(|e| Error::invalid_file(path, format!("bad JSON: {e}")))
}

/// Writes a JSON file of the run directory atomically.
pub fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<()> {
    let text = serde_json::to_string_pretty(value)
        .map_err(|e| Error::Invalid(format!("{}: {e}", path.display())))?;
    Ok(write_bytes_atomically(path, text.as_bytes())?)
}

/// The model's weights as burnpack bytes (what checkpoints store); `path` names the
/// checkpoint in errors.
pub fn model_bytes(model: &HyperBrdf, path: &Path) -> Result<Vec<u8>> {
    let bytes = model
        .clone()
        .into_record()
        .into_bytes()
        .map_err(|e| Error::invalid_file(path, format!("cannot serialise the model: {e}")))?;
    Ok(bytes.to_vec())
}

/// Loads model weights (burnpack bytes of a checkpoint) into a model of `config`'s shape.
pub fn load_model(
    config: &TrainConfig,
    bytes: &[u8],
    device: &Device,
    path: &Path,
) -> Result<HyperBrdf> {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(0);
    let model = HyperBrdf::init(&config.net, &mut rng, device);
    let record = ModuleRecord::from_bytes(Bytes::from_bytes_vec(bytes.to_vec()))
        .map_err(|e| Error::invalid_file(path, format!("bad model weights: {e}")))?;
    model.try_load_record(record).map_err(|e| {
        Error::invalid_file(
            path,
            format!("model weights do not fit the configuration: {e}"),
        )
    })
}
