//! `render energy`: where the energy of material-editing sweeps goes (issue 49). For pairs of
//! materials A → B it decodes the codes along the sweep and integrates the directional albedo
//! of each frame ([`renderer::neural::energy::AlbedoQuadrature`], the same directions for
//! every BRDF at one θo), per RGB channel, for these variants:
//!
//! - `z`: the codes' z alone interpolated (offsets δ and residuals ΔΘ dropped);
//! - `z+δ`: z and the offsets;
//! - `full`: the sweep of `render --sweep` ([`LatentLibrary::sweep`]: z and δ
//!   interpolated, each end's residual ΔΘ faded out within 0.25 of its end, δ balanced so
//!   that the frame's albedo summed over θo = 0°, 45°, 75° is the blend of the ends');
//! - `unbalanced`: the same without the balance ([`LatentCode::lerp`]);
//! - `encoder`: the set encoder's own z of both ends (from samples of the ends' NBRDF
//!   networks, unrefined: points of the encoder's output manifold), interpolated;
//! - `encoder(blend)`: at each t the encoder's z of the blended table (1 − t) f_A + t f_B,
//!   decoded: whether the decoder can hold the mixture at all when the code comes from it;
//! - `log-blend`: no decoder: the two tables blended in the mapped space, f + ε =
//!   (f_A + ε)^(1−t) (f_B + ε)^t, which is what interpolating the mapped values y (or a
//!   decoder linear in z) gives;
//! - `table`: the linear blend of the two tables (the NBRDF networks of `--nbrdf`), whose
//!   albedo is the blend of the ends' albedos.
//!
//! Materials are looked up by name in `--nbrdf`'s `merl/`, `rgl-isotropic/` and `nielsen/`;
//! those without a code in `--material` (e.g. RGL materials not encoded into it) get the
//! encoder variants only. Writes `albedo.csv` (every albedo), `codes.csv`, `reciprocity.csv`
//! and `summary.md` (the figures of docs/training.md's "Editing: latent sweeps").

use anyhow::{bail, Context, Result};
use clap::Parser;
use glam::{DVec3, Vec3};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use renderer::brdf_coords::rendered_point;
use renderer::bsdf::nbrdf::NbrdfBsdf;
use renderer::bsdf::neural::NeuralBsdf;
use renderer::formats::latent_file::LatentFile;
use renderer::formats::merl::TrilinearAxes;
use renderer::bsdf::tabulated_sampling::TabulatedSamplerConfig;
use renderer::neural::energy::{self, AlbedoQuadrature};
use renderer::neural::latent_library::{LatentCode, LatentLibrary};
use renderer::neural::mlp::Encoder;
use renderer::neural::nbrdf::NbrdfNetwork;
use renderer::neural::sweep::Sweep;
use renderer::neural::reference::ReferenceTable;
use renderer::Rgb;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The pairs of the issue-49 study (see docs/training.md): metal ↔ metal, metal ↔ fabric,
/// paint ↔ plastic and others, training and held-out MERL materials, and RGL materials.
pub const DEFAULT_PAIRS: &[(&str, &str)] = &[
    // the three
    ("alum-bronze", "chrome"),
    ("blue-fabric", "nickel"),
    ("red-plastic", "gold-paint"),
    // metal ↔ metal
    ("nickel", "brass"),
    ("aluminium", "tungsten-carbide"),
    ("steel", "two-layer-gold"),
    ("chrome-steel", "alum-bronze"),
    ("ss440", "hematite"),
    ("chrome", "nickel"),
    // metal ↔ fabric
    ("beige-fabric", "chrome"),
    ("red-fabric", "brass"),
    ("white-fabric", "chrome"),
    ("green-fabric", "steel"),
    ("pink-felt", "aluminium"),
    // paint ↔ plastic
    ("orange-paint", "yellow-plastic"),
    ("light-red-paint", "red-specular-plastic"),
    ("blue-metallic-paint", "green-plastic"),
    ("pearl-paint", "black-phenolic"),
    ("white-paint", "gray-plastic"),
    // others
    ("black-obsidian", "white-diffuse-bball"),
    ("pure-rubber", "specular-white-phenolic"),
    ("green-acrylic", "color-changing-paint1"),
    ("colonial-maple-223", "gold-metallic-paint3"),
    ("red-phenolic", "violet-rubber"),
    ("white-marble", "black-soft-plastic"),
    // RGL (encoded with the shipped file's encoder)
    ("acrylic_felt_green_rgb", "satin_gold_rgb"),
    ("chm_mint_rgb", "paper_white_rgb"),
    ("spectralon_rgb", "ilm_l3_37_metallic_rgb"),
    ("cc_amber_citrine_rgb", "chrome"),
    ("paper_blue_rgb", "nickel"),
];

