"""gonio ingest on values outside the numeric ranges: one line naming the file, the row
and the column, exit 2, nothing written (before: an overflow in the standard deviation and
an internal error while writing JSON)."""

from __future__ import annotations

import pytest
from bad_inputs import SAMPLE, assert_refused, run


def _with_value(tmp_path, value: str):
    lines = (SAMPLE / "ink_red.csv").read_text().splitlines()
    k = next(i for i, line in enumerate(lines) if line[:1].isdigit())
    cells = lines[k].split(",")
    cells[-1] = value
    lines[k] = ",".join(cells)
    path = tmp_path / "red.csv"
    path.write_text("\n".join(lines) + "\n")
    return path, k + 1


@pytest.mark.parametrize("value", ["1e300", "-1e300", "1e31", "inf", "nan"])
def test_value_beyond_the_range_is_refused_naming_row_and_column(tmp_path, value):
    csv, row = _with_value(tmp_path, value)
    out = tmp_path / "red.measurement.json"
    code, err = run("ingest", csv, "-o", out)
    assert_refused(code, err, names=(f"{csv}:{row}", "column value"), outputs=[out])


@pytest.mark.parametrize("scale", ["1e31", "1e300", "0", "-1"])
def test_scale_beyond_the_range_is_refused(tmp_path, scale):
    out = tmp_path / "red.measurement.json"
    code, err = run("ingest", SAMPLE / "ink_red.csv", "-o", out, "--scale", scale)
    assert_refused(code, err, names=("--scale",), outputs=[out])


@pytest.mark.parametrize("grid", ["380:780:1e-300", "380:1e300:10", "380:200000:10"])
def test_grid_beyond_the_range_is_refused_before_allocating(tmp_path, grid):
    out = tmp_path / "red.measurement.json"
    code, err = run("ingest", SAMPLE / "ink_red.csv", "-o", out, "--grid-nm", grid)
    assert_refused(code, err, names=("--grid-nm", "at most 4001 samples"), outputs=[out])


@pytest.mark.parametrize("aperture,distance", [("1e-300", "1e300"), ("1e-9", "400"),
                                               ("4", "1e31")])
def test_receptor_whose_solid_angle_underflows_is_refused(tmp_path, aperture, distance):
    out = tmp_path / "red.measurement.json"
    code, err = run("ingest", SAMPLE / "ink_red.csv", "-o", out, "--quantity", "flux-ratio",
                    "--aperture-mm", aperture, "--distance-mm", distance)
    assert_refused(code, err, names=("--aperture-mm", "--distance-mm"), outputs=[out])
