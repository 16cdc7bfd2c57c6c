//! The render loop: progressive passes over the image, each pass split into tiles that
//! rayon's threads take one at a time. Every sample draws from its own random stream
//! ([`crate::sampler::Sampler`]) and each pixel's samples are accumulated in sample order
//! whichever thread renders its tile, so the image is bit-identical for any number of
//! threads, and a [`Region`] of it rendered alone is bit-identical to the same pixels of the
//! whole image (tiles lie on one grid over the whole image; a pixel's streams depend on its
//! position in the whole image).

use crate::camera::PinholeCamera;
use crate::film::{Film, PixelAccumulator, Region, TILE_SIZE};
use crate::accel::{negative_axes, Hit, Ray, DEPTH_CLASSES};
use crate::integrator::{BatchBuffers, PathState, PathTracer, StepResults};
use crate::lanes::{Vec2s, LANES};
use crate::render_scene::RenderScene;
use crate::sampler::Sampler;
use crate::Rgb;
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use serde::Serialize;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::time::{Duration, Instant};

/// The most samples per pixel one pass takes, with a sample or a time budget: Ctrl-C is
/// answered within one tile of this many samples per pixel.
const MAX_PASS_SAMPLES: u32 = 16;

/// Width and height in pixels of the blocks whose camera rays are made together and follow
/// one another in a tile's batch, so that a packet of rays (16 with AVX-512, 8 with AVX2)
/// holds a square of pixels (or half of one), not a row: a square's rays spread less and
/// visit fewer nodes and leaves together. The glossy sphere's render: +6 % against rows of
/// 16, its bounces following in the same order; the same image.
const CAMERA_BLOCK: (u32, u32) = (4, 4);
const _: () = assert!(CAMERA_BLOCK.0 * CAMERA_BLOCK.1 == LANES as u32 && TILE_SIZE.is_multiple_of(CAMERA_BLOCK.0) && TILE_SIZE.is_multiple_of(CAMERA_BLOCK.1));

/// When to stop rendering.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Budget {
    /// This many samples per pixel.
    Spp(u32),
    /// Passes of one sample per pixel until this much wall time has passed (at least one).
    Time(Duration),
}

/// How the caller follows and stops a render ([`Renderer::render_region`]).
pub struct Monitor<'a> {
    /// Set (e.g. by Ctrl-C) to stop: the tiles under way finish and the render returns the
    /// film as it stands.
    pub cancel: &'a AtomicBool,
    /// Called with the number of samples of each tile as it finishes (a progress bar), from
    /// any thread.
    pub progress: &'a (dyn Fn(u64) + Sync),
    /// Called after each pass with the film and the time since the render began (an error
    /// log, a time-budget display).
    pub after_pass: &'a mut dyn FnMut(&Film, Duration),
}

/// Counts of one or more passes.
#[derive(Clone, Copy, Debug, Default)]
pub struct PassCounters {
    /// Pixel samples accumulated.
    pub samples: u64,
    /// Closest-hit rays.
    pub rays: u64,
    /// Shadow rays.
    pub shadow_rays: u64,
    /// Samples discarded because their radiance was NaN, infinite or negative.
    pub discarded: u64,
}

impl PassCounters {
    fn add(&mut self, o: &PassCounters) {
        self.samples += o.samples;
        self.rays += o.rays;
        self.shadow_rays += o.shadow_rays;
        self.discarded += o.discarded;
    }
}

