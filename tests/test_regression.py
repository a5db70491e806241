"""Batch regression tests: every stage's output on sample_data/ against stored
references, within the tolerances stated (and defended) in tests/regression/.

One test per artifact, named after it (``fit-red-goniochromatic``, ``render-print-small``
…). A failure names the artifact, the metric, its value and tolerance, and how to refresh
the reference when the change is intended (tests/regression/README.md).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent / "regression"))

import gonio_regression as reg  # noqa: E402


@pytest.mark.parametrize("name", list(reg.ARTIFACTS))
def test_matches_reference(name):
    art = reg.ARTIFACTS[name]
    ref = reg.load(art)  # FileNotFoundError names the file and the refresh command
    checks = reg.compare(art, art.compute(), ref)
    assert checks, f"{name}: nothing was compared"
    if not all(c.ok for c in checks):
        pytest.fail(reg.failure_message(art, checks), pytrace=False)


# The comparisons themselves must be able to fail: each is fed a shifted copy of a
# reference and must reject it (STYLE 11: no test that cannot fail).

def test_numbers_comparison_rejects_a_shift():
    art = reg.ARTIFACTS["fit-red-goniochromatic"]
    ref = reg.load(art)
    shifted = dict(ref, alpha=ref["alpha"] * (1 + 10 * art.rel_tol))
    checks = reg.compare(art, shifted, ref)
    bad = [c for c in checks if not c.ok]
    assert [c.metric for c in bad] == ["alpha: relative error"]
    msg = reg.failure_message(art, checks)
    assert "fit-red-goniochromatic" in msg and "refresh.py fit-red-goniochromatic" in msg
    missing = {k: v for k, v in ref.items() if k != "c"}
    assert not all(c.ok for c in reg.compare(art, missing, ref))


def test_fit_data_error_that_rises_fails():
    for name in ("fit-red-goniochromatic", "fit-paint-cook-torrance"):
        art = reg.ARTIFACTS[name]
        ref = reg.load(art)
        assert all(c.ok for c in reg.compare(art, dict(ref), ref))
        worse = dict(ref, log_rmse=ref["log_rmse"] * 1.10)           # a fit 10 % worse
        bad = [c.metric for c in reg.compare(art, worse, ref) if not c.ok]
        assert bad == ["log_rmse: relative error"], name
        # an equally good point: the data error within the stationary-point tolerance
        same = dict(ref, log_rmse=ref["log_rmse"] * (1 + 0.5 * reg.DATA_ERROR_TOL))
        assert all(c.ok for c in reg.compare(art, same, ref))


def test_paint_parameters_are_stored_not_compared():
    """ks·F(f0) and m trade against each other on the multi-angle paint data: another
    optimiser's equally good parameters must pass, its worse data error must not."""
    art = reg.ARTIFACTS["fit-paint-cook-torrance"]
    ref = reg.load(art)
    other = dict(ref, ks=ref["ks"] * 1.5, m=ref["m"] * 0.8)
    assert all(c.ok for c in reg.compare(art, other, ref))
    assert "stored, not compared: f0, kd, ks, m" in reg.tolerance_text(art)
    # the inks' alpha is identifiable and still compared
    ink = reg.ARTIFACTS["fit-green-torrance-sparrow"]
    ref = reg.load(ink)
    assert not all(c.ok for c in reg.compare(ink, dict(ref, alpha=ref["alpha"] * 1.001), ref))


def test_basis_compares_eq4_error_not_exponents():
    art = reg.ARTIFACTS["lobes-basis"]
    ref = reg.load(art)
    # another, equally good basis: exponents moved by 3-6 % (as other stopping rules give),
    # eq. 4 errors within the measured spread (5e-5): passes
    rng = np.random.default_rng(4)
    other = {k: (v * (1 + rng.uniform(0.03, 0.06, v.shape)) if k.startswith("exponents_")
                 else v * (1 + 5e-5)) for k, v in ref.items()}
    assert all(c.ok for c in reg.compare(art, other, ref))
    # a basis 10 % worse at one lobe count fails, naming that count
    worse = dict(ref, error_7=ref["error_7"] * 1.10)
    bad = [c.metric for c in reg.compare(art, worse, ref) if not c.ok]
    assert bad == ["error_7: relative error"]


def test_lp_weights_compare_by_optimum_not_vertex():
    """HiGHS returns other optimal vertices than the exact simplex on the red ink's
    degenerate channels: its weights pass (same L1 optimum); an L1 10 % worse fails."""
    art = reg.ARTIFACTS["lobes-red"]
    # both computed in this run (the comparison alone is tested, whatever the fit)
    ref = reg.lobes_numbers("red", "goniochromatic", "seed001", "lp")
    highs = reg.lobes_numbers("red", "goniochromatic", "seed001", "highs")
    assert any(not np.allclose(highs[k], ref[k], rtol=1e-5, atol=0)
               for k in ("diffuse", "directional_diffuse", "gloss"))
    assert all(c.ok for c in reg.compare(art, highs, ref))
    k = np.unravel_index(int(np.argmax(ref["l1"])), ref["l1"].shape)
    l1 = ref["l1"].copy()
    l1[k] *= 1.10
    bad = [c.metric for c in reg.compare(art, dict(ref, l1=l1), ref) if not c.ok]
    assert bad == ["l1: relative error"]


def test_numbers_comparison_floor_keeps_zeros_comparable():
    art = reg.ARTIFACTS["lobes-red"]
    ref = {"w": np.array([0.0, 1.0])}
    assert all(c.ok for c in reg.compare(art, {"w": np.array([1e-12, 1.0])}, ref))
    assert not all(c.ok for c in reg.compare(art, {"w": np.array([1e-3, 1.0])}, ref))


def test_mask_comparison_rejects_one_pixel():
    art = reg.ARTIFACTS["halftone-floyd-steinberg"]
    ref = reg.load(art)
    moved = ref.copy()
    moved[0, 0] = (moved[0, 0] + 1) % 4
    (check,) = reg.compare(art, moved, ref)
    assert not check.ok and check.value == pytest.approx(1 / ref.size)


def test_image_comparison_rejects_a_visible_shift():
    art = reg.ARTIFACTS["render-figure5-small"]
    ref = reg.load(art)
    assert all(c.ok for c in reg.compare(art, ref, ref))
    # a 2 % darker image (about one just noticeable difference on the spheres)
    darker = np.round(ref * 0.98).astype(np.uint8)
    assert not all(c.ok for c in reg.compare(art, darker, ref))
    # the image moved by one pixel: same colours, structure shifted
    moved = np.roll(ref, 1, axis=1)
    assert not all(c.ok for c in reg.compare(art, moved, ref))


def test_sample_sky_is_reproduced_byte_for_byte(tmp_path):
    """The regression input sky.exr comes from sample_data/make_sky.py: a rerun (even with
    SOURCE_DATE_EPOCH set otherwise) writes the very bytes tracked, header date included."""
    import os
    import subprocess

    out = tmp_path / "sky.exr"
    env = dict(os.environ, SOURCE_DATE_EPOCH="0")
    subprocess.run([sys.executable, str(reg.SAMPLE / "make_sky.py"), str(out)], check=True,
                   env=env, capture_output=True, cwd=reg.ROOT)
    assert reg.sha256(out) == reg.sha256(reg.SKY)
