//! `material-nn eval`: evaluation of a trained model ([`EvalModel`]: a run, or a latent file
//! that carries its encoder) on held-out materials — the reconstruction
//! (talk Table 1) and editing (talk Table 2) analogues — optionally beside the per-material
//! NBRDF baseline of [`crate::nbrdf_fit`].
//!
//! # BRDF space
//! For each material: its code in the latent file when the model is a file that has one;
//! otherwise z = encoder over [`crate::inference::ENCODE_SAMPLES`] samples of its table,
//! refined as `encode` refines it ([`EvalSettings::encode`]);
//! then the decoded network is compared with the table at `samples` uniform points (θh, θd,
//! φd) of the rendered domain ([`renderer::brdf_coords::rendered_point`]: wi and wo above
//! the horizon, φd folded as the renderer folds it) drawn from a fixed seed (trilinear
//! look-ups, unmeasured points left out):
//! - `rmse`: √ mean over points and RGB of ((f' − f) cos θi)², f in 1/sr (f' clamped ≥ 0);
//! - `rec`: mean |(y' − y) cos θi| in the run's mapped space (the L_rec data term);
//! - `fre`: L_fre of the mapped, cos-weighted values, with the run's L_fre settings.
//!
//! An NBRDF network is compared at the same points, evaluated as the renderer evaluates it
//! (φd folded into [0, π)): its f' gives `rmse` directly, and its mapped values
//! y' = mapping(f', f_ref) with the run's mapping, ε and f_ref give `rec` and `fre`, so all
//! three columns measure the same quantity for both models.
//!
//! Editing: `pairs` random pairs (a, b) of the materials and t ~ U(0, 1); the frame at t of
//! the renderer's editing sweep from a to b ([`LatentLibrary::sweep`]: z and offsets
//! interpolated, residuals faded out near their ends, the offsets balanced to the blend of
//! the ends' albedo — what `render --sweep` and the plugins' blends decode) is compared with the linear blend (1 − t) f_a + t f_b of the
//! tables, with the same metrics. NBRDF has no latent space: its edit is the naive one, every
//! weight of the two materials' networks blended with t ([`NbrdfNetwork::lerp`]). The first
//! `editing_images` pairs are rendered too (the blended table is the reference), which gives
//! the editing rows PSNR and SSIM (the talk's Table 2).
//!
//! # Images
//! Unless turned off, each material is also rendered in the material-preview scene
//! ([`ImageSettings`]: its material `preview` bound in turn to the tabulated table, to the
//! decoded network and to the NBRDF network), every image with the same seed, samples per
//! pixel and path depth 8. Each model's image is compared with the table's by
//! [`renderer::metrics::ImageError::between`] on 8-bit display values (clamp tone map,
//! exposure 0): `psnr` (dB, data range 255), `ssim` (7-pixel window) and `image_rmse` (linear
//! radiance). The decoded network uses f_ref as a latent file stores it (f16), as a render of
//! the file does.

use crate::config::FreConfig;
use crate::dataset::{MaterialTable, SampleSet};
use crate::error::{Error, Result};
use crate::inference::{Codec, EncodeSettings, TrainedRun};
use crate::loss::FreOperator;
use crate::splat::SplatMap;
use rand::{Rng, SeedableRng};
use renderer::brdf_coords::rendered_point;
use crate::dataset::draw_angles;
use renderer::bsdf::merl::{Interpolation, MerlBsdf};
use renderer::bsdf::nbrdf::NbrdfBsdf;
use renderer::bsdf::tabulated_sampling::TabulatedSamplerConfig;
use renderer::bsdf::Bxdf;
use renderer::material::{Binding, SharedBsdf};
use renderer::camera::PinholeCamera;
use renderer::formats::image_io::ToneMap;
use renderer::integrator::PathTracer;
use renderer::formats::latent_file::{LatentFile, WeightType};
use renderer::metrics::{display_values, ImageError};
use renderer::neural::latent_library::{LatentCode, LatentLibrary};
use renderer::neural::nbrdf::NbrdfNetwork;
use renderer::render::{Budget, Renderer};
use renderer::render_scene::RenderScene;
use renderer::scene::{SceneDescription, SurfaceModel};
use renderer::Rgb;
use glam::Vec3;
use renderer::bsdf::albedo::guided_directional_albedo;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

