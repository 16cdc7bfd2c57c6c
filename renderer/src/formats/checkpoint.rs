//! Render checkpoints (`render --checkpoint FILE`): a render at a pass boundary
//! ([`RenderState`]: the film's per-pixel sums, sums of squares and sample counts, the
//! samples per pixel done and their counts) with the settings that decide its pixels, so
//! that a render started again continues it and ends with the uninterrupted render's image
//! bit for bit.
//!
//! Layout, little-endian:
//!
//! | bytes        | content                                                              |
//! |--------------|----------------------------------------------------------------------|
//! | 8            | magic `RNDRCKPT`                                                     |
//! | 4            | format version ([`FORMAT_VERSION`])                                  |
//! | 4            | header length H                                                      |
//! | H            | header, JSON: settings (string to string), image size, region, samples per pixel done, sample/ray/discard counts |
//! | 24 n         | per-pixel sums, f64 RGB, row-major over the region (n pixels)        |
//! | 24 n         | per-pixel sums of squares, f64 RGB                                   |
//! | 4 n          | per-pixel sample counts, u32                                         |
//! | 32           | SHA-256 of every byte before it                                      |
//!
//! Files are written to a temporary file that is renamed into place, so a checkpoint is
//! whole or absent. Reading checks, in order: magic, version, length (truncated), checksum
//! (corrupted), header, and then [`Checkpoint::check_settings`] that the settings are the
//! caller's; any failure is a [`CheckpointError`] naming the file and the problem, and no
//! part of such a file is used.

use crate::film::{Film, Region};
use crate::render::{PassCounters, RenderState};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

/// The first bytes of every checkpoint.
pub const MAGIC: &[u8; 8] = b"RNDRCKPT";
/// Version of the layout above; a checkpoint of another version is refused.
pub const FORMAT_VERSION: u32 = 1;
const PREFIX: usize = 16;
const CHECKSUM: usize = 32;

/// A checkpoint that cannot be written or used: the file and the problem.
#[derive(Debug, thiserror::Error)]
#[error("{}: {problem}", path.display())]
pub struct CheckpointError {
    pub path: PathBuf,
    pub problem: CheckpointProblem,
}

