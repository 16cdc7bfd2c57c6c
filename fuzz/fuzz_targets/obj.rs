//! OBJ text (and the MTL text after a `\n#--mtl--\n` line, served for every `mtllib`)
//! through `renderer::scene::obj::load_from_bytes_with`, named `/fuzz-scene/scene.obj`;
//! any `.png` texture is a 2×2 image. Seeds: `cargo run --manifest-path fuzz/Cargo.toml
//! --example make_seeds`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use renderer_fuzz::{check_file_error, fuzz_path, scene_file, split_obj_input};

fuzz_target!(|data: &[u8]| {
    let (obj, mtl) = split_obj_input(data);
    let path = fuzz_path("scene.obj");
    match renderer::scene::obj::load_from_bytes_with(obj, &path, |p| scene_file(p, mtl)) {
        Ok(scene) => {
            scene.validate().expect("a loaded scene is valid");
            let _ = scene.camera_or_default(None, Some(1.5));
        }
        Err(error) => check_file_error(&error),
    }
});
