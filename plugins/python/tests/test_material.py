"""neural_brdf.Material: opening, evaluation, sampling, exported data and errors."""

import shutil

import numpy as np
import pytest

import neural_brdf
from conftest import direction_pairs, hemisphere


@pytest.fixture(scope="module")
def bronze(latent_path):
    return neural_brdf.Material.open(latent_path, "alum-bronze")


def test_opens_each_kind(latent_path, table_path, network_path):
    assert neural_brdf.Material.open(latent_path, "chrome").kind == "neural"
    table = neural_brdf.Material.open(table_path)
    assert table.kind == "merl" and table.table.shape == (90, 90, 180, 3)
    assert table.layers is None and table.f_ref is None and table.mapping is None
    assert neural_brdf.Material.open(network_path).kind == "nbrdf"


def test_batches_agree_with_single_rows_and_accept_any_float(bronze):
    rng = np.random.default_rng(1)
    wo, wi = direction_pairs(rng, 500)
    f, pdf = bronze.eval(wo, wi), bronze.pdf(wo, wi)
    assert f.shape == (500, 3) and pdf.shape == (500,) and f.dtype == np.float32
    assert np.all(f >= 0) and np.all(pdf >= 0) and f.max() > 1.0
    f2, pdf2 = bronze.eval_pdf(wo.astype(np.float64), wi.astype(np.float64))
    np.testing.assert_array_equal(f, f2)
    np.testing.assert_array_equal(pdf, pdf2)
    for i in range(0, 500, 97):
        np.testing.assert_array_equal(bronze.eval(wo[i : i + 1], wi[i : i + 1])[0], f[i])
    below = wi * np.array([1, 1, -1], dtype=np.float32)
    assert not bronze.eval(wo, below).any() and not bronze.pdf(wo, below).any()


@pytest.mark.parametrize("numbers", [2, 3])
def test_samples_carry_their_value_and_density(bronze, numbers):
    rng = np.random.default_rng(2)
    wo = hemisphere(rng, 4000)
    wi, f, pdf = bronze.sample(wo, rng.random((4000, numbers)))
    drawn = pdf > 0
    assert drawn.mean() > 0.95
    assert np.allclose(np.linalg.norm(wi[drawn], axis=1), 1.0, atol=1e-5) and np.all(wi[drawn, 2] > 0)
    np.testing.assert_allclose(bronze.pdf(wo[drawn], wi[drawn]), pdf[drawn], rtol=1e-4)
    np.testing.assert_array_equal(bronze.eval(wo[drawn], wi[drawn]), f[drawn])
    assert not wi[~drawn].any() and not f[~drawn].any()


@pytest.mark.parametrize("numbers", [2, 3])
def test_directions_of_any_length_are_normalised(bronze, numbers):
    # The property tests' finding (wo = (0, 0, 2.9e-23), two numbers): tiny, subnormal, short
    # and huge vectors give what the unit vector gives, bit for bit.
    unit = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]], dtype=np.float32)
    u = np.array([[0.5, 0.5, 0.5], [0.25, 0.75, 0.9]], dtype=np.float32)[:, :numbers]
    wi = np.array([[0.0, 0.6, 0.8], [-0.3, 0.1, 0.9]], dtype=np.float32)
    expected = bronze.sample(unit, u)
    for scale in [2.895132e-23, 1e-40, 0.5, 3.0e30]:
        wo = (unit * np.float32(scale)).astype(np.float32)
        for got, want in zip(bronze.sample(wo, u), expected):
            np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(bronze.eval_pdf(wo, wi)[1], bronze.pdf(unit, wi))


def test_exports_the_decoded_net_reference_mapping_and_sampler_tables(bronze):
    layers = bronze.layers
    assert layers[0][0].shape[0] == 6 and layers[-1][0].shape[1] == 3
    for (w, b), (w_next, _) in zip(layers, layers[1:]):
        assert w.shape[1] == b.shape[0] == w_next.shape[0]
    assert bronze.f_ref.shape == (90, 90, 180, 3) and (bronze.f_ref >= 0).mean() > 0.5
    form, epsilon = bronze.mapping
    assert form in ("code", "talk") and epsilon > 0
    t = bronze.sampler_tables()
    assert t["values"].shape == (len(t["theta_o"]), len(t["row_v"]), t["columns"] + 1)
    assert t["values"].max() == 1.0 and t["values"].min() >= 0.0
    assert t["row_v"][0] == 0.0 and t["row_v"][-1] == pytest.approx(1.0) and 0 < t["cosine_fraction"] < 1