/// Statistics of a finished render (written by `render --stats`).
#[derive(Clone, Debug, Serialize)]
pub struct RenderStats {
    /// Size of the whole image.
    pub width: u32,
    pub height: u32,
    /// The pixels rendered (the whole image unless `render --region`).
    pub region: Region,
    /// Mean samples per rendered pixel actually taken.
    pub spp: f64,
    pub samples: u64,
    /// Wall time of this run (of the resumed part when `resumed_spp` > 0); the rates are of
    /// this run's samples and rays.
    pub wall_seconds: f64,
    pub samples_per_second: f64,
    /// Closest-hit plus shadow rays.
    pub rays: u64,
    pub rays_per_second: f64,
    /// Samples whose radiance was NaN, infinite or negative and were left out.
    pub discarded_samples: u64,
    /// Samples per pixel read from a checkpoint, which this run continued (0 when it began
    /// from nothing); `spp`, `samples`, `rays` and `discarded_samples` count them too.
    pub resumed_spp: u32,
    pub threads: usize,
    pub max_depth: i32,
    pub seed: u64,
    /// True when the render was interrupted (Ctrl-C) before its budget was spent.
    pub interrupted: bool,
    /// How closest-hit and occlusion rays were traced, per class of path depth (camera
    /// rays and their shadow rays, the first bounce, deeper bounces; see
    /// [`crate::accel::DEPTH_CLASSES`]): "packets", "single rays", or "no rays" for a class
    /// that traced none (the first batch with rays is measured both ways, so every class
    /// that traced rays has a choice).
    pub closest_traversal: [&'static str; DEPTH_CLASSES],
    pub occlusion_traversal: [&'static str; DEPTH_CLASSES],
}

/// The buffers of a tile's batch of paths, reused from tile to tile by a worker thread.
#[derive(Default)]
struct TileScratch<'s> {
    paths: Vec<PathState>,
    /// Sample index (within the tile's pass) of each path.
    owners: Vec<u32>,
    /// Paths still going.
    active: Vec<u32>,
    rays: Vec<Ray>,
    hits: Vec<Option<Hit>>,
    /// The shadow tests of the current vertex and the paths that go on after it.
    step: StepResults,
    blocked: Vec<bool>,
    buffers: BatchBuffers<'s>,
    radiance: Vec<Rgb>,
    /// Per pixel of the tile, row by row: its random streams' [`Sampler::pixel_key`].
    keys: Vec<u64>,
    /// The paths of a batch in the order they are traced ([`octant_order`]).
    order: Vec<u32>,
}

/// Fills `order` with the indices of `directions` grouped by octant (bit 0: x < 0, bit 1:
/// y < 0, bit 2: z < 0), a stable counting sort that keeps the batch's order within an
/// octant. Rays traced in that order share packets with rays that visit a node's children
/// in the same order, as a pixel block's camera rays do; after a scattering vertex, the rays
/// of a block point every way. The order changes which rays share a packet, never a hit or
/// a path's random stream.
fn octant_order(directions: impl Iterator<Item = Vec3> + Clone, order: &mut Vec<u32>) {
    let octant = |d: Vec3| negative_axes(d.into()) as usize;
    let mut start = [0u32; 9];
    for d in directions.clone() {
        start[octant(d) + 1] += 1;
    }
    for o in 0..8 {
        start[o + 1] += start[o];
    }
    order.clear();
    order.resize(start[8] as usize, 0);
    for (i, d) in directions.enumerate() {
        let o = octant(d);
        order[start[o] as usize] = i as u32;
        start[o] += 1;
    }
}

/// The tiles of one pass, rendered but not yet added to the film.
struct TracedPass {
    tiles: Tiles,
    results: Vec<(u32, Vec<PixelAccumulator>, PassCounters)>,
}

impl TracedPass {
    /// True when every tile of the pass was rendered (no cancellation cut it short).
    fn is_complete(&self) -> bool {
        self.results.len() == self.tiles.count() as usize
    }

    /// Adds the tiles' samples to `film`; returns their counts.
    fn merge_into(self, film: &mut Film) -> PassCounters {
        let (region, w) = (film.region, film.width);
        let mut total = PassCounters::default();
        // Each pixel lies in one tile, so the order of the merges does not change the film.
        for (tile, pixels, counters) in self.results {
            total.add(&counters);
            let (x0, y0, x1, y1) = self.tiles.bounds(tile);
            let mut i = 0;
            for y in y0..y1 {
                for x in x0..x1 {
                    film.merge((x - region.x0 + (y - region.y0) * w) as usize, &pixels[i]);
                    i += 1;
                }
            }
        }
        total
    }
}

/// A render at a pass boundary: the film, the samples per pixel taken so far (whole passes)
/// and the counts of those samples. A render continued from it ([`Renderer::continue_region`])
/// with the same scene, camera, integrator, seed and sample budget gives the image of the
/// uninterrupted render bit for bit, because the passes are sized by the budget and the
/// samples done alone and each sample draws from its own random stream.
#[derive(Clone, Debug)]
pub struct RenderState {
    pub film: Film,
    /// Samples per pixel of the passes done (every pixel of the film has had them).
    pub samples_done: u32,
    /// Counts of the samples of those passes.
    pub counters: PassCounters,
}

impl RenderState {
    /// A render of `region` of a `width` × `height` image that has not begun.
    pub fn new(width: u32, height: u32, region: Region) -> Self {
        RenderState {
            film: Film::of_region(width, height, region),
            samples_done: 0,
            counters: PassCounters::default(),
        }
    }
}

/// The size of the pass that follows `done` samples per pixel under a sample budget of
/// `spp`: at least 8 passes (an error log of 8 rows or more) of at most MAX_PASS_SAMPLES.
/// Each tile's pass is one batch of paths, and more samples fill a batch's later, sparser
/// bounces better: the README's 64-spp render ran 1–5 % faster in 8 passes of 8 than in 16
/// of 4, the GGX preview and the Cornell box at 256 spp 2–3 % faster in passes of 16 than
/// of 8 (the neural preview the same within noise). The progress bar moves tile by tile
/// either way. It depends on `spp` and `done` alone, so a render resumed at a pass boundary
/// runs the passes that the uninterrupted render runs.
fn spp_pass_size(spp: u32, done: u32) -> u32 {
    spp.saturating_sub(done).min(spp.div_ceil(8).clamp(1, MAX_PASS_SAMPLES))
}

/// What renders one image: scene, camera, integrator and seed.
pub struct Renderer<'a> {
    pub scene: &'a RenderScene,
    pub camera: PinholeCamera,
    pub integrator: PathTracer,
    pub seed: u64,
}

