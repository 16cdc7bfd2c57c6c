//! `latent.bin` bytes through `renderer::formats::latent_file::LatentFile::from_bytes`; the first
//! byte picks how the rest becomes a file (as it is, with its checksum fixed, or with the
//! 8.7 MB f_ref table filled in at a `FREF` marker: see `renderer_fuzz::latent_bytes`). A
//! file that loads must decode every latent code into a target net that runs (and, when
//! the renderer's evaluator accepts its shape, runs there too), and its encoder, if any,
//! must encode a sample into a code of latent_dim values.
#![no_main]

use libfuzzer_sys::fuzz_target;
use renderer::formats::latent_file::LatentFile;
use renderer::neural::target_net::TargetNet;
use renderer_fuzz::{check_file_error, fuzz_path, latent_bytes};

fuzz_target!(|data: &[u8]| {
    let bytes = latent_bytes(data);
    match LatentFile::from_bytes(&bytes, &fuzz_path("latent.bin")) {
        Ok(file) => {
            for latent in &file.latents {
                let mlp = file.decode(&latent.z, latent.offset, &latent.residual);
                let y = mlp.forward(&vec![0.1; file.target_widths[0]]);
                assert_eq!(y.len(), *file.target_widths.last().expect("widths"));
                if let Ok(net) = TargetNet::new(&mlp) {
                    let _ = net.forward([0.1; 6]);
                }
            }
            if let Some(encoder) = &file.encoder {
                assert_eq!(encoder.encode(&[[0.1; 9]]).len(), file.latent_dim);
            }
        }
        Err(error) => check_file_error(&error),
    }
});