/// `render energy`.
#[derive(Parser, Debug)]
#[command(
    name = "render energy",
    about = "Directional albedo along material-editing sweeps, per variant of the codes (where the energy goes), and the reciprocity of decoded nets"
)]
pub struct EnergyArgs {
    /// The latent file (decoder, encoder, f_ref and codes).
    #[arg(long, default_value = "scenes/materials/latent.bin")]
    material: PathBuf,
    /// Directory of the NBRDF networks (the tables): merl/, rgl-isotropic/, nielsen/.
    #[arg(long, default_value = "../shared/data/nbrdf")]
    nbrdf: PathBuf,
    /// Pairs A:B, comma-separated (default: the study's 30 pairs, see docs/training.md).
    #[arg(long, value_delimiter = ',', value_parser = parse_pair)]
    pairs: Vec<(String, String)>,
    /// Points t of each sweep (0 and 1 are the ends the ratios refer to).
    #[arg(long, value_delimiter = ',', default_value = "0,0.25,0.5,0.75,1")]
    times: Vec<f32>,
    /// Viewing angles θo, degrees.
    #[arg(long, value_delimiter = ',', default_value = "0,45,75")]
    theta_o: Vec<f32>,
    /// Samples of each table the set encoder sees (drawn as training drew them).
    #[arg(long, default_value_t = 65_536)]
    encoder_samples: usize,
    /// Seed of the encoder's samples and of the reciprocity points.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Quadrature: steps of sqrt(θh) × steps of φh over [0, π].
    #[arg(long, default_value = "90x64", value_parser = parse_quadrature)]
    quadrature: AlbedoQuadrature,
    /// Points per code of the reciprocity measure (0: skip it).
    #[arg(long, default_value_t = 20_000)]
    reciprocity: usize,
    /// Output directory.
    #[arg(long, default_value = "data/energy")]
    out: PathBuf,
    /// Print the default pairs (A:B, one per line; the MERL pairs, then the RGL ones) and exit.
    #[arg(long)]
    list_pairs: bool,
}

fn parse_pair(s: &str) -> std::result::Result<(String, String), String> {
    match s.split_once(':') {
        Some((a, b)) if !a.is_empty() && !b.is_empty() => Ok((a.to_string(), b.to_string())),
        _ => Err(format!("'{s}' is not A:B")),
    }
}

fn parse_quadrature(s: &str) -> std::result::Result<AlbedoQuadrature, String> {
    let err = || format!("'{s}' is not THETAxPHI (e.g. 90x64)");
    let (a, b) = s.split_once('x').ok_or_else(err)?;
    let (a, b) = (a.parse::<usize>().map_err(|_| err())?, b.parse::<usize>().map_err(|_| err())?);
    if a == 0 || b == 0 {
        return Err(err());
    }
    Ok(AlbedoQuadrature { theta_h_steps: a, phi_h_steps: b })
}

/// The variants of a sweep (module documentation), in report order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Variant {
    Z,
    ZOffset,
    Full,
    Encoder,
    EncoderOfBlend,
    LogBlend,
    Unbalanced,
    Table,
}

impl Variant {
    const ALL: [Variant; 8] = [
        Variant::Z,
        Variant::ZOffset,
        Variant::Full,
        Variant::Encoder,
        Variant::EncoderOfBlend,
        Variant::LogBlend,
        Variant::Unbalanced,
        Variant::Table,
    ];

