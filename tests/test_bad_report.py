"""gonio report on bad measurements and materials: one line naming the file and the
field, exit 2, and no report folder."""

from __future__ import annotations

import shutil

import pytest
from bad_inputs import assert_refused, broken, make_good, run, set_key


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    return make_good(tmp_path_factory)


#: case → (which input, change, the field the error must name)
BAD = {
    "measurement value 1e300": ("measurement", lambda d: d["brdf"][0].__setitem__(0, 1e300),
                                "'brdf'"),
    "measurement wavelengths decrease": (
        "measurement", lambda d: d.__setitem__("wavelength_nm", d["wavelength_nm"][::-1]),
        "'wavelength_nm'"),
    "material status 5": ("material", set_key("status", 5), "'status'"),
    "material fit a string": ("material", set_key("fit", "x"), "'fit'"),
    "material negative alpha": ("material", set_key("alpha", -0.5), "'alpha'"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_input_is_one_line_and_no_report(good, tmp_path, case):
    which, change, field = BAD[case]
    bad = broken(good[which], tmp_path / "in", change)
    other = tmp_path / "in" / good["material" if which == "measurement" else "measurement"].name
    shutil.copy(good["material" if which == "measurement" else "measurement"], other)
    out = tmp_path / "report"
    code, err = run("report", *sorted([bad, other]), "-o", out, "--quick",
                    "--sections", "table1,sheets")
    assert_refused(code, err, names=(str(bad), field), outputs=[out])


def test_all_zero_measurement_fitted_in_memory_is_named(good, tmp_path):
    import numpy as np

    zero = broken(good["measurement"], tmp_path, lambda d: d.update(
        brdf=np.zeros(np.shape(d["brdf"])).tolist(), brdf_std=None))
    out = tmp_path / "report"
    code, err = run("report", zero, "-o", out, "--quick", "--sections", "table1")
    assert_refused(code, err, names=(str(zero), "no wavelength"), outputs=[out])
