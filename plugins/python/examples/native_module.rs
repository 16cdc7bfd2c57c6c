//! The extension module `neural_brdf._native` as `cargo test` builds it: the test suite
//! compiles examples but not the library's cdylib, so this example re-exports the library
//! as a cdylib (`target/*/examples/libnative_module.so`, exporting `PyInit__native`), which
//! tests/python.rs installs beside the package's Python files for pytest.

pub use _native::*;
