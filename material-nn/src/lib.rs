//! Learns neural materials from measured BRDFs (FreNBRDF, with HyperBRDF and NBRDF as
//! baselines); docs/training.md describes the method, the commands and the measured results.

pub mod augment;
pub mod backend;
pub mod checkpoint;
pub mod config;
pub mod dataset;
pub mod error;
pub mod eval;
pub mod export;
pub mod inference;
pub mod interpolation;
pub mod loss;
pub mod model;
pub mod nbrdf_fit;
pub mod run;
pub mod search;
pub mod sh;
pub mod splat;
pub mod tables;
pub mod tabulate;
pub mod training;

pub use error::{Error, Result};