def test_latent_vectors_decode_like_their_codes(latent_path, bronze):
    codes = neural_brdf.latent_codes(latent_path)
    assert "alum-bronze" in codes and "chrome" in codes and codes["chrome"].dtype == np.float32
    # z, 3 offsets and the residual (zeros for a code without one): one length for the file.
    assert {len(v) for v in codes.values()} == {40 + 3 + 11_580}
    same = neural_brdf.Material.from_latent_vector(latent_path, codes["alum-bronze"].astype(np.float64), "copy")
    assert same.name == "copy"
    wo, wi = direction_pairs(np.random.default_rng(3), 200)
    np.testing.assert_array_equal(same.eval(wo, wi), bronze.eval(wo, wi))
    halfway = neural_brdf.Material.from_latent_vector(latent_path, 0.5 * (codes["alum-bronze"] + codes["chrome"]))
    assert not np.array_equal(halfway.eval(wo, wi), bronze.eval(wo, wi))


def test_errors_carry_the_cli_messages(latent_path, tmp_path, bronze):
    with pytest.raises(OSError, match="/nonexistent/latent.bin"):
        neural_brdf.Material.open("/nonexistent/latent.bin", "chrome")
    with pytest.raises(neural_brdf.UnknownNameError, match="latent code 'gold' not found .*alum-bronze"):
        neural_brdf.Material.open(latent_path, "gold")
    wrong = tmp_path / "wrong-version.bin"
    shutil.copy(latent_path, wrong)
    data = bytearray(wrong.read_bytes())
    data[8:12] = (99).to_bytes(4, "little")
    wrong.write_bytes(bytes(data))
    with pytest.raises(neural_brdf.InvalidFileError, match=str(wrong)):
        neural_brdf.Material.open(wrong, "chrome")
    with pytest.raises(ValueError, match="name one of its codes"):
        neural_brdf.Material.open(latent_path)
    with pytest.raises(ValueError, match=r"wo must have shape \(N, 3\)"):
        bronze.eval(np.zeros((4, 2)), np.zeros((4, 3)))
    with pytest.raises(ValueError, match="wo has 4 rows but wi has 3"):
        bronze.eval(np.ones((4, 3)), np.ones((3, 3)))
    with pytest.raises(ValueError, match="not finite"):
        bronze.pdf(np.array([[0.0, 0.0, np.nan]]), np.array([[0.0, 0.0, 1.0]]))
    with pytest.raises(ValueError, match=r"not in \[0, 1\]"):
        bronze.sample(np.array([[0.0, 0.0, 1.0]]), np.array([[0.5, 1.5]]))
    with pytest.raises(ValueError):
        neural_brdf.Material.from_latent_vector(latent_path, np.zeros(3))
    # Errors leave the material usable.
    assert bronze.eval(np.array([[0.0, 0.6, 0.8]]), np.array([[0.0, -0.6, 0.8]])).max() > 0


def test_blends_decode_the_interpolated_vector_and_end_at_their_codes(latent_path, bronze):
    chrome = neural_brdf.Material.open(latent_path, "chrome")
    wo, wi = direction_pairs(np.random.default_rng(4), 300)
    ends = [neural_brdf.Material.blend(latent_path, "alum-bronze", "chrome", t) for t in (0.0, 1.0)]
    np.testing.assert_array_equal(ends[0].eval(wo, wi), bronze.eval(wo, wi))
    np.testing.assert_array_equal(ends[1].eval(wo, wi), chrome.eval(wo, wi))
    # The blend at t is the decode of the interpolated latent vector (z and offsets
    # interpolated, each end's residual faded out within t = 0.25 of its end: none at 0.3)
    # with the offsets then balanced to the blend of the ends' albedo: under the shipped
    # file's log-relative mapping, f + eps = (f_ref + eps) exp(y), a changed offset scales
    # each channel's f + eps by one factor at every direction.
    codes = neural_brdf.latent_codes(latent_path)
    t = np.float32(0.3)
    vector = (np.float32(1) - t) * codes["alum-bronze"] + t * codes["chrome"]
    residual = sum(w.size + b.size for w, b in bronze.layers) - bronze.layers[-1][1].size
    vector[len(vector) - residual :] = 0
    blend = neural_brdf.Material.blend(latent_path, "alum-bronze", "chrome", float(t))
    assert blend.kind == "neural" and blend.layers is not None and blend.weights is None
    f = blend.eval(wo, wi)
    assert not np.array_equal(f, bronze.eval(wo, wi))
    g = neural_brdf.Material.from_latent_vector(latent_path, vector).eval(wo, wi)
    eps = 0.002
    kept = (f > 1e-5).all(axis=1) & (g > 1e-5).all(axis=1)
    assert kept.sum() > 100
    ratio = (f[kept] + eps) / (g[kept] + eps)
    np.testing.assert_allclose(ratio, np.broadcast_to(np.median(ratio, axis=0), ratio.shape), rtol=1e-3)