impl<'a> Renderer<'a> {
    /// Adds samples `first_sample .. first_sample + count` to every pixel of `film`.
    /// Tiles not yet started when `cancel` becomes true are skipped; `progress` is called
    /// with the number of samples of each finished tile.
    ///
    /// The pool's threads take tiles one at a time from a shared counter until none is left,
    /// each with one set of batch buffers: the pass ends at most one tile's time after the
    /// first thread runs out of work. (Split as a parallel iterator, rayon hands each thread
    /// runs of hundreds of tiles, and one thread idled for 5–9 % of every pass while the
    /// other finished its last run.)
    pub fn render_pass(
        &self,
        film: &mut Film,
        first_sample: u32,
        count: u32,
        cancel: &AtomicBool,
        progress: &(dyn Fn(u64) + Sync),
    ) -> PassCounters {
        let pass = self.trace_pass(film, first_sample, count, cancel, progress);
        pass.merge_into(film)
    }

    /// The tiles of a pass ([`Renderer::render_pass`]) rendered but not yet added to the
    /// film: all of them, or those finished before `cancel` was set.
    fn trace_pass(&self, film: &Film, first_sample: u32, count: u32, cancel: &AtomicBool, progress: &(dyn Fn(u64) + Sync)) -> TracedPass {
        let region = film.region;
        let tiles = Tiles::new(film.full_width, region);
        let samples = first_sample..first_sample + count;
        let next_tile = AtomicU32::new(0);
        let workers = rayon::current_num_threads().clamp(1, tiles.count().max(1) as usize);
        let results: Vec<(u32, Vec<PixelAccumulator>, PassCounters)> = (0..workers)
            .into_par_iter()
            .with_max_len(1)
            .flat_map_iter(|_| {
                let mut scratch = TileScratch::default();
                let mut finished = Vec::new();
                loop {
                    let tile = next_tile.fetch_add(1, Ordering::Relaxed);
                    if tile >= tiles.count() || cancel.load(Ordering::Relaxed) {
                        break finished;
                    }
                    let (pixels, counters) = self.render_tile(&mut scratch, tiles, tile, samples.clone());
                    progress(counters.samples);
                    finished.push((tile, pixels, counters));
                }
            })
            .collect();
        TracedPass { tiles, results }
    }