/// Name of the NBRDF baseline's rows.
pub const NBRDF_MODEL: &str = "nbrdf";
/// The material of the preview scene that the evaluated BSDFs are bound to.
pub const PREVIEW_MATERIAL: &str = "preview";
/// Longest path of the preview renders, in segments.
pub const PREVIEW_MAX_DEPTH: i32 = 8;

/// Metrics of one comparison.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Metrics {
    /// Cos-weighted RMSE of f_r (1/sr).
    pub rmse: f64,
    /// Mean |(y' − y) cos θi| (mapped space).
    pub rec: f64,
    /// L_fre.
    pub fre: f64,
    /// Image metrics against the table's preview (when rendered).
    pub image: Option<ImageError>,
    /// Directional albedo of the candidate over the table's, per channel, at each of
    /// [`ALBEDO_THETAS`] (reconstruction rows).
    pub albedo_ratio: Option<[[f64; 3]; 3]>,
}

/// Viewing angles θo (degrees from the normal) of the directional albedos compared.
pub const ALBEDO_THETAS: [f32; 3] = [0.0, 45.0, 75.0];

/// The candidate's directional albedo over the table's at [`ALBEDO_THETAS`], both integrated
/// over the same directions guided by the table's sampler
/// ([`renderer::bsdf::albedo::guided_directional_albedo`]); a table channel with no energy gives
/// ratio 1 when the candidate has none either.
pub fn albedo_ratios(candidate: &impl Bxdf, table: &MerlBsdf, samples: usize) -> [[f64; 3]; 3] {
    ALBEDO_THETAS.map(|deg| {
        let t = deg.to_radians();
        let wo = Vec3::new(t.sin(), 0.0, t.cos());
        let a = guided_directional_albedo(candidate, table, wo, samples).to_array();
        let b = guided_directional_albedo(table, table, wo, samples).to_array();
        [0, 1, 2].map(|c| if b[c] > 1e-9 { a[c] / b[c] } else if a[c] > 1e-9 { f64::INFINITY } else { 1.0 })
    })
}

/// One evaluated row.
#[derive(Clone, Debug)]
pub struct Row {
    /// The model: the run's (`frenbrdf`, `hyperbrdf`) or [`NBRDF_MODEL`].
    pub model: String,
    /// Material name, or `a|b` for an editing pair.
    pub name: String,
    /// Blend parameter t (0 for reconstruction rows).
    pub t: f32,
    /// The metrics.
    pub metrics: Metrics,
}

/// Preview rendering settings.
#[derive(Clone, Debug)]
pub struct ImageSettings {
    /// The scene: a glTF file with a material named [`PREVIEW_MATERIAL`].
    pub scene: PathBuf,
    /// Image size in pixels.
    pub width: u32,
    /// See `width`.
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Where to write the previews as PNG (`NAME-table.png`, `NAME-MODEL.png`), if anywhere.
    pub out_dir: Option<PathBuf>,
    /// Where the tables' renders are kept between evaluations, if anywhere
    /// ([`PreviewScene::render_table`]).
    pub reference_cache: Option<PathBuf>,
}

/// Evaluation settings.
#[derive(Clone, Debug)]
pub struct EvalSettings {
    /// Comparison points per material.
    pub samples: usize,
    /// Editing pairs.
    pub pairs: usize,
    /// Seed of points, pairs, t and the renders.
    pub seed: u64,
    /// Directory of NBRDF networks (`DIR/NAME_fc1.npy` ...) to evaluate beside the run.
    pub nbrdf_dir: Option<PathBuf>,
    /// Preview rendering; `None` for BRDF-space metrics only.
    pub images: Option<ImageSettings>,
    /// How each material is encoded (its seed is offset by the material's position).
    pub encode: EncodeSettings,
    /// Directions per directional-albedo estimate.
    pub albedo_samples: usize,
    /// Editing pairs (the first ones) also rendered: the blended table, the model's z(t) and
    /// the NBRDF networks' weight blend, PSNR / SSIM against the blended table's render.
    pub editing_images: usize,
}

