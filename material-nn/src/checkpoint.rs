//! Training checkpoints: one self-checking file holding everything a run needs to go on as if
//! it had never stopped — the configuration, the loop's state (epoch, position in the epoch's
//! material order, random generator, early-stopping bookkeeping, history), the model's weights
//! and the optimiser's state (both as burn's burnpack bytes, parameter ids included).
//!
//! Layout (little-endian): magic `"MNNCKPT\0"`, version u32, then three sections each as
//! length u64 + bytes (state JSON, model burnpack, optimiser burnpack), then an FNV-1a 64
//! checksum of every preceding byte. Written atomically (`renderer::support::write_atomically`).

use crate::config::TrainConfig;
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

use std::path::Path;

/// The 8 bytes every checkpoint starts with.
pub const MAGIC: [u8; 8] = *b"MNNCKPT\0";
/// The checkpoint format version.
pub const VERSION: u32 = 1;

/// One epoch's figures.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EpochRecord {
    /// Epoch number, from 1.
    pub epoch: usize,
    /// Mean total training loss over the epoch's steps.
    pub train_loss: f64,
    /// Mean L_rec data term over the epoch's steps.
    pub train_rec: f64,
    /// Mean L_fre over the epoch's steps (0 when not used).
    pub train_fre: f64,
    /// Validation loss (data term + η L_fre where used), if there are validation materials.
    pub validation: Option<f64>,
    /// Wall time of the epoch, seconds (not part of the run's determinism).
    pub seconds: f64,
}

/// The training loop's state between steps.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrainState {
    /// Epochs completed.
    pub epoch: usize,
    /// Material order (indices into the training split) of the epoch in progress; empty
    /// between epochs.
    pub order: Vec<usize>,
    /// Materials of `order` already stepped on.
    pub position: usize,
    /// Optimiser steps taken in all.
    pub step: u64,
    /// The run's random generator (samples, material order).
    pub rng: rand_pcg::Pcg64,
    /// Sums of (total, rec, fre) over the epoch in progress, and its step count.
    pub epoch_sums: [f64; 3],
    /// Steps of the epoch in progress.
    pub epoch_steps: usize,
    /// Best validation (or, without validation materials, training) loss so far.
    pub best: Option<f64>,
    /// Epoch of `best`.
    pub best_epoch: usize,
    /// Epochs since `best` improved.
    pub epochs_without_improvement: usize,
    /// Whether the run is over (all epochs or early stopping).
    pub finished: bool,
    /// Per-epoch figures.
    pub history: Vec<EpochRecord>,
}

/// A checkpoint in memory.
#[derive(Clone, Debug)]
pub struct Checkpoint {
    /// The run's configuration.
    pub config: TrainConfig,
    /// The loop's state.
    pub state: TrainState,
    /// Model weights, burnpack bytes.
    pub model: Vec<u8>,
    /// Optimiser state, burnpack bytes.
    pub optimizer: Vec<u8>,
}

#[derive(Serialize, Deserialize)]
struct Header {
    config: TrainConfig,
    state: TrainState,
}


impl Checkpoint {
    /// Serialises the checkpoint.
    pub fn to_bytes(&self) -> Result<Vec<u8>> {
        let header = serde_json::to_vec(&Header {
            config: self.config.clone(),
            state: self.state.clone(),
        })
        .map_err(|e| Error::Invalid(format!("cannot serialise the training state: {e}")))?;
        let mut out =
            Vec::with_capacity(header.len() + self.model.len() + self.optimizer.len() + 48);
        out.extend_from_slice(&MAGIC);
        out.extend_from_slice(&VERSION.to_le_bytes());
        for section in [&header, &self.model, &self.optimizer] {
            out.extend_from_slice(&(section.len() as u64).to_le_bytes());
            out.extend_from_slice(section);
        }
        let sum = renderer::support::fnv1a64(&out);
        out.extend_from_slice(&sum.to_le_bytes());
        Ok(out)
    }