    fn name(self) -> &'static str {
        match self {
            Variant::Z => "z",
            Variant::ZOffset => "z+δ",
            Variant::Full => "full",
            Variant::Encoder => "encoder",
            Variant::EncoderOfBlend => "encoder(blend)",
            Variant::LogBlend => "log-blend",
            Variant::Unbalanced => "unbalanced",
            Variant::Table => "table",
        }
    }

    fn needs_code(self) -> bool {
        matches!(self, Variant::Z | Variant::ZOffset | Variant::Full | Variant::Unbalanced)
    }
}

/// Where a material comes from and whether the decoder was trained on it.
fn role(file: &LatentFile, name: &str, set: &str) -> &'static str {
    match (set, file.training_materials.iter().any(|t| t == name)) {
        ("merl", true) => "train",
        ("merl", false) => "held-out",
        ("rgl-isotropic", _) => "RGL",
        _ => "Nielsen",
    }
}

/// One end of a sweep.
struct Material {
    name: String,
    role: &'static str,
    table: NbrdfBsdf,
    /// The table's values at the encoder's sample points.
    values: Vec<[f32; 3]>,
    /// The code in the latent file, if any.
    code: Option<LatentCode>,
    /// The encoder's z of the table.
    encoder_z: Vec<f32>,
    /// The table's albedo per θo.
    albedo: Vec<DVec3>,
}

/// The encoder's sample points, shared by every material (so blends are sampled alike).
struct SamplePoints {
    inputs: Vec<[f32; 6]>,
    f_ref: Vec<[f32; 3]>,
}

impl SamplePoints {
    /// `n` points drawn as training drew them: θh with MERL's spacing for a share
    /// `peak_share`, uniform otherwise; θd uniform in [0, π/2], φd in [0, 2π); inside the
    /// rendered domain and where f_ref is measured.
    fn draw(n: usize, peak_share: f32, reference: &ReferenceTable, seed: u64) -> SamplePoints {
        use std::f32::consts::{FRAC_PI_2, TAU};
        let mut rng = renderer::sampler::Sampler::new(seed, 0, 0);
        let (mut inputs, mut f_ref) = (Vec::with_capacity(n), Vec::with_capacity(n));
        while inputs.len() < n {
            let peak = rng.next_1d() < peak_share;
            let u = rng.next_1d();
            let theta_h = if peak { u * u } else { u } * FRAC_PI_2;
            let (theta_d, phi_d) = (rng.next_1d() * FRAC_PI_2, rng.next_1d() * TAU);
            let Some(p) = rendered_point(theta_h, theta_d, phi_d) else { continue };
            let r = reference.lookup(&TrilinearAxes::new(p.angles[0], p.angles[1], p.angles[2]));
            if r == [0.0; 3] {
                continue;
            }
            inputs.push(p.input);
            f_ref.push(r);
        }
        SamplePoints { inputs, f_ref }
    }

    /// The encoder's z of the values `f` at these points (mapped with the file's mapping).
    fn encode(&self, file: &LatentFile, encoder: &Encoder, f: impl Fn(usize) -> [f32; 3] + Sync) -> Vec<f32> {
        let chunk = 4096;
        let sums: Vec<(Vec<f32>, usize)> = (0..self.inputs.len().div_ceil(chunk))
            .into_par_iter()
            .map(|k| {
                let range = k * chunk..((k + 1) * chunk).min(self.inputs.len());
                let samples: Vec<[f32; 9]> = range
                    .clone()
                    .map(|i| {
                        let (x, r, v) = (self.inputs[i], self.f_ref[i], f(i));
                        let y = [0, 1, 2].map(|c| file.mapping.forward(v[c].max(0.0), r[c].max(0.0), file.epsilon));
                        [x[0], x[1], x[2], x[3], x[4], x[5], y[0], y[1], y[2]]
                    })
                    .collect();
                (encoder.encode(&samples), samples.len())
            })
            .collect();
        let total: usize = sums.iter().map(|s| s.1).sum();
        let mut z = vec![0f64; file.latent_dim];
        for (part, n) in &sums {
            for (zi, p) in z.iter_mut().zip(part) {
                *zi += f64::from(*p) * *n as f64;
            }
        }
        z.into_iter().map(|v| (v / total.max(1) as f64) as f32).collect()
    }
}

