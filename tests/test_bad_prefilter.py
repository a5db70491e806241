"""gonio prefilter on bad lobes files, maps and options: one line naming the file and the
field (or the option), exit 2, no output folder."""

from __future__ import annotations

import numpy as np
import pytest
from bad_inputs import SAMPLE, assert_refused, broken, make_good, run, set_key

from gonio_cli.imageio import write_exr


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    return make_good(tmp_path_factory)


#: case → (change to the lobes file, the field the error must name)
BAD_LOBES = {
    "exponents a number": (set_key("exponents", 3), "'exponents'"),
    "exponents empty": (set_key("exponents", []), "'exponents'"),
    "exponent 0.5": (set_key("exponents", [0.5, 8.0]), "'exponents'"),
    "exponent 1e300": (set_key("exponents", [8.0, 1e300]), "'exponents'"),
    "exponent a string": (set_key("exponents", ["8"]), "'exponents'"),
    "no exponents": (lambda d: d.pop("exponents"), "'exponents'"),
}


@pytest.mark.parametrize("case", sorted(BAD_LOBES))
def test_bad_lobes_file_is_one_line_naming_file_and_field(good, tmp_path, case):
    change, field = BAD_LOBES[case]
    bad = broken(good["lobes"], tmp_path, change)
    out = tmp_path / "sky"
    code, err = run("prefilter", SAMPLE / "sky.exr", "--lobes", bad, "-o", out,
                    "--resolution", "8")
    assert_refused(code, err, names=(str(bad), field), outputs=[out])


@pytest.mark.parametrize("value", [3e38, 1e31], ids=["3e38", "1e31"])
def test_huge_texels_are_refused_before_any_arithmetic(tmp_path, value):
    """Beyond 1e30 (docs/conventions.md, Numeric ranges) a texel would overflow the
    prefilter's sums into inf and NaN maps."""
    env = tmp_path / "big.exr"
    img = np.ones((8, 16, 3), np.float32)
    img[2, 3, 1] = value
    write_exr(env, img)
    out = tmp_path / "sky"
    code, err = run("prefilter", env, "-e", "8", "-o", out)
    assert_refused(code, err, names=(str(env), "(row 2, col 3)"), outputs=[out])


@pytest.mark.parametrize("exponents", ["8,1e300", "0.5", "8,inf"])
def test_exponents_option_outside_the_range_is_refused(tmp_path, exponents):
    out = tmp_path / "sky"
    code, err = run("prefilter", SAMPLE / "sky.exr", "-e", exponents, "-o", out)
    assert_refused(code, err, names=("outside [1, 1e+06]",), outputs=[out])
