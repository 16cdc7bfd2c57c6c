//! A `.gltf` (JSON) or `.glb` file through `renderer::scene::gltf::load_from_bytes_with`,
//! named `/fuzz-scene/scene.gltf`; the files it refers to come from memory
//! (`renderer_fuzz::scene_file`: `scene.bin` is the Cornell box buffer, any `.png` a 2×2
//! RGBA image, any `.jpg` a 2×2 JPEG). A scene that loads is also prepared for rendering and
//! probed with camera rays (`renderer_fuzz::render_probe`). Seeds:
//! `cargo run --manifest-path fuzz/Cargo.toml --example make_seeds`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use renderer_fuzz::{check_file_error, fuzz_path, render_probe, scene_file};

fuzz_target!(|data: &[u8]| {
    let path = fuzz_path("scene.gltf");
    match renderer::scene::gltf::load_from_bytes_with(data, &path, |p| scene_file(p, &[])) {
        Ok(scene) => {
            scene.validate().expect("a loaded scene is valid");
            let _ = scene.camera_or_default(None, Some(1.5));
            render_probe(scene);
        }
        Err(error) => check_file_error(&error),
    }
});
