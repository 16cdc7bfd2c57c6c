//! `material-nn search`: the learning-rate search of the talk.

use clap::Args;
use material_nn::config::TrainConfig;
use std::path::PathBuf;
use super::STOP;

#[derive(Args)]
pub struct SearchArgs {
    /// Directory of MERL-layout tables.
    #[arg(long, value_name = "DIR")]
    pub data: PathBuf,
    /// Search directory (one run directory per trial).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Base configuration (its learning rate is replaced by each trial's).
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Epochs per trial.
    #[arg(long, default_value_t = 3)]
    pub epochs: usize,
    /// Random trials after the grid.
    #[arg(long, default_value_t = 4)]
    pub trials: usize,
}

pub fn run(args: SearchArgs) -> anyhow::Result<()> {
    let mut base = match &args.config {
        Some(path) => TrainConfig::read(path)?,
        None => TrainConfig::default(),
    };
    base.epochs = args.epochs.max(1);
    super::catch_ctrl_c()?;
    let trials =
        material_nn::search::search(&args.data, &args.out, &base, args.trials, &STOP, &mut |t| {
            let how = t
                .failure
                .as_deref()
                .map_or(String::new(), |f| format!(" ({f})"));
            println!("lr {:.3e}: score {:.5}{how}", t.learning_rate, t.score);
        })?;
    if let Some(best) = trials.first() {
        println!(
            "best: lr {:.3e}, score {:.5} ({})",
            best.learning_rate,
            best.score,
            best.run.display()
        );
    }
    Ok(())
}
