"""Colour differences for fit verdicts: CIE L*a*b* and CIEDE2000 written in gonio (so
``gonio fit`` need not import colour-science), checked against published test data and
against colour-science itself."""

from __future__ import annotations

import numpy as np
import pytest

from gonio_cli import spectra

# Sharma, Wu & Dalal (2005), Table 1: (L1, a1, b1), (L2, a2, b2), ΔE00 to 4 decimals.
SHARMA = [
    ((50.0000, 2.6772, -79.7751), (50.0000, 0.0000, -82.7485), 2.0425),
    ((50.0000, 0.0000, 0.0000), (50.0000, -1.0000, 2.0000), 2.3669),
    ((50.0000, 2.5000, 0.0000), (73.0000, 25.0000, -18.0000), 27.1492),
    ((60.2574, -34.0099, 36.2677), (60.4626, -34.1751, 39.4387), 1.2644),
    ((22.7233, 20.0904, -46.6940), (23.0331, 14.9730, -42.5619), 2.0373),
]


@pytest.mark.parametrize("lab1, lab2, expected", SHARMA)
def test_ciede2000_matches_sharmas_table(lab1, lab2, expected):
    assert spectra.delta_e_2000(lab1, lab2) == pytest.approx(expected, abs=5e-5)


def test_ciede2000_matches_colour_science_and_is_symmetric():
    import colour
    rng = np.random.default_rng(7)
    a = np.column_stack([rng.uniform(0, 100, 500), rng.uniform(-90, 90, (500, 2))])
    b = a + rng.normal(0, 8, a.shape)
    ours = spectra.delta_e_2000(a, b)
    theirs = colour.delta_E(a, b, method="CIE 2000")
    np.testing.assert_allclose(ours, theirs, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(spectra.delta_e_2000(b, a), ours, rtol=1e-10, atol=1e-10)
    assert spectra.delta_e_2000(a[:3], a[:3]) == pytest.approx(np.zeros(3))


def test_lab_of_reflectance_matches_colour_science():
    import colour
    grid = np.arange(400.0, 701.0, 10.0)
    rng = np.random.default_rng(3)
    refl = rng.uniform(0.05, 0.9, (4, grid.size))
    white = spectra.reflectance_to_xyz(np.ones(grid.size), grid)
    lab = spectra.xyz_to_lab(spectra.reflectance_to_xyz(refl, grid), white)
    # colour-science on the same sampled tables (its own integration of the same sums)
    cmfs = colour.MSDS_CMFS["CIE 1964 10 Degree Standard Observer"]
    d65 = colour.SDS_ILLUMINANTS["D65"]
    cm = np.stack([np.interp(grid, cmfs.wavelengths, cmfs.values[:, k]) for k in range(3)], -1)
    s = np.interp(grid, d65.wavelengths, d65.values)
    xyz = (refl * s) @ cm / (s @ cm[:, 1])
    ref = colour.XYZ_to_Lab(xyz, colour.XYZ_to_xy((s @ cm) / (s @ cm[:, 1])))
    np.testing.assert_allclose(lab, ref, atol=1e-8)
    # a perfect white is L* = 100, a* = b* = 0; a 18 % grey is L* ≈ 49.5
    assert spectra.xyz_to_lab(white, white) == pytest.approx([100.0, 0.0, 0.0])
    grey = spectra.xyz_to_lab(spectra.reflectance_to_xyz(np.full(grid.size, 0.18), grid), white)
    assert grey[0] == pytest.approx(49.496, abs=1e-3)
