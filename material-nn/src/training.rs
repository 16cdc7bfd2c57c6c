//! The training loop of HyperBRDF / FreNBRDF (`material-nn train`).
//!
//! One step: for each of `materials_per_step` training materials (the method uses 1; with
//! `augment`, a share of them replaced by a synthetic variant, [`crate::augment`]) draw a
//! fresh sample set of the rendered domain ([`crate::dataset::Sampler`]: θh partly with MERL's
//! spacing, φd folded as the renderer folds it, nothing below either horizon), encode its
//! first `encoder_samples` samples into z, decode z into target-net weights, evaluate the
//! target net on every sample (with `interpolation`, a share of the steps adds an
//! interpolated frame between the material and a partner, [`crate::interpolation`]: its code
//! the blend of the two encoder codes, its samples the blend of the two tables'), and take an
//! Adam step on L_rec (+ η L_fre for FreNBRDF, in the
//! configured form: fixed θh slices or the released code's splat) with the global gradient
//! norm clipped and the learning rate of the configured schedule. With `fre.eta_share`, η is
//! set before the first step so that η·L_fre is that share of the data term for the initial
//! model, and recorded in the run's configuration. An epoch visits every training material
//! once, in an order shuffled by the run's generator. After each epoch: validation (data
//! term + η L_fre on a fixed sample set per validation material — the same sets every epoch),
//! early stopping after `patience` epochs without improvement (on the training loss when
//! there are no validation materials), and a checkpoint. A stop request (Ctrl-C) ends the run
//! after the current step with a checkpoint.
//!
//! The run's files are described in [`crate::run`]. Everything random comes from one seeded generator whose
//! state is checkpointed, so a resumed run ends with the same weights as an uninterrupted one.

use crate::backend::{optimizer, training_device};
use crate::checkpoint::{Checkpoint, EpochRecord, TrainState};
use crate::config::{FreForm, TrainConfig};
use crate::dataset::{MaterialDataset, MaterialTable, SampleSet, Sampler, Split};
use crate::error::{Error, Result};
use crate::loss::{FreOperator, ReconstructionLoss, SliceTarget, SlicedFre};
use crate::model::HyperBrdf;
use crate::run::{load_model, model_bytes, read_json, write_json, RunDir, RunInfo};
use crate::tables::{list_tables, material_name};
use burn::module::{Module, ModuleVisitor, Param, ParamId};
use burn::optim::{GradientsParams, ModuleOptimizer};
use burn::tensor::{Bytes, Device, Tensor, TensorData};
use rand::SeedableRng;
use rand::seq::SliceRandom;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// What `train` was asked to do.
#[derive(Clone, Debug)]
pub struct TrainRequest {
    /// Directory of `.binary` tables.
    pub data_dir: PathBuf,
    /// Run directory (created if missing).
    pub run_dir: PathBuf,
    /// Configuration of a new run (defaults if `None`); with `resume`, must equal the
    /// checkpoint's if given.
    pub config: Option<TrainConfig>,
    /// Continue from the run's checkpoint.
    pub resume: bool,
    /// Stop (with a checkpoint) once this many optimiser steps have been taken in all, as a
    /// stop request would.
    pub stop_after_steps: Option<u64>,
    /// Memory for tables (training and validation together): when they need more, they are
    /// streamed from their files (see [`MaterialDataset`]); the result is the same.
    pub table_cache_bytes: u64,
}

/// Default of [`TrainRequest::table_cache_bytes`]: 4 GiB, 245 tables.
pub const DEFAULT_TABLE_CACHE_BYTES: u64 = 4 << 30;

/// What happened during training, for progress display.
#[derive(Clone, Debug)]
pub enum Event {
    /// Training starts: steps in the whole run and steps already done.
    Start {
        total_steps: u64,
        done: u64,
        parameters: usize,
    },
    /// One optimiser step: (total, L_rec data term, L_fre).
    Step { step: u64, losses: [f64; 3] },
    /// An epoch ended.
    Epoch(EpochRecord),
}

/// How a run ended.
#[derive(Clone, Debug, PartialEq)]
pub enum Outcome {
    /// All epochs done.
    Completed,
    /// Early stopping; the best epoch.
    EarlyStopped { best_epoch: usize },
    /// Stopped on request after this many steps, with a checkpoint.
    Interrupted { step: u64 },
}

