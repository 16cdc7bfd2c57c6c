//! Learns neural materials from measured BRDFs; see the crate README.

pub mod tabulate;
