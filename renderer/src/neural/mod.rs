//! The neural-material runtime, with no ML framework: the log-relative mapping, the
//! reference f32 forward passes of a latent file's model (hypernetwork, encoder), the fast
//! target net, NBRDF networks, and the library of latent files a render binds codes from.

pub mod energy;
pub mod latent_library;
pub mod mapping;
pub mod mlp;
pub mod nbrdf;
pub mod reference;
pub mod target_net;
