"""Property tests (hypothesis) of neural_brdf.Material's calls with arbitrary arrays: any shape
(0 to 3 dimensions, empty included), dtype (floats of every width, integers, booleans,
complex), memory layout (transposed, strided, negative strides) and values (NaN, ±inf,
subnormals, huge). Each call either returns arrays of the documented shapes, float32, finite and
≥ 0 (directions drawn: unit, or 0 with pdf 0 where the draw failed), equal to the same call on a
contiguous float32 copy; or raises ValueError or TypeError with a message. Never a crash, a
panic (pyo3's PanicException) or another exception; valid input is never refused.

Examples per test: a few dozen in CI (`cargo test -p neural-brdf-python --test python`, about a
second), more with NEURAL_BRDF_HYPOTHESIS_EXAMPLES=N (the offline runs in docs/fuzzing.md):

    NEURAL_BRDF_HYPOTHESIS_EXAMPLES=200000 PYTHONPATH=target/debug/python-plugin \\
        python3 -m pytest -q -p no:cacheprovider plugins/python/tests/test_properties.py
"""

import os
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import neural_brdf

_EXAMPLES = int(os.environ.get("NEURAL_BRDF_HYPOTHESIS_EXAMPLES", "0"))
settings.register_profile(
    "neural_brdf",
    max_examples=_EXAMPLES or 40,
    deadline=None,
    database=None,
    # CI runs the same examples every time; offline runs explore.
    derandomize=not _EXAMPLES,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much],
    print_blob=True,
)
settings.load_profile("neural_brdf")

# Calls that open a file (it is read, and a valid code decoded) get fewer examples.
_FILE_EXAMPLES = max(4, (_EXAMPLES or 40) // 1000)

REFUSED = (ValueError, TypeError)

DTYPES = [np.float16, np.float32, np.float64, np.longdouble, np.int8, np.int32, np.int64, np.uint8, np.uint64, np.bool_, np.complex64]

SPECIAL = [0.0, -0.0, 1.0, -1.0, 0.5, np.nan, np.inf, -np.inf, 1e-45, -1e-45, 1e-40, 1.1754944e-38, 3.4e38, -3.4e38, 1e300, 1e-300]


@pytest.fixture(scope="module")
def materials(latent_path, table_path, network_path):
    code = neural_brdf.Material.open(latent_path, "alum-bronze")
    table = neural_brdf.Material.open(table_path)
    network = neural_brdf.Material.open(network_path)
    mixture = neural_brdf.Material.mix([code, table, network], [0.5, 0.3, 0.2])
    return [code, table, network, mixture]


def _cast(x, dtype):
    with np.errstate(all="ignore"):
        return np.array(x).astype(dtype)[()]


def _values(dtype):
    """Elements for an array of `dtype`: anything it holds, special floats mixed in."""
    dtype = np.dtype(dtype)
    if dtype.kind == "f":
        width = min(dtype.itemsize * 8, 64)
        return st.one_of(st.floats(width=width, allow_nan=True, allow_infinity=True, allow_subnormal=True),
                         st.sampled_from(SPECIAL).map(lambda x: _cast(x, dtype)),
                         st.floats(-1.0, 1.0, width=width))
    if dtype.kind == "c":
        return st.complex_numbers(allow_nan=True, allow_infinity=True, width=64)
    return hnp.from_dtype(dtype)


@st.composite
def arrays(draw, rows=None, columns=None, unit_like=False):
    """An array of any dtype, shape and layout; with `rows` and `columns`, mostly of shape
    (rows, columns), sometimes of any other. `unit_like`: floats are unit vectors in half of
    the cases (the 3-column ones), so that evaluations reach the networks."""
    dtype = np.dtype(draw(st.sampled_from(DTYPES)))
    if rows is not None and draw(st.integers(0, 9)) < 8:
        shape = (rows, columns)
    else:
        shape = draw(hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=5))
    if unit_like and dtype.kind == "f" and len(shape) == 2 and shape[1] == 3 and draw(st.booleans()):
        v = draw(hnp.arrays(np.float64, shape, elements=st.floats(-1.0, 1.0)))
        norm = np.linalg.norm(v, axis=1, keepdims=True)
        v = np.where(norm > 1e-3, v / np.maximum(norm, 1e-3), [0.0, 0.0, 1.0])
        a = v.astype(dtype)
    elif draw(st.booleans()):
        # Raw bytes: every bit pattern (NaN payloads, infinities, subnormals), cheaply.
        size = int(np.prod(shape)) * dtype.itemsize
        raw = np.frombuffer(draw(st.binary(min_size=size, max_size=size)), dtype=np.uint8)
        a = (raw != 0).reshape(shape) if dtype.kind == "b" else raw.view(dtype).reshape(shape).copy()
    else:
        a = draw(hnp.arrays(dtype, shape, elements=_values(dtype)))
    layout = draw(st.sampled_from(["contiguous", "fortran", "strided", "reversed", "transposed"]))
    if layout == "fortran":
        a = np.asfortranarray(a)
    elif layout == "strided" and a.ndim >= 1:
        wide = np.zeros((a.shape[0] * 2,) + a.shape[1:], dtype=a.dtype)
        wide[::2] = a
        a = wide[::2]
    elif layout == "reversed" and a.ndim >= 1:
        a = np.ascontiguousarray(a[::-1])[::-1]
    elif layout == "transposed" and a.ndim == 2:
        a = np.ascontiguousarray(a.T).T
    return a