/// Everything the sweeps share.
struct Study<'a> {
    args: &'a EnergyArgs,
    /// `--material`, one file.
    library: LatentLibrary,
    points: SamplePoints,
    wos: Vec<Vec3>,
}

impl Study<'_> {
    fn code(z: &[f32]) -> LatentCode {
        LatentCode { file: 0, z: z.to_vec(), offset: [0.0; 3], residual: Vec::new() }
    }

    fn file(&self) -> &LatentFile {
        self.library.latent_file(0).expect("one file")
    }

    fn decoded(&self, code: &LatentCode, label: &str) -> Result<NeuralBsdf> {
        Ok(self.library.decode_for_evaluation(code, label)?)
    }

    fn albedos_of(&self, bsdf: &NeuralBsdf) -> Vec<DVec3> {
        self.wos.iter().map(|&wo| self.args.quadrature.albedo(bsdf, wo)).collect()
    }

    fn load(&self, name: &str) -> Result<Material> {
        let set = ["merl", "rgl-isotropic", "nielsen"]
            .into_iter()
            .find(|set| self.args.nbrdf.join(set).join(format!("{name}_fc1.npy")).is_file())
            .with_context(|| format!("no NBRDF network '{name}' in {}/{{merl,rgl-isotropic,nielsen}}", self.args.nbrdf.display()))?;
        let network = NbrdfNetwork::load(self.args.nbrdf.join(set).join(name))?;
        let values: Vec<[f32; 3]> = self.points.inputs.par_iter().map(|&x| network.eval_input(x).to_array()).collect();
        let table = NbrdfBsdf::new(network, &TabulatedSamplerConfig::EVAL_ONLY);
        let encoder = self.file().encoder.as_ref().context("the latent file has no encoder")?;
        let encoder_z = self.points.encode(self.file(), encoder, |i| values[i]);
        let albedo = self.wos.iter().map(|&wo| self.args.quadrature.albedo(&table, wo)).collect();
        Ok(Material {
            name: name.to_string(),
            role: role(self.file(), name, set),
            table,
            values,
            code: self.library.latent(name).ok(),
            encoder_z,
            albedo,
        })
    }

    /// Albedo per θo of one variant at t.
    fn albedo(&self, a: &Material, b: &Material, sweep: Option<&Sweep>, variant: Variant, t: f32) -> Result<Vec<DVec3>> {
        let label = format!("{}→{}@{t}", a.name, b.name);
        let lerp_code = |strip: fn(&LatentCode) -> LatentCode| -> Result<LatentCode> {
            let (ca, cb) = (a.code.as_ref().context("no code")?, b.code.as_ref().context("no code")?);
            Ok(strip(ca).lerp(&strip(cb), t)?)
        };
        Ok(match variant {
            Variant::Z => self.albedos_of(&self.decoded(&lerp_code(|c| Study::code(&c.z))?, &label)?),
            Variant::ZOffset => self.albedos_of(&self.decoded(
                &lerp_code(|c| LatentCode { offset: c.offset, ..Study::code(&c.z) })?,
                &label,
            )?),
            Variant::Full => self.albedos_of(&self.decoded(&sweep.context("no code")?.code(t)?, &label)?),
            Variant::Encoder => {
                let z = Study::code(&a.encoder_z).lerp(&Study::code(&b.encoder_z), t)?;
                self.albedos_of(&self.decoded(&z, &label)?)
            }
            Variant::EncoderOfBlend => {
                let z = if t == 0.0 {
                    a.encoder_z.clone()
                } else if t == 1.0 {
                    b.encoder_z.clone()
                } else {
                    let encoder = self.file().encoder.as_ref().context("no encoder")?;
                    self.points.encode(self.file(), encoder, |i| {
                        let (x, y) = (a.values[i], b.values[i]);
                        [0, 1, 2].map(|c| (1.0 - t) * x[c] + t * y[c])
                    })
                };
                self.albedos_of(&self.decoded(&Study::code(&z), &label)?)
            }
            Variant::LogBlend => {
                let eps = self.file().epsilon;
                self.wos
                    .iter()
                    .map(|&wo| {
                        self.args.quadrature.albedo_with(wo, |wo, wis, values| {
                            let mut fb = vec![Rgb::ZERO; wis.len()];
                            energy::eval_batch(&a.table, wo, wis, values);
                            energy::eval_batch(&b.table, wo, wis, &mut fb);
                            for (v, g) in values.iter_mut().zip(fb) {
                                *v = Rgb::from_array([0, 1, 2].map(|c| {
                                    ((v[c] + eps).powf(1.0 - t) * (g[c] + eps).powf(t) - eps).max(0.0)
                                }));
                            }
                        })
                    })
                    .collect()
            }
            Variant::Unbalanced => self.albedos_of(&self.decoded(&lerp_code(|c| c.clone())?, &label)?),
            Variant::Table => a.albedo.iter().zip(&b.albedo).map(|(x, y)| (1.0 - f64::from(t)) * *x + f64::from(t) * *y).collect(),
        })
    }
}

