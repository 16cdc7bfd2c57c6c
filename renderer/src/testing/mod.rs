//! Testing support, for this crate's unit tests, benchmarks and examples and for other
//! crates' tests: statistical checks of any [`crate::bsdf::Bxdf`] ([`chi2`]), reproducible
//! ray sets for traversal benchmarks ([`rays`]), cheap latent files for the plugins' and fuzz
//! targets' tests ([`latent`]) and, in unit tests, the checks shared by the
//! BSDFs made from data (`bsdfs`) and the real data they read (`data`).
//!
//! Not part of the library as shipped: it is compiled for this crate's unit tests and with
//! the `testing` feature (which also brings `statrs`), which this crate's benchmarks and
//! examples enable through their dev-dependency on the crate itself, and another crate's
//! tests through theirs. What production code needs (the directional albedo) lives in
//! [`crate::bsdf::albedo`].

#[cfg(test)]
pub(crate) mod bsdfs;
pub mod chi2;
pub mod latent;
pub mod rays;
#[cfg(test)]
pub(crate) mod data;
