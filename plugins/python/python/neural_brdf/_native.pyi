"""Type stubs of the native module (see the docstrings of neural_brdf.Material)."""

import os
from typing import Dict, List, Optional, Sequence, Tuple, TypedDict

import numpy as np
import numpy.typing as npt

MAX_LOG_VALUE: float
PALETTE_SIZE: int
"""Entries of the renderer's blend palette (t = k / (PALETTE_SIZE - 1))."""
MAX_MIX_PARTS: int

class InvalidFileError(ValueError):
    """A file was read but is not a valid material file."""

class UnknownNameError(LookupError):
    """The latent file has no code of that name."""

def latent_codes(path: "str | os.PathLike[str]") -> Dict[str, npt.NDArray[np.float32]]:
    """The latent codes of a latent file by name: z followed by the code's 3 output offsets
    and its residual (zeros when it has none; every vector of a file has one length)."""

class SamplerTables(TypedDict):
    theta_o: npt.NDArray[np.float32]
    row_v: npt.NDArray[np.float32]
    columns: int
    cosine_fraction: float
    values: npt.NDArray[np.float32]

_Directions = npt.ArrayLike
_Rgb = npt.NDArray[np.float32]
_Pdf = npt.NDArray[np.float32]

class Material:
    @staticmethod
    def open(path: "str | os.PathLike[str]", name: Optional[str] = None) -> "Material":
        """Opens a latent file (with the code ``name``), a MERL table (``.binary``) or an
        NBRDF network (the prefix of its ``.npy`` files)."""
    @staticmethod
    def from_latent_vector(path: "str | os.PathLike[str]", z: npt.ArrayLike, label: str = "latent vector") -> "Material":
        """Decodes the latent vector ``z`` (z, optionally followed by the 3 output offsets, then
        optionally by the residual) with the decoder of the latent file ``path``."""
    @staticmethod
    def blend(path: "str | os.PathLike[str]", a: str, b: str, t: float) -> "Material":
        """The blend of the codes ``a`` and ``b`` of the latent file ``path`` at ``t`` in
        [0, 1]: the latent interpolation decoded exactly as ``render --sweep`` does
        (``ValueError`` for t outside [0, 1] or NaN, ``UnknownNameError`` for a code)."""
    @staticmethod
    def blend_palette(path: "str | os.PathLike[str]", a: str, b: str) -> List["Material"]:
        """The renderer's palette of the blend of ``a`` and ``b``: ``PALETTE_SIZE`` blends at
        t = k / (PALETTE_SIZE - 1)."""
    @staticmethod
    def mix(materials: Sequence["Material"], weights: npt.ArrayLike) -> "Material":
        """The mixture of 1 to 4 materials with ``weights`` (normalised; zero weights drop
        parts), as the renderer's ``mix`` material at a texel of these weights
        (``ValueError`` for bad counts or weights)."""
    @property
    def weights(self) -> Optional[List[float]]:
        """A mixture's weights as given; ``None`` for a single material."""
    @property
    def name(self) -> str: ...
    @property
    def kind(self) -> str:
        """``"neural"``, ``"merl"``, ``"nbrdf"`` or ``"mixture"``."""
    def eval(self, wo: _Directions, wi: _Directions) -> _Rgb:
        """f_r(wo, wi) in 1/sr, shape (N, 3), without the cosine."""
    def pdf(self, wo: _Directions, wi: _Directions) -> _Pdf:
        """Solid-angle density (1/sr) of ``sample``, shape (N,)."""
    def eval_pdf(self, wo: _Directions, wi: _Directions) -> Tuple[_Rgb, _Pdf]: ...
    def sample(self, wo: _Directions, u: npt.ArrayLike) -> Tuple[_Rgb, _Rgb, _Pdf]:
        """``(wi, f, pdf)`` drawn from uniform numbers ``u`` of shape (N, 2) or (N, 3);
        a failed draw has pdf 0."""
    @property
    def layers(self) -> Optional[List[Tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]]]:
        """The decoded target net, ``(W, b)`` per layer, ``y = x @ W + b``; ``None``
        unless a latent code."""
    @property
    def f_ref(self) -> Optional[npt.NDArray[np.float32]]:
        """f_ref per MERL bin, shape (90, 90, 180, 3); negative = unmeasured."""
    @property
    def table(self) -> Optional[npt.NDArray[np.float32]]:
        """A MERL table's f_r per bin, shape (90, 90, 180, 3)."""
    @property
    def mapping(self) -> Optional[Tuple[str, float]]:
        """``(form, epsilon)``, form ``"code"`` or ``"talk"``."""
    def sampler_tables(self) -> SamplerTables:
        """``ValueError`` for a mixture."""
