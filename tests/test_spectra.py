"""gonio_cli.spectra: the working grid, resampling and colour, against analytic truth.

Resampling is checked on functions whose resampled values are known in closed form
(straight lines, a Gaussian with error bounds from its second derivative); colour on
the conventions' own normalisations and on published CIE / IEC 61966-2-1 numbers.
"""

from __future__ import annotations

import numpy as np
import pytest

from gonio_cli import spectra as sp
from gonio_cli.errors import InputError

GRID = sp.parse_grid()

#: Exact arithmetic for a straight line is lost only to rounding of sums of ≤ 21 terms
#: of size ~1: ~1e-15. 1e-12 relative is ~1000 ulp; the end bias a one-sided hat gives
#: a line is slope × step / 3 ≈ 3e-3 here, nine orders larger.
LINEAR_RTOL = 1e-12


def line(wavelength_nm):
    """A positive straight-line spectrum (reflectance rising to the red)."""
    return 0.2 + 0.0015 * (np.asarray(wavelength_nm) - 380.0)


def gaussian(wavelength_nm, centre=550.0, sigma=30.0):
    return np.exp(-0.5 * ((np.asarray(wavelength_nm) - centre) / sigma) ** 2)


def uniform_nm(start, stop, step):
    return start + step * np.arange(int(round((stop - start) / step)) + 1)


# ----------------------------------------------------------------------- the grid --

def test_default_grid_is_41_samples_380_to_780():
    g = sp.parse_grid()
    assert g.shape == (41,)
    assert g[0] == 380.0 and g[-1] == 780.0
    np.testing.assert_array_equal(np.diff(g), 10.0)
    np.testing.assert_array_equal(sp.parse_grid("380:780:5"), uniform_nm(380, 780, 5))


@pytest.mark.parametrize("spec", [
    "380:780", "380:780:10:1", "a:b:c", "", "780:380:10", "380:780:0", "380:780:-10",
    "0:780:10", "-10:780:10", "380:785:10", "380:780:nan", "nan:780:10",
    "380:inf:10",
])
def test_bad_grid_specs_raise_input_error_naming_the_spec_and_fix(spec):
    with pytest.raises(InputError) as exc:
        sp.parse_grid(spec)
    assert repr(spec) in str(exc.value)
    assert exc.value.fix and "--grid-nm 380:780:10" in exc.value.fix


# --------------------------------------------------------------------- resampling --

@pytest.mark.parametrize("wavelength_in", [
    pytest.param(uniform_nm(380, 780, 20), id="20nm-coarser"),
    pytest.param(uniform_nm(370, 790, 1), id="1nm-beyond-the-ends"),
    pytest.param(uniform_nm(370, 790, 2.5), id="2.5nm-beyond-the-ends"),
    pytest.param(uniform_nm(380, 780, 1), id="1nm-exactly-covering"),
])
def test_resample_reproduces_a_straight_line(wavelength_in):
    got = sp.resample(wavelength_in, line(wavelength_in), GRID)
    np.testing.assert_allclose(got, line(GRID), rtol=LINEAR_RTOL)


def test_resample_coarser_onto_finer_grid_reproduces_a_straight_line():
    fine = sp.parse_grid("380:780:5")
    got = sp.resample(GRID, line(GRID), fine)
    np.testing.assert_allclose(got, line(fine), rtol=LINEAR_RTOL)


def test_resample_of_a_gaussian_finer_onto_coarser_is_within_the_hat_bias():
    # A hat of half-width h has variance h²/6, so it smooths f by h²/12 · f'' to second
    # order; max|f''| of a unit Gaussian is 1/σ². 10 % over that bound covers the fourth
    # order term ((h/σ)⁴ ~ 1e-2 of it) and the 1 nm sampling of the hat integral.
    h, sigma = 10.0, 30.0
    w = uniform_nm(380, 780, 1)
    got = sp.resample(w, gaussian(w, sigma=sigma), GRID)
    bound = h ** 2 / 12.0 / sigma ** 2
    err = np.abs(got - gaussian(GRID, sigma=sigma))
    assert err.max() <= 1.1 * bound
    assert err.max() >= 0.5 * bound  # it is the filter we expect, not point sampling