    /// Parses a checkpoint; `path` names the file in errors.
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Self> {
        let bad = |reason: &str| Error::invalid_file(path, reason.to_string());
        if bytes.len() < 12 || bytes[..8] != MAGIC {
            return Err(bad("not a material-nn checkpoint (bad magic)"));
        }
        let version = u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]);
        if version != VERSION {
            return Err(Error::invalid_file(
                path,
                format!("checkpoint version {version}, this build reads version {VERSION}"),
            ));
        }
        if bytes.len() < 20 {
            return Err(bad("truncated checkpoint"));
        }
        let (body, tail) = bytes.split_at(bytes.len() - 8);
        let mut sum = [0u8; 8];
        sum.copy_from_slice(tail);
        if renderer::support::fnv1a64(body) != u64::from_le_bytes(sum) {
            return Err(bad(
                "checksum mismatch: the checkpoint is corrupt or truncated",
            ));
        }
        let mut at = 12usize;
        let mut sections = Vec::new();
        for _ in 0..3 {
            if body.len() < at + 8 {
                return Err(bad("truncated checkpoint section"));
            }
            let mut len = [0u8; 8];
            len.copy_from_slice(&body[at..at + 8]);
            let len = u64::from_le_bytes(len) as usize;
            at += 8;
            if body.len() - at < len {
                return Err(bad("truncated checkpoint section"));
            }
            sections.push(&body[at..at + len]);
            at += len;
        }
        if at != body.len() {
            return Err(bad("unexpected bytes after the last section"));
        }
        let header: Header = serde_json::from_slice(sections[0])
            .map_err(|e| Error::invalid_file(path, format!("bad checkpoint state: {e}")))?;
        header.config.check().map_err(|e| {
            Error::invalid_file(path, format!("bad configuration in checkpoint: {e}"))
        })?;
        Ok(Checkpoint {
            config: header.config,
            state: header.state,
            model: sections[1].to_vec(),
            optimizer: sections[2].to_vec(),
        })
    }

    /// Reads a checkpoint file.
    pub fn read(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        Self::from_bytes(&bytes, path)
    }

    /// Writes the checkpoint atomically (temporary file in the same directory, synced,
    /// renamed over `path`).
    pub fn write(&self, path: &Path) -> Result<()> {
        Ok(renderer::support::write_bytes_atomically(path, &self.to_bytes()?)?)
    }
}


#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn sample() -> Checkpoint {
        Checkpoint {
            config: TrainConfig::default(),
            state: TrainState {
                epoch: 2,
                order: vec![1, 0],
                position: 1,
                step: 5,
                rng: rand_pcg::Pcg64::seed_from_u64(3),
                epoch_sums: [1.0, 0.5, 0.25],
                epoch_steps: 1,
                best: Some(0.3),
                best_epoch: 1,
                epochs_without_improvement: 1,
                finished: false,
                history: vec![],
            },
            model: vec![1, 2, 3],
            optimizer: vec![4, 5],
        }
    }

    #[test]
    fn round_trip_and_damage() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("checkpoint.bin");
        sample().write(&path).unwrap();
        let back = Checkpoint::read(&path).unwrap();
        assert_eq!(back.state, sample().state);
        assert_eq!((back.model, back.optimizer), (vec![1, 2, 3], vec![4, 5]));

        let good = sample().to_bytes().unwrap();
        let err = |b: &[u8]| Checkpoint::from_bytes(b, &path).unwrap_err().to_string();
        let mut corrupt = good.clone();
        corrupt[30] ^= 1;
        assert!(err(&corrupt).contains("checksum"));
        assert!(err(&good[..good.len() / 2]).contains("checksum"));
        assert!(err(b"{\"some\": \"json\"}").contains("not a material-nn checkpoint"));
        let mut v9 = good.clone();
        v9[8] = 9;
        assert!(err(&v9).contains("version 9"));
        assert!(err(&v9).contains("checkpoint.bin"));
    }
}
