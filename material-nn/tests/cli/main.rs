//! `material-nn` end to end (its commands as processes, its library entry points), in one test
//! binary: each file under tests/ would be a binary of its own, linked against burn and the
//! renderer, and cargo runs test binaries one after another.

mod common;
mod nbrdf_fit;
mod tabulate;
mod train;
#[cfg(feature = "wgpu")]
mod wgpu_backend;
