//! `latent.bin`: a trained FreNBRDF/HyperBRDF decoder with its named latent codes — the one
//! reader and writer of the format (material-nn writes it, the renderer reads it). The byte
//! layout is documented in `docs/latent-format.md`; in short (all little-endian):
//!
//! ```text
//! magic "FRENBRDF" | version u32 = 4 (1 to 3 are read too) | latent_dim u32
//! target layer count u32 = K | target widths u32 × (K+1)            (6 60 60 60 60 3)
//! hypernetwork hidden layer count u32 = H | hidden widths u32 × H    (128 128)
//! mapping u8 (0 talk, 1 code) | weight dtype u8 (0 f32, 1 f16) | 2 zero bytes | epsilon f32
//! hypernetwork: per target tensor (W0 b0 W1 b1 ...), per layer: weight [d_in, d_out]
//!               row-major, then bias [d_out], in the weight dtype
//! encoder (version 2 only): flag u8 (0 none, 1 present); when present: peak_share f32 |
//!               layer count u32 = E | widths u32 × (E+1) (9 128 128 128 latent_dim) |
//!               per layer: weight [d_in, d_out] row-major, then bias [d_out], always f32
//! f_ref: dims u32 × 3 (90 90 180) | f16 × bins × 3, bin-major RGB, f_r in 1/sr, < 0 unmeasured
//! latent codes: count u32 | per code: name length u32, UTF-8 name, f32 × latent_dim (z),
//!               f32 × 3 (output offset δ; version ≥ 3) | residual length u32 = R (0 or
//!               the target net's parameter count less its output width; version 4) |
//!               R residual values in the weight dtype
//! training materials: count u32 | per name: length u32, UTF-8 name
//! checksum u64: FNV-1a 64 of every preceding byte
//! ```
//!
//! Conventions: dense layers compute y = x · W + b with W stored [d_in, d_out] row-major (as
//! NBRDF's `.npy` tensors and burn's `Linear`); ReLU after every hidden layer of both the
//! hypernetwork and the target net, the last layers are linear. The target net maps the 6D
//! input of [`crate::brdf_coords::network_input`] to the mapped value y per RGB channel; f_r
//! comes back through [`MappingForm::inverse`] with f_ref looked up in the table. The optional
//! set [`Encoder`] maps measured samples to a latent code (ReLU after every layer, its last
//! included, then the mean over the samples). A code's output offset δ is added to the
//! decoded target net's output bias and its residual ΔΘ to the other decoded parameters
//! ([`LatentFile::decode`]). Version 1 files have no encoder section and read with
//! `encoder: None`; versions 1 and 2 have no offsets and read with δ = 0; versions before 4
//! have no residuals and read with none; writing always writes [`VERSION`].
//!
//! This module is the format only: the forward passes (hypernetwork, encoder, target net) are
//! in [`crate::neural`].

use crate::formats::merl::{BIN_COUNT, PHI_D_BINS, THETA_D_BINS, THETA_H_BINS};
use crate::neural::mapping::MappingForm;
use crate::neural::mlp::{decode_target_net, DenseLayer, Encoder, Mlp};
use crate::{Error, Result};
use half::f16;
use std::path::Path;

/// The 8 bytes every latent file starts with.
pub const MAGIC: [u8; 8] = *b"FRENBRDF";
/// The format version this module writes; it reads this one, version 3 (no residuals),
/// version 2 (no output offsets either) and version 1 (no encoder either).
pub const VERSION: u32 = 4;
/// The oldest format version this module reads.
const OLDEST_VERSION: u32 = 1;
/// Upper bound on any one width, latent size or name length (sanity limit of the reader).
const MAX_DIM: usize = 1 << 20;

/// Element type of the hypernetwork weights in the file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WeightType {
    /// 4 bytes per weight, exact.
    F32,
    /// 2 bytes per weight (halves the decoder's size; relative rounding ≈ 5e-4).
    F16,
}

/// A named latent code.
#[derive(Clone, Debug, PartialEq)]
pub struct NamedLatent {
    /// Material name (unique in the file).
    pub name: String,
    /// z, `latent_dim` values.
    pub z: Vec<f32>,
    /// Output offset δ per RGB channel, added to the target net's output y (the mapped value):
    /// under the talk mapping f_r + ε is scaled by e^δ, a colour gain the shared decoder
    /// may not reach through z for a material it never saw. Fitted with z when a material is
    /// encoded (`material-nn encode`); 0 for codes that need none and in files before
    /// version 3. Interpolated with z in edits.
    pub offset: [f32; 3],
    /// Residual ΔΘ added to the decoded target net's parameters: every tensor in the
    /// hypernetwork's order (W0 b0 W1 b1 … W_last) except the output bias, whose correction
    /// is `offset` — [`LatentFile::residual_len`] values, or none (empty). Fitted with z and
    /// δ when a material is encoded with residual refinement (the shared decoder keeps what
    /// the materials have in common, the residual what it has no code for, such as colour
    /// that changes with angle); empty in files before version 4. Interpolated with z in
    /// edits. Stored in the file's weight dtype.
    pub residual: Vec<f32>,
}