def test_resample_of_a_gaussian_coarser_onto_finer_is_within_the_interpolation_bound():
    # Linear interpolation between samples h apart errs by at most h²/8 · max|f''|.
    h, sigma = 10.0, 30.0
    fine = sp.parse_grid("380:780:5")
    got = sp.resample(GRID, gaussian(GRID, sigma=sigma), fine)
    assert np.abs(got - gaussian(fine, sigma=sigma)).max() <= h ** 2 / 8.0 / sigma ** 2


@pytest.mark.parametrize("direction", ["finer-onto-coarser", "coarser-onto-finer"])
def test_resample_keeps_non_negative_spectra_non_negative(direction, rng):
    if direction == "finer-onto-coarser":  # irregular, spiky, mostly zero: the hard case
        w = np.sort(np.concatenate([[370.0, 790.0], rng.uniform(370.0, 790.0, 900)]))
        grid = GRID
    else:
        w, grid = uniform_nm(370, 790, 15), sp.parse_grid("380:780:1")
    v = np.where(rng.uniform(size=(5, w.size)) < 0.2, rng.exponential(size=(5, w.size)), 0.0)
    got = sp.resample(w, v, grid)
    assert got.shape == (5, grid.size)
    assert np.all(got >= 0.0) and np.all(got.sum(axis=-1) > 0.0)


def test_resample_on_the_same_grid_is_a_copy():
    v = line(GRID)
    got = sp.resample(GRID + 1e-9, v, GRID)  # float noise below WAVELENGTH_TOL_NM
    np.testing.assert_array_equal(got, v)
    got[0] = -1.0
    assert v[0] != -1.0


@pytest.mark.parametrize("wavelength_in, expected", [
    (GRID, True),
    (uniform_nm(300, 900, 1), True),
    (GRID + 1e-7, True),  # within WAVELENGTH_TOL_NM
    (uniform_nm(390, 780, 10), False),
    (uniform_nm(380, 770, 10), False),
    (GRID + 1e-3, False),
])
def test_covers(wavelength_in, expected):
    assert sp.covers(wavelength_in, GRID) is expected


# ------------------------------------------------------------------------- colour --

def test_white_lambertian_at_normal_incidence_under_equal_energy_has_y_one():
    # docs/conventions.md: f = 1/π, E = π, S = 1, cos θi = 1 → L = f E S cos θi = 1, Y = 1.
    f, e, s, cos_i = 1.0 / np.pi, np.pi, np.ones(GRID.size), 1.0
    xyz = sp.spectrum_to_xyz(f * e * s * cos_i, GRID)
    assert xyz[1] == pytest.approx(1.0, abs=1e-12)
    # Equal-energy white is x = y = 1/3 by construction of the CIE 1931 observer; the
    # 380–780 nm, 10 nm sampling moves it by ~1.2e-4 here, so 5e-4.
    np.testing.assert_allclose(xyz[:2] / xyz.sum(), [1 / 3, 1 / 3], atol=5e-4)


def test_spectrum_to_xyz_is_linear_and_broadcasts(rng):
    spectra = rng.uniform(0.0, 2.0, (2, 3, GRID.size))
    xyz = sp.spectrum_to_xyz(spectra, GRID)
    assert xyz.shape == (2, 3, 3)
    np.testing.assert_allclose(xyz[1, 2], sp.spectrum_to_xyz(spectra[1, 2], GRID), rtol=1e-14)
    np.testing.assert_allclose(sp.spectrum_to_xyz(3.0 * spectra, GRID), 3.0 * xyz, rtol=1e-14)


@pytest.mark.parametrize("grid_spec", ["380:780:10", "380:780:5"])
def test_d65_is_scaled_to_unit_luminance(grid_spec):
    grid = sp.parse_grid(grid_spec)
    s = sp.illuminant("D65", grid)
    ybar = sp.cmfs(grid)[:, 1]
    assert (s @ ybar) / ybar.sum() == pytest.approx(1.0, abs=1e-12)