/// Ids and ranks of a module's float parameters.
struct ParamIds(Vec<(ParamId, usize)>);

impl ModuleVisitor for ParamIds {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        self.0.push((param.id, D));
    }
}

/// Scales all gradients so that their global L2 norm is at most `max_norm` (PyTorch's
/// `clip_grad_norm_`). Returns the norm before clipping.
fn clip_global_norm(grads: &mut GradientsParams, model: &HyperBrdf, max_norm: f32) -> f64 {
    let mut ids = ParamIds(Vec::new());
    model.visit(&mut ids);
    let mut sq = 0f64;
    for &(id, rank) in &ids.0 {
        let s: Option<f32> = match rank {
            1 => grads.get::<1>(id).map(|g| g.square().sum().into_scalar()),
            2 => grads.get::<2>(id).map(|g| g.square().sum().into_scalar()),
            _ => None,
        };
        sq += s.unwrap_or(0.0) as f64;
    }
    let norm = sq.sqrt();
    if norm > max_norm as f64 {
        let scale = (max_norm as f64 / (norm + 1e-6)) as f32;
        for &(id, rank) in &ids.0 {
            match rank {
                1 => {
                    if let Some(g) = grads.remove::<1>(id) {
                        grads.register(id, g * scale);
                    }
                }
                2 => {
                    if let Some(g) = grads.remove::<2>(id) {
                        grads.register(id, g * scale);
                    }
                }
                _ => {}
            }
        }
    }
    norm
}

/// The sample sets of a batch and where its materials' latent codes come from.
struct BatchSets {
    /// One per material of the loss.
    sets: Vec<SampleSet>,
    /// The set encoder sees the first `encoded` of `sets` (each set's first
    /// `encoder_samples` samples), then `partners`.
    encoded: usize,
    /// Encoder sets of interpolation partners (codes used only through `mix`).
    partners: Vec<SampleSet>,
    /// Material i's code as weights over the encoder's codes; empty: material i has the code
    /// of set i.
    mix: Vec<Vec<f32>>,
}

impl BatchSets {
    /// Materials coded by their own sets.
    fn own(sets: Vec<SampleSet>) -> Self {
        BatchSets { encoded: sets.len(), sets, partners: Vec::new(), mix: Vec::new() }
    }

    /// z [B, latent] of the loss's B materials.
    fn latent(&self, model: &HyperBrdf, encoder_samples: usize, device: &Device) -> Tensor<2> {
        let encoded: Vec<&SampleSet> = self.sets[..self.encoded].iter().chain(&self.partners).collect();
        let (b, m) = (encoded.len(), encoder_samples.min(encoded[0].len()));
        let enc: Vec<f32> = encoded.iter().flat_map(|s| s.encoder_input(m)).collect();
        let z = model.encode(Tensor::from_data(TensorData::new(enc, [b, m, 9]), device));
        if self.mix.is_empty() {
            return z;
        }
        let weights: Vec<f32> = self.mix.iter().flatten().copied().collect();
        Tensor::from_data(TensorData::new(weights, [self.mix.len(), b]), device).matmul(z)
    }
}

/// `width` weights, 1 at `i`.
fn unit_row(width: usize, i: usize) -> Vec<f32> {
    (0..width).map(|j| if j == i { 1.0 } else { 0.0 }).collect()
}

/// Tensors of a batch of sample sets: (x [B, N, 6], y [B, N, 3], cos θi [B, N, 1]).
fn batch_tensors(sets: &[SampleSet], device: &Device) -> (Tensor<3>, Tensor<3>, Tensor<3>) {
    let b = sets.len();
    let n = sets[0].len();
    let x: Vec<f32> = sets.iter().flat_map(|s| s.inputs.iter().copied()).collect();
    let y: Vec<f32> = sets.iter().flat_map(|s| s.values.iter().copied()).collect();
    let c: Vec<f32> = sets.iter().flat_map(|s| s.cos_i.iter().copied()).collect();
    (
        Tensor::from_data(TensorData::new(x, [b, n, 6]), device),
        Tensor::from_data(TensorData::new(y, [b, n, 3]), device),
        Tensor::from_data(TensorData::new(c, [b, n, 1]), device),
    )
}