    /// Renders samples `first_sample .. first_sample + count` of a tile's pixels as one batch
    /// of paths advanced together vertex by vertex: all closest hits (in packets or one by
    /// one, see [`crate::accel::TracePolicy`]), then all shading steps, then all shadow rays.
    /// Neighbouring iterations are independent paths, which the CPU overlaps, where one path
    /// alone is a chain of dependent latencies. Each path consumes its random stream exactly
    /// as [`PathTracer::radiance`] does, so the image is the same.
    fn render_tile(&self, scratch: &mut TileScratch<'a>, tiles: Tiles, tile: u32, samples: Range<u32>) -> (Vec<PixelAccumulator>, PassCounters) {
        let count = samples.len() as u32;
        let w = tiles.full_width;
        let (x0, y0, x1, y1) = tiles.bounds(tile);
        let tile_w = x1 - x0;
        let n = (tile_w * (y1 - y0)) as usize;
        // Every sample of the pass in one batch (sample-major): late in the paths, when most
        // have ended, the survivors still fill packets.
        let batch = n * count as usize;
        let mut counters = PassCounters::default();
        let TileScratch {
            paths,
            owners,
            active,
            rays,
            hits,
            step,
            blocked,
            buffers,
            radiance,
            keys,
            order,
        } = scratch;
        paths.clear();
        owners.clear();
        active.clear();
        let scene = self.scene;
        // Camera rays are made LANES at a time (the same rays as one by one), one block of
        // CAMERA_BLOCK pixels per group; a path's owner is its sample's index in the batch,
        // sample-major then row by row.
        let origin = self.camera.origin();
        let mut film = Vec2s::default();
        let mut samplers: [Sampler; LANES] = std::array::from_fn(|_| Sampler::new(0, 0, 0));
        let (block_w, block_h) = CAMERA_BLOCK;
        // Per lane of a block: the pixel, and its index in the tile (row by row).
        let mut pixels_of = [(0u32, 0u32, 0u32); LANES];
        // The random streams' per-pixel part, once per tile rather than once per sample.
        keys.clear();
        keys.extend((y0..y1).flat_map(|y| (x0..x1).map(move |x| Sampler::pixel_key(self.seed, (x + y * w) as u64))));
        for (k, s) in samples.enumerate() {
            for by in (y0..y1).step_by(block_h as usize) {
                for bx in (x0..x1).step_by(block_w as usize) {
                    let mut count = 0;
                    for y in by..(by + block_h).min(y1) {
                        for x in bx..(bx + block_w).min(x1) {
                            pixels_of[count] = (x, y, (y - y0) * tile_w + (x - x0));
                            count += 1;
                        }
                    }
                    for (lane, &(x, y, local)) in pixels_of[..count].iter().enumerate() {
                        let mut sampler = Sampler::of_pixel(keys[local as usize], s as u64);
                        film.set(lane, Vec2::new(x as f32, y as f32) + sampler.next_2d());
                        samplers[lane] = sampler;
                    }
                    let directions = self.camera.generate_directions(&film);
                    for (lane, sampler) in samplers[..count].iter().enumerate() {
                        if let Some(path) = self.integrator.start(Ray::new(origin, directions.get(lane)), sampler.clone()) {
                            paths.push(path);
                            owners.push(k as u32 * n as u32 + pixels_of[lane].2);
                        }
                    }
                }
            }
        }
        active.extend(0..paths.len() as u32);
        let mut depth = 0;
        while !active.is_empty() {
            counters.rays += active.len() as u64;
            if depth > 0 {
                // Camera rays come in pixel blocks already; later rays are grouped.
                octant_order(active.iter().map(|&i| paths[i as usize].ray.direction), order);
                std::mem::swap(active, &mut step.next);
                active.clear();
                active.extend(order.iter().map(|&k| step.next[k as usize]));
            }
            rays.clear();
            rays.extend(active.iter().map(|&i| paths[i as usize].ray));
            scene.intersect_all(rays, hits, depth);
            self.integrator.step_batch(scene, paths, active, hits, buffers, step);
            counters.shadow_rays += step.shadows.len() as u64;
            scene.occluded_all(&step.shadow_rays, blocked, depth);
            for (&(i, contribution), &blocked) in step.shadows.iter().zip(blocked.iter()) {
                if !blocked {
                    paths[i as usize].l += contribution;
                }
            }
            std::mem::swap(active, &mut step.next);
            depth += 1;
        }
        radiance.clear();
        radiance.resize(batch, Rgb::ZERO);
        for (path, &j) in paths.iter().zip(owners.iter()) {
            radiance[j as usize] = path.l;
        }
        // Samples of a pixel are accumulated in sample order, as one path at a time would.
        let mut pixels = vec![PixelAccumulator::default(); n];
        for sample in radiance.chunks(n) {
            for (acc, &l) in pixels.iter_mut().zip(sample) {
                counters.samples += 1;
                if l.is_finite() && l.min_element() >= 0.0 {
                    acc.add(l);
                } else {
                    counters.discarded += 1;
                }
            }
        }
        (pixels, counters)
    }

    /// Renders the whole `width` × `height` image until `budget` is spent or `cancel` is
    /// set, calling `progress` with sample counts as tiles finish and `after_pass` with the
    /// film and elapsed time after each pass. Returns the film and the statistics.
    pub fn render(
        &self,
        width: u32,
        height: u32,
        budget: Budget,
        cancel: &AtomicBool,
        progress: &(dyn Fn(u64) + Sync),
        after_pass: &mut dyn FnMut(&Film, Duration),
    ) -> (Film, RenderStats) {
        let monitor = Monitor { cancel, progress, after_pass };
        self.render_region(width, height, Region::whole(width, height), budget, monitor)
    }

    /// [`Renderer::render`] of `region` of the image only: with a sample budget, its pixels
    /// equal the whole render's bit for bit (a time budget gives each region its own sample
    /// count). `region` must lie inside the image.
    pub fn render_region(&self, width: u32, height: u32, region: Region, budget: Budget, monitor: Monitor<'_>) -> (Film, RenderStats) {
        self.continue_region(RenderState::new(width, height, region), budget, monitor, &mut |_, _| {})
    }