/// What is wrong with a checkpoint file.
#[derive(Debug, thiserror::Error)]
pub enum CheckpointProblem {
    #[error("cannot read the checkpoint: {0}")]
    Read(std::io::Error),
    #[error("cannot write the checkpoint: {0}")]
    Write(String),
    #[error("not a render checkpoint")]
    NotACheckpoint,
    #[error("checkpoint format version {found}; this renderer reads version {FORMAT_VERSION}")]
    Version { found: u32 },
    #[error("truncated checkpoint ({len} bytes where {expected} are needed)")]
    Truncated { len: usize, expected: usize },
    #[error("corrupted checkpoint ({0})")]
    Corrupted(&'static str),
    #[error("malformed checkpoint header: {0}")]
    Malformed(String),
    /// The checkpoint was written by a render with other settings.
    #[error("checkpoint of another render: {key} is '{recorded}' there but '{current}' here (remove the file to start afresh)")]
    OtherSettings { key: String, recorded: String, current: String },
}

/// The header: everything but the per-pixel arrays.
#[derive(Serialize, Deserialize)]
struct Header {
    settings: BTreeMap<String, String>,
    full_width: u32,
    full_height: u32,
    /// x0, y0, x1, y1 (ends exclusive).
    region: [u32; 4],
    samples_done: u32,
    samples: u64,
    rays: u64,
    shadow_rays: u64,
    discarded: u64,
}

/// A render at a pass boundary and the settings that decide its pixels.
#[derive(Clone, Debug)]
pub struct Checkpoint {
    /// Settings by name (scene hash, resolution, spp, seed, ...), as the writer chose them;
    /// compared whole by [`Checkpoint::check_settings`].
    pub settings: BTreeMap<String, String>,
    pub state: RenderState,
}

fn error(path: &Path, problem: CheckpointProblem) -> CheckpointError {
    CheckpointError { path: path.to_path_buf(), problem }
}

/// Bytes of the per-pixel arrays of `n` pixels.
fn payload_len(n: usize) -> usize {
    n * (24 + 24 + 4)
}

/// Writes `state` and `settings` to `path` atomically (temporary file, sync, rename).
pub fn write(path: &Path, settings: &BTreeMap<String, String>, state: &RenderState) -> Result<(), CheckpointError> {
    let film = &state.film;
    let r = film.region;
    let header = Header {
        settings: settings.clone(),
        full_width: film.full_width,
        full_height: film.full_height,
        region: [r.x0, r.y0, r.x1, r.y1],
        samples_done: state.samples_done,
        samples: state.counters.samples,
        rays: state.counters.rays,
        shadow_rays: state.counters.shadow_rays,
        discarded: state.counters.discarded,
    };
    let header = serde_json::to_vec(&header).map_err(|e| error(path, CheckpointProblem::Write(e.to_string())))?;
    let (sum, sum_sq, count) = film.accumulators();
    let mut bytes = Vec::with_capacity(PREFIX + header.len() + payload_len(count.len()) + CHECKSUM);
    bytes.extend_from_slice(MAGIC);
    bytes.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    bytes.extend_from_slice(&(header.len() as u32).to_le_bytes());
    bytes.extend_from_slice(&header);
    for v in sum.iter().chain(sum_sq).flatten() {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    for c in count {
        bytes.extend_from_slice(&c.to_le_bytes());
    }
    let checksum = Sha256::digest(&bytes);
    bytes.extend_from_slice(&checksum);
    crate::support::write_atomically(path, |w| w.write_all(&bytes)).map_err(|e| error(path, CheckpointProblem::Write(e.to_string())))
}

impl Checkpoint {
    /// Reads a checkpoint, refusing any file that is not one whole and intact (see the
    /// module documentation); the settings are not checked here.
    pub fn read(path: &Path) -> Result<Checkpoint, CheckpointError> {
        let bytes = std::fs::read(path).map_err(|e| error(path, CheckpointProblem::Read(e)))?;
        Self::from_bytes(&bytes).map_err(|problem| error(path, problem))
    }

    fn from_bytes(bytes: &[u8]) -> Result<Checkpoint, CheckpointProblem> {
        let len = bytes.len();
        let magic_len = len.min(MAGIC.len());
        if bytes[..magic_len] != MAGIC[..magic_len] {
            return Err(CheckpointProblem::NotACheckpoint);
        }
        if len < PREFIX + CHECKSUM {
            return Err(CheckpointProblem::Truncated { len, expected: PREFIX + CHECKSUM });
        }
        let version = u32::from_le_bytes(bytes[8..12].try_into().expect("4 bytes"));
        let header_len = u32::from_le_bytes(bytes[12..16].try_into().expect("4 bytes")) as usize;
        let checksum_ok = || Sha256::digest(&bytes[..len - CHECKSUM])[..] == bytes[len - CHECKSUM..];
        if version != FORMAT_VERSION {
            // A flipped byte in the version field is corruption, not a version.
            return Err(if checksum_ok() { CheckpointProblem::Version { found: version } } else { CheckpointProblem::Corrupted("checksum mismatch") });
        }
        if PREFIX + header_len + CHECKSUM > len {
            return Err(if checksum_ok() {
                CheckpointProblem::Malformed("header length past the end".into())
            } else {
                CheckpointProblem::Truncated { len, expected: PREFIX + header_len + CHECKSUM }
            });
        }
        let header: Result<Header, _> = serde_json::from_slice(&bytes[PREFIX..PREFIX + header_len]);
        let header = match header {
            Ok(h) => h,
            Err(e) if checksum_ok() => return Err(CheckpointProblem::Malformed(e.to_string())),
            Err(_) => return Err(CheckpointProblem::Corrupted("checksum mismatch")),
        };
        let [x0, y0, x1, y1] = header.region;
        let region = Region { x0, y0, x1, y1 };
        if !region.is_within(header.full_width, header.full_height) {
            return Err(if checksum_ok() { CheckpointProblem::Malformed(format!("region {region} outside the image")) } else { CheckpointProblem::Corrupted("checksum mismatch") });
        }
        let n = region.pixel_count();
        let expected = PREFIX + header_len + payload_len(n) + CHECKSUM;
        if len < expected {
            return Err(CheckpointProblem::Truncated { len, expected });
        }
        if len > expected {
            return Err(CheckpointProblem::Corrupted("bytes after the end"));
        }
        if !checksum_ok() {
            return Err(CheckpointProblem::Corrupted("checksum mismatch"));
        }
        let mut at = PREFIX + header_len;
        let mut f64s = |count: usize| -> Vec<[f64; 3]> {
            let v = bytes[at..at + 24 * count]
                .chunks_exact(24)
                .map(|c| std::array::from_fn(|i| f64::from_le_bytes(c[8 * i..8 * i + 8].try_into().expect("8 bytes"))))
                .collect();
            at += 24 * count;
            v
        };
        let sum = f64s(n);
        let sum_sq = f64s(n);
        let count: Vec<u32> = bytes[at..at + 4 * n].chunks_exact(4).map(|c| u32::from_le_bytes(c.try_into().expect("4 bytes"))).collect();
        let film = Film::from_accumulators(header.full_width, header.full_height, region, sum, sum_sq, count)
            .ok_or_else(|| CheckpointProblem::Malformed("pixel arrays do not match the region".into()))?;
        Ok(Checkpoint {
            settings: header.settings,
            state: RenderState {
                film,
                samples_done: header.samples_done,
                counters: PassCounters {
                    samples: header.samples,
                    rays: header.rays,
                    shadow_rays: header.shadow_rays,
                    discarded: header.discarded,
                },
            },
        })
    }

    /// Checks that the checkpoint at `path` was written with `current` settings: the first
    /// setting that differs (or is missing on either side) is an
    /// [`CheckpointProblem::OtherSettings`] error.
    pub fn check_settings(&self, path: &Path, current: &BTreeMap<String, String>) -> Result<(), CheckpointError> {
        check_settings(path, &self.settings, current)
    }
}

/// [`Checkpoint::check_settings`] of `recorded` settings (of the checkpoint at `path`).
pub fn check_settings(path: &Path, recorded: &BTreeMap<String, String>, current: &BTreeMap<String, String>) -> Result<(), CheckpointError> {
    let missing = || "(none)".to_string();
    for key in recorded.keys().chain(current.keys()) {
        let (recorded, now) = (recorded.get(key), current.get(key));
        if recorded != now {
            return Err(error(
                path,
                CheckpointProblem::OtherSettings {
                    key: key.clone(),
                    recorded: recorded.cloned().unwrap_or_else(missing),
                    current: now.cloned().unwrap_or_else(missing),
                },
            ));
        }
    }
    Ok(())
}

/// Hex SHA-256 of `bytes`: how checkpoints identify the files a render reads.
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::film::PixelAccumulator;
    use crate::Rgb;

    fn sample_state() -> RenderState {
        let region: Region = "1,2,4,5".parse().unwrap();
        let mut state = RenderState::new(6, 7, region);
        for i in 0..region.pixel_count() {
            let mut acc = PixelAccumulator::default();
            acc.add(Rgb::new(0.1 * i as f32, 1.0 / 3.0, 7.25));
            acc.add(Rgb::new(1e-30, 2.5, 0.0));
            state.film.merge(i, &acc);
        }
        state.samples_done = 2;
        state.counters = PassCounters { samples: 18, rays: 40, shadow_rays: 30, discarded: 0 };
        state
    }

    fn settings() -> BTreeMap<String, String> {
        BTreeMap::from([("spp".to_string(), "4".to_string()), ("seed".to_string(), "1".to_string())])
    }

    #[test]
    fn round_trips_bit_for_bit_and_refuses_damage() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.ckpt");
        let state = sample_state();
        write(&path, &settings(), &state).unwrap();
        let back = Checkpoint::read(&path).unwrap();
        assert_eq!(back.settings, settings());
        assert_eq!(back.state.samples_done, 2);
        assert_eq!(back.state.counters.rays, 40);
        assert_eq!(back.state.film.accumulators(), state.film.accumulators());
        assert_eq!((back.state.film.region, back.state.film.full_width, back.state.film.full_height), (state.film.region, 6, 7));
        back.check_settings(&path, &settings()).unwrap();
        let mut other = settings();
        other.insert("spp".into(), "8".into());
        let e = back.check_settings(&path, &other).unwrap_err();
        assert!(matches!(e.problem, CheckpointProblem::OtherSettings { ref key, .. } if key == "spp"), "{e}");
        assert!(e.to_string().starts_with(&path.display().to_string()), "{e}");

        let bytes = std::fs::read(&path).unwrap();
        for cut in [0, 5, 20, bytes.len() / 2, bytes.len() - 1] {
            let problem = Checkpoint::from_bytes(&bytes[..cut]).unwrap_err();
            assert!(matches!(problem, CheckpointProblem::Truncated { .. }), "cut at {cut}: {problem}");
        }
        for i in 8..bytes.len() {
            let mut b = bytes.clone();
            b[i] ^= 0x10;
            let problem = Checkpoint::from_bytes(&b).unwrap_err();
            assert!(matches!(problem, CheckpointProblem::Corrupted(_) | CheckpointProblem::Truncated { .. }), "byte {i}: {problem}");
        }
        let mut b = bytes.clone();
        b[0] = b'X';
        assert!(matches!(Checkpoint::from_bytes(&b), Err(CheckpointProblem::NotACheckpoint)));
        assert!(matches!(Checkpoint::from_bytes(b"PK\x03\x04 a zip"), Err(CheckpointProblem::NotACheckpoint)));
    }
}
