//! `material-nn eval`: BRDF-space evaluation of a trained run on held-out materials — the
//! reconstruction (talk Table 1) and editing (talk Table 2) analogues that need no renderer.
//!
//! For each material: z = encoder over [`crate::export::ENCODE_SAMPLES`] samples of its table,
//! then the decoded network is compared with the table at `samples` uniform points (θh, θd,
//! φd) drawn from a fixed seed (trilinear look-ups, unmeasured points left out):
//! - `rmse`: √ mean over points and RGB of ((f' − f) cos θi)², f in 1/sr (f' clamped ≥ 0);
//! - `rec`: mean |(y' − y) cos θi| in the mapped space (the L_rec data term);
//! - `fre`: L_fre of the mapped, cos-weighted values, with the run's L_fre settings.
//!
//! Editing: `pairs` random pairs (a, b) of the materials and t ~ U(0, 1); the network of
//! z(t) = (1 − t) z_a + t z_b is compared with the linear blend (1 − t) f_a + t f_b of the
//! tables, with the same metrics. Image metrics (PSNR, SSIM of rendered previews) need the
//! renderer's neural BSDF and are not computed here.

use crate::config::FreConfig;
use crate::dataset::{MaterialTable, SampleSet};
use crate::error::{Error, Result};
use crate::export::ENCODE_SAMPLES;
use crate::inference::TrainedRun;
use crate::loss::FreOperator;
use burn::tensor::Device;
use rand::{Rng, SeedableRng};
use std::f32::consts::{FRAC_PI_2, TAU};
use std::fmt::Write as _;
use std::path::Path;

/// Metrics of one comparison.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Metrics {
    /// Cos-weighted RMSE of f_r (1/sr).
    pub rmse: f64,
    /// Mean |(y' − y) cos θi| (mapped space).
    pub rec: f64,
    /// L_fre.
    pub fre: f64,
}

/// One evaluated row.
#[derive(Clone, Debug)]
pub struct Row {
    /// Material name, or `a|b` for an editing pair.
    pub name: String,
    /// Blend parameter t (0 for reconstruction rows).
    pub t: f32,
    /// The metrics.
    pub metrics: Metrics,
}

/// Evaluation settings.
#[derive(Clone, Debug)]
pub struct EvalSettings {
    /// Comparison points per material.
    pub samples: usize,
    /// Editing pairs.
    pub pairs: usize,
    /// Seed of points, pairs and t.
    pub seed: u64,
}

/// Compares the network of `z` with a reference BRDF `truth(θh, θd, φd)` (1/sr).
fn compare(
    run: &TrainedRun,
    z: &[f32],
    truth: &dyn Fn(f32, f32, f32) -> Option<[f32; 3]>,
    settings: &EvalSettings,
    fre: &FreOperator,
    device: &Device,
) -> Result<Metrics> {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(settings.seed);
    let mut set = SampleSet::default();
    let mut f_true = Vec::new();
    let mut f_ref = Vec::new();
    let mut attempts = 0;
    while set.len() < settings.samples && attempts < 64 * settings.samples {
        attempts += 1;
        let (th, td, pd) = (
            rng.random::<f32>() * FRAC_PI_2,
            rng.random::<f32>() * FRAC_PI_2,
            rng.random::<f32>() * TAU,
        );
        let (Some(f), Some(r)) = (truth(th, td, pd), run.sampler.reference.lookup(th, td, pd))
        else {
            continue;
        };
        if let Some((x, y, c)) = run.sampler.sample_at(th, td, pd, f) {
            set.push(x, y, c);
            f_true.push(f);
            f_ref.push(r);
        }
    }
    if set.is_empty() {
        return Err(Error::Invalid("no measured points to evaluate".to_string()));
    }
    let pred = run.predict(z, &set.inputs);
    let n = set.len();
    let (mut se, mut abs) = (0f64, 0f64);
    let mut pred_cos = Vec::with_capacity(3 * n);
    let mut true_cos = Vec::with_capacity(3 * n);
    for i in 0..n {
        let c = set.cos_i[i] as f64;
        for ch in 0..3 {
            let y_pred = pred[3 * i + ch];
            let y_true = set.values[3 * i + ch];
            let f_pred = run
                .sampler
                .mapping
                .inverse(y_pred, f_ref[i][ch].max(0.0), run.sampler.epsilon)
                .max(0.0) as f64;
            se += ((f_pred - f_true[i][ch] as f64) * c).powi(2);
            abs += ((y_pred - y_true) as f64 * c).abs();
            pred_cos.push(y_pred as f64 * c);
            true_cos.push(y_true as f64 * c);
        }
    }
    let splat = fre.splat(&set.directions(), device)?;
    Ok(Metrics {
        rmse: (se / (3 * n) as f64).sqrt(),
        rec: abs / (3 * n) as f64,
        fre: fre.loss_cpu(&splat.map, &pred_cos, &true_cos),
    })
}