/// The contents of a latent file.
#[derive(Clone, Debug, PartialEq)]
pub struct LatentFile {
    /// Size of a latent code z.
    pub latent_dim: usize,
    /// Target-net widths, input first (6, 60, 60, 60, 60, 3).
    pub target_widths: Vec<usize>,
    /// Hidden widths of each hypernetwork head (128, 128).
    pub hyper_hidden: Vec<usize>,
    /// Form of the log-relative mapping.
    pub mapping: MappingForm,
    /// ε of the mapping.
    pub epsilon: f32,
    /// How the hypernetwork weights are stored on disk.
    pub weight_type: WeightType,
    /// One head per target-net tensor, in the order W0, b0, W1, b1, ...: latent_dim →
    /// hidden... → numel of that tensor.
    pub hypernetwork: Vec<Mlp>,
    /// The set encoder that made the codes, when the file carries it (always f32 on disk;
    /// `None` in version 1 files). `material-nn encode --model FILE` needs it.
    pub encoder: Option<Encoder>,
    /// f_ref per MERL bin (within-channel index), RGB, 1/sr, as f16; negative = unmeasured.
    pub f_ref: Vec<[f16; 3]>,
    /// The latent codes.
    pub latents: Vec<NamedLatent>,
    /// Names of the materials the decoder was trained on.
    pub training_materials: Vec<String>,
}

impl LatentFile {
    /// The shapes (d_in, d_out) of the target-net layers.
    pub fn target_layers(&self) -> Vec<(usize, usize)> {
        self.target_widths
            .windows(2)
            .map(|w| (w[0], w[1]))
            .collect()
    }

    /// Length of a code's residual ([`NamedLatent::residual`]): the target net's parameter
    /// count less its output width (11,580 for 6-60-60-60-60-3).
    pub fn residual_len(&self) -> usize {
        let params: usize = self.target_layers().iter().map(|(i, o)| i * o + o).sum();
        params - self.target_widths.last().copied().unwrap_or(0)
    }

    /// Decodes a latent code into the target net ([`decode_target_net`] with this file's
    /// hypernetwork and target-net shape): the code's output offset (per channel of the last
    /// layer) added to its output bias and its residual (empty: none; see
    /// [`NamedLatent::residual`]) to the other parameters.
    ///
    /// # Panics
    /// If `z.len()` differs from `latent_dim`, the target net does not end in
    /// `offset.len()` outputs, or the residual is neither empty nor
    /// [`LatentFile::residual_len`] long (a file read by [`LatentFile::read`] is
    /// consistent; check user-made codes first).
    pub fn decode(&self, z: &[f32], offset: [f32; 3], residual: &[f32]) -> Mlp {
        assert_eq!(z.len(), self.latent_dim, "latent code size");
        assert!(
            residual.is_empty() || residual.len() == self.residual_len(),
            "residual size"
        );
        decode_target_net(&self.hypernetwork, &self.target_layers(), z, offset, residual)
    }

    /// The latent code called `name`.
    pub fn latent(&self, name: &str) -> Option<&NamedLatent> {
        self.latents.iter().find(|l| l.name == name)
    }

    /// The names of the latent codes, in file order.
    pub fn latent_names(&self) -> Vec<String> {
        self.latents.iter().map(|l| l.name.clone()).collect()
    }

    /// f_ref of a bin (within-channel index) as f32, 1/sr; negative channels unmeasured.
    #[inline]
    pub fn f_ref(&self, bin: usize) -> [f32; 3] {
        self.f_ref[bin].map(f16::to_f32)
    }

    /// A tiny file for tests, fuzzing seeds and examples: target net 6-4-3, latent size 2,
    /// hypernetwork heads with hidden widths `hyper_hidden` and fixed pseudo-random weights in
    /// [−0.5, 0.5), talk mapping with ε = 0.002, f_ref 0.25 everywhere, codes "gold" (0.5, 1)
    /// and "blue-acrylic" (0, 2; with an output offset and a residual, both exact in f16),
    /// trained on "gold" and "silver", no encoder (see
    /// [`LatentFile::with_synthetic_encoder`]). Valid unless a hidden width is 0 (which
    /// [`LatentFile::validate`] rejects).
    pub fn synthetic(hyper_hidden: &[usize], weight_type: WeightType) -> LatentFile {
        let (widths, latent_dim) = (vec![6, 4, 3], 2);
        let mut next = pseudo_random(1);
        let mut hypernetwork = Vec::new();
        for w in widths.windows(2) {
            for numel in [w[0] * w[1], w[1]] {
                let dims: Vec<usize> = std::iter::once(latent_dim)
                    .chain(hyper_hidden.iter().copied())
                    .chain(std::iter::once(numel))
                    .collect();
                let layers = dims
                    .windows(2)
                    .map(|d| DenseLayer {
                        d_in: d[0],
                        d_out: d[1],
                        weight: (0..d[0] * d[1]).map(|_| next()).collect(),
                        bias: (0..d[1]).map(|_| next()).collect(),
                    })
                    .collect();
                hypernetwork.push(Mlp { layers });
            }
        }
        LatentFile {
            latent_dim,
            target_widths: widths,
            hyper_hidden: hyper_hidden.to_vec(),
            mapping: MappingForm::Talk,
            epsilon: 0.002,
            weight_type,
            hypernetwork,
            f_ref: vec![[f16::from_f32(0.25); 3]; BIN_COUNT],
            latents: vec![
                NamedLatent {
                    name: "gold".into(),
                    z: vec![0.5, 1.0],
                    offset: [0.0; 3],
                    residual: Vec::new(),
                },
                NamedLatent {
                    name: "blue-acrylic".into(),
                    z: vec![0.0, 2.0],
                    offset: [0.25, 0.0, -0.5],
                    residual: (0..40).map(|i| ((i % 7) as f32 - 3.0) / 32.0).collect(),
                },
            ],
            encoder: None,
            training_materials: vec!["gold".into(), "silver".into()],
        }
    }

