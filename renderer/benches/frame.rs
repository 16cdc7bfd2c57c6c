//! A full Cornell-box frame (128², 4 spp, max depth 8) through the library, as `render` does.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use renderer::camera::PinholeCamera;
use renderer::integrator::PathTracer;
use renderer::render::{Budget, Renderer};
use renderer::render_scene::RenderScene;
use renderer::scene::SceneDescription;
use std::path::Path;
use std::sync::atomic::AtomicBool;

fn bench(c: &mut Criterion) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell-box/scene.gltf");
    let description = SceneDescription::load(&path).expect("shipped scene");
    let camera = description.camera(None).expect("camera").clone();
    let scene = RenderScene::new(description).expect("scene");
    let (w, h, spp) = (128u32, 128u32, 4u32);
    let renderer = Renderer {
        scene: &scene,
        camera: PinholeCamera::new(&camera, w, h),
        integrator: PathTracer {
            max_depth: 8,
            ..PathTracer::default()
        },
        seed: 0,
    };
    let cancel = AtomicBool::new(false);
    let mut group = c.benchmark_group("frame");
    group.sample_size(10);
    group.throughput(Throughput::Elements((w * h * spp) as u64));
    group.bench_function("cornell-box 128x128 4spp depth 8 (samples/s)", |b| {
        b.iter(|| renderer.render(w, h, Budget::Spp(spp), &cancel, &|_| {}, &mut |_, _| {}))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
