//! The real data unit tests read: the shared NBRDF networks (`../shared/data/nbrdf`, always
//! next to the repository), the shipped scenes and the shipped latent file.

use crate::neural::latent_library::LatentLibrary;
use crate::neural::nbrdf::NbrdfNetwork;
use crate::scene::SceneDescription;
use std::path::PathBuf;
use std::sync::OnceLock;

/// The shared NBRDF data directory.
pub(crate) fn data_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/nbrdf")
}

/// The NBRDF network fitted to MERL material `name`.
pub(crate) fn merl_network(name: &str) -> NbrdfNetwork {
    NbrdfNetwork::load(data_dir().join("merl").join(name)).unwrap()
}

/// The shipped scene `scenes/NAME/scene.gltf`, loaded.
pub(crate) fn shipped_scene(name: &str) -> SceneDescription {
    let path = format!(concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/{}/scene.gltf"), name);
    SceneDescription::load(path.as_ref()).expect("shipped scene")
}

/// The shipped latent file, read once per test process.
pub(crate) fn shipped_latents() -> &'static LatentLibrary {
    static LIB: OnceLock<LatentLibrary> = OnceLock::new();
    LIB.get_or_init(|| {
        LatentLibrary::load(&[super::latent::shipped_latent_path()]).expect("scenes/materials/latent.bin")
    })
}