/// The model `evaluate` measures: a trained run's best epoch, or a latent file that carries
/// its set encoder, each as the renderer decodes it (f_ref as the file stores it, f16).
pub struct EvalModel {
    /// Encodes the materials that have no code, and predicts mapped values.
    pub codec: Codec,
    /// The decoder as one latent file: a run's (no codes) or the file given, whose codes are
    /// evaluated as they are.
    pub library: LatentLibrary,
    /// L_fre's settings, for the `fre` column.
    pub fre: FreConfig,
    /// The model's name in rows, summaries and image names (`frenbrdf`, `hyperbrdf`, or the
    /// file's stem).
    pub name: String,
}

impl EvalModel {
    /// A run's best epoch (its decoder exported in f32, without codes).
    pub fn of_run(run: TrainedRun, dir: &Path) -> Self {
        let file = crate::export::latent_file(&run, WeightType::F32);
        EvalModel {
            name: format!("{:?}", run.config.model).to_lowercase(),
            fre: run.config.fre,
            library: LatentLibrary::from_file(dir, file),
            codec: run.codec,
        }
    }

    /// A latent file that carries its set encoder (`export`'s); the `fre` column uses the
    /// default L_fre settings (the file does not record the run's: they are the talk's
    /// slices, which every shipped recipe keeps).
    pub fn of_file(path: &Path) -> Result<Self> {
        let file = LatentFile::read(path)?;
        let codec = Codec::from_latent_file(&file, path)?;
        let name = path.file_stem().map_or_else(|| "latent".to_string(), |s| s.to_string_lossy().into_owned());
        Ok(EvalModel { codec, library: LatentLibrary::from_file(path, file), fre: FreConfig::default(), name })
    }

    /// The code the file carries for `name`, if any.
    pub fn stored_code(&self, name: &str) -> Option<LatentCode> {
        self.library.latent(name).ok()
    }
}

