"""The guards around the validation layer: every array is checked finite before it is
written (one helper, gonio_cli.artifact.check_finite), and Python warnings reach the user
as gonio warning lines naming the file (gonio_cli.log.python_warnings)."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest
from bad_inputs import make_good, run

from gonio_cli import log
from gonio_cli.artifact import check_finite, write_json
from gonio_cli.errors import NumericError
from gonio_cli.imageio import write_exr, write_png

#: Python's own warning format (``file.py:12: RuntimeWarning: …``), which must never show.
PYTHON_WARNING = re.compile(r"\.py:\d+: \w*Warning")


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    return make_good(tmp_path_factory)


def test_check_finite_names_what_how_many_and_where():
    a = np.ones((4, 5, 3))
    check_finite(a, "x")                                  # finite: nothing
    check_finite(np.arange(6), "ints")                    # integers cannot be NaN
    a[2, 3, 1], a[3, 0, 0] = np.inf, np.nan
    with pytest.raises(NumericError) as info:
        check_finite(a, "the image", "out.exr")
    text = str(info.value)
    assert text.startswith("out.exr: the image holds 2 NaN or inf values")
    assert "inf at [2, 3, 1]" in text and "\n" not in text


def test_write_json_names_the_nonfinite_field_and_writes_nothing(tmp_path):
    out = tmp_path / "m.json"
    with pytest.raises(NumericError, match=r"field 'fit\.methods\[1\]\.rho' is nan"):
        write_json(out, {"fit": {"methods": [{"rho": 1.0}, {"rho": np.float64("nan")}]}})
    assert not out.exists() and not list(tmp_path.iterdir())


def test_write_json_names_an_overflow_inside_an_array(tmp_path):
    out = tmp_path / "m.json"
    with pytest.raises(NumericError, match=r"field 'rho\[2\]' is inf"):
        with np.errstate(over="ignore"):
            rho = np.array([1.0, 2.0, 1e300]) * 1e10
        write_json(out, {"rho": rho})
    assert not out.exists()


def test_images_with_nan_or_float32_overflow_are_not_written(tmp_path):
    png, exr = tmp_path / "a.png", tmp_path / "a.exr"
    img = np.full((4, 4, 3), 0.5)
    img[1, 1, 1] = np.nan
    with pytest.raises(NumericError, match="a.png: the image holds 1 NaN"):
        write_png(png, img)
    big = np.full((4, 4, 3), 1e39)                        # finite in float64, inf in float32
    with pytest.raises(NumericError, match=r"a.exr: the image \(float32\) holds 48"):
        write_exr(exr, big)
    assert not list(tmp_path.iterdir())


def test_python_warnings_become_one_gonio_line_each(capsys):
    with log.python_warnings("red.material.json"):
        for _ in range(3):                               # the same text: shown once
            warnings.warn("overflow encountered in exp", RuntimeWarning)
        warnings.warn("Covariance of the parameters could not be estimated", UserWarning)
        warnings.warn("old API", DeprecationWarning)     # developer warning: silenced
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        "gonio: warning: red.material.json: overflow encountered in exp (RuntimeWarning "
        "from test_schemas_guards)",
        "gonio: warning: red.material.json: Covariance of the parameters could not be "
        "estimated (UserWarning from test_schemas_guards)"]


def test_quiet_silences_python_warnings_too(capsys):
    log.set_quiet(True)
    try:
        with log.python_warnings("x.json"):
            warnings.warn("overflow", RuntimeWarning)
    finally:
        log.set_quiet(False)
    assert capsys.readouterr().err == ""


def test_a_numpy_warning_in_a_command_names_its_input_file(good, tmp_path, monkeypatch):
    """A RuntimeWarning raised by numpy inside a stage reaches stderr as a gonio line
    naming the command's first input file, never as Python's two-line warning."""
    from gonio_cli.schemas import Material

    real = Material.evaluate

    def noisy(self, cos):
        np.log(np.zeros(2))                              # numpy: divide by zero in log
        return real(self, cos)

    monkeypatch.setattr(Material, "evaluate", noisy)
    out = tmp_path / "model.json"
    code, err = run("eval", good["material"], "--at", good["measurement"], "-o", out)
    assert code == 0, err
    assert not PYTHON_WARNING.search(err), err
    lines = [l for l in err.splitlines() if "divide by zero" in l]
    assert len(lines) == 1 and lines[0].startswith(
        f"gonio: warning: {good['material']}: divide by zero encountered in log"), err