def _as_f32(a):
    """What the package reads: the array as numpy casts it to float32 (complex numbers lose
    their imaginary part, out-of-range values become ±inf), or None when numpy cannot."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with np.errstate(all="ignore"):
            try:
                return np.array(a, dtype=np.float32, order="C")
            except REFUSED:
                return None


def _valid_directions(a, rows=None):
    f = _as_f32(a)
    return f is not None and f.ndim == 2 and f.shape[1] == 3 and (rows is None or f.shape[0] == rows) and bool(np.isfinite(f).all())


def _check_values(array, shape):
    assert array.dtype == np.float32 and array.shape == shape, (array.dtype, array.shape, shape)
    assert np.all(np.isfinite(array)) and np.all(array >= 0), array


def _call(fn, *args):
    """fn(*args) with numpy's casting warnings silenced; None when refused."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            return fn(*args)
        except REFUSED as e:
            assert str(e), "an exception without a message"
            return None


@given(data=st.data(), which=st.integers(0, 3), call=st.sampled_from(["eval", "pdf", "eval_pdf"]), n=st.integers(0, 6))
def test_eval_and_pdf_take_any_array(materials, data, which, call, n):
    m = materials[which]
    wo = data.draw(arrays(n, 3, unit_like=True), label="wo")
    wi = data.draw(arrays(n, 3, unit_like=True), label="wi")
    result = _call(getattr(m, call), wo, wi)
    valid = _valid_directions(wo) and _valid_directions(wi, _as_f32(wo).shape[0])
    assert (result is not None) == valid, (wo, wi)
    if result is None:
        return
    rows = _as_f32(wo).shape[0]
    f, pdf = {"eval": (result, None), "pdf": (None, result), "eval_pdf": result}[call]
    if f is not None:
        _check_values(f, (rows, 3))
    if pdf is not None:
        _check_values(pdf, (rows,))
    # Any layout and dtype gives what a contiguous float32 copy gives.
    again = getattr(m, call)(_as_f32(wo), _as_f32(wi))
    for x, y in zip(result if call == "eval_pdf" else [result], again if call == "eval_pdf" else [again]):
        np.testing.assert_array_equal(x, y)


