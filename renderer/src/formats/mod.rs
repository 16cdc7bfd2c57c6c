//! File formats, each read and written in one place: MERL BRDF tables, NumPy `.npy` arrays
//! (NBRDF networks), `latent.bin` (trained neural materials), images (EXR, PNG, HDR) and
//! parts of images rendered separately (EXR with data and display windows) and render
//! checkpoints.

pub mod checkpoint;
pub mod image_io;
pub mod image_part;
pub mod latent_file;
pub mod merl;
pub mod npy;