    /// [`Renderer::render_region`] from `state` (a render at a pass boundary, e.g. read
    /// from a checkpoint, or [`RenderState::new`]): with a sample budget, the film returned
    /// equals the uninterrupted render's bit for bit. A time budget counts from this call.
    ///
    /// `at_boundary(state, interrupted)` is called at the pass boundaries: after every pass
    /// but the last (with `interrupted` false), and once when `cancel` stops the render
    /// (`interrupted` true) with the state after the last whole pass — before the tiles of a
    /// pass cut short are added to the film that is returned. A render whose budget is
    /// spent gives no call for its last pass.
    pub fn continue_region(
        &self,
        state: RenderState,
        budget: Budget,
        monitor: Monitor<'_>,
        at_boundary: &mut dyn FnMut(&RenderState, bool),
    ) -> (Film, RenderStats) {
        let Monitor { cancel, progress, after_pass } = monitor;
        let (width, height, region) = (state.film.full_width, state.film.full_height, state.film.region);
        assert!(region.is_within(width, height), "region {region} outside the {width}x{height} image");
        let start = Instant::now();
        let mut state = state;
        let resumed_spp = state.samples_done;
        // Counts of this call's passes alone (the rates in the statistics).
        let mut session = PassCounters::default();
        loop {
            let done = state.samples_done;
            let count = match budget {
                Budget::Spp(spp) => spp_pass_size(spp, done),
                // One sample per pass at first, then passes growing by a quarter of the
                // samples done, up to MAX_PASS_SAMPLES as `spp_pass_size` explains, as long as one fits in the
                // time left: an error log gets at least four rows per doubling of the samples
                // (even on a log-scale time axis), and long renders run the larger batches
                // that `Budget::Spp` runs.
                Budget::Time(t) => {
                    let here = done - resumed_spp;
                    let per_sample = start.elapsed().as_secs_f64() / here.max(1) as f64;
                    let left = t.as_secs_f64() - start.elapsed().as_secs_f64();
                    let fits = if here == 0 { 1 } else { (left / per_sample.max(1e-9)) as u32 };
                    (done / 4).clamp(1, MAX_PASS_SAMPLES).min(fits.max(1))
                }
            };
            if count == 0 {
                break;
            }
            let pass = self.trace_pass(&state.film, done, count, cancel, progress);
            let complete = pass.is_complete();
            if !complete {
                at_boundary(&state, true);
            }
            let c = pass.merge_into(&mut state.film);
            session.add(&c);
            state.counters.add(&c);
            if complete {
                state.samples_done += count;
            }
            after_pass(&state.film, start.elapsed());
            if !complete {
                break;
            }
            let finished = match budget {
                Budget::Spp(spp) => state.samples_done >= spp,
                Budget::Time(t) => start.elapsed() >= t,
            };
            let cancelled = cancel.load(Ordering::Relaxed);
            if cancelled || !finished {
                at_boundary(&state, cancelled);
            }
            if finished || cancelled {
                break;
            }
        }
        let totals = state.counters;
        let film = state.film;
        let wall = start.elapsed().as_secs_f64();
        let pixels = region.pixel_count() as u64;
        let rays = totals.rays + totals.shadow_rays;
        let stats = RenderStats {
            width,
            height,
            region,
            spp: totals.samples as f64 / pixels as f64,
            samples: totals.samples,
            wall_seconds: wall,
            samples_per_second: session.samples as f64 / wall.max(1e-9),
            rays,
            rays_per_second: (session.rays + session.shadow_rays) as f64 / wall.max(1e-9),
            resumed_spp,
            discarded_samples: totals.discarded,
            threads: rayon::current_num_threads(),
            max_depth: self.integrator.max_depth,
            seed: self.seed,
            interrupted: cancel.load(Ordering::Relaxed),
            closest_traversal: self.scene.trace_modes().map(|(closest, _)| traversal_name(closest)),
            occlusion_traversal: self.scene.trace_modes().map(|(_, occlusion)| traversal_name(occlusion)),
        };
        (film, stats)
    }
}

/// How `--stats` names a trace mode ([`RenderScene::trace_modes`]).
fn traversal_name(mode: Option<bool>) -> &'static str {
    match mode {
        Some(true) => "packets",
        Some(false) => "single rays",
        None => "no rays",
    }
}

/// The tiles of a region of an image: the squares of [`TILE_SIZE`] pixels of one grid over
/// the whole image that the region touches, cut to the region, numbered row-major.
#[derive(Clone, Copy, Debug)]
struct Tiles {
    region: Region,
    /// Width of the whole image (a pixel's index in it seeds its random streams).
    full_width: u32,
    first_column: u32,
    first_row: u32,
    columns: u32,
    rows: u32,
}

impl Tiles {
    fn new(full_width: u32, region: Region) -> Self {
        let (first_column, first_row) = (region.x0 / TILE_SIZE, region.y0 / TILE_SIZE);
        Tiles {
            region,
            full_width,
            first_column,
            first_row,
            columns: region.x1.div_ceil(TILE_SIZE) - first_column,
            rows: region.y1.div_ceil(TILE_SIZE) - first_row,
        }
    }

    fn count(&self) -> u32 {
        self.columns * self.rows
    }

