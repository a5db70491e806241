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
