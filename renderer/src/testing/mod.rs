//! Testing support, used by this crate's unit tests and by other crates' tests, benchmarks
//! and evaluations: statistical checks of any [`crate::bsdf::Bxdf`] ([`chi2`]), reproducible
//! ray sets for traversal benchmarks ([`rays`]) and, in unit tests, the checks shared by the
//! BSDFs made from data (`bsdfs`) and the real data they read (`data`).

#[cfg(test)]
pub(crate) mod bsdfs;
pub mod chi2;
pub mod rays;
#[cfg(test)]
pub(crate) mod data;
