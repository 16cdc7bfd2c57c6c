//! File formats, each read and written in one place: MERL BRDF tables, NumPy `.npy` arrays
//! (NBRDF networks), `latent.bin` (trained neural materials) and images (EXR, PNG, HDR).

pub mod image_io;
pub mod latent_file;
pub mod merl;
pub mod npy;