def test_d65_has_the_cie_relative_spectrum():
    # CIE 015 table of D65 (normalised to 100 at 560 nm), published to 6 digits.
    cie = {380: 49.9755, 460: 117.812, 500: 109.354, 550: 104.046, 560: 100.0, 600: 90.0062}
    s = sp.illuminant("D65", GRID)
    rel = {w: s[GRID == w][0] / s[GRID == 560][0] * 100.0 for w in cie}
    for w, value in cie.items():
        assert rel[w] == pytest.approx(value, rel=1e-5), w


def test_unknown_illuminant_is_an_input_error():
    with pytest.raises(InputError) as exc:
        sp.illuminant("D66", GRID)
    assert "'D66'" in str(exc.value) and "D65" in exc.value.fix


def test_xyz_to_srgb_matrix_is_iec_61966_2_1():
    # Published to four decimals, hence 5e-5.
    iec = [[3.2406, -1.5372, -0.4986], [-0.9689, 1.8758, 0.0415], [0.0557, -0.2040, 1.0570]]
    np.testing.assert_allclose(sp.xyz_to_linear_srgb_matrix(), iec, atol=5e-5)


def test_d65_light_is_srgb_white():
    # A white Lambertian under D65 (Y = 1) is linear sRGB (1, 1, 1). Integrating D65 on
    # the 10 nm grid puts its xy at (0.31273, 0.32913) instead of (0.3127, 0.3290); that
    # moves RGB by ≤ 9.3e-4, so 2e-3. A wrong white (D50, or adaptation) moves it by > 3 %.
    xyz = sp.spectrum_to_xyz(sp.illuminant("D65", GRID), GRID)
    rgb = sp.xyz_to_linear_srgb(xyz)
    np.testing.assert_allclose(rgb, xyz[1] * np.ones(3), atol=2e-3)


def test_srgb_encode_at_the_curve_points():
    # 0.01 lies between the linear-side knee 0.0031308 and the encoded-side 0.04045, the
    # two thresholds that are easy to swap.
    x = np.array([0.0, 0.0031308, 0.01, 0.5, 1.0, -0.5, 2.0])
    power = lambda v: 1.055 * v ** (1 / 2.4) - 0.055  # noqa: E731
    want = [0.0, 12.92 * 0.0031308, power(0.01), power(0.5), 1.0, 0.0, 1.0]
    got = sp.srgb_encode(x)
    np.testing.assert_allclose(got, want, rtol=1e-15, atol=1e-15)
    # The two branches meet at the knee (IEC 61966-2-1: continuous to ~1e-7 there).
    assert power(0.0031308) == pytest.approx(got[1], abs=1e-6)


def test_colour_tables_are_cached_on_disk_and_equal_colour_science(tmp_path, monkeypatch):
    # The cache spares every later run the ~1.5 s colour-science import; its content must be
    # colour-science's own numbers, and a corrupt cache file is recomputed, not trusted.
    import colour

    from gonio_cli import spectra
    from gonio_cli.cache import CACHE_ENV

    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    spectra.colour_tables.cache_clear()
    try:
        t = spectra.colour_tables()
        files = list(tmp_path.glob("colour-tables-*.npz"))
        assert len(files) == 1
        cm = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
        np.testing.assert_array_equal(t["cmfs_values"], cm.values)
        files[0].write_bytes(b"not an npz")
        spectra.colour_tables.cache_clear()
        np.testing.assert_array_equal(spectra.colour_tables()["cmfs_values"], cm.values)
    finally:
        spectra.colour_tables.cache_clear()


def test_rgb_basis_white_is_d65_with_y_one():
    from gonio_cli.spectra import illuminant, rgb_spectral_basis, spectrum_to_xyz

    g = sp.parse_grid()
    basis = rgb_spectral_basis(g)
    # Mallett–Yuksel: the three basis functions sum to 1 at every wavelength (to 1e-3).
    np.testing.assert_allclose(basis.sum(axis=1), illuminant("D65", g), rtol=2e-3)
    assert spectrum_to_xyz(basis @ np.ones(3), g)[1] == pytest.approx(1.0, rel=2e-3)
