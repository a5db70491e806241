"""gonio lobes on bad bases and materials: one line naming the file and the field, exit 2,
nothing written."""

from __future__ import annotations

import pytest
from bad_inputs import assert_refused, broken, make_good, run, set_key


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    return make_good(tmp_path_factory)


def _basis(key, value):
    return lambda doc: doc["bases"][0].__setitem__(key, value)


#: case → (change to the basis, the field the error must name)
BAD_BASES = {
    "bases a string": (set_key("bases", "x"), "'bases'"),
    "bases empty": (set_key("bases", []), "'bases'"),
    "exponents empty": (_basis("exponents", []), "'bases[0].exponents'"),
    "exponent 0.5": (_basis("exponents", [0.5]), "'bases[0].exponents'"),
    "exponent 1e300": (_basis("exponents", [1e300]), "'bases[0].exponents'"),
    "exponent a string": (_basis("exponents", ["8"]), "'bases[0].exponents'"),
    "n_lobes a string": (_basis("n_lobes", "1"), "'bases[0].n_lobes'"),
    "n_lobes disagrees": (_basis("n_lobes", 5), "'bases[0].n_lobes'"),
    "error negative": (_basis("error", -1.0), "'bases[0].error'"),
    "extra field in a basis": (_basis("weights", []), "bases[0].weights"),
    "channels unknown": (set_key("channels", "rgb"), "'channels'"),
    "solver missing": (lambda d: d.pop("solver"), "'solver'"),
    "materials not a list": (set_key("materials", {}), "'materials'"),
}


@pytest.mark.parametrize("case", sorted(BAD_BASES))
def test_bad_basis_is_one_line_naming_file_and_field(good, tmp_path, case):
    change, field = BAD_BASES[case]
    bad = broken(good["basis"], tmp_path, change)
    out = tmp_path / "red.lobes.json"
    code, err = run("lobes", "fit", good["material"], "--basis", bad, "--lobes", "1",
                    "-o", out)
    assert_refused(code, err, names=(str(bad), field), outputs=[out])


@pytest.mark.parametrize("change,field", [
    (set_key("alpha", -0.1), "'alpha'"),
    (lambda d: d["rho"].__setitem__(3, 1e300), "'rho'"),
    (set_key("fit", 7), "'fit'"),
], ids=["negative alpha", "rho 1e300", "fit a number"])
def test_bad_material_for_basis_is_one_line(good, tmp_path, change, field):
    bad = broken(good["material"], tmp_path, change)
    out = tmp_path / "basis.json"
    code, err = run("lobes", "basis", bad, "--max-lobes", "1", "-o", out)
    assert_refused(code, err, names=(str(bad), field), outputs=[out])


@pytest.mark.parametrize("exponents, why", [("0.5,8", "outside [1, 1e+06]"),
                                             ("1,1e300", "outside [1, 1e+06]"),
                                             ("1,nan", "'nan' is not a number")])
def test_exponents_option_outside_the_range_is_refused(good, tmp_path, exponents, why):
    out = tmp_path / "red.lobes.json"
    code, err = run("lobes", "fit", good["material"], "--exponents", exponents, "-o", out)
    assert_refused(code, err, names=("--exponents", why), outputs=[out])
