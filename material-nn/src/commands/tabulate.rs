//! `material-nn tabulate`: MERL-layout tables from NBRDF networks, as the median of tables, or
//! from an analytic model.

use anyhow::{bail, Context};
use clap::{ArgGroup, Args, ValueEnum};
use material_nn::tabulate::{self, TableOutcome};
use renderer::analytic::AnalyticBrdf;
use renderer::Rgb;
use std::path::PathBuf;
use std::time::Instant;
use super::{parse_rgb, parse_positive, parse_non_negative, progress_bar};

/// Analytic model families for `tabulate --analytic`.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum AnalyticKind {
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
pub struct TabulateArgs {
    /// Tabulate the NBRDF networks (`NAME_fc1.npy` ...) of this directory into --out (a
    /// directory) as NAME.binary; tables already present are skipped, so a run resumes.
    #[arg(long, value_name = "DIR")]
    pub nbrdf: Option<PathBuf>,
    /// With --nbrdf: only these networks (comma-separated names), default all.
    #[arg(
        long,
        value_name = "A,B,...",
        value_delimiter = ',',
        requires = "nbrdf"
    )]
    pub materials: Option<Vec<String>>,
    /// Write the per-bin median of the TABLE files to --out (unmeasured entries left out).
    #[arg(long, requires = "tables")]
    pub median: bool,
    /// Write the per-bin median of every .binary table in DIR (except --out) to --out.
    #[arg(long, value_name = "DIR")]
    pub median_of: Option<PathBuf>,
    /// Write the table of an analytic model to --out.
    #[arg(long, value_enum, value_name = "KIND")]
    pub analytic: Option<AnalyticKind>,
    /// Diffuse albedo (analytic models): R,G,B or one grey value.
    #[arg(long, value_parser = parse_rgb, default_value = "0.5")]
    pub albedo: Rgb,
    /// Specular reflectance (analytic models: F0 for ggx/beckmann, rho_s for ward): R,G,B or
    /// one grey value.
    #[arg(long, value_parser = parse_rgb, default_value = "0.04")]
    pub specular: Rgb,
    /// Microfacet roughness alpha (ggx, beckmann, ward).
    #[arg(long, default_value_t = 0.2, value_parser = parse_positive)]
    pub alpha: f32,
    /// Oren-Nayar slope angle sigma in radians.
    #[arg(long, default_value_t = 0.3, value_parser = parse_non_negative)]
    pub sigma: f32,
    /// Output: a directory for --nbrdf, a file otherwise.
    #[arg(long, value_name = "PATH")]
    pub out: PathBuf,
    /// Input tables of --median.
    #[arg(value_name = "TABLE")]
    pub tables: Vec<PathBuf>,
}

pub fn run(args: TabulateArgs) -> anyhow::Result<()> {
    let start = Instant::now();
    if let Some(dir) = &args.nbrdf {
        let names = tabulate::select_networks(dir, args.materials.as_deref())?;
        let bar = progress_bar(names.len(), "tabulate");
        let outcomes = tabulate::tabulate_networks(dir, &names, &args.out, |outcome| {
            let (TableOutcome::Written(p) | TableOutcome::Skipped(p)) = outcome;
            bar.set_message(
                p.file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default(),
            );
            bar.inc(1);
        });
        bar.finish_and_clear();
        let outcomes = outcomes?;
        let written = outcomes
            .iter()
            .filter(|o| matches!(o, TableOutcome::Written(_)))
            .count();
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
            Some(dir) => material_nn::tables::list_tables(dir, Some(&args.out))?,
            None => args.tables.clone(),
        };
        let bar = progress_bar(0, "median");
        let table = material_nn::tables::median_table(&inputs, |done, total| {
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
    table.write(&args.out)?;
    println!(
        "{}: written in {:.1} s",
        args.out.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}