    /// The file with a tiny encoder for tests, fuzzing seeds and examples: widths 9 → 5 →
    /// latent_dim, fixed pseudo-random weights in [−0.5, 0.5), biases in [0, 1) (so most
    /// outputs are positive), peak_share 0.5.
    pub fn with_synthetic_encoder(mut self) -> LatentFile {
        let mut next = pseudo_random(7);
        let layers = [Encoder::INPUT_WIDTH, 5, self.latent_dim]
            .windows(2)
            .map(|d| DenseLayer {
                d_in: d[0],
                d_out: d[1],
                weight: (0..d[0] * d[1]).map(|_| next()).collect(),
                bias: (0..d[1]).map(|_| next() + 0.5).collect(),
            })
            .collect();
        self.encoder = Some(Encoder {
            layers,
            peak_share: 0.5,
        });
        self
    }

    /// Checks every invariant the renderer relies on; `path` names the file in errors.
    pub fn validate(&self, path: &Path) -> Result<()> {
        let bad = |reason: String| Err(Error::invalid_file(path, reason));
        if self.latent_dim == 0
            || self.target_widths.len() < 2
            || self.target_widths.contains(&0)
            || self.hyper_hidden.contains(&0)
        {
            return bad(format!(
                "bad shape: latent_dim {}, target widths {:?}, hypernetwork widths {:?}",
                self.latent_dim, self.target_widths, self.hyper_hidden
            ));
        }
        if self.target_widths.last() != Some(&3) {
            return bad(format!(
                "the target net has {} outputs, expected 3 (RGB)",
                self.target_widths[self.target_widths.len() - 1]
            ));
        }
        if !(self.epsilon.is_finite() && self.epsilon > 0.0) {
            return bad(format!(
                "mapping epsilon {} is not a positive number",
                self.epsilon
            ));
        }
        let layers = self.target_layers();
        if self.hypernetwork.len() != 2 * layers.len() {
            return bad(format!(
                "{} hypernetwork heads, the target net has {} tensors",
                self.hypernetwork.len(),
                2 * layers.len()
            ));
        }
        for (t, head) in self.hypernetwork.iter().enumerate() {
            let (d_in, d_out) = layers[t / 2];
            let numel = if t % 2 == 0 { d_in * d_out } else { d_out };
            let mut widths = vec![self.latent_dim];
            widths.extend(&self.hyper_hidden);
            widths.push(numel);
            if head.layers.len() + 1 != widths.len() {
                return bad(format!(
                    "hypernetwork head {t} has {} layers",
                    head.layers.len()
                ));
            }
            for (l, layer) in head.layers.iter().enumerate() {
                layer
                    .check(widths[l], widths[l + 1])
                    .map_err(|e| Error::invalid_file(path, format!("hypernetwork head {t} layer {l}: {e}")))?;
            }
        }
        if let Some(encoder) = &self.encoder {
            self.validate_encoder(encoder, path)?;
        }
        if self.f_ref.len() != BIN_COUNT {
            return bad(format!(
                "f_ref has {} bins, expected {BIN_COUNT}",
                self.f_ref.len()
            ));
        }
        if let Some(i) = self
            .f_ref
            .iter()
            .position(|v| v.iter().any(|c| !c.is_finite()))
        {
            return bad(format!("non-finite f_ref value at bin {i}"));
        }
        let mut names = std::collections::HashSet::new();
        for l in &self.latents {
            if l.z.len() != self.latent_dim {
                return bad(format!(
                    "latent '{}' has {} values, expected {}",
                    l.name,
                    l.z.len(),
                    self.latent_dim
                ));
            }
            if !l.residual.is_empty() && l.residual.len() != self.residual_len() {
                return bad(format!(
                    "latent '{}' has a residual of {} values, expected {} or none",
                    l.name,
                    l.residual.len(),
                    self.residual_len()
                ));
            }
            if l.z.iter().chain(&l.offset).chain(&l.residual).any(|v| !v.is_finite()) {
                return bad(format!("latent '{}' has a non-finite value", l.name));
            }
            if !names.insert(l.name.as_str()) {
                return bad(format!("latent name '{}' appears twice", l.name));
            }
        }
        Ok(())
    }

    /// The encoder's part of [`LatentFile::validate`].
    fn validate_encoder(&self, encoder: &Encoder, path: &Path) -> Result<()> {
        let bad = |reason: String| Err(Error::invalid_file(path, reason));
        if !(0.0..=1.0).contains(&encoder.peak_share) {
            return bad(format!(
                "encoder peak_share {} is not in [0, 1]",
                encoder.peak_share
            ));
        }
        let mut widths = vec![encoder.layers.first().map_or(0, |l| l.d_in)];
        widths.extend(encoder.layers.iter().map(|l| l.d_out));
        if encoder.layers.is_empty()
            || widths[0] != Encoder::INPUT_WIDTH
            || widths.last() != Some(&self.latent_dim)
            || widths.iter().any(|&w| w == 0 || w > MAX_DIM)
        {
            return bad(format!(
                "bad encoder shape: widths {widths:?}, expected {} first, latent_dim {} last",
                Encoder::INPUT_WIDTH,
                self.latent_dim
            ));
        }
        for (l, layer) in encoder.layers.iter().enumerate() {
            layer
                .check(widths[l], widths[l + 1])
                .map_err(|e| Error::invalid_file(path, format!("encoder layer {l}: {e}")))?;
        }
        Ok(())
    }