/// Reconstruction and editing rows for the materials `names` of `data_dir`.
pub fn evaluate(
    run: &TrainedRun,
    data_dir: &Path,
    names: &[String],
    settings: &EvalSettings,
) -> Result<(Vec<Row>, Vec<Row>)> {
    if names.is_empty() {
        return Err(Error::Invalid(
            "no materials to evaluate (the split is empty)".to_string(),
        ));
    }
    let device = run.device.clone();
    let fre_config: FreConfig = run.config.fre.clone();
    let fre = FreOperator::new(&fre_config, &device);
    let mut tables = Vec::new();
    let mut codes = Vec::new();
    for (i, name) in names.iter().enumerate() {
        let path = data_dir.join(format!("{name}.{}", crate::tabulate::TABLE_EXTENSION));
        let table = MaterialTable::read(&path)?;
        codes.push(run.encode_table(
            &table,
            ENCODE_SAMPLES,
            settings.seed.wrapping_add(i as u64),
        )?);
        tables.push(table);
    }
    let mut reconstruction = Vec::new();
    for ((name, table), z) in names.iter().zip(&tables).zip(&codes) {
        let metrics = compare(
            run,
            z,
            &|a, b, c| table.lookup(a, b, c),
            settings,
            &fre,
            &device,
        )?;
        reconstruction.push(Row {
            name: name.clone(),
            t: 0.0,
            metrics,
        });
    }
    let mut editing = Vec::new();
    if tables.len() >= 2 {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(settings.seed ^ 0xed17);
        for _ in 0..settings.pairs {
            let a = rng.random_range(0..tables.len());
            let mut b = rng.random_range(0..tables.len() - 1);
            if b >= a {
                b += 1;
            }
            let t: f32 = rng.random();
            let z: Vec<f32> = codes[a]
                .iter()
                .zip(&codes[b])
                .map(|(x, y)| (1.0 - t) * x + t * y)
                .collect();
            let (ta, tb) = (&tables[a], &tables[b]);
            let blend = |h: f32, d: f32, p: f32| -> Option<[f32; 3]> {
                let (fa, fb) = (ta.lookup(h, d, p)?, tb.lookup(h, d, p)?);
                Some([0, 1, 2].map(|c| (1.0 - t) * fa[c] + t * fb[c]))
            };
            let metrics = compare(run, &z, &blend, settings, &fre, &device)?;
            editing.push(Row {
                name: format!("{}|{}", names[a], names[b]),
                t,
                metrics,
            });
        }
    }
    Ok((reconstruction, editing))
}

/// Mean metrics of rows.
pub fn mean(rows: &[Row]) -> Metrics {
    let n = rows.len().max(1) as f64;
    let sum = rows.iter().fold(Metrics::default(), |acc, r| Metrics {
        rmse: acc.rmse + r.metrics.rmse,
        rec: acc.rec + r.metrics.rec,
        fre: acc.fre + r.metrics.fre,
    });
    Metrics {
        rmse: sum.rmse / n,
        rec: sum.rec / n,
        fre: sum.fre / n,
    }
}

/// Rows as CSV (`name,t,rmse,rec,fre`).
pub fn to_csv(rows: &[Row]) -> String {
    let mut out = String::from("name,t,rmse,rec,fre\n");
    for r in rows {
        let _ = writeln!(
            out,
            "{},{},{:.6e},{:.6e},{:.6e}",
            r.name, r.t, r.metrics.rmse, r.metrics.rec, r.metrics.fre
        );
    }
    out
}

/// The two tables' means as markdown, with the talk's scalings.
pub fn to_markdown(model: &str, reconstruction: &[Row], editing: &[Row]) -> String {
    let (r, e) = (mean(reconstruction), mean(editing));
    format!(
        "| {model} | materials / pairs | RMSE×10² (cos-weighted f_r) | L_rec data ×10² | L_fre×10³ |\n\
         | --- | --- | --- | --- | --- |\n\
         | reconstruction | {} | {:.3} | {:.3} | {:.4} |\n\
         | editing | {} | {:.3} | {:.3} | {:.4} |\n",
        reconstruction.len(),
        r.rmse * 1e2,
        r.rec * 1e2,
        r.fre * 1e3,
        editing.len(),
        e.rmse * 1e2,
        e.rec * 1e2,
        e.fre * 1e3,
    )
}