    /// Pixel bounds (x0, y0, x1, y1) of tile `tile` in the whole image, ends exclusive.
    fn bounds(&self, tile: u32) -> (u32, u32, u32, u32) {
        let (tx, ty) = (self.first_column + tile % self.columns, self.first_row + tile / self.columns);
        let (x0, y0) = (tx * TILE_SIZE, ty * TILE_SIZE);
        let r = &self.region;
        (x0.max(r.x0), y0.max(r.y0), (x0 + TILE_SIZE).min(r.x1), (y0 + TILE_SIZE).min(r.y1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::{PathCounters, Strategy};

    /// The batched tile loop must give exactly the per-path estimator's image: same random
    /// streams, same arithmetic, same accumulation order.
    #[test]
    fn batched_tiles_equal_paths_traced_one_by_one() {
        // The material-preview's sphere: metallic-roughness without a latent file, the decoded
        // neural material with the shipped one, or its slot given a MERL table or an NBRDF
        // network (all three scattered with their values evaluated together).
        #[derive(Clone, Copy, Debug, PartialEq)]
        enum Sphere {
            Gltf,
            Neural,
            Merl,
            Nbrdf,
            /// Rough glass (in lanes, transmitted paths with their volume).
            Glass,
            /// Smooth glass (delta lobes).
            SmoothGlass,
            /// Rough thin-walled glass (no volume).
            ThinGlass,
            /// Rough glass mixed with an opaque part (one by one).
            HalfGlass,
            /// Metallic-roughness under a sheen and a clear coat (one by one).
            Layered,
            /// The decoded neural material under a sheen and a clear coat (in its batch).
            LayeredNeural,
            /// A MERL table under a clear coat (in its batch).
            CoatedMerl,
        }
        let cases = [
            ("cornell-box", 8, Strategy::Mis, Sphere::Gltf, false),
            ("cornell-box", 1, Strategy::Mis, Sphere::Gltf, false),
            ("cornell-box", 6, Strategy::LightOnly, Sphere::Gltf, false),
            ("cornell-box", 6, Strategy::BsdfOnly, Sphere::Gltf, false),
            ("material-preview", 6, Strategy::Mis, Sphere::Gltf, false),
            ("material-preview", 4, Strategy::LightOnly, Sphere::Gltf, false),
            ("material-preview", 5, Strategy::BsdfOnly, Sphere::Gltf, false),
            ("material-preview", 6, Strategy::Mis, Sphere::Neural, false),
            ("material-preview", 5, Strategy::LightOnly, Sphere::Neural, false),
            ("material-preview", 5, Strategy::BsdfOnly, Sphere::Neural, false),
            ("material-preview", 6, Strategy::Mis, Sphere::Merl, false),
            ("material-preview", 5, Strategy::BsdfOnly, Sphere::Merl, false),
            ("material-preview", 6, Strategy::Mis, Sphere::Nbrdf, false),
            ("material-preview", 5, Strategy::LightOnly, Sphere::Nbrdf, false),
            // The preview's environment map replaced by a constant one (the lane kernels and the
            // deferred vertices draw either kind's samples in lanes).
            ("material-preview", 6, Strategy::Mis, Sphere::Gltf, true),
            ("material-preview", 5, Strategy::LightOnly, Sphere::Gltf, true),
            ("material-preview", 8, Strategy::Mis, Sphere::Glass, false),
            ("material-preview", 8, Strategy::LightOnly, Sphere::SmoothGlass, false),
            ("material-preview", 8, Strategy::BsdfOnly, Sphere::SmoothGlass, false),
            ("material-preview", 8, Strategy::Mis, Sphere::ThinGlass, false),
            ("material-preview", 8, Strategy::Mis, Sphere::HalfGlass, true),
            ("material-preview", 6, Strategy::Mis, Sphere::Layered, false),
            ("material-preview", 6, Strategy::Mis, Sphere::LayeredNeural, false),
            ("material-preview", 5, Strategy::LightOnly, Sphere::LayeredNeural, false),
            ("material-preview", 5, Strategy::BsdfOnly, Sphere::LayeredNeural, true),
            ("material-preview", 6, Strategy::Mis, Sphere::CoatedMerl, false),
        ];
        for (name, max_depth, strategy, sphere, constant_environment) in cases {
            let mut description = crate::testing::data::shipped_scene(name);
            if constant_environment {
                let spec = description.environment.as_mut().expect("the scene has an environment");
                spec.source = crate::scene::EnvironmentSource::Constant(Rgb::new(0.9, 1.0, 1.2));
            }
            let camera = description.camera(None).expect("camera").clone();
            if matches!(sphere, Sphere::Glass | Sphere::SmoothGlass | Sphere::ThinGlass | Sphere::HalfGlass | Sphere::Layered | Sphere::LayeredNeural | Sphere::CoatedMerl) {
                let m = description.materials.iter_mut().find(|m| m.name == "preview").expect("the preview material");
                if matches!(sphere, Sphere::Layered | Sphere::LayeredNeural | Sphere::CoatedMerl) {
                    m.clearcoat = Some(crate::scene::Clearcoat { factor: 0.8, texture: None, roughness: 0.1, roughness_texture: None, normal_texture: None });
                    if sphere != Sphere::CoatedMerl {
                        m.sheen = Some(crate::scene::SheenLayer { color: Rgb::new(0.6, 0.5, 0.7), color_texture: None, roughness: 0.4, roughness_texture: None });
                    }
                } else {
                    m.transmission = if sphere == Sphere::HalfGlass { 0.5 } else { 1.0 };
                    m.metallic = 0.0;
                    m.roughness = if sphere == Sphere::SmoothGlass { 0.0 } else { 0.3 };
                    m.volume = if sphere == Sphere::ThinGlass { None } else { crate::scene::Volume::from_attenuation(Rgb::new(0.9, 0.7, 0.5), 2.0) };
                }
            }
            let latents = match sphere {
                Sphere::Gltf | Sphere::Glass | Sphere::SmoothGlass | Sphere::ThinGlass | Sphere::HalfGlass | Sphere::Layered => &crate::neural::latent_library::LatentLibrary::default(),
                _ => crate::testing::data::shipped_latents(),
            };
            let mut scene = RenderScene::with_latents(description, latents).expect("scene");
            let slots = scene.materials.neural_slots();
            assert_eq!(slots.len(), matches!(sphere, Sphere::Neural | Sphere::Merl | Sphere::Nbrdf | Sphere::LayeredNeural | Sphere::CoatedMerl) as usize, "{name}: the sphere's neural binding");
            if matches!(sphere, Sphere::Merl | Sphere::CoatedMerl) {
                let table = crate::testing::bsdfs::merl_fitted_table("alum-bronze");
                let merl = crate::bsdf::merl::MerlBsdf::new(&table, Default::default(), &Default::default());
                scene.materials.set_shared(slots[0], crate::material::SharedBsdf::Merl(merl));
            }
            if sphere == Sphere::Nbrdf {
                let nbrdf = crate::testing::bsdfs::nbrdf_bsdf("alum-bronze");
                scene.materials.set_shared(slots[0], crate::material::SharedBsdf::Nbrdf(nbrdf));
            }
            // 20 × 18: partial tiles at the right and bottom edges.
            let (w, h, spp) = (20, 18, 3);
            let renderer = Renderer {
                scene: &scene,
                camera: PinholeCamera::new(&camera, w, h),
                integrator: PathTracer {
                    max_depth,
                    strategy,
                    ..PathTracer::default()
                },
                seed: 11,
            };
            let never = AtomicBool::new(false);
            let (film, stats) = renderer.render(w, h, Budget::Spp(spp), &never, &|_| {}, &mut |_, _| {});
            let mut counters = PathCounters::default();
            let mut expected = Vec::new();
            for y in 0..h {
                for x in 0..w {
                    let mut acc = PixelAccumulator::default();
                    for s in 0..spp {
                        let mut sampler = Sampler::new(11, (x + y * w) as u64, s as u64);
                        let ray = renderer.camera.generate_ray(Vec2::new(x as f32, y as f32) + sampler.next_2d());
                        acc.add(renderer.integrator.radiance(&scene, ray, &mut sampler, &mut counters));
                    }
                    let k = 1.0 / acc.count as f64;
                    expected.push(Rgb::new((acc.sum[0] * k) as f32, (acc.sum[1] * k) as f32, (acc.sum[2] * k) as f32));
                }
            }
            assert_eq!(film.mean(), expected, "{name}, depth {max_depth}, {strategy:?}, {sphere:?}, constant {constant_environment}");
            assert_eq!(stats.rays, counters.rays + counters.shadow_rays, "{name}");
            assert!(expected.iter().any(|l| l.max_element() > 0.0), "{name}: the image is not black");
        }
    }

    /// A shipped scene ready to render, with its default camera.
    fn shipped_scene(name: &str) -> (RenderScene, crate::scene::Camera) {
        let description = crate::testing::data::shipped_scene(name);
        let camera = description.camera(None).expect("camera").clone();
        (RenderScene::new(description).expect("scene"), camera)
    }

    /// Cancelled from its progress callback after the first tile, a render stops within the
    /// tiles its threads had already taken: at most one per thread, each with all the pass's
    /// samples, and reports itself interrupted.
    #[test]
    fn cancelling_stops_after_the_tiles_in_flight() {
        let (scene, camera) = shipped_scene("cornell-box");
        let (w, h) = (64, 64);
        let renderer = Renderer {
            scene: &scene,
            camera: PinholeCamera::new(&camera, w, h),
            integrator: PathTracer::default(),
            seed: 3,
        };
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
            let cancel = AtomicBool::new(false);
            let (film, stats) = pool.install(|| renderer.render(w, h, Budget::Spp(4), &cancel, &|_| cancel.store(true, Ordering::Relaxed), &mut |_, _| {}));
            let tile_samples = (TILE_SIZE * TILE_SIZE) as u64;
            assert!(stats.interrupted, "{threads} threads");
            assert_eq!(stats.samples % tile_samples, 0, "{threads} threads: whole tiles");
            assert!((1..=threads as u64).contains(&(stats.samples / tile_samples)), "{threads} threads: {} samples", stats.samples);
            assert_eq!(film.total_samples(), stats.samples);
        }
    }

    /// A render continued from any of its pass boundaries (as a checkpoint holds them) ends
    /// with the uninterrupted render's film bit for bit, for the whole image and a region;
    /// cancelled, it reports the state of the passes done before the pass cut short.
    #[test]
    fn continuing_from_a_pass_boundary_gives_the_same_film() {
        let (scene, camera) = shipped_scene("cornell-box");
        let (w, h) = (37, 21);
        let renderer = Renderer {
            scene: &scene,
            camera: PinholeCamera::new(&camera, w, h),
            integrator: PathTracer::default(),
            seed: 9,
        };
        let never = AtomicBool::new(false);
        for (region, spp) in [(Region::whole(w, h), 20), ("5,3,30,19".parse().unwrap(), 9)] {
            let mut boundaries = Vec::new();
            let monitor = Monitor { cancel: &never, progress: &|_| {}, after_pass: &mut |_, _| {} };
            let (whole, stats) = renderer.continue_region(RenderState::new(w, h, region), Budget::Spp(spp), monitor, &mut |state, interrupted| {
                assert!(!interrupted);
                boundaries.push(state.clone());
            });
            assert_eq!(boundaries.len() as u32, spp.div_ceil(spp.div_ceil(8)) - 1, "a boundary after every pass but the last");
            for state in boundaries {
                let done = state.samples_done;
                let monitor = Monitor { cancel: &never, progress: &|_| {}, after_pass: &mut |_, _| {} };
                let (film, resumed) = renderer.continue_region(state, Budget::Spp(spp), monitor, &mut |_, _| {});
                assert_eq!(film.accumulators(), whole.accumulators(), "continued from {done} spp of {spp}, region {region}");
                assert_eq!((resumed.samples, resumed.rays, resumed.resumed_spp), (stats.samples, stats.rays, done));
            }
        }
        // Cancelled during the second pass: the boundary reported is the first pass's.
        let cancel = AtomicBool::new(false);
        let tiles = AtomicU32::new(0);
        let tile_count = Tiles::new(w, Region::whole(w, h)).count();
        let progress = |_| {
            if tiles.fetch_add(1, Ordering::Relaxed) + 1 == tile_count + 1 {
                cancel.store(true, Ordering::Relaxed);
            }
        };
        let mut reported = Vec::new();
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("pool");
        let (film, stats) = pool.install(|| {
            let monitor = Monitor { cancel: &cancel, progress: &progress, after_pass: &mut |_, _| {} };
            renderer.continue_region(RenderState::new(w, h, Region::whole(w, h)), Budget::Spp(16), monitor, &mut |state, interrupted| {
                reported.push((state.samples_done, state.film.total_samples(), interrupted))
            })
        });
        assert!(stats.interrupted);
        let pixels = (w * h) as u64;
        assert_eq!(reported, vec![(2, 2 * pixels, false), (2, 2 * pixels, true)]);
        assert!(film.total_samples() > 2 * pixels && film.total_samples() < 4 * pixels, "the returned film has the tile of the cut pass");
    }

    /// A region rendered alone holds exactly the whole render's pixels: regions cut across
    /// tiles, single pixels and rows, and the bands `render --tile` makes.
    #[test]
    fn regions_equal_the_whole_render() {
        let (scene, camera) = shipped_scene("material-preview");
        let (w, h, spp) = (37, 35, 3);
        let renderer = Renderer {
            scene: &scene,
            camera: PinholeCamera::new(&camera, w, h),
            integrator: PathTracer::default(),
            seed: 5,
        };
        let never = AtomicBool::new(false);
        let (whole, _) = renderer.render(w, h, Budget::Spp(spp), &never, &|_| {}, &mut |_, _| {});
        let whole = whole.mean();
        let mut regions: Vec<Region> = ["3,5,29,33", "17,17,18,18", "0,34,37,35", "36,0,37,35"].iter().map(|r| r.parse().unwrap()).collect();
        regions.extend((1..=3).map(|k| Region::band(w, h, k, 3).unwrap()));
        for region in regions {
            let monitor = Monitor { cancel: &never, progress: &|_| {}, after_pass: &mut |_, _| {} };
            let (film, stats) = renderer.render_region(w, h, region, Budget::Spp(spp), monitor);
            let part = film.mean();
            assert_eq!(part.len(), region.pixel_count());
            assert_eq!((stats.width, stats.height, stats.region, stats.spp), (w, h, region, spp as f64));
            for y in region.y0..region.y1 {
                for x in region.x0..region.x1 {
                    let i = (x - region.x0 + (y - region.y0) * region.width()) as usize;
                    assert_eq!(part[i], whole[(x + y * w) as usize], "pixel ({x}, {y}) of region {region}");
                }
            }
        }
    }
}
