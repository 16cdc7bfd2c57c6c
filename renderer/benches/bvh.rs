//! BVH build time and traversal throughput (closest hit and occlusion, Mrays/s) on the
//! shipped scenes, with incoherent rays from points inside the scene's bounds.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use obvhs::BvhBuildParams;
use renderer::accel::Bvh;
use renderer::scene::SceneDescription;
use renderer::testing::rays::{interior_rays, surface_rays};
use std::hint::black_box;
use std::path::Path;

fn load(name: &str) -> SceneDescription {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes").join(name).join("scene.gltf");
    SceneDescription::load(&path).expect("shipped scene")
}

fn bench(c: &mut Criterion) {
    for name in ["cornell-box", "material-preview"] {
        let scene = load(name);
        let g = &scene.geometry;
        let corners = || (0..g.triangle_count()).map(|i| g.triangle_positions(i));
        let mut group = c.benchmark_group(format!("bvh/{name} ({} triangles)", g.triangle_count()));
        group.bench_function("build", |b| b.iter(|| black_box(Bvh::build(corners()))));
        let rays = interior_rays(g, 4096);
        group.throughput(Throughput::Elements(rays.len() as u64));
        let from_surfaces = surface_rays(g, 4096);
        let presets = [
            ("fast", BvhBuildParams::fast_build()),
            ("medium", BvhBuildParams::medium_build()),
            ("slow", BvhBuildParams::slow_build()),
            ("very slow", BvhBuildParams::very_slow_build()),
        ];
        // Packets (16 rays with AVX-512, 8 with AVX2) against single rays, on the default
        // build.
        let bvh = Bvh::build(corners());
        let (mut hits, mut blocked) = (Vec::new(), Vec::new());
        let packets_label = match Bvh::packet_width() {
            Some(width) => format!("packets of {width}"),
            None => "packets (none on this CPU: single rays)".to_string(),
        };
        for (mode, packets) in [("single rays".to_string(), false), (packets_label, true)] {
            group.bench_function(format!("closest hit, {} nodes, {mode}", bvh.node_count()), |b| {
                b.iter(|| bvh.intersect_all_with(&rays, &mut hits, packets))
            });
            group.bench_function(format!("occlusion, {} nodes, {mode}", bvh.node_count()), |b| {
                b.iter(|| bvh.occluded_all_with(&rays, &mut blocked, packets))
            });
            group.bench_function(format!("closest hit from surfaces, {mode}"), |b| {
                b.iter(|| bvh.intersect_all_with(&from_surfaces, &mut hits, packets))
            });
        }
        for (preset, params) in presets {
            let bvh = Bvh::build_with(corners(), params);
            group.bench_function(format!("closest hit, {preset} build"), |b| {
                b.iter(|| rays.iter().filter(|r| bvh.intersect(r).is_some()).count())
            });
            group.bench_function(format!("occlusion, {preset} build"), |b| {
                b.iter(|| rays.iter().filter(|r| bvh.occluded(r)).count())
            });
        }
        group.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