/// One albedo: pair, variant, t, θo index, RGB.
struct Row {
    pair: usize,
    variant: Variant,
    t: f32,
    albedo: Vec<DVec3>,
}

/// Rec. 709 luminance.
fn luminance(c: DVec3) -> f64 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// The smallest interior-t ratio of a variant's albedo to the darker end's, per channel
/// (and where), its luminance counterpart, and the smallest ratio to the table blend.
struct Dip {
    ratio: f64,
    at: String,
    luminance: f64,
    vs_table: f64,
}

fn dip(rows: &[&Row], table: &[&Row], thetas: &[f32]) -> Option<Dip> {
    let end = |t: f32| rows.iter().find(|r| r.t == t);
    let (e0, e1) = (end(0.0)?, end(1.0)?);
    let mut d = Dip { ratio: f64::INFINITY, at: String::new(), luminance: f64::INFINITY, vs_table: f64::INFINITY };
    for r in rows.iter().filter(|r| r.t > 0.0 && r.t < 1.0) {
        let blend = table.iter().find(|b| b.t == r.t)?;
        for (k, a) in r.albedo.iter().enumerate() {
            let low = e0.albedo[k].min(e1.albedo[k]);
            for c in 0..3 {
                let ratio = a[c] / low[c].max(1e-9);
                if ratio < d.ratio {
                    d.ratio = ratio;
                    d.at = format!("t={} θo={}° {}", r.t, thetas[k], ["R", "G", "B"][c]);
                }
                d.vs_table = d.vs_table.min(a[c] / blend.albedo[k][c].max(1e-9));
            }
            let low_y = luminance(e0.albedo[k]).min(luminance(e1.albedo[k]));
            d.luminance = d.luminance.min(luminance(*a) / low_y.max(1e-9));
        }
    }
    Some(d)
}

