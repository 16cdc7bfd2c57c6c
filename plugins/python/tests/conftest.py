"""Shared fixtures. The suite is run by `cargo test` (tests/python_plugin.rs at the repository
root), which passes the data through the environment:

- NEURAL_BRDF_LATENT: a latent file (default: the shipped scenes/materials/latent.bin);
- NEURAL_BRDF_TABLE: a MERL table (.binary) made from the shared measured data;
- NEURAL_BRDF_NETWORK: an NBRDF network prefix from ../shared/data/nbrdf.
"""

import os
import pathlib

import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[3]


def _path(variable, default=None):
    value = os.environ.get(variable) or default
    if value is None or not pathlib.Path(value).exists() and not pathlib.Path(str(value) + "_b1.npy").exists():
        pytest.fail(f"{variable} is not set or does not exist ({value}); run the suite with `cargo test -p neural-brdf-python --test python`")
    return str(value)


@pytest.fixture(scope="session")
def latent_path():
    return _path("NEURAL_BRDF_LATENT", REPO / "scenes/materials/latent.bin")


@pytest.fixture(scope="session")
def table_path():
    return _path("NEURAL_BRDF_TABLE")


@pytest.fixture(scope="session")
def network_path():
    return _path("NEURAL_BRDF_NETWORK", REPO.parent / "shared/data/nbrdf/merl/chrome")


def hemisphere(rng, n):
    """n random unit directions with z > 0 (float32)."""
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    v[:, 2] = np.abs(v[:, 2]) + 1e-3
    v /= np.linalg.norm(v, axis=1)[:, None]
    return v.astype(np.float32)


def direction_pairs(rng, n):
    """(wo, wi): random pairs, a quarter of them within ~1° of the mirror configuration."""
    wo, wi = hemisphere(rng, n), hemisphere(rng, n)
    k = n // 4
    mirror = wo[:k] * np.array([-1.0, -1.0, 1.0]) + 0.01 * rng.normal(size=(k, 3))
    mirror[:, 2] = np.abs(mirror[:, 2])
    wi[:k] = mirror / np.linalg.norm(mirror, axis=1)[:, None]
    return wo, wi.astype(np.float32)
