//! `material-nn search`: the talk's hyperparameter search for the learning rate — a coarse
//! grid (1e-1, 1e-3, 1e-5), then random trials log-uniform within a decade either side of the
//! grid's best. Each trial is a short training run (its own run directory under the search
//! directory) scored by its best validation loss (training loss without validation
//! materials); a diverged trial scores +∞. A stop request (Ctrl-C) ends the trial in progress
//! with a checkpoint and skips the rest.

use crate::checkpoint::Checkpoint;
use crate::config::TrainConfig;
use crate::error::{Error, Result};
use crate::run::RunDir;
use crate::training::{train, TrainRequest};
use rand::{Rng, SeedableRng};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

/// The coarse grid of learning rates.
pub const GRID: [f64; 3] = [1e-1, 1e-3, 1e-5];

/// One trial's outcome.
#[derive(Clone, Debug)]
pub struct Trial {
    /// Run directory.
    pub run: PathBuf,
    /// Learning rate tried.
    pub learning_rate: f64,
    /// Best validation (or training) loss; +∞ when the run diverged.
    pub score: f64,
    /// Why the run failed, if it did.
    pub failure: Option<String>,
}

fn run_trial(
    data: &Path,
    dir: &Path,
    base: &TrainConfig,
    lr: f64,
    stop: &AtomicBool,
) -> Result<Trial> {
    let run = dir.join(format!("lr-{lr:.3e}"));
    let config = TrainConfig {
        learning_rate: lr,
        ..base.clone()
    };
    let request = TrainRequest {
        data_dir: data.to_path_buf(),
        run_dir: run.clone(),
        config: Some(config),
        resume: false,
        stop_after_steps: None,
        table_cache_bytes: crate::training::DEFAULT_TABLE_CACHE_BYTES,
    };
    let outcome = train(&request, stop, &mut |_| {});
    let (score, failure) = match outcome {
        Ok(_) => {
            let ckpt = Checkpoint::read(&RunDir(run.clone()).checkpoint())?;
            (ckpt.state.best.unwrap_or(f64::INFINITY), None)
        }
        Err(Error::Invalid(reason)) => (f64::INFINITY, Some(reason)),
        Err(e) => return Err(e),
    };
    Ok(Trial {
        run,
        learning_rate: lr,
        score,
        failure,
    })
}

/// Runs the grid and `random_trials` random trials with `base` (its `epochs` per trial);
/// `on_trial` sees each trial as it ends. Returns every trial, best first.
pub fn search(
    data: &Path,
    dir: &Path,
    base: &TrainConfig,
    random_trials: usize,
    stop: &AtomicBool,
    on_trial: &mut dyn FnMut(&Trial),
) -> Result<Vec<Trial>> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let mut trials = Vec::new();
    for lr in GRID {
        if stop.load(Ordering::SeqCst) {
            break;
        }
        let t = run_trial(data, dir, base, lr, stop)?;
        on_trial(&t);
        trials.push(t);
    }
    let best = trials
        .iter()
        .min_by(|a, b| a.score.total_cmp(&b.score))
        .map_or(base.learning_rate, |t| t.learning_rate);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(base.seed ^ 0x5ea7c4);
    for _ in 0..random_trials {
        if stop.load(Ordering::SeqCst) {
            break;
        }
        let lr = best * 10f64.powf(rng.random_range(-1.0..1.0));
        let t = run_trial(data, dir, base, lr, stop)?;
        on_trial(&t);
        trials.push(t);
    }
    trials.sort_by(|a, b| a.score.total_cmp(&b.score));
    let mut csv = String::from("run,learning_rate,score,failure\n");
    for t in &trials {
        let _ = writeln!(
            csv,
            "{},{:.6e},{},{}",
            t.run.display(),
            t.learning_rate,
            t.score,
            t.failure.as_deref().unwrap_or("").replace(',', ";")
        );
    }
    renderer::support::write_bytes_atomically(&dir.join("search.csv"), csv.as_bytes())?;
    if let Some(best) = trials.first().filter(|t| t.score.is_finite()) {
        let config = TrainConfig {
            learning_rate: best.learning_rate,
            ..base.clone()
        };
        let text =
            serde_json::to_string_pretty(&config).map_err(|e| Error::Invalid(e.to_string()))?;
        renderer::support::write_bytes_atomically(&dir.join("best-config.json"), text.as_bytes())?;
    }
    Ok(trials)
}