/// Runs the study (see the module documentation).
pub fn run(args: EnergyArgs) -> Result<()> {
    if args.list_pairs {
        for (a, b) in DEFAULT_PAIRS {
            println!("{a}:{b}");
        }
        return Ok(());
    }
    if !args.times.contains(&0.0) || !args.times.contains(&1.0) {
        bail!("invalid value for --times: the ends 0 and 1 must be included");
    }
    let pairs: Vec<(String, String)> = if args.pairs.is_empty() {
        DEFAULT_PAIRS.iter().map(|(a, b)| (a.to_string(), b.to_string())).collect()
    } else {
        args.pairs.clone()
    };
    let library = LatentLibrary::load(&[&args.material])?;
    let file = library.latent_file(0)?;
    let encoder = file.encoder.as_ref().with_context(|| format!("{}: no set encoder in the file", args.material.display()))?;
    let points = SamplePoints::draw(args.encoder_samples, encoder.peak_share, &*library.reference(0)?, args.seed);
    let wos = args.theta_o.iter().map(|d| energy::view_direction(d.to_radians())).collect();
    let study = Study { args: &args, library, points, wos };

    let mut names: Vec<String> = pairs.iter().flat_map(|(a, b)| [a.clone(), b.clone()]).collect();
    names.sort();
    names.dedup();
    let style = ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {pos}/{len} {msg}")
        .expect("valid template")
        .progress_chars("=> ");
    let bar = ProgressBar::new(names.len() as u64).with_style(style.clone());
    bar.set_message("tables and encoder codes");
    let mut materials = Vec::new();
    for n in &names {
        materials.push(study.load(n)?);
        bar.inc(1);
    }
    bar.finish_and_clear();
    let material = |n: &str| materials.iter().find(|m| m.name == n).expect("loaded");

    let bar = ProgressBar::new(pairs.len() as u64).with_style(style.clone());
    bar.set_message("sweeps");
    let mut rows: Vec<Row> = Vec::new();
    for (p, (a, b)) in pairs.iter().enumerate() {
        let (ma, mb) = (material(a), material(b));
        let sweep = match (&ma.code, &mb.code) {
            (Some(ca), Some(cb)) => Some(study.library.sweep(ca, cb)?),
            _ => None,
        };
        let jobs: Vec<(Variant, f32)> = Variant::ALL
            .iter()
            .filter(|v| !v.needs_code() || (ma.code.is_some() && mb.code.is_some()))
            .flat_map(|&v| args.times.iter().map(move |&t| (v, t)))
            .collect();
        let done: Vec<Result<Row>> = jobs
            .par_iter()
            .map(|&(variant, t)| Ok(Row { pair: p, variant, t, albedo: study.albedo(ma, mb, sweep.as_ref(), variant, t)? }))
            .collect();
        for r in done {
            rows.push(r?);
        }
        bar.inc(1);
    }
    bar.finish_and_clear();

    // albedo.csv
    let mut csv = String::from("from,to,from_role,to_role,variant,t,theta_o,r,g,b,table_r,table_g,table_b\n");
    for r in &rows {
        let (a, b) = &pairs[r.pair];
        let table = rows.iter().find(|x| x.pair == r.pair && x.variant == Variant::Table && x.t == r.t).expect("table row");
        for (k, v) in r.albedo.iter().enumerate() {
            let tb = table.albedo[k];
            writeln!(
                csv,
                "{a},{b},{},{},{},{},{},{:.5},{:.5},{:.5},{:.5},{:.5},{:.5}",
                material(a).role,
                material(b).role,
                r.variant.name(),
                r.t,
                args.theta_o[k],
                v.x,
                v.y,
                v.z,
                tb.x,
                tb.y,
                tb.z
            )?;
        }
    }
    // The output directory is made only once there is something to write (a bad pair or
    // file is refused before).
    std::fs::create_dir_all(&args.out).with_context(|| format!("{}: cannot create", args.out.display()))?;
    write(&args.out.join("albedo.csv"), &csv)?;

    // The dips.
    let mut md = String::new();
    writeln!(
        md,
        "# Directional albedo along sweeps\n\n`render energy` on {} ({} pairs; t = {:?}; θo = {:?}°; quadrature {} × {}; encoder samples {}, seed {}).\n",
        args.material.display(),
        pairs.len(),
        args.times,
        args.theta_o,
        args.quadrature.theta_h_steps,
        args.quadrature.phi_h_steps,
        args.encoder_samples,
        args.seed
    )?;
    let mut dips: Vec<Vec<Option<Dip>>> = Vec::new();
    for p in 0..pairs.len() {
        let table: Vec<&Row> = rows.iter().filter(|r| r.pair == p && r.variant == Variant::Table).collect();
        dips.push(
            Variant::ALL
                .iter()
                .map(|&v| {
                    let of: Vec<&Row> = rows.iter().filter(|r| r.pair == p && r.variant == v).collect();
                    dip(&of, &table, &args.theta_o)
                })
                .collect(),
        );
    }
    writeln!(md, "## Per variant: min over interior t, θo and channel of albedo(t) / min(albedo(0), albedo(1))\n")?;
    writeln!(md, "| variant | pairs | mean | median | worst (pair, where) | pairs < 0.95 | luminance: mean / worst | vs table blend: mean / worst |")?;
    writeln!(md, "| --- | --- | --- | --- | --- | --- | --- | --- |")?;
    for (vi, v) in Variant::ALL.iter().enumerate() {
        let mut of: Vec<(usize, &Dip)> = dips.iter().enumerate().filter_map(|(p, d)| d[vi].as_ref().map(|d| (p, d))).collect();
        if of.is_empty() {
            continue;
        }
        of.sort_by(|a, b| a.1.ratio.total_cmp(&b.1.ratio));
        let n = of.len() as f64;
        let mean = of.iter().map(|d| d.1.ratio).sum::<f64>() / n;
        let median = of[of.len() / 2].1.ratio;
        let (wp, wd) = of[0];
        let below = of.iter().filter(|d| d.1.ratio < 0.95).count();
        let lum_mean = of.iter().map(|d| d.1.luminance).sum::<f64>() / n;
        let lum_worst = of.iter().map(|d| d.1.luminance).fold(f64::INFINITY, f64::min);
        let vt_mean = of.iter().map(|d| d.1.vs_table).sum::<f64>() / n;
        let vt_worst = of.iter().map(|d| d.1.vs_table).fold(f64::INFINITY, f64::min);
        writeln!(
            md,
            "| {} | {} | {mean:.3} | {median:.3} | {wn:.3} ({} → {}, {}) | {below} | {lum_mean:.3} / {lum_worst:.3} | {vt_mean:.3} / {vt_worst:.3} |",
            v.name(),
            of.len(),
            pairs[wp].0,
            pairs[wp].1,
            wd.at,
            wn = wd.ratio
        )?;
    }
    writeln!(md, "\n## Per pair: min ratio per variant (per channel; roles: train / held-out / RGL)\n")?;
    write!(md, "| pair | roles |")?;
    for v in Variant::ALL {
        write!(md, " {} |", v.name())?;
    }
    writeln!(md, " full: where |")?;
    writeln!(md, "|{}", " --- |".repeat(Variant::ALL.len() + 3))?;
    for (p, (a, b)) in pairs.iter().enumerate() {
        write!(md, "| {a} → {b} | {} / {} |", material(a).role, material(b).role)?;
        for d in &dips[p] {
            match d {
                Some(d) => write!(md, " {:.3} |", d.ratio)?,
                None => write!(md, " – |")?,
            }
        }
        let at = dips[p][2].as_ref().or(dips[p][3].as_ref()).map_or("–".to_string(), |d| d.at.clone());
        writeln!(md, " {at} |")?;
    }

    // The codes against the encoder's (the projection z ≥ 0 and the manifold).
    let mut codes = String::from("name,role,zeros_refined,zeros_encoder,rel_distance,offset_r,offset_g,offset_b,residual_rms\n");
    writeln!(md, "\n## The codes against the encoder's z of the same table\n")?;
    writeln!(md, "| material | role | z components at 0 (refined / encoder) | ‖z − z_enc‖ / ‖z_enc‖ | δ (R G B) | ΔΘ rms |")?;
    writeln!(md, "| --- | --- | --- | --- | --- | --- |")?;
    for m in &materials {
        let Some(c) = &m.code else { continue };
        let zeros = |z: &[f32]| z.iter().filter(|&&v| v == 0.0).count();
        let dist = c.z.iter().zip(&m.encoder_z).map(|(a, b)| (a - b).powi(2)).sum::<f32>().sqrt()
            / m.encoder_z.iter().map(|v| v * v).sum::<f32>().sqrt().max(1e-12);
        let rms = (c.residual.iter().map(|v| v * v).sum::<f32>() / c.residual.len().max(1) as f32).sqrt();
        writeln!(
            codes,
            "{},{},{},{},{dist:.4},{:.4},{:.4},{:.4},{rms:.5}",
            m.name,
            m.role,
            zeros(&c.z),
            zeros(&m.encoder_z),
            c.offset[0],
            c.offset[1],
            c.offset[2]
        )?;
        writeln!(
            md,
            "| {} | {} | {} / {} | {dist:.3} | {:.2} {:.2} {:.2} | {rms:.4} |",
            m.name,
            m.role,
            zeros(&c.z),
            zeros(&m.encoder_z),
            c.offset[0],
            c.offset[1],
            c.offset[2]
        )?;
    }
    write(&args.out.join("codes.csv"), &codes)?;

    // The tables' own albedo.
    writeln!(md, "\n## The tables' albedo (max over channels) per θo\n")?;
    for m in &materials {
        let v: Vec<String> = m.albedo.iter().map(|a| format!("{:.3}", a.max_element())).collect();
        writeln!(md, "- {} ({}): {}", m.name, m.role, v.join(" / "))?;
    }

    // Reciprocity of every code of the file.
    if args.reciprocity > 0 {
        let names = study.file().latent_names();
        let bar = ProgressBar::new(names.len() as u64).with_style(style);
        bar.set_message("reciprocity");
        let results: Vec<Result<(String, energy::Reciprocity)>> = names
            .par_iter()
            .map(|n| {
                let code = study.library.latent(n)?;
                // The default sampler is not needed: f is what is compared.
                let bsdf = study.decoded(&code, n)?;
                let r = energy::reciprocity(&bsdf, args.reciprocity, args.seed);
                bar.inc(1);
                Ok((n.clone(), r))
            })
            .collect();
        bar.finish_and_clear();
        let results: Vec<(String, energy::Reciprocity)> = results.into_iter().collect::<Result<_>>()?;
        let mut csv = String::from("name,rendered_max,net_mean,net_p95,net_weighted,seam_mean\n");
        for (n, r) in &results {
            writeln!(csv, "{n},{:.3e},{:.4},{:.4},{:.4},{:.4}", r.rendered_max, r.net_mean, r.net_p95, r.net_weighted, r.seam_mean)?;
        }
        write(&args.out.join("reciprocity.csv"), &csv)?;
        let stat = |f: fn(&energy::Reciprocity) -> f64| {
            let mut v: Vec<f64> = results.iter().map(|r| f(&r.1)).collect();
            v.sort_by(f64::total_cmp);
            let worst = results.iter().max_by(|a, b| f(&a.1).total_cmp(&f(&b.1))).map_or("", |r| r.0.as_str());
            format!("{:.4} / {:.4} ({worst})", v[v.len() / 2], v[v.len() - 1])
        };
        writeln!(md, "\n## Reciprocity of the {} codes (relative |f − f'| / ((f + f')/2 + ε); median / worst code)\n", results.len())?;
        writeln!(md, "| measure | median / worst |")?;
        writeln!(md, "| --- | --- |")?;
        writeln!(md, "| rendered f(wo, wi) vs f(wi, wo), max | {} |", stat(|r| r.rendered_max))?;
        writeln!(md, "| net, unfolded d vs (−dx, −dy, dz), mean | {} |", stat(|r| r.net_mean))?;
        writeln!(md, "| net, unfolded, 95th percentile | {} |", stat(|r| r.net_p95))?;
        writeln!(md, "| net, unfolded, energy-weighted | {} |", stat(|r| r.net_weighted))?;
        writeln!(md, "| seam of the fold (φd = 0 vs π), mean | {} |", stat(|r| r.seam_mean))?;
    }
    write(&args.out.join("summary.md"), &md)?;
    print!("{md}");
    eprintln!("wrote albedo.csv, codes.csv, reciprocity.csv and summary.md to {}", args.out.display());
    Ok(())
}

fn write(path: &Path, text: &str) -> Result<()> {
    renderer::support::write_bytes_atomically(path, text.as_bytes()).with_context(|| format!("{}: cannot write", path.display()))
}