/// L_fre of a run in its configured form, on one device.
pub enum FreLoss {
    /// The released code's splat of each step's samples.
    Splat(Box<FreOperator>),
    /// The talk's fixed θh slices, with the fixed part of each material (by name).
    Slices {
        /// The slices and grid.
        op: Box<SlicedFre>,
        /// Each material's weights and coefficients.
        targets: HashMap<String, SliceTarget>,
    },
}

impl FreLoss {
    /// L_fre of `config` for the materials of `dataset` (whose slice targets it precomputes,
    /// reading each table once).
    pub fn new(config: &TrainConfig, dataset: &MaterialDataset, sampler: &Sampler, device: &Device) -> Result<Self> {
        Ok(match config.fre.form {
            FreForm::Splat => FreLoss::Splat(Box::new(FreOperator::new(&config.fre, device))),
            FreForm::Slices => {
                let op = Box::new(SlicedFre::new(&config.fre, device));
                let mut targets = HashMap::new();
                for i in 0..dataset.len() {
                    let t = dataset.table(i)?;
                    dataset.prefetch((i + 1..dataset.len()).take(1).collect());
                    targets.insert(t.name.clone(), slice_target(&op, &t, sampler, device));
                }
                FreLoss::Slices { op, targets }
            }
        })
    }

    /// The slice target of a material made during the run (an augmentation variant), which
    /// [`FreLoss::new`] could not precompute; `None` for the splat form, which needs none.
    fn target_of(&self, table: &MaterialTable, sampler: &Sampler, device: &Device) -> Option<SliceTarget> {
        match self {
            FreLoss::Splat(_) => None,
            FreLoss::Slices { op, .. } => Some(slice_target(op, table, sampler, device)),
        }
    }
}

/// The fixed part of L_fre on slices for `table`: its mapped values on the slices' grid.
fn slice_target(op: &SlicedFre, table: &MaterialTable, sampler: &Sampler, device: &Device) -> SliceTarget {
    op.target(
        |p| {
            let [h, d, f] = p.angles;
            sampler.sample_of(p, table.lookup(h, d, f)?).map(|(_, y, _)| y)
        },
        device,
    )
}

/// Forward pass and losses of a batch of materials `tables` with sample sets and codes from
/// `sets`: (total, data term, L_fre) as tensors. `own_targets[i]`, where
/// present, is material i's slice target (a variant's or an interpolated frame's); the
/// others are looked up by name in `fre`.
fn batch_loss(
    model: &HyperBrdf,
    tables: &[&MaterialTable],
    own_targets: &[Option<SliceTarget>],
    batch: &BatchSets,
    config: &TrainConfig,
    fre: Option<&FreLoss>,
    device: &Device,
) -> Result<(Tensor<1>, Tensor<1>, Option<Tensor<1>>)> {
    let sets = &batch.sets;
    let (x, y, cos) = batch_tensors(sets, device);
    let z = batch.latent(model, config.encoder_samples, device);
    let params = model.decode(z.clone());
    let pred = model.target_forward(&params, x);
    let b = sets.len();
    let slice_pred = match fre {
        Some(FreLoss::Slices { op, .. }) => Some(model.target_forward(&params, op.inputs(b))),
        _ => None,
    };
    let (mut total, data) = ReconstructionLoss::of(config).forward(pred.clone(), y.clone(), cos.clone(), &params, z);
    let mut fre_total: Option<Tensor<1>> = None;
    for (i, set) in sets.iter().enumerate() {
        let l = match fre {
            None => break,
            Some(FreLoss::Splat(op)) => {
                let n = set.len();
                let splat = op.splat(&set.directions(), device)?;
                let c = cos.clone().narrow(0, i, 1).reshape([n, 1]);
                let p = pred.clone().narrow(0, i, 1).reshape([n, 3]) * c.clone();
                let t = y.clone().narrow(0, i, 1).reshape([n, 3]) * c;
                op.loss(&splat, p, t)
            }
            Some(FreLoss::Slices { op, targets }) => {
                let name = &tables[i].name;
                let own = own_targets.get(i).and_then(Option::as_ref);
                let target = own.or_else(|| targets.get(name)).ok_or_else(|| {
                    Error::Invalid(format!("no L_fre slice target for material '{name}'"))
                })?;
                let p = slice_pred.as_ref().map(|p| p.clone().narrow(0, i, 1));
                op.loss(p.expect("slice predictions of the slices form"), target)
            }
        } / b as f32;
        fre_total = Some(match fre_total {
            Some(acc) => acc + l,
            None => l,
        });
    }
    if let Some(l) = &fre_total {
        total = total + l.clone() * config.fre.eta;
    }
    Ok((total, data, fre_total))
}

