//! Renders of whole scenes, in one test binary (README.md in tests/ says what each module
//! checks): each file under tests/ would be a binary of its own, linked against the whole
//! renderer, and cargo runs test binaries one after another, so one slow test left a core
//! idle. Run one module with `cargo test --test renders -- MODULE::`.

mod analytic;
mod cornell_box;
mod estimators;
mod feature_scene;
mod glass;
mod glass_and_coats;
mod layers;
mod neural_material;
mod neural_texture;
mod stiff_cases;