@given(data=st.data(), which=st.integers(0, 3), n=st.integers(0, 6), numbers=st.sampled_from([2, 3]))
def test_sample_takes_any_array(materials, data, which, n, numbers):
    m = materials[which]
    wo = data.draw(arrays(n, 3, unit_like=True), label="wo")
    if data.draw(st.booleans(), label="u in [0, 1]"):
        u = data.draw(hnp.arrays(data.draw(st.sampled_from([np.float32, np.float64, np.float16])), (n, numbers), elements=st.floats(0.0, 1.0, width=16)), label="u")
    else:
        u = data.draw(arrays(n, numbers), label="u")
    result = _call(m.sample, wo, u)
    u32 = _as_f32(u)
    # Two or three numbers per row, each in [0, 1].
    valid = (_valid_directions(wo) and u32 is not None and u32.ndim == 2 and u32.shape[1] in (2, 3)
             and u32.shape[0] == _as_f32(wo).shape[0] and bool(np.all((u32 >= 0) & (u32 <= 1))))
    assert (result is not None) == valid, (wo, u)
    if result is None:
        return
    wi, f, pdf = result
    rows = _as_f32(wo).shape[0]
    _check_values(f, (rows, 3))
    _check_values(pdf, (rows,))
    assert wi.dtype == np.float32 and wi.shape == (rows, 3) and np.all(np.isfinite(wi))
    drawn = pdf > 0
    np.testing.assert_allclose(np.linalg.norm(wi[drawn], axis=1), 1.0, atol=1e-4)
    assert not wi[~drawn].any() and not f[~drawn].any()
    again = m.sample(_as_f32(wo), u32)
    for x, y in zip(result, again):
        np.testing.assert_array_equal(x, y)


@given(data=st.data(), count=st.integers(0, 6))
def test_mix_takes_any_weights(materials, data, count):
    parts = [materials[data.draw(st.integers(0, 2))] for _ in range(count)]
    weights = data.draw(st.one_of(arrays(), hnp.arrays(np.float64, count, elements=_values(np.float64))), label="weights")
    mixed = _call(neural_brdf.Material.mix, parts, weights)
    w = _as_f32(weights)
    with np.errstate(all="ignore"):
        valid = (w is not None and w.ndim == 1 and w.size == count and 1 <= count <= 4 and bool(np.all(np.isfinite(w) & (w >= 0)))
                 and bool(np.isfinite(w.sum())) and w.sum() > 0)
    assert (mixed is not None) == valid, (count, weights)
    if mixed is not None:
        assert mixed.kind == "mixture" and len(mixed.weights) == count
        f = mixed.eval([[0.0, 0.6, 0.8]], [[0.0, -0.6, 0.8]])
        _check_values(f, (1, 3))


@settings(max_examples=_FILE_EXAMPLES)
@given(t=st.one_of(st.sampled_from([0.0, 1.0, np.nan, np.inf, -np.inf, -0.0, 1.0000001, -1e-45, 1e-45]), st.floats(allow_nan=True, allow_infinity=True, width=32)))
def test_blend_takes_any_t(latent_path, t):
    blend = _call(neural_brdf.Material.blend, latent_path, "alum-bronze", "chrome", t)
    # t is read as float32: 1.0000001 rounds to 1.
    assert (blend is not None) == bool(0.0 <= _cast(t, np.float32) <= 1.0), t
    if blend is not None:
        _check_values(blend.eval([[0.0, 0.6, 0.8]], [[0.0, -0.6, 0.8]]), (1, 3))


@settings(max_examples=_FILE_EXAMPLES)
@given(data=st.data(), length=st.one_of(st.sampled_from([0, 1, 39, 40, 41, 42, 43, 44, 11622, 11623, 11624]), st.integers(0, 20000)))
def test_latent_vectors_of_any_length(latent_path, data, length):
    dtype = data.draw(st.sampled_from([np.float32, np.float64, np.float16, np.int32]), label="dtype")
    head = data.draw(hnp.arrays(dtype, min(length, 64), elements=_values(dtype)), label="head")
    z = np.resize(head, length) if length else head[:0]
    if data.draw(st.booleans(), label="2-D"):
        z = z.reshape(1, -1)
    m = _call(neural_brdf.Material.from_latent_vector, latent_path, z)
    v = _as_f32(z)
    if v is None or v.ndim != 1 or length not in (40, 43, 11623) or not np.all(np.isfinite(v)):
        assert m is None, (length, z)
    if m is not None:
        _check_values(m.eval([[0.0, 0.6, 0.8]], [[0.0, -0.6, 0.8]]), (1, 3))