/// What is compared with a reference BRDF.
enum Candidate<'a> {
    /// The run's decoder at a latent code (z, output offset and residual).
    Latent(&'a LatentCode),
    /// An NBRDF network.
    Nbrdf(&'a NbrdfNetwork),
}

/// Compares a candidate with a reference BRDF `truth(θh, θd, φd)` (1/sr).
fn compare(
    model: &EvalModel,
    candidate: &Candidate<'_>,
    truth: &dyn Fn(f32, f32, f32) -> Option<[f32; 3]>,
    settings: &EvalSettings,
    fre: &FreOperator,
    splats: &mut SplatCache,
) -> Result<Metrics> {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(settings.seed);
    let mut set = SampleSet::default();
    let mut f_true = Vec::new();
    let mut f_ref = Vec::new();
    let mut angles = Vec::new();
    let mut attempts = 0;
    while set.len() < settings.samples && attempts < 64 * settings.samples {
        attempts += 1;
        let [th, td, pd] = draw_angles(0.0, &mut rng);
        let Some(point) = rendered_point(th, td, pd) else {
            continue;
        };
        let [th, td, pd] = point.angles;
        let (Some(f), Some(r)) = (truth(th, td, pd), model.codec.sampler.reference.lookup(th, td, pd))
        else {
            continue;
        };
        if let Some((x, y, c)) = model.codec.sampler.sample_of(&point, f) {
            set.push(x, y, c);
            f_true.push(f);
            f_ref.push(r);
            angles.push(point.angles);
        }
    }
    if set.is_empty() {
        return Err(Error::Invalid("no measured points to evaluate".to_string()));
    }
    let n = set.len();
    let (mapping, epsilon) = (model.codec.sampler.mapping, model.codec.sampler.epsilon);
    // (y', f') per point and channel.
    let predicted: Vec<(f32, f32)> = match candidate {
        Candidate::Latent(code) => {
            let y = model.codec.predict(&code.z, code.offset, &code.residual, &set.inputs);
            (0..3 * n)
                .map(|k| {
                    let r = f_ref[k / 3][k % 3].max(0.0);
                    (y[k], mapping.inverse(y[k], r, epsilon).max(0.0))
                })
                .collect()
        }
        Candidate::Nbrdf(net) => angles
            .iter()
            .zip(&f_ref)
            .flat_map(|(&[th, td, pd], r)| {
                let f = net.eval_angles(th, td, pd);
                (0..3).map(move |c| (mapping.forward(f[c], r[c].max(0.0), epsilon), f[c]))
            })
            .collect(),
    };
    let (mut se, mut abs) = (0f64, 0f64);
    let mut pred_cos = Vec::with_capacity(3 * n);
    let mut true_cos = Vec::with_capacity(3 * n);
    for i in 0..n {
        let c = set.cos_i[i] as f64;
        for ch in 0..3 {
            let (y_pred, f_pred) = predicted[3 * i + ch];
            let y_true = set.values[3 * i + ch];
            se += ((f_pred as f64 - f_true[i][ch] as f64) * c).powi(2);
            abs += ((y_pred - y_true) as f64 * c).abs();
            pred_cos.push(y_pred as f64 * c);
            true_cos.push(y_true as f64 * c);
        }
    }
    let map = splats.map(fre, set.directions())?;
    Ok(Metrics {
        rmse: (se / (3 * n) as f64).sqrt(),
        rec: abs / (3 * n) as f64,
        fre: fre.loss_cpu(map, &pred_cos, &true_cos),
        image: None,
        albedo_ratio: None,
    })
}

/// The material-preview scene, ready to render with any BSDF bound to its preview material.
pub struct PreviewScene {
    scene_path: PathBuf,
    scene: RenderScene,
    camera: PinholeCamera,
    slot: usize,
    width: u32,
    height: u32,
    spp: u32,
    seed: u64,
}

impl PreviewScene {
    /// Loads the scene of `settings` with [`PREVIEW_MATERIAL`] bound to the table at
    /// `table` (any table: every render replaces it). Errors name the scene file.
    pub fn load(settings: &ImageSettings, table: &Path, seed: u64) -> Result<Self> {
        let path = &settings.scene;
        let mut description = SceneDescription::load(path)?;
        let index = description
            .materials
            .iter()
            .position(|m| m.name == PREVIEW_MATERIAL)
            .ok_or_else(|| {
                Error::invalid_file(
                    path,
                    format!("no material named '{PREVIEW_MATERIAL}' to bind the BRDFs to"),
                )
            })?;
        let table = std::path::absolute(table).map_err(|e| Error::io(table, e))?;
        description.materials[index].model = SurfaceModel::Bound(Binding::Merl(table));
        let camera = description.camera(None)?.clone();
        let scene = RenderScene::new(description)?;
        let slot = scene.materials.shared_slot(PREVIEW_MATERIAL).ok_or_else(|| {
            Error::invalid_file(path, format!("material '{PREVIEW_MATERIAL}' is on no triangle"))
        })?;
        Ok(PreviewScene {
            scene_path: path.clone(),
            camera: PinholeCamera::new(&camera, settings.width, settings.height),
            scene,
            slot,
            width: settings.width,
            height: settings.height,
            spp: settings.spp,
            seed,
        })
    }

    /// Renders the scene with `bsdf` on the preview material: linear radiance, row-major.
    pub fn render(&mut self, bsdf: SharedBsdf) -> Vec<Rgb> {
        self.scene.materials.set_shared(self.slot, bsdf);
        let renderer = Renderer {
            scene: &self.scene,
            camera: self.camera.clone(),
            integrator: PathTracer {
                max_depth: PREVIEW_MAX_DEPTH,
                ..PathTracer::default()
            },
            seed: self.seed,
        };
        let (film, _) = renderer.render(
            self.width,
            self.height,
            Budget::Spp(self.spp),
            &AtomicBool::new(false),
            &|_| {},
            &mut |_, _| {},
        );
        film.mean()
    }

    /// The render of the table at `path` (loaded as `bsdf`), or, with a `cache` directory,
    /// the one kept there by an earlier evaluation with the same scene file and table file
    /// (each by path, size and modification time), resolution, spp and seed: two models of one
    /// seed are compared against the same reference renders, which cost half an
    /// evaluation's previews. A linear f32 EXR per table, so a kept render equals a fresh
    /// one bit for bit — with the same build: the key does not cover the renderer's code,
    /// so clear the cache after changing it.
    pub fn render_table(&mut self, path: &Path, bsdf: MerlBsdf, cache: Option<&Path>) -> Result<Vec<Rgb>> {
        let Some(dir) = cache else {
            return Ok(self.render(SharedBsdf::Merl(bsdf)));
        };
        let kept = dir.join(format!("{}-{:016x}.exr", crate::tables::material_name(path)?, self.key_of(path)?));
        if let Ok((w, h, pixels)) = renderer::formats::image_io::read_image(&kept) {
            if (w, h) == (self.width, self.height) {
                return Ok(pixels);
            }
        }
        let image = self.render(SharedBsdf::Merl(bsdf));
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        renderer::formats::image_io::write_exr(&kept, self.width, self.height, &image)?;
        Ok(image)
    }

    /// What a render of the table at `table` depends on besides the code, hashed: the scene
    /// file and the table file (each by path, size and modification time), and the render
    /// settings.
    fn key_of(&self, table: &Path) -> Result<u64> {
        use std::hash::{Hash, Hasher};
        let identity = |path: &Path| -> Result<(PathBuf, u64, Option<std::time::SystemTime>)> {
            let path = std::path::absolute(path).map_err(|e| Error::io(path, e))?;
            let meta = std::fs::metadata(&path).map_err(|e| Error::io(&path, e))?;
            Ok((path, meta.len(), meta.modified().ok()))
        };
        let mut hasher = std::collections::hash_map::DefaultHasher::new();
        (identity(&self.scene_path)?, identity(table)?).hash(&mut hasher);
        (self.width, self.height, self.spp, self.seed, PREVIEW_MAX_DEPTH).hash(&mut hasher);
        Ok(hasher.finish())
    }

    /// The image metrics of `image` against `reference` (see the module documentation).
    pub fn error(&self, image: &[Rgb], reference: &[Rgb]) -> ImageError {
        ImageError::between(
            image,
            reference,
            self.width as usize,
            self.height as usize,
            |img| display_values(img, ToneMap::Clamp, 0.0),
        )
    }

    /// Writes `image` as a PNG (clamp tone map) to `dir/file`.
    fn write_png(&self, dir: Option<&Path>, file: &str, image: &[Rgb]) -> Result<()> {
        if let Some(dir) = dir {
            renderer::formats::image_io::write_png(
                &dir.join(file),
                self.width,
                self.height,
                image,
                ToneMap::Clamp,
                0.0,
            )?;
        }
        Ok(())
    }
}

/// The NBRDF prefix `dir/name`, checked to hold a network.
fn nbrdf_prefix(dir: &Path, name: &str) -> Result<PathBuf> {
    let prefix = dir.join(name);
    let fc1 = renderer::neural::nbrdf::tensor_paths(&prefix)[0].clone();
    if !fc1.is_file() {
        return Err(Error::invalid_file(
            fc1,
            format!("no NBRDF network for '{name}' (fit it with material-nn nbrdf-fit)"),
        ));
    }
    Ok(prefix)
}

/// The splat map of the last sample set's directions: every comparison draws its points
/// with the evaluation's seed, so the sets (and their maps, half of an evaluation's time
/// when recomputed) are the same unless a table leaves points out.
#[derive(Default)]
struct SplatCache {
    last: Option<(Vec<[f32; 3]>, SplatMap)>,
}

impl SplatCache {
    /// The map of `directions`, made only when they differ from the last ones.
    fn map(&mut self, fre: &FreOperator, directions: Vec<[f32; 3]>) -> Result<&SplatMap> {
        if self.last.as_ref().is_none_or(|(last, _)| *last != directions) {
            let map = fre.splat_map(&directions)?;
            self.last = Some((directions, map));
        }
        Ok(&self.last.as_ref().expect("just filled").1)
    }
}

/// Reconstruction and editing rows for the materials `names` of `data_dir`; `progress` is
/// called with a description of each step as it starts.
pub fn evaluate(
    model: &EvalModel,
    data_dir: &Path,
    names: &[String],
    settings: &EvalSettings,
    progress: &mut dyn FnMut(&str),
) -> Result<(Vec<Row>, Vec<Row>)> {
    if names.is_empty() {
        return Err(Error::Invalid(
            "no materials to evaluate (the split is empty)".to_string(),
        ));
    }
    let fre = FreOperator::new(&model.fre, &model.codec.device);
    let mut splats = SplatCache::default();
    let table_path =
        |name: &str| crate::tables::table_path(data_dir, name);
    let nbrdf_prefixes = match &settings.nbrdf_dir {
        Some(dir) => Some(
            names
                .iter()
                .map(|n| nbrdf_prefix(dir, n))
                .collect::<Result<Vec<_>>>()?,
        ),
        None => None,
    };
    let mut tables = Vec::new();
    let mut codes = Vec::new();
    for (i, name) in names.iter().enumerate() {
        let table = MaterialTable::read(&table_path(name))?;
        let code = match model.stored_code(name) {
            Some(code) => code,
            None => {
                progress(&format!("encoding {name}"));
                let encode = EncodeSettings {
                    seed: settings.seed.wrapping_add(i as u64),
                    ..settings.encode.clone()
                };
                model.codec.encode(&table, &encode)?.into_code(0)
            }
        };
        codes.push(code);
        tables.push(table);
    }
    let mut preview = match &settings.images {
        Some(images) => {
            if let Some(dir) = &images.out_dir {
                std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
            }
            Some((
                PreviewScene::load(images, &table_path(&names[0]), settings.seed)?,
                images.out_dir.clone(),
            ))
        }
        None => None,
    };
    let mut reconstruction = Vec::new();
    let mut nbrdf_nets = Vec::new();
    for (i, ((name, table), code)) in names.iter().zip(&tables).zip(&codes).enumerate() {
        progress(&format!("reconstruction {name}"));
        let truth = |a, b, c| table.lookup(a, b, c);
        let mut latent = compare(model, &Candidate::Latent(code), &truth, settings, &fre, &mut splats)?;
        let table_bsdf = MerlBsdf::load(table_path(name))?;
        let neural = model.library.decode_code(code, name)?;
        latent.albedo_ratio = Some(albedo_ratios(&neural, &table_bsdf, settings.albedo_samples));
        let (mut nbrdf, nbrdf_bsdf) = match &nbrdf_prefixes {
            Some(prefixes) => {
                let net = NbrdfNetwork::load(&prefixes[i])?;
                let mut m = compare(
                    model,
                    &Candidate::Nbrdf(&net),
                    &truth,
                    settings,
                    &fre,
                    &mut splats,
                )?;
                let bsdf = NbrdfBsdf::new(net.clone(), &TabulatedSamplerConfig::default());
                m.albedo_ratio = Some(albedo_ratios(&bsdf, &table_bsdf, settings.albedo_samples));
                nbrdf_nets.push(net);
                (Some(m), Some(bsdf))
            }
            None => (None, None),
        };
        if let Some((scene, dir)) = &mut preview {
            let dir = dir.as_deref();
            let cache = settings.images.as_ref().and_then(|i| i.reference_cache.as_deref());
            let table_image = scene.render_table(&table_path(name), table_bsdf, cache)?;
            scene.write_png(dir, &format!("{name}-table.png"), &table_image)?;
            let image = scene.render(SharedBsdf::Neural(neural));
            scene.write_png(dir, &format!("{name}-{}.png", model.name), &image)?;
            latent.image = Some(scene.error(&image, &table_image));
            if let (Some(m), Some(bsdf)) = (&mut nbrdf, nbrdf_bsdf) {
                let image = scene.render(SharedBsdf::Nbrdf(bsdf));
                scene.write_png(dir, &format!("{name}-{NBRDF_MODEL}.png"), &image)?;
                m.image = Some(scene.error(&image, &table_image));
            }
        }
        reconstruction.push(Row {
            model: model.name.clone(),
            name: name.clone(),
            t: 0.0,
            metrics: latent,
        });
        if let Some(metrics) = nbrdf {
            reconstruction.push(Row {
                model: NBRDF_MODEL.to_string(),
                name: name.clone(),
                t: 0.0,
                metrics,
            });
        }
    }
    let mut editing = Vec::new();
    if tables.len() >= 2 {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(settings.seed ^ 0xed17);
        for k in 0..settings.pairs {
            progress(&format!("editing pair {}/{}", k + 1, settings.pairs));
            let a = rng.random_range(0..tables.len());
            let mut b = rng.random_range(0..tables.len() - 1);
            if b >= a {
                b += 1;
            }
            let t: f32 = rng.random();
            let code = model.library.sweep(&codes[a], &codes[b])?.code(t)?;
            let (ta, tb) = (&tables[a], &tables[b]);
            let blend = |h: f32, d: f32, p: f32| -> Option<[f32; 3]> {
                let (fa, fb) = (ta.lookup(h, d, p)?, tb.lookup(h, d, p)?);
                Some([0, 1, 2].map(|c| (1.0 - t) * fa[c] + t * fb[c]))
            };
            let name = format!("{}|{}", names[a], names[b]);
            let mut latent = compare(model, &Candidate::Latent(&code), &blend, settings, &fre, &mut splats)?;
            let net = (!nbrdf_nets.is_empty()).then(|| nbrdf_nets[a].lerp(&nbrdf_nets[b], t));
            let mut nbrdf = net.as_ref().map(|net| compare(model, &Candidate::Nbrdf(net), &blend, settings, &fre, &mut splats)).transpose()?;
            if let Some((scene, dir)) = preview.as_mut().filter(|_| k < settings.editing_images) {
                let dir = dir.as_deref();
                let blended = ta.blend(tb, name.clone(), |_| t).to_merl()?;
                let reference = scene.render(SharedBsdf::Merl(MerlBsdf::new(&blended, Interpolation::default(), &TabulatedSamplerConfig::default())));
                scene.write_png(dir, &format!("edit-{k:04}-table.png"), &reference)?;
                let image = scene.render(SharedBsdf::Neural(model.library.decode_code(&code, &name)?));
                scene.write_png(dir, &format!("edit-{k:04}-{}.png", model.name), &image)?;
                latent.image = Some(scene.error(&image, &reference));
                if let (Some(m), Some(net)) = (&mut nbrdf, net) {
                    let image = scene.render(SharedBsdf::Nbrdf(NbrdfBsdf::new(net, &TabulatedSamplerConfig::default())));
                    scene.write_png(dir, &format!("edit-{k:04}-{NBRDF_MODEL}.png"), &image)?;
                    m.image = Some(scene.error(&image, &reference));
                }
            }
            editing.push(Row { model: model.name.clone(), name: name.clone(), t, metrics: latent });
            if let Some(metrics) = nbrdf {
                editing.push(Row { model: NBRDF_MODEL.to_string(), name, t, metrics });
            }
        }
    }
    Ok((reconstruction, editing))
}

/// Mean metrics of rows; the image metrics are the means over the rows that have them.
pub fn mean(rows: &[Row]) -> Metrics {
    let n = rows.len().max(1) as f64;
    let mut m = Metrics::default();
    let (mut images, mut count) = (
        ImageError {
            rmse: 0.0,
            psnr: 0.0,
            ssim: 0.0,
        },
        0usize,
    );
    for r in rows {
        m.rmse += r.metrics.rmse / n;
        m.rec += r.metrics.rec / n;
        m.fre += r.metrics.fre / n;
        if let Some(e) = r.metrics.image {
            images.rmse += e.rmse;
            images.psnr += e.psnr;
            images.ssim += e.ssim;
            count += 1;
        }
    }
    if count > 0 {
        let c = count as f64;
        m.image = Some(ImageError {
            rmse: images.rmse / c,
            psnr: images.psnr / c,
            ssim: images.ssim / c,
        });
    }
    m
}

/// The rows of one model.
fn rows_of(rows: &[Row], model: &str) -> Vec<Row> {
    rows.iter().filter(|r| r.model == model).cloned().collect()
}

/// Rows as CSV (`model,name,t,rmse,rec,fre,psnr,ssim,image_rmse`, then the albedo ratios
/// `albedo_DEG_r,albedo_DEG_g,albedo_DEG_b` for each of [`ALBEDO_THETAS`]; the image and albedo
/// columns are empty where they were not measured).
pub fn to_csv(rows: &[Row]) -> String {
    let mut out = String::from("model,name,t,rmse,rec,fre,psnr,ssim,image_rmse");
    for deg in ALBEDO_THETAS {
        for c in ["r", "g", "b"] {
            let _ = write!(out, ",albedo_{deg}_{c}");
        }
    }
    out.push('\n');
    for r in rows {
        let m = &r.metrics;
        let image = m.image.map_or(",,".to_string(), |e| {
            format!("{:.4},{:.6},{:.6e}", e.psnr, e.ssim, e.rmse)
        });
        let albedo = m.albedo_ratio.map_or_else(
            || vec![String::new(); 3 * ALBEDO_THETAS.len()].join(","),
            |a| a.iter().flatten().map(|v| format!("{v:.4}")).collect::<Vec<_>>().join(","),
        );
        let _ = writeln!(
            out,
            "{},{},{},{:.6e},{:.6e},{:.6e},{image},{albedo}",
            r.model, r.name, r.t, m.rmse, m.rec, m.fre
        );
    }
    out
}

/// Per-material reconstruction rows of `model` as markdown, worst preview PSNR first (BRDF
/// RMSE when there are no previews): PSNR, SSIM, RMSE and the albedo ratios per channel.
pub fn per_material_markdown(reconstruction: &[Row], model: &str) -> String {
    let mut rows = rows_of(reconstruction, model);
    let key = |r: &Row| r.metrics.image.map_or(-r.metrics.rmse, |e| e.psnr);
    rows.sort_by(|a, b| key(a).total_cmp(&key(b)));
    let mut out = String::from("| material | PSNR (dB) | SSIM | RMSE×10² |");
    for deg in ALBEDO_THETAS {
        let _ = write!(out, " albedo ratio θo={deg}° (R G B) |");
    }
    out.push_str("\n| --- | --- | --- | --- |");
    out.push_str(&" --- |".repeat(ALBEDO_THETAS.len()));
    out.push('\n');
    for r in &rows {
        let m = &r.metrics;
        let (psnr, ssim) = m.image.map_or(("–".to_string(), "–".to_string()), |e| {
            (format!("{:.2}", e.psnr), format!("{:.4}", e.ssim))
        });
        let _ = write!(out, "| {} | {psnr} | {ssim} | {:.3} |", r.name, m.rmse * 1e2);
        for a in m.albedo_ratio.iter().flatten() {
            let _ = write!(out, " {:.2} {:.2} {:.2} |", a[0], a[1], a[2]);
        }
        out.push('\n');
    }
    out
}

/// The means per model and table as markdown, with the talk's scalings; `images` describes
/// the preview renders (or `None` when there were none).
pub fn to_markdown(reconstruction: &[Row], editing: &[Row], images: Option<&str>) -> String {
    let mut models: Vec<&str> = Vec::new();
    for r in reconstruction.iter().chain(editing) {
        if !models.contains(&r.model.as_str()) {
            models.push(&r.model);
        }
    }
    let mut out = String::from(
        "| model | evaluation | materials / pairs | RMSE×10² (cos-weighted f_r) | L_rec data ×10² \
         | L_fre×10³ | PSNR (dB) | SSIM×10 |\n\
         | --- | --- | --- | --- | --- | --- | --- | --- |\n",
    );
    for model in &models {
        for (what, rows) in [("reconstruction", reconstruction), ("editing", editing)] {
            let rows = rows_of(rows, model);
            if rows.is_empty() && what == "editing" {
                continue;
            }
            let m = mean(&rows);
            let (psnr, ssim) = m.image.map_or(("–".to_string(), "–".to_string()), |e| {
                (format!("{:.2}", e.psnr), format!("{:.3}", e.ssim * 10.0))
            });
            let _ = writeln!(
                out,
                "| {model} | {what} | {} | {:.3} | {:.3} | {:.4} | {psnr} | {ssim} |",
                rows.len(),
                m.rmse * 1e2,
                m.rec * 1e2,
                m.fre * 1e3,
            );
        }
    }
    for model in &models {
        let rows = rows_of(reconstruction, model);
        if rows.is_empty() {
            continue;
        }
        let psnrs: Vec<f64> = rows.iter().filter_map(|r| r.metrics.image.map(|e| e.psnr)).collect();
        let _ = write!(out, "\n### {model}: per material, worst first\n\n");
        if let Some(worst) = psnrs.iter().copied().reduce(f64::min) {
            let mut sorted = rows.clone();
            sorted.sort_by(|a, b| {
                let key = |r: &Row| r.metrics.image.map_or(f64::INFINITY, |e| e.psnr);
                key(a).total_cmp(&key(b))
            });
            let names: Vec<&str> = sorted.iter().take(5).map(|r| r.name.as_str()).collect();
            let _ = writeln!(
                out,
                "Preview PSNR mean {:.2} dB, worst {worst:.2} dB over {} materials; worst five: {}.\n",
                psnrs.iter().sum::<f64>() / psnrs.len() as f64,
                psnrs.len(),
                names.join(", ")
            );
        }
        out.push_str(&per_material_markdown(reconstruction, model));
    }
    if let Some(images) = images {
        let _ = writeln!(out, "\n{images}");
    }
    out
}
