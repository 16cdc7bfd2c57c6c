//! `material-nn train`: trains (or resumes) a HyperBRDF / FreNBRDF run with a progress bar;
//! Ctrl-C stops with a checkpoint.

use clap::Args;
use material_nn::config::TrainConfig;
use material_nn::training::{self, Event, Outcome, TrainRequest};
use std::path::PathBuf;
use std::time::Instant;
use super::{progress_bar, STOP};

#[derive(Args)]
pub struct TrainArgs {
    /// Directory of MERL-layout tables (NAME.binary).
    #[arg(long, value_name = "DIR")]
    pub data: PathBuf,
    /// Run directory (created): configuration, split, f_ref, checkpoints.
    #[arg(long, value_name = "RUN")]
    pub out: PathBuf,
    /// Configuration JSON (any subset of the fields; defaults otherwise).
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Continue the run from its checkpoint.
    #[arg(long)]
    pub resume: bool,
    /// Stop with a checkpoint after this many optimiser steps in all (as Ctrl-C would).
    #[arg(long, value_name = "N")]
    pub stop_after_steps: Option<u64>,
    /// Memory for tables in MiB (17.5 MB each); a larger training set is streamed from its
    /// files with the same result.
    #[arg(long, value_name = "MIB", default_value_t = training::DEFAULT_TABLE_CACHE_BYTES >> 20)]
    pub table_cache_mb: u64,
}

pub fn run(args: TrainArgs) -> anyhow::Result<()> {
    let config = args.config.as_deref().map(TrainConfig::read).transpose()?;
    super::catch_ctrl_c()?;
    let request = TrainRequest {
        data_dir: args.data,
        run_dir: args.out.clone(),
        config,
        resume: args.resume,
        stop_after_steps: args.stop_after_steps,
        table_cache_bytes: args.table_cache_mb << 20,
    };
    let bar = progress_bar(0, "train");
    let mut last_epoch = String::new();
    let start = Instant::now();
    let outcome = training::train(&request, &STOP, &mut |event| match event {
        Event::Start {
            total_steps,
            done,
            parameters,
        } => {
            bar.set_length(total_steps);
            bar.set_position(done);
            bar.suspend(|| println!("{parameters} parameters, {total_steps} steps, {done} done, on {}", material_nn::backend::backend_name()));
        }
        Event::Step { step, losses } => {
            bar.set_position(step);
            bar.set_message(format!(
                "loss {:.4} rec {:.4} fre {:.2e}{last_epoch}",
                losses[0], losses[1], losses[2]
            ));
        }
        Event::Epoch(r) => {
            let val = r.validation.map_or("-".to_string(), |v| format!("{v:.4}"));
            last_epoch = format!(" | epoch {} val {val}", r.epoch);
            bar.suspend(|| {
                println!(
                    "epoch {:>3}: train {:.5} (rec {:.5}, fre {:.3e}), validation {val}, {:.1} s",
                    r.epoch, r.train_loss, r.train_rec, r.train_fre, r.seconds
                )
            });
        }
    });
    bar.finish_and_clear();
    let outcome = outcome?;
    let what = match outcome {
        Outcome::Completed => "completed".to_string(),
        Outcome::EarlyStopped { best_epoch } => format!("stopped early (best epoch {best_epoch})"),
        Outcome::Interrupted { step } => {
            format!("stopped after step {step}; continue with --resume")
        }
    };
    println!(
        "{}: {what} in {:.1} s",
        args.out.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}
