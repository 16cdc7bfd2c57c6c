//! `material-nn`: learns neural materials from measured BRDFs; see the crate README.
//!
//! Errors are reported as one line `error: ...` naming the file and the problem, exit code 2.

use anyhow::{bail, Context};
use clap::{ArgGroup, Args, Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use material_nn::tabulate::{self, TableOutcome};
use renderer::analytic::AnalyticBrdf;
use renderer::Rgb;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

#[derive(Parser)]
#[command(name = "material-nn", version, about = "Neural materials from measured BRDFs")]
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
    Tabulate(TabulateArgs),
}

/// Analytic model families for `tabulate --analytic`.
#[derive(Clone, Copy, Debug, ValueEnum)]
enum AnalyticKind {
    /// Lambert + GGX microfacet (height-correlated Smith, Schlick Fresnel with F0 = --specular).
    Ggx,
    /// Lambert + Beckmann microfacet (Smith, Schlick Fresnel with F0 = --specular).
    Beckmann,
    /// Lambert + isotropic Ward lobe of reflectance --specular.
    Ward,
    /// Oren-Nayar diffuse with slope angle --sigma.
    OrenNayar,
}

#[derive(Args)]
#[command(group(ArgGroup::new("mode").required(true).args(["nbrdf", "median", "median_of", "analytic"])))]
struct TabulateArgs {
    /// Tabulate the NBRDF networks (`NAME_fc1.npy` ...) of this directory into --out (a
    /// directory) as NAME.binary; tables already present are skipped, so a run resumes.
    #[arg(long, value_name = "DIR")]
    nbrdf: Option<PathBuf>,
    /// With --nbrdf: only these networks (comma-separated names), default all.
    #[arg(long, value_name = "A,B,...", value_delimiter = ',', requires = "nbrdf")]
    materials: Option<Vec<String>>,
    /// Write the per-bin median of the TABLE files to --out (unmeasured entries left out).
    #[arg(long, requires = "tables")]
    median: bool,
    /// Write the per-bin median of every .binary table in DIR (except --out) to --out.
    #[arg(long, value_name = "DIR")]
    median_of: Option<PathBuf>,
    /// Write the table of an analytic model to --out.
    #[arg(long, value_enum, value_name = "KIND")]
    analytic: Option<AnalyticKind>,
    /// Diffuse albedo (analytic models): R,G,B or one grey value.
    #[arg(long, value_parser = parse_rgb, default_value = "0.5")]
    albedo: Rgb,
    /// Specular reflectance (analytic models: F0 for ggx/beckmann, rho_s for ward): R,G,B or
    /// one grey value.
    #[arg(long, value_parser = parse_rgb, default_value = "0.04")]
    specular: Rgb,
    /// Microfacet roughness alpha (ggx, beckmann, ward).
    #[arg(long, default_value_t = 0.2, value_parser = parse_positive)]
    alpha: f32,
    /// Oren-Nayar slope angle sigma in radians.
    #[arg(long, default_value_t = 0.3, value_parser = parse_non_negative)]
    sigma: f32,
    /// Output: a directory for --nbrdf, a file otherwise.
    #[arg(long, value_name = "PATH")]
    out: PathBuf,
    /// Input tables of --median.
    #[arg(value_name = "TABLE")]
    tables: Vec<PathBuf>,
}

fn parse_rgb(s: &str) -> Result<Rgb, String> {
    let values: Vec<f32> = s
        .split(',')
        .map(|v| v.trim().parse::<f32>().map_err(|e| format!("'{v}': {e}")))
        .collect::<Result<_, _>>()?;
    let rgb = match values[..] {
        [g] => Rgb::splat(g),
        [r, g, b] => Rgb::new(r, g, b),
        _ => return Err(format!("'{s}': expected R,G,B or one value")),
    };
    if !(rgb.is_finite() && rgb.min_element() >= 0.0 && rgb.max_element() <= 1.0) {
        return Err(format!("'{s}': values must lie in [0, 1]"));
    }
    Ok(rgb)
}

fn parse_positive(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("'{s}': expected a positive number")),
    }
}

fn parse_non_negative(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(format!("'{s}': expected a non-negative number")),
    }
}

fn progress_bar(len: usize, what: &str) -> ProgressBar {
    let bar = ProgressBar::new(len as u64);
    if let Ok(style) = ProgressStyle::with_template("{prefix} [{bar:40}] {pos}/{len} {elapsed_precise} eta {eta} {msg}") {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_prefix(what.to_string());
    bar
}

fn tabulate(args: TabulateArgs) -> anyhow::Result<()> {
    let start = Instant::now();
    if let Some(dir) = &args.nbrdf {
        let names = tabulate::select_networks(dir, args.materials.as_deref())?;
        let bar = progress_bar(names.len(), "tabulate");
        let outcomes = tabulate::tabulate_networks(dir, &names, &args.out, |outcome| {
            let (TableOutcome::Written(p) | TableOutcome::Skipped(p)) = outcome;
            bar.set_message(p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default());
            bar.inc(1);
        });
        bar.finish_and_clear();
        let outcomes = outcomes?;
        let written = outcomes.iter().filter(|o| matches!(o, TableOutcome::Written(_))).count();
        println!(
            "{}: wrote {written} tables, {} already present, in {:.1} s",
            args.out.display(),
            outcomes.len() - written,
            start.elapsed().as_secs_f64()
        );
        return Ok(());
    }
    let table = if args.median || args.median_of.is_some() {
        let inputs = match &args.median_of {
            Some(dir) => tabulate::tables_in(dir, Some(&args.out))?,
            None => args.tables.clone(),
        };
        let bar = progress_bar(0, "median");
        let table = tabulate::median_table(&inputs, |done, total| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        });
        bar.finish_and_clear();
        println!("median of {} tables", inputs.len());
        table?
    } else if let Some(kind) = args.analytic {
        let brdf = match kind {
            AnalyticKind::Ggx => AnalyticBrdf::LambertGgx {
                albedo: args.albedo,
                specular: args.specular,
                alpha: args.alpha,
            },
            AnalyticKind::Beckmann => AnalyticBrdf::LambertBeckmann {
                albedo: args.albedo,
                specular: args.specular,
                alpha: args.alpha,
            },
            AnalyticKind::Ward => AnalyticBrdf::Ward {
                albedo: args.albedo,
                specular: args.specular,
                alpha: args.alpha,
            },
            AnalyticKind::OrenNayar => AnalyticBrdf::OrenNayar {
                albedo: args.albedo,
                sigma: args.sigma,
            },
        };
        tabulate::table_from_analytic(&brdf)
    } else {
        bail!("tabulate needs one of --nbrdf, --median, --median-of, --analytic");
    };
    if let Some(parent) = args.out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).with_context(|| parent.display().to_string())?;
    }
    tabulate::write_table_atomic(&table, &args.out)?;
    println!("{}: written in {:.1} s", args.out.display(), start.elapsed().as_secs_f64());
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Tabulate(args) => tabulate(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}