/// Mean (data term, L_fre) over the materials of `tables`, each on a fixed sample set drawn
/// from the run's seed and the material's position.
fn mean_losses(
    model: &HyperBrdf,
    tables: &MaterialDataset,
    sampler: &Sampler,
    config: &TrainConfig,
    fre: Option<&FreLoss>,
    device: &Device,
) -> Result<(f64, f64)> {
    let model = model.valid();
    let (mut data_sum, mut fre_sum) = (0.0, 0.0);
    for i in 0..tables.len() {
        let table = tables.table(i)?;
        // With a cache smaller than the set, the next table is read while this one is used.
        tables.prefetch((i + 1..tables.len()).take(1).collect());
        let mut rng = rand_pcg::Pcg64::seed_from_u64(
            config.seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ (i as u64 + 1),
        );
        let set = sampler.draw(&table, config.validation_samples, &mut rng)?;
        let (_, data, l_fre) = batch_loss(
            &model,
            &[table.as_ref()],
            &[],
            &BatchSets::own(vec![set]),
            config,
            fre,
            device,
        )?;
        data_sum += data.into_scalar::<f32>() as f64;
        fre_sum += l_fre.map_or(0.0, |l| l.into_scalar::<f32>() as f64);
    }
    let n = tables.len().max(1) as f64;
    Ok((data_sum / n, fre_sum / n))
}

/// Mean validation loss (data term + η L_fre) over the materials of `tables`, each on a fixed
/// sample set drawn from the run's seed and the material's position.
pub fn validation_loss(
    model: &HyperBrdf,
    tables: &MaterialDataset,
    sampler: &Sampler,
    config: &TrainConfig,
    fre: Option<&FreLoss>,
    device: &Device,
) -> Result<Option<f64>> {
    if tables.is_empty() {
        return Ok(None);
    }
    let (data, l_fre) = mean_losses(model, tables, sampler, config, fre, device)?;
    Ok(Some(data + config.fre.eta as f64 * l_fre))
}

/// Everything a run needs besides the model.
struct Setup {
    config: TrainConfig,
    train: MaterialDataset,
    validation: MaterialDataset,
    sampler: Sampler,
}

fn new_run(req: &TrainRequest, run: &RunDir) -> Result<Setup> {
    let config = req.config.clone().unwrap_or_default();
    config.check().map_err(Error::Invalid)?;
    let paths = list_tables(&req.data_dir, None)?;
    let names = paths
        .iter()
        .map(|p| material_name(p))
        .collect::<Result<Vec<_>>>()?;
    let split = Split::new(&names, config.split, config.split_seed());
    let (train, validation) = open_split(&req.data_dir, &split, req.table_cache_bytes)?;
    let reference = MaterialTable::median("reference", &train)?;
    std::fs::create_dir_all(&run.0).map_err(|e| Error::io(&run.0, e))?;
    reference.to_merl()?.write(run.reference())?;
    write_json(&run.config(), &config)?;
    write_json(&run.split(), &split)?;
    write_json(
        &run.info(),
        &RunInfo {
            data_dir: req.data_dir.clone(),
            materials: names,
        },
    )?;
    Ok(Setup {
        sampler: config.sampler(reference),
        config,
        train,
        validation,
    })
}

