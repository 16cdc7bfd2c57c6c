//! The neural-material runtime, with no ML framework: the log-relative mapping, the
//! reference f32 forward passes of a latent file's model (hypernetwork, encoder), the fast
//! target net, NBRDF networks, the library of latent files a render binds codes from, and editing sweeps between codes.

pub mod energy;
pub mod latent_library;
pub mod mapping;
pub mod mlp;
pub mod nbrdf;
pub mod reference;
pub mod sweep;
pub mod target_net;
