"""gonio fit on bad measurements: one line naming the file and the field, exit 2, nothing
written (docs/conventions.md, Files and errors; Numeric ranges)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from bad_inputs import assert_refused, broken, make_good, run, set_key

from gonio_cli.brdf import MODELS
from gonio_cli.schemas import read_material


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    return make_good(tmp_path_factory)


def _reverse(key):
    return lambda doc: doc.__setitem__(key, doc[key][::-1])


def _cell(key, value):
    return lambda doc: doc[key][0].__setitem__(0, value)


#: case → (change to the measurement, the field the error must name)
BAD_MEASUREMENTS = {
    "value 1e300": (_cell("brdf", 1e300), "'brdf'"),
    "value -1e300": (_cell("brdf", -1e300), "'brdf'"),
    "value null": (_cell("brdf", None), "'brdf'"),
    "wavelengths decrease": (_reverse("wavelength_nm"), "'wavelength_nm'"),
    "wavelength repeated": (lambda d: d["wavelength_nm"].__setitem__(1, d["wavelength_nm"][0]),
                            "'wavelength_nm'"),
    "negative std": (_cell("brdf_std", -0.01), "'brdf_std'"),
    "std 1e300": (_cell("brdf_std", 1e300), "'brdf_std'"),
    "repeats 0": (lambda d: d["n_repeats"].__setitem__(0, 0), "'n_repeats'"),
    "repeats 1.5": (lambda d: d["n_repeats"].__setitem__(0, 1.5), "'n_repeats'"),
    "brdf a string": (set_key("brdf", "0.1"), "'brdf'"),
    "brdf empty": (set_key("brdf", []), "'brdf'"),
    "theta_i 95": (lambda d: d["theta_i_deg"].__setitem__(0, 95.0), "'theta_i_deg'"),
    "theta_o -90": (lambda d: d["theta_o_deg"].__setitem__(0, -90.0), "'theta_o_deg'"),
    "quantity unknown": (set_key("quantity", "radiance"), "'quantity'"),
    "summary a list": (set_key("summary", []), "'summary'"),
    "extra field": (set_key("brdf_per_sr", 1), "brdf_per_sr"),
    "inputs not a list": (set_key("inputs", "red.csv"), "'inputs'"),
    "time_s negative": (set_key("time_s", -1.0), "'time_s'"),
    "shapes disagree": (lambda d: d.__setitem__("theta_o_deg", d["theta_o_deg"][:-1]),
                        "inconsistent shapes"),
}


@pytest.mark.parametrize("case", sorted(BAD_MEASUREMENTS))
def test_bad_measurement_is_one_line_naming_file_and_field(good, tmp_path, case):
    change, field = BAD_MEASUREMENTS[case]
    bad = broken(good["measurement"], tmp_path, change)
    out = tmp_path / "out.material.json"
    code, err = run("fit", bad, "-o", out)
    assert_refused(code, err, names=(str(bad), field), outputs=[out])


@pytest.mark.parametrize("model", sorted(MODELS))
def test_all_zero_data_with_on_failure_write_never_writes_nan(good, tmp_path, model):
    """All-zero data: either refused in one line naming the measurement, or written with
    status failed and only finite numbers (JSON has no NaN; the material reads back)."""
    zero = broken(good["measurement"], tmp_path, lambda d: d.update(
        brdf=np.zeros(np.shape(d["brdf"])).tolist(), brdf_std=None))
    out = tmp_path / "zero.material.json"
    code, err = run("fit", zero, "-o", out, "--model", model, "--on-failure", "write")
    assert "Traceback" not in err and "internal error" not in err, err
    if code == 2:
        assert_refused(code, err, names=(str(zero),), outputs=[out])
        return
    assert code == 0, err
    text = out.read_text()
    assert "NaN" not in text and "Infinity" not in text
    material = read_material(out)
    assert material.status == "failed"
    assert all(np.all(np.isfinite(v)) for v in material.params.values())
    json.loads(text)


@pytest.mark.parametrize("weight", ["1e300", "-1", "nan"])
def test_weight_beyond_the_range_is_refused_naming_the_row(good, tmp_path, weight):
    m = json.loads(good["measurement"].read_text())
    csv = tmp_path / "weights.csv"
    csv.write_text(f"theta_i_deg,theta_o_deg,weight\n{m['theta_i_deg'][0]},"
                   f"{m['theta_o_deg'][0]},{weight}\n")
    out = tmp_path / "out.material.json"
    code, err = run("fit", good["measurement"], "-o", out, "--weights", csv)
    assert_refused(code, err, names=(f"{csv}:2", "weight"), outputs=[out])


# ------------------------------------------- one configuration (issue 32, item 1) --

def _one_configuration(tmp_path, rows=1):
    """A measurement of the first ``rows`` rows of the green sample ink (ingested by gonio)."""
    from bad_inputs import SAMPLE

    lines = (SAMPLE / "ink_green.csv").read_text(encoding="utf-8-sig").splitlines()
    first = next(i for i, line in enumerate(lines) if line.startswith("theta_i_deg"))
    csv = tmp_path / "one.csv"
    csv.write_text("\n".join(lines[:first + 1 + rows]) + "\n")
    m = tmp_path / "one.measurement.json"
    code, err = run("ingest", csv, "--quantity", "ratio-to-white", "-o", m)
    assert code == 0, err
    return m


@pytest.mark.parametrize("options", [(), ("--alpha", "0.1"), ("--no-refine",)])
@pytest.mark.parametrize("model", sorted(MODELS))
def test_one_configuration_is_a_fit_or_one_line_never_an_internal_error(tmp_path, model,
                                                                        options):
    """A single configuration, every model, with α fixed or without the refinement: a
    material that reads back, or one line naming the measurement (or the option) and a fix,
    exit 2, nothing written; never "internal error … KeyError"."""
    m = _one_configuration(tmp_path)
    out = tmp_path / "one.material.json"
    code, err = run("fit", m, "--model", model, "-o", out, *options)
    assert "internal error" not in err and "Traceback" not in err, err
    if code == 0:
        assert read_material(out).model == model
        return
    named = str(m) if str(m) in err else options[0]
    assert_refused(code, err, names=(named, "; "), outputs=[out])


@pytest.mark.parametrize("options", [("--alpha", "0.1"), ("--no-refine",)])
def test_one_angle_of_incidence_two_steps_say_what_to_do(tmp_path, options):
    """One θi: seed 000's step 2 on mirror rows cannot separate ρ and c. Was "internal
    error: KeyError: 'rho'"; now the reason and the options that get a fit."""
    m = _one_configuration(tmp_path, rows=13)
    out = tmp_path / "one.material.json"
    code, err = run("fit", m, "-o", out, *options)
    assert_refused(code, err, names=(str(m), "2 or more angles of incidence",
                                     "--step2 all"), outputs=[out])
    code, err = run("fit", m, "-o", out, "--step2", "all", *options)
    assert "internal error" not in err, err
