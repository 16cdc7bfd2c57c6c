//! Rays leaving a scene's surfaces (as continuation and shadow rays do), written for other
//! ray tracers, and our closest-hit throughput on them, one thread: the traversal half of
//! `assets-scripts/compare_embree_rays.py`.
//!
//!     cargo run --release -p renderer --example surface_rays -- SCENE OUT_DIR [RAYS]
//!
//! Writes OUT_DIR/triangles.f32 (corners, 9 little-endian f32 per triangle, world space) and
//! OUT_DIR/rays.f32 (origin and unit direction, 6 f32 per ray); prints one JSON line with
//! the rays per second of single-ray and packet traversal (best of five passes) and the
//! number of rays that hit.

use renderer::accel::Bvh;
use renderer::scene::SceneDescription;
use renderer::testing::rays::surface_rays;
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

fn write_f32s(path: &PathBuf, values: impl Iterator<Item = f32>) -> std::io::Result<()> {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path)?);
    for v in values {
        f.write_all(&v.to_le_bytes())?;
    }
    f.flush()
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(scene_path), Some(out)) = (args.first(), args.get(1)) else {
        eprintln!("usage: surface_rays SCENE OUT_DIR [RAYS]");
        return ExitCode::from(2);
    };
    let n: usize = match args.get(2).map(|s| s.parse()) {
        None => 1 << 16,
        Some(Ok(n)) if n > 0 => n,
        Some(_) => {
            eprintln!("error: RAYS must be a positive integer");
            return ExitCode::from(2);
        }
    };
    let scene = match SceneDescription::load(std::path::Path::new(scene_path)) {
        Ok(s) if s.geometry.triangle_count() > 0 => s,
        Ok(_) => {
            eprintln!("error: {scene_path}: no triangles");
            return ExitCode::from(2);
        }
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    let g = &scene.geometry;
    let rays = surface_rays(g, n);
    let out = PathBuf::from(out);
    let written = std::fs::create_dir_all(&out)
        .and_then(|_| write_f32s(&out.join("triangles.f32"), (0..g.triangle_count()).flat_map(|i| g.triangle_positions(i)).flat_map(|v| v.to_array())))
        .and_then(|_| write_f32s(&out.join("rays.f32"), rays.iter().flat_map(|r| r.origin.to_array().into_iter().chain(r.direction.to_array()))));
    if let Err(e) = written {
        eprintln!("error: {}: {e}", out.display());
        return ExitCode::from(2);
    }
    let bvh = Bvh::build((0..g.triangle_count()).map(|i| g.triangle_positions(i)));
    let mut hits = Vec::new();
    let mut rate = |packets: bool| {
        let best = (0..5)
            .map(|_| {
                let start = Instant::now();
                bvh.intersect_all_with(&rays, &mut hits, packets);
                start.elapsed().as_secs_f64()
            })
            .fold(f64::INFINITY, f64::min);
        n as f64 / best
    };
    let (single, packets) = (rate(false), rate(true));
    let hit_count = hits.iter().filter(|h| h.is_some()).count();
    println!("{{\"rays\": {n}, \"triangles\": {}, \"single_rays_per_s\": {single:.0}, \"packet_rays_per_s\": {packets:.0}, \"hits\": {hit_count}}}", g.triangle_count());
    ExitCode::SUCCESS
}
