//! `material-nn nbrdf-fit`: the per-material NBRDF baseline fitted to each table.

use clap::Args;
use material_nn::nbrdf_fit::{self, FitConfig, FitEvent, FitOutcome};
use std::path::PathBuf;
use std::time::Instant;
use super::{progress_bar, STOP};

#[derive(Args)]
pub struct NbrdfFitArgs {
    /// Directory of MERL-layout tables (NAME.binary).
    #[arg(long, value_name = "DIR")]
    pub data: PathBuf,
    /// Output directory of the networks (created).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Only these materials (comma-separated names), default every table of --data.
    #[arg(long, value_name = "A,B,...", value_delimiter = ',')]
    pub materials: Option<Vec<String>>,
    /// Epochs per material (each --steps-per-epoch Adam steps).
    #[arg(long, default_value_t = FitConfig::default().epochs)]
    pub epochs: usize,
    /// Adam steps per epoch.
    #[arg(long, default_value_t = FitConfig::default().steps_per_epoch)]
    pub steps_per_epoch: usize,
    /// Fresh uniform samples per step.
    #[arg(long, default_value_t = FitConfig::default().samples_per_step)]
    pub samples_per_step: usize,
    /// Seed (mixed with each material's name).
    #[arg(long, default_value_t = FitConfig::default().seed)]
    pub seed: u64,
    /// Adam learning rate.
    #[arg(long, default_value_t = FitConfig::default().learning_rate)]
    pub learning_rate: f64,
}

pub fn run(args: NbrdfFitArgs) -> anyhow::Result<()> {
    let config = FitConfig {
        epochs: args.epochs,
        steps_per_epoch: args.steps_per_epoch,
        samples_per_step: args.samples_per_step,
        learning_rate: args.learning_rate,
        seed: args.seed,
        ..FitConfig::default()
    };
    config.check()?;
    let tables = nbrdf_fit::select_tables(&args.data, args.materials.as_deref())?;
    super::catch_ctrl_c()?;
    let start = Instant::now();
    let epochs = config.epochs as u64;
    let steps_per_epoch = config.steps_per_epoch as u64;
    let bar = progress_bar(tables.len() * config.epochs, "nbrdf-fit");
    let (mut base, mut current) = (0u64, String::new());
    let report = nbrdf_fit::fit_all(
        &tables,
        &args.out,
        &config,
        &STOP,
        &mut |event| match event {
            FitEvent::Material(name) => current = name.to_string(),
            FitEvent::Step(step, loss) => {
                bar.set_position(base + step / steps_per_epoch);
                bar.set_message(format!("{current}: loss {loss:.4e}"));
            }
            FitEvent::Done(name, outcome) => {
                base += epochs;
                bar.set_position(base);
                bar.suspend(|| match outcome {
                    FitOutcome::Fitted(f) => println!(
                        "{name}: loss {:.4e} -> {:.4e} in {:.1} s",
                        f.initial_loss, f.final_loss, f.seconds
                    ),
                    FitOutcome::Skipped => println!("{name}: already fitted, skipped"),
                });
            }
        },
    );
    bar.finish_and_clear();
    let report = report?;
    let fitted = report
        .outcomes
        .iter()
        .filter(|(_, o)| matches!(o, FitOutcome::Fitted(_)))
        .count();
    let skipped = report.outcomes.len() - fitted;
    let what = if report.interrupted {
        format!(
            "stopped after {fitted} fitted, {skipped} skipped, {} left; run again to go on",
            tables.len() - report.outcomes.len()
        )
    } else {
        format!("{fitted} fitted, {skipped} already present")
    };
    println!(
        "{}: {what} in {:.1} s",
        args.out.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}
