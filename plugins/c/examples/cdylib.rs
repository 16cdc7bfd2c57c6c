//! `libneural_brdf` as `cargo test` builds it: the test suite compiles examples but not the
//! library's cdylib, so this example re-exports the library as a cdylib of the same name
//! (`target/*/examples/libneural_brdf.so`), which the C example is linked against.

pub use neural_brdf::*;