    /// Serialises the file (see the module documentation), checksum included.
    pub fn to_bytes(&self) -> Vec<u8> {
        self.to_bytes_of_version(VERSION)
    }

    /// Serialises the file in the layout of `version` (1 to [`VERSION`]); what an older
    /// version cannot hold (the encoder before 2, output offsets before 3, residuals before
    /// 4) is left out.
    fn to_bytes_of_version(&self, version: u32) -> Vec<u8> {
        let mut w = Vec::new();
        w.extend_from_slice(&MAGIC);
        put_u32(&mut w, version);
        put_u32(&mut w, self.latent_dim as u32);
        put_u32(&mut w, (self.target_widths.len() - 1) as u32);
        self.target_widths
            .iter()
            .for_each(|&v| put_u32(&mut w, v as u32));
        put_u32(&mut w, self.hyper_hidden.len() as u32);
        self.hyper_hidden
            .iter()
            .for_each(|&v| put_u32(&mut w, v as u32));
        w.push(self.mapping.code());
        w.push(match self.weight_type {
            WeightType::F32 => 0,
            WeightType::F16 => 1,
        });
        w.extend_from_slice(&[0, 0]);
        w.extend_from_slice(&self.epsilon.to_le_bytes());
        let put_weight = |w: &mut Vec<u8>, v: f32| match self.weight_type {
            WeightType::F32 => w.extend_from_slice(&v.to_le_bytes()),
            WeightType::F16 => w.extend_from_slice(&f16::from_f32(v).to_le_bytes()),
        };
        for head in &self.hypernetwork {
            for layer in &head.layers {
                for v in layer.weight.iter().chain(&layer.bias) {
                    put_weight(&mut w, *v);
                }
            }
        }
        match &self.encoder {
            _ if version < 2 => {}
            None => w.push(0),
            Some(encoder) => {
                w.push(1);
                w.extend_from_slice(&encoder.peak_share.to_le_bytes());
                put_u32(&mut w, encoder.layers.len() as u32);
                if let Some(first) = encoder.layers.first() {
                    put_u32(&mut w, first.d_in as u32);
                }
                for layer in &encoder.layers {
                    put_u32(&mut w, layer.d_out as u32);
                }
                for layer in &encoder.layers {
                    for v in layer.weight.iter().chain(&layer.bias) {
                        w.extend_from_slice(&v.to_le_bytes());
                    }
                }
            }
        }
        for dim in [THETA_H_BINS, THETA_D_BINS, PHI_D_BINS] {
            put_u32(&mut w, dim as u32);
        }
        for v in self.f_ref.iter().flatten() {
            w.extend_from_slice(&v.to_le_bytes());
        }
        put_u32(&mut w, self.latents.len() as u32);
        for l in &self.latents {
            put_str(&mut w, &l.name);
            let offset: &[f32] = if version >= 3 { &l.offset } else { &[] };
            l.z.iter()
                .chain(offset)
                .for_each(|v| w.extend_from_slice(&v.to_le_bytes()));
            if version >= 4 {
                put_u32(&mut w, l.residual.len() as u32);
                l.residual.iter().for_each(|v| put_weight(&mut w, *v));
            }
        }
        put_u32(&mut w, self.training_materials.len() as u32);
        self.training_materials
            .iter()
            .for_each(|n| put_str(&mut w, n));
        let sum = crate::support::fnv1a64(&w);
        w.extend_from_slice(&sum.to_le_bytes());
        w
    }

