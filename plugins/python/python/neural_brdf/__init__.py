"""Neural (FreNBRDF) and measured (MERL, NBRDF) BRDFs of the neural-BRDF path tracer.

>>> import numpy as np, neural_brdf
>>> bronze = neural_brdf.Material.open("scenes/materials/latent.bin", "alum-bronze")
>>> wo = np.array([[0.0, 0.6, 0.8]]); wi = np.array([[0.0, -0.6, 0.8]])
>>> f = bronze.eval(wo, wi)            # (1, 3): f_r in 1/sr, without the cosine
>>> wi, f, pdf = bronze.sample(wo, np.random.default_rng(1).random((1, 2)))
>>> codes = neural_brdf.latent_codes("scenes/materials/latent.bin")
>>> z = 0.5 * (codes["alum-bronze"] + codes["chrome"])
>>> halfway = neural_brdf.Material.from_latent_vector("scenes/materials/latent.bin", z, "halfway")
>>> blend = neural_brdf.Material.blend("scenes/materials/latent.bin", "alum-bronze", "chrome", 0.5)
>>> worn = neural_brdf.Material.mix([bronze, blend], [0.7, 0.3])   # f = 0.7 f_bronze + 0.3 f_blend

Directions are ``(N, 3)`` arrays in the local shading frame (z = shading normal, ``wo``
toward the viewer, ``wi`` toward the light, both pointing away from the surface). Values
and densities are zero below either horizon. ``neural_brdf.mitsuba.register()`` adds the
materials to Mitsuba 3 as the BSDF plugin ``"neural_brdf"``.
"""

from ._native import (
    MAX_LOG_VALUE,
    MAX_MIX_PARTS,
    PALETTE_SIZE,
    InvalidFileError,
    Material,
    UnknownNameError,
    latent_codes,
)

__all__ = ["Material", "latent_codes", "InvalidFileError", "UnknownNameError", "MAX_LOG_VALUE", "PALETTE_SIZE",
           "MAX_MIX_PARTS"]
