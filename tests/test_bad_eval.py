"""gonio eval on bad materials: one line naming the file and the field, exit 2, nothing
written. The material cases (schema v1 and v2) hold for every stage that reads a material
(lobes, render, report): they share gonio_cli.schemas.Material."""

from __future__ import annotations

import pytest
from bad_inputs import assert_refused, broken, make_good, run, set_key


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    return make_good(tmp_path_factory)


def _item(key, value, k=0):
    return lambda doc: doc[key].__setitem__(k, value)


#: case → (change to the material, the field the error must name)
BAD_MATERIALS = {
    "fit a string": (set_key("fit", "refined"), "'fit'"),
    "status 5": (set_key("status", 5), "'status'"),
    "status unknown": (set_key("status", "great"), "'status'"),
    "v1 status of v2": (lambda d: d.update(schema_version=1, status="good"), "'status'"),
    "v2 status of v1": (set_key("status", "success"), "'status'"),
    "alpha negative": (set_key("alpha", -0.2), "'alpha'"),
    "alpha zero": (set_key("alpha", 0.0), "'alpha'"),
    "alpha above 1": (set_key("alpha", 1.5), "'alpha'"),
    "alpha a list": (set_key("alpha", [0.2]), "'alpha'"),
    "alpha true": (set_key("alpha", True), "'alpha'"),
    "rho 1e300": (_item("rho", 1e300), "'rho'"),
    "rho negative": (_item("rho", -0.1), "'rho'"),
    "rho null": (_item("rho", None), "'rho'"),
    "rho empty": (set_key("rho", []), "'rho'"),
    "rho too short": (lambda d: d.__setitem__("rho", d["rho"][:-1]), "'rho'"),
    "c 1e6": (_item("c", 1e6), "'c'"),
    "wavelengths decrease": (lambda d: d.__setitem__("wavelength_nm", d["wavelength_nm"][::-1]),
                             "'wavelength_nm'"),
    "wavelength negative": (_item("wavelength_nm", -380.0), "'wavelength_nm'"),
    "model unknown": (set_key("model", "phong"), "'model'"),
    "model a number": (set_key("model", 3), "'model'"),
    "param of another model": (set_key("kd", [0.1]), "kd"),
    "missing rho": (lambda d: d.pop("rho"), "'rho'"),
    "extra field": (set_key("note", "hello"), "note"),
    "schema_version 3": (set_key("schema_version", 3), "schema_version"),
}


@pytest.mark.parametrize("case", sorted(BAD_MATERIALS))
def test_bad_material_is_one_line_naming_file_and_field(good, tmp_path, case):
    change, field = BAD_MATERIALS[case]
    bad = broken(good["material"], tmp_path, change)
    out = tmp_path / "model.measurement.json"
    code, err = run("eval", bad, "--at", good["measurement"], "-o", out)
    assert_refused(code, err, names=(str(bad), field), outputs=[out])


def test_version_1_material_with_its_own_status_is_read(good, tmp_path):
    """Schema v1 (status success/failed) is still read: the check is per version."""
    v1 = broken(good["material"], tmp_path, lambda d: d.update(schema_version=1,
                                                                status="success"))
    out = tmp_path / "model.measurement.json"
    code, err = run("eval", v1, "--at", good["measurement"], "-o", out)
    assert code == 0, err
    assert out.is_file()


def test_bad_measurement_for_eval_names_it(good, tmp_path):
    bad = broken(good["measurement"], tmp_path,
                 lambda d: d["brdf_std"][2].__setitem__(3, -1.0))
    out = tmp_path / "model.measurement.json"
    code, err = run("eval", good["material"], "--at", bad, "-o", out)
    assert_refused(code, err, names=(str(bad), "'brdf_std'", "[2, 3]"), outputs=[out])