/// The training and validation datasets of `split`, sharing `cache_bytes` in proportion to
/// their sizes.
fn open_split(data_dir: &Path, split: &Split, cache_bytes: u64) -> Result<(MaterialDataset, MaterialDataset)> {
    let (n_train, n_valid) = (split.train.len() as u64, split.validation.len() as u64);
    let train_bytes = (cache_bytes as u128 * n_train as u128 / (n_train + n_valid).max(1) as u128) as u64;
    Ok((
        MaterialDataset::open(data_dir, &split.train, train_bytes)?,
        MaterialDataset::open(data_dir, &split.validation, cache_bytes - train_bytes)?,
    ))
}

/// Loads what a finished or interrupted run needs to go on (or to be evaluated).
fn existing_run(data_dir: &Path, run: &RunDir, config: TrainConfig, table_cache_bytes: u64) -> Result<Setup> {
    let split: Split = read_json(&run.split())?;
    let (train, validation) = open_split(data_dir, &split, table_cache_bytes)?;
    let reference = MaterialTable::read(&run.reference())?;
    Ok(Setup {
        sampler: config.sampler(reference),
        config,
        train,
        validation,
    })
}

/// Trains (or resumes) a run; see the module documentation. `stop` is polled after every
/// step; `on_event` receives progress.
pub fn train(
    req: &TrainRequest,
    stop: &AtomicBool,
    on_event: &mut dyn FnMut(Event),
) -> Result<Outcome> {
    let run = RunDir(req.run_dir.clone());
    let device = training_device()?;
    let ckpt_path = run.checkpoint();
    let (setup, mut model, mut optim, mut state) = if req.resume {
        let ckpt = Checkpoint::read(&ckpt_path)?;
        if let Some(c) = &req.config {
            // η chosen by `eta_share` at the start of the run is recorded in the checkpoint.
            let mut given = c.clone();
            if given.fre.eta_share.is_some() {
                given.fre.eta = ckpt.config.fre.eta;
            }
            if given != ckpt.config {
                return Err(Error::invalid_file(
                    &ckpt_path,
                    "the configuration given differs from the checkpoint's (resume without --config)",
                ));
            }
        }
        let setup = existing_run(&req.data_dir, &run, ckpt.config.clone(), req.table_cache_bytes)?;
        let model = load_model(&setup.config, &ckpt.model, &device, &ckpt_path)?;
        let optim = optimizer()
            .from_bytes(Bytes::from_bytes_vec(ckpt.optimizer))
            .map_err(|e| Error::invalid_file(&ckpt_path, format!("bad optimiser state: {e}")))?;
        (setup, model, optim, ckpt.state)
    } else {
        if ckpt_path.exists() {
            return Err(Error::invalid_file(
                &ckpt_path,
                "the run directory already holds a checkpoint: use --resume, or a new --out",
            ));
        }
        let setup = new_run(req, &run)?;
        let mut rng = rand_pcg::Pcg64::seed_from_u64(setup.config.seed);
        let model = HyperBrdf::init(&setup.config.net, &mut rng, &device);
        let state = TrainState {
            epoch: 0,
            order: Vec::new(),
            position: 0,
            step: 0,
            rng,
            epoch_sums: [0.0; 3],
            epoch_steps: 0,
            best: None,
            best_epoch: 0,
            epochs_without_improvement: 0,
            finished: false,
            history: Vec::new(),
        };
        (setup, model, optimizer(), state)
    };
    let mut config = setup.config.clone();
    let n_train = setup.train.len();
    let steps_per_epoch = n_train.div_ceil(config.materials_per_step) as u64;
    let inner = device.clone().without_autodiff();
    let fre = config
        .uses_fre()
        .then(|| FreLoss::new(&config, &setup.train, &setup.sampler, &device))
        .transpose()?;
    let fre_valid = config
        .uses_fre()
        .then(|| FreLoss::new(&config, &setup.validation, &setup.sampler, &inner))
        .transpose()?;
    if let (false, Some(valid), Some(share)) = (req.resume, &fre_valid, config.fre.eta_share) {
        // A new run: η such that η·L_fre is `share` of the data term with the initial model,
        // on the validation materials (the training ones when there are none).
        let (data, l_fre) = if setup.validation.is_empty() {
            let tables = &setup.train;
            let fre = FreLoss::new(&config, tables, &setup.sampler, &inner)?;
            mean_losses(&model, tables, &setup.sampler, &config, Some(&fre), &inner)?
        } else {
            let tables = &setup.validation;
            mean_losses(&model, tables, &setup.sampler, &config, Some(valid), &inner)?
        };
        if l_fre > 0.0 && data > 0.0 {
            config.fre.eta = (share as f64 * data / l_fre) as f32;
            write_json(&run.config(), &config)?;
        }
    }
    let config = config;
    on_event(Event::Start {
        total_steps: steps_per_epoch * config.epochs as u64,
        done: state.step,
        parameters: model.num_params(),
    });
    let mut epoch_start = Instant::now();
    let save = |model: &HyperBrdf,
                optim: &ModuleOptimizer,
                state: &TrainState,
                path: &Path|
     -> Result<()> {
        let optimizer = optim
            .into_bytes()
            .map_err(|e| Error::invalid_file(path, format!("cannot serialise the optimiser: {e}")))?
            .to_vec();
        Checkpoint {
            config: config.clone(),
            state: state.clone(),
            model: model_bytes(model, path)?,
            optimizer,
        }
        .write(path)
    };
    while !state.finished {
        if state.order.is_empty() {
            state.order = (0..n_train).collect();
            state.order.shuffle(&mut state.rng);
            state.position = 0;
            state.epoch_sums = [0.0; 3];
            state.epoch_steps = 0;
        }
        let end = (state.position + config.materials_per_step).min(state.order.len());
        let next_end = (end + config.materials_per_step).min(state.order.len());
        setup.train.prefetch(state.order[end..next_end].to_vec());
        let mut sets = Vec::with_capacity(end - state.position);
        let mut tables = Vec::with_capacity(end - state.position);
        let mut own_targets = Vec::with_capacity(end - state.position);
        let mut frames = Vec::new();
        for &i in &state.order[state.position..end] {
            let mut table = setup.train.table(i)?;
            let mut own_target = None;
            if let Some(recipe) = config.augment.draw(i, n_train, &mut state.rng) {
                let partner = recipe.partner.map(|p| setup.train.table(p.index)).transpose()?;
                table = Arc::new(recipe.apply(&table, partner.as_deref()));
                own_target = fre.as_ref().and_then(|f| f.target_of(&table, &setup.sampler, &device));
            }
            sets.push(setup.sampler.draw(&table, config.samples_per_step, &mut state.rng)?);
            if let Some(frame) = config.interpolation.draw(i, n_train, &mut state.rng) {
                frames.push((sets.len() - 1, Arc::clone(&table), frame));
            }
            tables.push(table);
            own_targets.push(own_target);
        }
        // Interpolated frames: one more material each, coded by the blend of its two ends'
        // encoder codes (the partner's encoder set drawn here).
        let mut batch = BatchSets::own(sets);
        let width = batch.encoded + frames.len();
        for (k, (a, table_a, frame)) in frames.into_iter().enumerate() {
            let table_b = setup.train.table(frame.partner)?;
            batch.partners.push(setup.sampler.draw(&table_b, config.encoder_samples, &mut state.rng)?);
            let name = format!("{}~{}@{:.3}", table_a.name, table_b.name, frame.t);
            let blend = Arc::new(table_a.blend(&table_b, name, |_| frame.t));
            batch.sets.push(setup.sampler.draw(&blend, config.samples_per_step, &mut state.rng)?);
            own_targets.push(fre.as_ref().and_then(|f| f.target_of(&blend, &setup.sampler, &device)));
            tables.push(blend);
            if batch.mix.is_empty() {
                batch.mix = (0..batch.encoded).map(|i| unit_row(width, i)).collect();
            }
            let mut row = unit_row(width, a);
            row[a] = 1.0 - frame.t;
            row[batch.encoded + k] = frame.t;
            batch.mix.push(row);
        }
        let tables: Vec<&MaterialTable> = tables.iter().map(Arc::as_ref).collect();
        let (total, data, l_fre) =
            batch_loss(&model, &tables, &own_targets, &batch, &config, fre.as_ref(), &device)?;
        let grads = total.backward();
        let mut grads = GradientsParams::from_grads(grads, &model);
        if let Some(max) = config.grad_clip_norm {
            clip_global_norm(&mut grads, &model, max);
        }
        let lr = config.learning_rate_at(state.step, steps_per_epoch * config.epochs as u64);
        model = optim.step(lr, model, grads);
        let losses = [
            total.into_scalar::<f32>() as f64,
            data.into_scalar::<f32>() as f64,
            l_fre.map_or(0.0, |l| l.into_scalar::<f32>() as f64),
        ];
        if losses.iter().any(|l| !l.is_finite()) {
            return Err(Error::Invalid(format!(
                "the loss became non-finite at step {} ({losses:?}); lower the learning rate",
                state.step + 1
            )));
        }
        for (s, l) in state.epoch_sums.iter_mut().zip(losses) {
            *s += l;
        }
        state.epoch_steps += 1;
        state.position = end;
        state.step += 1;
        on_event(Event::Step {
            step: state.step,
            losses,
        });
        if state.position >= state.order.len() {
            let validation = validation_loss(
                &model,
                &setup.validation,
                &setup.sampler,
                &config,
                fre_valid.as_ref(),
                &inner,
            )?;
            let k = state.epoch_steps.max(1) as f64;
            state.epoch += 1;
            let record = EpochRecord {
                epoch: state.epoch,
                train_loss: state.epoch_sums[0] / k,
                train_rec: state.epoch_sums[1] / k,
                train_fre: state.epoch_sums[2] / k,
                validation,
                seconds: epoch_start.elapsed().as_secs_f64(),
            };
            epoch_start = Instant::now();
            let score = validation.unwrap_or(record.train_loss);
            let improved = state.best.is_none_or(|b| score < b);
            if improved {
                state.best = Some(score);
                state.best_epoch = state.epoch;
                state.epochs_without_improvement = 0;
            } else {
                state.epochs_without_improvement += 1;
            }
            state.history.push(record.clone());
            state.order.clear();
            state.position = 0;
            let early = state.epochs_without_improvement >= config.patience.max(1);
            state.finished = state.epoch >= config.epochs || early;
            save(&model, &optim, &state, &ckpt_path)?;
            if improved {
                save(&model, &optim, &state, &run.best())?;
            }
            on_event(Event::Epoch(record));
            if early && state.epoch < config.epochs {
                return Ok(Outcome::EarlyStopped {
                    best_epoch: state.best_epoch,
                });
            }
        }
        let requested =
            stop.load(Ordering::SeqCst) || req.stop_after_steps.is_some_and(|s| state.step >= s);
        if requested && !state.finished {
            save(&model, &optim, &state, &ckpt_path)?;
            return Ok(Outcome::Interrupted { step: state.step });
        }
    }
    Ok(Outcome::Completed)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::ModelConfig;
    use rand::Rng;

    #[test]
    fn an_interpolated_frame_is_coded_by_the_blend_of_its_ends_codes() {
        let device = Device::flex();
        let config = ModelConfig { latent_dim: 5, encoder_hidden: vec![16], ..ModelConfig::default() };
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        let model = HyperBrdf::init(&config, &mut rng, &device);
        let set = |seed: u64| {
            let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
            let mut set = SampleSet::default();
            for _ in 0..40 {
                let input: [f32; 6] = std::array::from_fn(|_| rng.random());
                set.push(input, [rng.random(), 0.5, -1.0], 0.7);
            }
            set
        };
        let (a, b) = (set(1), set(2));
        let own = BatchSets::own(vec![a.clone(), b.clone()]).latent(&model, 32, &device);
        let own = crate::model::to_vec(own);
        // A's code, then a frame at t = 0.25 between A and partner B.
        let t = 0.25;
        let frame = BatchSets {
            sets: vec![a, set(9)],
            encoded: 1,
            partners: vec![b],
            mix: vec![unit_row(2, 0), vec![1.0 - t, t]],
        };
        let z = crate::model::to_vec(frame.latent(&model, 32, &device));
        assert_eq!(z.len(), 10);
        for k in 0..5 {
            assert_eq!(z[k], own[k], "A keeps its own code");
            let blend = (1.0 - t) * own[k] + t * own[5 + k];
            assert!((z[5 + k] - blend).abs() <= 1e-6 * (1.0 + blend.abs()), "{} against {blend}", z[5 + k]);
        }
    }
}