    /// Parses and validates a file's bytes; `path` names it in errors.
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Self> {
        let bad = |reason: String| Error::invalid_file(path, reason);
        if bytes.len() < 12 || bytes[..8] != MAGIC {
            return Err(bad(
                "not a latent file (bad magic; expected \"FRENBRDF\")".to_string()
            ));
        }
        let version = u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]);
        if !(OLDEST_VERSION..=VERSION).contains(&version) {
            return Err(bad(format!(
                "latent file version {version}, this build reads versions {OLDEST_VERSION} to \
                 {VERSION}"
            )));
        }
        if bytes.len() < 20 {
            return Err(bad(format!("truncated latent file: {} bytes", bytes.len())));
        }
        let (body, tail) = bytes.split_at(bytes.len() - 8);
        let stored = u64::from_le_bytes(tail.try_into().map_err(|_| bad("truncated".into()))?);
        if crate::support::fnv1a64(body) != stored {
            return Err(bad(
                "checksum mismatch: the file is corrupt or truncated".to_string()
            ));
        }
        let mut r = Cursor {
            bytes: body,
            at: 12,
            path,
        };
        let latent_dim = r.dim("latent_dim")?;
        let layer_count = r.dim("target layer count")?;
        let target_widths = (0..=layer_count)
            .map(|_| r.dim("target width"))
            .collect::<Result<Vec<_>>>()?;
        let hidden_count = r.dim("hypernetwork layer count")?;
        let hyper_hidden = (0..hidden_count)
            .map(|_| r.dim("hypernetwork width"))
            .collect::<Result<Vec<_>>>()?;
        let flags = r.take(4)?;
        let mapping = match flags[0] {
            0 => MappingForm::Talk,
            1 => MappingForm::Code,
            m => return Err(bad(format!("unknown mapping form {m}"))),
        };
        let weight_type = match flags[1] {
            0 => WeightType::F32,
            1 => WeightType::F16,
            t => return Err(bad(format!("unknown weight type {t}"))),
        };
        let epsilon = r.f32()?;
        if target_widths.len() < 2 {
            return Err(bad("the target net needs at least one layer".to_string()));
        }
        let mut hypernetwork = Vec::new();
        for (d_in, d_out) in target_widths.windows(2).map(|w| (w[0], w[1])) {
            for numel in [d_in * d_out, d_out] {
                let mut widths = vec![latent_dim];
                widths.extend(&hyper_hidden);
                widths.push(numel);
                let mut layers = Vec::new();
                for w in widths.windows(2) {
                    let weight = r.weights(w[0] * w[1], weight_type)?;
                    let bias = r.weights(w[1], weight_type)?;
                    layers.push(DenseLayer {
                        d_in: w[0],
                        d_out: w[1],
                        weight,
                        bias,
                    });
                }
                hypernetwork.push(Mlp { layers });
            }
        }
        let encoder = if version >= 2 { r.encoder()? } else { None };
        let dims = [r.u32()?, r.u32()?, r.u32()?];
        if dims != [THETA_H_BINS as u32, THETA_D_BINS as u32, PHI_D_BINS as u32] {
            return Err(bad(format!("f_ref dims {dims:?}, expected [90, 90, 180]")));
        }
        let raw = r.take(BIN_COUNT * 6)?;
        let f_ref = raw
            .chunks_exact(6)
            .map(|c| [0, 2, 4].map(|k| f16::from_le_bytes([c[k], c[k + 1]])))
            .collect();
        let count = r.dim("latent count")?;
        let mut latents = Vec::new();
        for _ in 0..count {
            let name = r.string()?;
            let z = (0..latent_dim)
                .map(|_| r.f32())
                .collect::<Result<Vec<_>>>()?;
            let offset = if version >= 3 { [r.f32()?, r.f32()?, r.f32()?] } else { [0.0; 3] };
            let residual = if version >= 4 {
                let n = r.dim("residual length")?;
                r.weights(n, weight_type)?
            } else {
                Vec::new()
            };
            latents.push(NamedLatent { name, z, offset, residual });
        }
        let count = r.dim("training material count")?;
        let training_materials = (0..count).map(|_| r.string()).collect::<Result<Vec<_>>>()?;
        if r.at != body.len() {
            return Err(bad(format!(
                "{} unexpected bytes after the last section",
                body.len() - r.at
            )));
        }
        let file = LatentFile {
            latent_dim,
            target_widths,
            hyper_hidden,
            mapping,
            epsilon,
            weight_type,
            hypernetwork,
            encoder,
            f_ref,
            latents,
            training_materials,
        };
        file.validate(path)?;
        Ok(file)
    }

    /// Reads and validates a latent file.
    pub fn read(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        Self::from_bytes(&bytes, path)
    }

    /// Validates and writes the file atomically ([`crate::support::write_atomically`]).
    pub fn write(&self, path: impl AsRef<Path>) -> Result<()> {
        let path = path.as_ref();
        self.validate(path)?;
        crate::support::write_bytes_atomically(path, &self.to_bytes())
    }
}

fn put_u32(w: &mut Vec<u8>, v: u32) {
    w.extend_from_slice(&v.to_le_bytes());
}

fn put_str(w: &mut Vec<u8>, s: &str) {
    put_u32(w, s.len() as u32);
    w.extend_from_slice(s.as_bytes());
}


/// Fixed pseudo-random numbers in [−0.5, 0.5) (an LCG) for the synthetic files.
fn pseudo_random(mut seed: u32) -> impl FnMut() -> f32 {
    move || {
        seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (seed >> 8) as f32 / (1 << 24) as f32 - 0.5
    }
}

/// A bounds-checked reader over the file's bytes.
struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
    path: &'a Path,
}

