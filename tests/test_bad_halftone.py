"""gonio halftone on images with values outside the numeric ranges and on options whose
arithmetic would overflow: one line naming the file or option, exit 2, no mask."""

from __future__ import annotations

import numpy as np
import pytest
from bad_inputs import SAMPLE, assert_refused, run

from gonio_cli.imageio import write_exr


@pytest.mark.parametrize("value", [3e38, -3e38, 1e31, np.inf, np.nan],
                         ids=["3e38", "-3e38", "1e31", "inf", "nan"])
def test_pixels_beyond_the_range_are_refused(tmp_path, value):
    """Above 1e30 (docs/conventions.md, Numeric ranges) r + g + b overflows float32."""
    src = tmp_path / "big.exr"
    img = np.full((8, 8, 3), 0.2, np.float32)
    img[3, 4, :] = value
    write_exr(src, img, allow_nonfinite=True)
    out = tmp_path / "mask.png"
    code, err = run("halftone", src, "-o", out, "--report", tmp_path / "r.json")
    assert_refused(code, err, names=(str(src), "1 pixels"),
                   outputs=[out, tmp_path / "r.json"])


@pytest.mark.parametrize("dpi,width_mm", [("1e300", "1e300"), ("1e300", "10"),
                                          ("300", "1e300")])
def test_print_size_that_overflows_is_refused(tmp_path, dpi, width_mm):
    out = tmp_path / "mask.png"
    code, err = run("halftone", SAMPLE / "print_image.png", "-o", out, "--dpi", dpi,
                    "--print-width-mm", width_mm)
    assert_refused(code, err, names=("--dpi", "--print-width-mm"), outputs=[out])