def test_mixtures_weigh_their_parts_and_sample_by_weight(latent_path, table_path, bronze):
    table = neural_brdf.Material.open(table_path)
    mix = neural_brdf.Material.mix([bronze, table], np.array([1.0, 3.0]))
    assert mix.kind == "mixture" and mix.weights == [1.0, 3.0] and mix.layers is None and mix.table is None
    rng = np.random.default_rng(5)
    wo, wi = direction_pairs(rng, 400)
    f, pdf = mix.eval_pdf(wo, wi)
    np.testing.assert_allclose(f, 0.25 * bronze.eval(wo, wi) + 0.75 * table.eval(wo, wi), rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(pdf, 0.25 * bronze.pdf(wo, wi) + 0.75 * table.pdf(wo, wi), rtol=1e-5, atol=1e-7)
    for i in range(0, 400, 101):
        np.testing.assert_array_equal(mix.eval(wo[i : i + 1], wi[i : i + 1])[0], f[i])
    for numbers in (2, 3):
        wo = hemisphere(rng, 2000)
        wi, f, pdf = mix.sample(wo, rng.random((2000, numbers)))
        drawn = pdf > 0
        assert drawn.mean() > 0.95
        np.testing.assert_allclose(mix.pdf(wo[drawn], wi[drawn]), pdf[drawn], rtol=1e-4)
        np.testing.assert_allclose(mix.eval(wo[drawn], wi[drawn]), f[drawn], rtol=1e-5, atol=1e-7)
    with pytest.raises(ValueError, match="no sampler tables"):
        mix.sampler_tables()
    # A zero weight drops its part: the other alone, bit for bit.
    only = neural_brdf.Material.mix([bronze, table], [0.0, 2.0])
    np.testing.assert_array_equal(only.eval(wo[:50], wo[:50] * [-1, -1, 1]), table.eval(wo[:50], wo[:50] * [-1, -1, 1]))


def test_bad_blends_and_mixtures_raise(latent_path, bronze):
    for t in (float("nan"), -0.01, 1.5):
        with pytest.raises(ValueError, match="invalid value for t"):
            neural_brdf.Material.blend(latent_path, "alum-bronze", "chrome", t)
    with pytest.raises(neural_brdf.UnknownNameError, match="no-such"):
        neural_brdf.Material.blend(latent_path, "alum-bronze", "no-such", 0.5)
    with pytest.raises(OSError, match="/nonexistent/latent.bin"):
        neural_brdf.Material.blend("/nonexistent/latent.bin", "alum-bronze", "chrome", 0.5)
    with pytest.raises(ValueError, match="1 to 4 parts, not 5"):
        neural_brdf.Material.mix([bronze] * 5, [1.0] * 5)
    with pytest.raises(ValueError, match="1 to 4 parts, not 0"):
        neural_brdf.Material.mix([], [])
    with pytest.raises(ValueError, match="weight 1 is -1"):
        neural_brdf.Material.mix([bronze, bronze], [1.0, -1.0])
    with pytest.raises(ValueError, match="weight 0 is NaN"):
        neural_brdf.Material.mix([bronze, bronze], [np.nan, 1.0])
    with pytest.raises(ValueError, match="sum to 0"):
        neural_brdf.Material.mix([bronze, bronze], [0.0, 0.0])
    with pytest.raises(ValueError, match="2 materials but 3 weights"):
        neural_brdf.Material.mix([bronze, bronze], [1.0, 1.0, 1.0])
    with pytest.raises(TypeError):
        neural_brdf.Material.mix([bronze, "chrome"], [1.0, 1.0])