impl Cursor<'_> {
    fn take(&mut self, n: usize) -> Result<&[u8]> {
        if self.bytes.len() - self.at < n {
            return Err(Error::invalid_file(
                self.path,
                format!(
                    "truncated latent file: {n} more bytes needed at offset {}",
                    self.at
                ),
            ));
        }
        self.at += n;
        Ok(&self.bytes[self.at - n..self.at])
    }

    fn u32(&mut self) -> Result<u32> {
        let b = self.take(4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    fn f32(&mut self) -> Result<f32> {
        Ok(f32::from_bits(self.u32()?))
    }

    fn dim(&mut self, what: &str) -> Result<usize> {
        let v = self.u32()? as usize;
        if v > MAX_DIM {
            return Err(Error::invalid_file(
                self.path,
                format!("{what} {v} is implausibly large"),
            ));
        }
        Ok(v)
    }

    fn weights(&mut self, n: usize, ty: WeightType) -> Result<Vec<f32>> {
        Ok(match ty {
            WeightType::F32 => self
                .take(4 * n)?
                .chunks_exact(4)
                .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .collect(),
            WeightType::F16 => self
                .take(2 * n)?
                .chunks_exact(2)
                .map(|b| f16::from_le_bytes([b[0], b[1]]).to_f32())
                .collect(),
        })
    }

    /// The encoder section of a version 2 file (flag, then the encoder when present); shapes
    /// and values are checked by [`LatentFile::validate`].
    fn encoder(&mut self) -> Result<Option<Encoder>> {
        match self.take(1)?[0] {
            0 => return Ok(None),
            1 => {}
            f => {
                return Err(Error::invalid_file(
                    self.path,
                    format!("unknown encoder flag {f} (0 none, 1 present)"),
                ))
            }
        }
        let peak_share = self.f32()?;
        let count = self.dim("encoder layer count")?;
        let widths = (0..=count)
            .map(|_| self.dim("encoder width"))
            .collect::<Result<Vec<_>>>()?;
        let layers = widths
            .windows(2)
            .map(|w| {
                Ok(DenseLayer {
                    d_in: w[0],
                    d_out: w[1],
                    weight: self.weights(w[0] * w[1], WeightType::F32)?,
                    bias: self.weights(w[1], WeightType::F32)?,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Some(Encoder { layers, peak_share }))
    }

    fn string(&mut self) -> Result<String> {
        let n = self.dim("name length")?;
        let path = self.path;
        String::from_utf8(self.take(n)?.to_vec())
            .map_err(|_| Error::invalid_file(path, "a name is not valid UTF-8"))
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A tiny valid file (see [`LatentFile::synthetic`]) with one hidden layer of 5.
    pub(crate) fn small_file(weight_type: WeightType) -> LatentFile {
        LatentFile::synthetic(&[5], weight_type)
    }

    #[test]
    fn round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("latent.bin");
        let file = small_file(WeightType::F32);
        file.write(&path).unwrap();
        let back = LatentFile::read(&path).unwrap();
        assert_eq!(back, file);
        let gold = back.latent("gold").unwrap();
        let net = back.decode(&gold.z, gold.offset, &gold.residual);
        assert_eq!(net.layers.len(), 2);
        assert_eq!(net.forward(&[0.1; 6]).len(), 3);
        assert_eq!(back.latent_names(), vec!["gold", "blue-acrylic"]);

        let half = small_file(WeightType::F16);
        let bytes = half.to_bytes();
        assert!(bytes.len() < file.to_bytes().len());
        let back = LatentFile::from_bytes(&bytes, &path).unwrap();
        let a = back.hypernetwork[0].layers[0].weight[3];
        assert!((a - half.hypernetwork[0].layers[0].weight[3]).abs() < 1e-3);
    }

    #[test]
    fn bad_files_are_rejected_with_the_reason() {
        let path = Path::new("dir/latent.bin");
        let good = small_file(WeightType::F32).to_bytes();
        let err = |b: &[u8]| LatentFile::from_bytes(b, path).unwrap_err().to_string();

        let e = err(b"PK\x03\x04 not a latent file");
        assert!(e.contains("latent.bin") && e.contains("bad magic"), "{e}");

        let mut v5 = good.clone();
        v5[8..12].copy_from_slice(&5u32.to_le_bytes());
        let e = err(&v5);
        assert!(
            e.contains("latent.bin")
                && e.contains("version 5")
                && e.contains("reads versions 1 to 4"),
            "{e}"
        );

        let e = err(&good[..good.len() - 100]);
        assert!(e.contains("checksum"), "{e}");

        let mut flipped = good.clone();
        flipped[40] ^= 0xff;
        assert!(err(&flipped).contains("checksum"));

        let mut nan = small_file(WeightType::F32);
        nan.latents[1].z[0] = f32::NAN;
        let e = err(&nan.to_bytes());
        assert!(
            e.contains("latent 'blue-acrylic' has a non-finite value"),
            "{e}"
        );
        let mut nan_offset = small_file(WeightType::F32);
        nan_offset.latents[0].offset[2] = f32::INFINITY;
        let e = err(&nan_offset.to_bytes());
        assert!(e.contains("latent 'gold' has a non-finite value"), "{e}");
        let mut short = small_file(WeightType::F32);
        short.latents[1].residual.pop();
        let e = err(&short.to_bytes());
        assert!(e.contains("residual of 39 values, expected 40 or none"), "{e}");
        let mut nan_residual = small_file(WeightType::F32);
        nan_residual.latents[1].residual[7] = f32::NAN;
        let e = err(&nan_residual.to_bytes());
        assert!(e.contains("latent 'blue-acrylic' has a non-finite value"), "{e}");
        assert!(nan
            .write(std::env::temp_dir().join("never-written.bin"))
            .is_err());

        let mut dup = small_file(WeightType::F32);
        dup.latents[1].name = "gold".into();
        assert!(err(&dup.to_bytes()).contains("appears twice"));
    }

    /// Where the encoder flag byte of `file`'s bytes (the current version) is: right before
    /// the encoder (if any) and the f_ref dims, which come 6 · BIN_COUNT bytes before the
    /// codes, the names and the checksum.
    fn encoder_flag_offset(file: &LatentFile, bytes: &[u8]) -> usize {
        let weight_size = match file.weight_type {
            WeightType::F32 => 4,
            WeightType::F16 => 2,
        };
        let codes: usize = file
            .latents
            .iter()
            .map(|l| 4 + l.name.len() + 4 * (l.z.len() + l.offset.len()) + 4 + weight_size * l.residual.len())
            .sum();
        let names: usize = file.training_materials.iter().map(|n| 4 + n.len()).sum();
        let tail = 4 + codes + 4 + names + 8;
        let encoder = file.encoder.as_ref().map_or(0, |e| {
            let values: usize = e.layers.iter().map(|l| l.weight.len() + l.bias.len()).sum();
            4 + 4 + 4 * (e.layers.len() + 1) + 4 * values
        });
        let at = bytes.len() - tail - 6 * BIN_COUNT - 12 - encoder - 1;
        let dims: Vec<u8> = [90u32, 90, 180]
            .iter()
            .flat_map(|d| d.to_le_bytes())
            .collect();
        let dims_at = at + 1 + encoder;
        assert_eq!(bytes[dims_at..dims_at + 12], dims[..], "f_ref dims located");
        at
    }

    fn fix_checksum(bytes: &mut Vec<u8>) {
        bytes.truncate(bytes.len() - 8);
        let sum = crate::support::fnv1a64(bytes);
        bytes.extend_from_slice(&sum.to_le_bytes());
    }

    /// A few encoder samples: [6D input ‖ 3 mapped values].
    const SAMPLES: [[f32; 9]; 3] = [
        [0.1, 0.0, 0.9, 0.3, 0.5, 0.7, -1.0, 0.5, 2.0],
        [0.7, 0.0, 0.6, 0.1, 0.2, 0.9, 0.3, 0.3, 0.3],
        [0.0, 0.0, 1.0, 0.8, 0.4, 0.2, -4.0, -3.0, 1.5],
    ];

    #[test]
    fn round_trip_with_encoder() {
        let path = Path::new("dir/latent.bin");
        for weight_type in [WeightType::F32, WeightType::F16] {
            let file = small_file(weight_type).with_synthetic_encoder();
            let bytes = file.to_bytes();
            assert_eq!(bytes[8..12], VERSION.to_le_bytes());
            let at = encoder_flag_offset(&file, &bytes);
            assert_eq!(bytes[at], 1, "encoder flag");
            let back = LatentFile::from_bytes(&bytes, path).unwrap();
            assert_eq!(back.to_bytes(), bytes, "{weight_type:?}");
            let (encoder, back_encoder) = (
                file.encoder.as_ref().unwrap(),
                back.encoder.as_ref().unwrap(),
            );
            // The encoder is stored as f32 whatever the hypernetwork's weight type: exact.
            assert_eq!(back_encoder, encoder, "{weight_type:?}");
            let z = encoder.encode(&SAMPLES);
            assert_eq!(z.len(), file.latent_dim);
            assert!(
                z.iter().all(|&v| v >= 0.0) && z.iter().any(|&v| v > 0.0),
                "{z:?}"
            );
            assert_eq!(back_encoder.encode(&SAMPLES), z);
        }
        // Without an encoder the flag is 0 and the file reads back with none.
        let plain = small_file(WeightType::F32);
        let bytes = plain.to_bytes();
        assert_eq!(bytes[encoder_flag_offset(&plain, &bytes)], 0);
        assert_eq!(LatentFile::from_bytes(&bytes, path).unwrap().encoder, None);
        // Through the file system too.
        let dir = tempfile::tempdir().unwrap();
        let file = small_file(WeightType::F32).with_synthetic_encoder();
        file.write(dir.path().join("latent.bin")).unwrap();
        assert!(LatentFile::read(dir.path().join("latent.bin")).unwrap() == file);
    }

    #[test]
    fn encode_is_relu_layers_then_the_mean() {
        // One layer 9 → 2: out0 = x0 + x6 + 0.5, out1 = −x7 (ReLU clamps it).
        let mut weight = vec![0.0; 18];
        weight[0] = 1.0;
        weight[2 * 6] = 1.0;
        weight[2 * 7 + 1] = -1.0;
        let encoder = Encoder {
            layers: vec![DenseLayer {
                d_in: 9,
                d_out: 2,
                weight,
                bias: vec![0.5, 0.0],
            }],
            peak_share: 0.25,
        };
        // Sample sums: out0 = 0.1 − 1 + 0.5 → 0 (ReLU), 0.7 + 0.3 + 0.5 = 1.5, 0 − 4 + 0.5 → 0;
        // out1 = −0.5 → 0, −0.3 → 0, 3.
        let z = encoder.encode(&SAMPLES);
        assert!(
            (z[0] - 0.5).abs() < 1e-6 && (z[1] - 1.0).abs() < 1e-6,
            "{z:?}"
        );
        assert_eq!(encoder.encode(&[]), vec![0.0, 0.0]);
        assert_eq!(encoder.output_width(), 2);
    }

    #[test]
    fn version_1_files_still_read_without_an_encoder() {
        let path = Path::new("dir/latent.bin");
        let file = small_file(WeightType::F16);
        let mut bytes = file.to_bytes_of_version(2);
        let at = encoder_flag_offset(&file, &file.to_bytes());
        assert_eq!(bytes[at], 0);
        let mut v1 = bytes.clone();
        v1.remove(at);
        v1[8..12].copy_from_slice(&1u32.to_le_bytes());
        fix_checksum(&mut v1);
        assert_eq!(v1, file.to_bytes_of_version(1));
        let back = LatentFile::from_bytes(&v1, path).unwrap();
        assert_eq!(back.encoder, None);
        // (f16 weights, no offsets: equal to the version 2 file read back, not to `file`.)
        assert!(back == LatentFile::from_bytes(&bytes, path).unwrap());
        // A version 2 file without the flag byte is not one.
        bytes.remove(at);
        fix_checksum(&mut bytes);
        assert!(LatentFile::from_bytes(&bytes, path).is_err());
    }

    #[test]
    fn version_2_and_3_files_read_without_offsets_or_residuals() {
        let path = Path::new("dir/latent.bin");
        let file = small_file(WeightType::F32).with_synthetic_encoder();
        assert!(file.latents.iter().any(|l| l.offset != [0.0; 3]));
        assert!(file.latents.iter().any(|l| !l.residual.is_empty()));
        let (v2, v3, v4) = (file.to_bytes_of_version(2), file.to_bytes_of_version(3), file.to_bytes());
        assert_eq!(v2[8..12], 2u32.to_le_bytes());
        assert_eq!(v3[8..12], 3u32.to_le_bytes());
        assert_eq!(v3.len() - v2.len(), 12 * file.latents.len(), "three f32 per code");
        let residuals: usize = file.latents.iter().map(|l| 4 + 4 * l.residual.len()).sum();
        assert_eq!(v4.len() - v3.len(), residuals, "a length and the f32 values per code");
        let strip = |offsets: bool| LatentFile {
            latents: file
                .latents
                .iter()
                .map(|l| NamedLatent {
                    offset: if offsets { l.offset } else { [0.0; 3] },
                    residual: Vec::new(),
                    ..l.clone()
                })
                .collect(),
            ..file.clone()
        };
        let back = LatentFile::from_bytes(&v2, path).unwrap();
        assert_eq!(back, strip(false));
        assert_eq!(LatentFile::from_bytes(&v3, path).unwrap(), strip(true));
        // Written again, it is the current version, and reads back the same.
        assert_eq!(LatentFile::from_bytes(&back.to_bytes(), path).unwrap(), strip(false));
    }

    #[test]
    fn the_offset_shifts_the_decoded_output_and_nothing_else() {
        let file = small_file(WeightType::F32);
        let code = file.latent("blue-acrylic").unwrap();
        let (plain, shifted) = (file.decode(&code.z, [0.0; 3], &[]), file.decode(&code.z, code.offset, &[]));
        let last = plain.layers.len() - 1;
        assert_eq!(plain.layers[..last], shifted.layers[..last]);
        assert_eq!(plain.layers[last].weight, shifted.layers[last].weight);
        let x = [0.2, 0.0, 0.9, 0.1, -0.3, 0.4];
        let (a, b) = (plain.forward(&x), shifted.forward(&x));
        for c in 0..3 {
            assert!((b[c] - a[c] - code.offset[c]).abs() < 1e-6, "channel {c}: {a:?} {b:?}");
        }
    }

    #[test]
    fn the_residual_adds_to_every_decoded_parameter_but_the_output_bias() {
        let file = small_file(WeightType::F32);
        let code = file.latent("blue-acrylic").unwrap();
        assert_eq!(code.residual.len(), file.residual_len());
        assert_eq!(file.residual_len(), 6 * 4 + 4 + 4 * 3, "6-4-3 less the output bias");
        let (plain, corrected) = (
            file.decode(&code.z, code.offset, &[]),
            file.decode(&code.z, code.offset, &code.residual),
        );
        let flat = |net: &Mlp| -> Vec<f32> {
            net.layers.iter().flat_map(|l| l.weight.iter().chain(&l.bias)).copied().collect()
        };
        let (a, b) = (flat(&plain), flat(&corrected));
        let n = file.residual_len();
        for k in 0..n {
            let d = b[k] - a[k];
            assert!((d - code.residual[k]).abs() < 1e-6, "parameter {k}: {d} vs {}", code.residual[k]);
        }
        assert_eq!(a[n..], b[n..], "the output bias is the offset's");
    }

    #[test]
    fn bad_encoders_are_rejected_with_the_reason() {
        let path = Path::new("dir/latent.bin");
        let err = |f: &LatentFile| {
            assert!(f
                .write(std::env::temp_dir().join("never-written.bin"))
                .is_err());
            LatentFile::from_bytes(&f.to_bytes(), path)
                .unwrap_err()
                .to_string()
        };
        let good = small_file(WeightType::F32).with_synthetic_encoder();
        assert!(LatentFile::from_bytes(&good.to_bytes(), path).is_ok());

        let mut wide = good.clone();
        let last = wide.encoder.as_mut().unwrap().layers.last_mut().unwrap();
        last.d_out = 3;
        last.weight = vec![0.1; last.d_in * 3];
        last.bias = vec![0.1; 3];
        let e = err(&wide);
        assert!(
            e.starts_with("dir/latent.bin")
                && e.contains("bad encoder shape")
                && e.contains("latent_dim 2"),
            "{e}"
        );

        let mut narrow = good.clone();
        let first = &mut narrow.encoder.as_mut().unwrap().layers[0];
        first.d_in = 8;
        first.weight.truncate(8 * first.d_out);
        let e = err(&narrow);
        assert!(
            e.contains("bad encoder shape") && e.contains("[8, 5, 2]"),
            "{e}"
        );

        let mut nan = good.clone();
        nan.encoder.as_mut().unwrap().layers[1].weight[3] = f32::NAN;
        let e = err(&nan);
        assert!(
            e.starts_with("dir/latent.bin") && e.contains("encoder layer 1: non-finite weight"),
            "{e}"
        );

        for share in [1.5, -0.1, f32::NAN] {
            let mut peak = good.clone();
            peak.encoder.as_mut().unwrap().peak_share = share;
            let e = err(&peak);
            assert!(
                e.starts_with("dir/latent.bin") && e.contains(&format!("peak_share {share}")),
                "{e}"
            );
        }

        let mut bytes = good.to_bytes();
        let at = encoder_flag_offset(&good, &bytes);
        bytes[at] = 2;
        fix_checksum(&mut bytes);
        let e = LatentFile::from_bytes(&bytes, path)
            .unwrap_err()
            .to_string();
        assert!(e.contains("unknown encoder flag 2"), "{e}");
    }

    #[test]
    fn mapping_inverts() {
        for form in [MappingForm::Talk, MappingForm::Code] {
            for (f, r) in [(0.0f32, 0.1f32), (3.0, 0.2), (500.0, 20.0)] {
                let y = form.forward(f, r, 0.002);
                let back = form.inverse(y, r, 0.002);
                assert!(
                    (back - f).abs() <= 1e-4 * f.max(1.0),
                    "{form:?} {f} {r} -> {back}"
                );
            }
        }
    }
}
