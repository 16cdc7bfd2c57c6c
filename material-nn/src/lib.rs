//! Learns neural materials from measured BRDFs; see the crate README.

pub mod checkpoint;
pub mod config;
pub mod dataset;
pub mod error;
pub mod eval;
pub mod export;
pub mod inference;
pub mod loss;
pub mod model;
pub mod nbrdf_fit;
pub mod search;
pub mod sh;
pub mod splat;
pub mod tabulate;
pub mod training;

pub use error::{Error, Result};
