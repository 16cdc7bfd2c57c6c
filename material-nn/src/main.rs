//! `material-nn`: learns neural materials from measured BRDFs (docs/training.md).
//!
//! Errors are reported as one line `error: ...` naming the file and the problem, exit code 2.

mod commands;

use clap::{Parser, Subcommand};
use commands::{encode, eval, export, nbrdf_fit, search, tabulate, train};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "material-nn",
    version,
    about = "Neural materials from measured BRDFs"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Write MERL-layout `.binary` tables (90 x 90 x 180 bins, f64) from NBRDF networks, as the
    /// per-bin median of other tables, or from an analytic model.
    ///
    ///   material-nn tabulate --nbrdf ../shared/data/nbrdf/merl --out data/merl-fitted
    ///   material-nn tabulate --median-of data/merl-fitted --out data/merl-median.binary
    ///   material-nn tabulate --analytic ggx --albedo 0.5,0.3,0.1 --alpha 0.2 --out ggx.binary
    #[command(verbatim_doc_comment)]
    Tabulate(tabulate::TabulateArgs),
    /// Train HyperBRDF / FreNBRDF on the MERL-layout tables of a directory (see docs/training.md).
    ///
    ///   material-nn train --data data/merl-fitted --out runs/frenbrdf [--config cfg.json]
    ///   material-nn train --data data/merl-fitted --out runs/frenbrdf --resume
    ///
    /// Ctrl-C stops after the current step with a checkpoint; --resume goes on from it.
    #[command(verbatim_doc_comment)]
    Train(train::TrainArgs),
    /// Write a run's decoder, f_ref and the latent codes of materials to one latent.bin.
    ///
    ///   material-nn export --run runs/frenbrdf --out scenes/materials/latent.bin
    #[command(verbatim_doc_comment)]
    Export(export::ExportArgs),
    /// Encode one material (a table or a sparse CSV sample set) into a latent code: the set
    /// encoder's code, refined with the decoder frozen together with the code's output offset
    /// and its residual of the decoded network; prints it as JSON.
    ///
    ///   material-nn encode --model scenes/materials/latent.bin --table gold.binary --add-to lib.bin
    ///   material-nn encode --model scenes/materials/latent.bin --samples measured.csv --name mine --add-to lib.bin
    ///   material-nn encode --run runs/frenbrdf --table gold.binary [--refine-steps 0]
    #[command(verbatim_doc_comment)]
    Encode(encode::EncodeArgs),
    /// Evaluation of a run on its test split, or of a latent file (its codes, the rest
    /// encoded): reconstruction and editing (RMSE of cos-weighted f_r, L_rec data term, L_fre)
    /// and PSNR / SSIM of material-preview renders against the tables', optionally beside
    /// NBRDF networks; writes RUN/eval/ (or --out) *.csv, summary.md, images/.
    ///
    ///   material-nn eval --run runs/frenbrdf [--pairs 200] [--nbrdf runs/nbrdf] [--no-images]
    ///   material-nn eval --model scenes/materials/latent.bin --data data/rgl-fitted --split all --out data/eval/rgl
    #[command(verbatim_doc_comment)]
    Eval(eval::EvalArgs),
    /// Learning-rate search as in the talk: grid 1e-1, 1e-3, 1e-5, then random trials within a
    /// decade of the best; short runs under --out, results in --out/search.csv and
    /// --out/best-config.json.
    ///
    ///   material-nn search --data data/merl-fitted --out runs/search --epochs 3 --trials 4
    #[command(verbatim_doc_comment)]
    Search(search::SearchArgs),
    /// Fit the per-material NBRDF baseline (6-21-21-3 MLP, Sztrajman et al.) to each table of
    /// --data; writes OUT/NAME_fc1.npy ... NAME_b3.npy (render --bind M=nbrdf:OUT/NAME) and
    /// OUT/fit.json. Materials already written are skipped; Ctrl-C keeps every finished one.
    ///
    ///   material-nn nbrdf-fit --data data/merl-fitted --out runs/nbrdf [--materials a,b]
    #[command(verbatim_doc_comment)]
    NbrdfFit(nbrdf_fit::NbrdfFitArgs),
}

fn main() -> ExitCode {
    renderer::support::exit_quietly_on_broken_pipe();
    if let Err(e) = renderer::support::cpu::check_build_features() {
        eprintln!("error: {e}");
        return ExitCode::from(2);
    }
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Tabulate(args) => tabulate::run(args),
        Command::Train(args) => train::run(args),
        Command::Export(args) => export::run(args),
        Command::Encode(args) => encode::run(args),
        Command::Eval(args) => eval::run(args),
        Command::Search(args) => search::run(args),
        Command::NbrdfFit(args) => nbrdf_fit::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}
