"""Every option that takes a list of numbers reads it with one grammar and refuses a bad
one with one form of error (gonio_cli.numbers): exit status 2, one line naming the option
as typed, the list, what is wrong with it and the fix, nothing written."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from gonio_cli.errors import InputError
from gonio_cli.numbers import NumberList, inclusive_range
from gonio_cli.schemas import Material, write_material
from gonio_cli.synthetic import ink_spectra

SAMPLE = Path(__file__).resolve().parent.parent / "sample_data"
PHOTOS = sorted((SAMPLE / "sparkle").glob("photo_ti*.png"))
WL = np.arange(380.0, 781.0, 10.0)


@pytest.fixture
def material(tmp_path):
    rho, c = ink_spectra("red", WL)
    path = tmp_path / "red.material.json"
    write_material(path, Material("goniochromatic", WL, {"alpha": 0.18, "rho": rho, "c": c}))
    return path


#: Every number-list option: (the option as the error names it: as typed, a short flag by
#: its long spelling; the command line with {} for the list).
OPTIONS = {
    "ingest --grid-nm": ("--grid-nm", lambda d, m: [
        "ingest", SAMPLE / "ink_red.csv", "-o", d / "out.json", "--grid-nm", "{}"]),
    "ingest --theta-i-deg": ("--theta-i-deg", lambda d, m: [
        "ingest", SAMPLE / "rgl_wrap_spec.bsdf", "-o", d / "out.json", "--theta-i-deg", "{}"]),
    "ingest --theta-o-deg": ("--theta-o-deg", lambda d, m: [
        "ingest", SAMPLE / "rgl_wrap_spec.bsdf", "-o", d / "out.json", "--theta-o-deg", "{}"]),
    "render --grid-nm": ("--grid-nm", lambda d, m: [
        "render", SAMPLE / "scenes" / "print.toml", "-o", d / "out.png", "--grid-nm", "{}"]),
    "lobes fit --exponents": ("--exponents", lambda d, m: [
        "lobes", "fit", m, "-o", d / "out.json", "--exponents", "{}"]),
    "lobes fit --view-angles-deg": ("--view-angles-deg", lambda d, m: [
        "lobes", "fit", m, "-o", d / "out.json", "--exponents", "1,10",
        "--view-angles-deg", "{}"]),
    "lobes fit --view-angles": ("--view-angles", lambda d, m: [
        "lobes", "fit", m, "-o", d / "out.json", "--exponents", "1,10", "--view-angles", "{}"]),
    "prefilter --exponents": ("--exponents", lambda d, m: [
        "prefilter", SAMPLE / "sky.exr", "-o", d / "out", "--exponents", "{}"]),
    # a short flag is named by its long spelling, as in every message
    "prefilter -e": ("--exponents", lambda d, m: [
        "prefilter", SAMPLE / "sky.exr", "-o", d / "out", "-e", "{}"]),
    "sparkle --theta-i-deg": ("--theta-i-deg", lambda d, m: [
        "sparkle", *PHOTOS, "-o", d / "out.png", "--theta-i-deg", "{}"]),
    "sparkle --theta-i": ("--theta-i", lambda d, m: [
        "sparkle", *PHOTOS, "-o", d / "out.png", "--theta-i", "{}"]),
}

#: The same bad lists for every option, and what the error says of each.
BAD = {"1,,x": "item 2 is empty",
       "5:1:1": "range '5:1:1' needs STEP > 0, START <= STOP and STOP - START a multiple "
                "of STEP",
       "10,ten": "'ten' is not a number or START:STOP:STEP",
       "": "is empty"}


@pytest.mark.parametrize("spec", list(BAD))
@pytest.mark.parametrize("name", list(OPTIONS))
def test_every_number_list_option_refuses_a_bad_list_in_one_form(run_gonio, tmp_path,
                                                                  material, name, spec):
    typed, command = OPTIONS[name]
    args = [spec if a == "{}" else a for a in command(tmp_path, material)]
    res = run_gonio(*args)
    assert res.exit_code == 2, res.stderr
    assert res.stderr.count("\n") == 1, res.stderr
    form = (rf"gonio: error: (\S+: )?{re.escape(typed)} {re.escape(repr(spec))}: "
            rf"{re.escape(BAD[spec])}; .*e\.g\. {re.escape(typed)} \S+\n")
    assert re.fullmatch(form, res.stderr), res.stderr
    assert not any(p.name.startswith("out") for p in tmp_path.iterdir())


# ---------------------------------------------------------------------- the grammar --

ANGLES = NumberList("--theta-i-deg", "10:70:10", unit="deg", lo=0.0, hi=90.0, hi_open=True)


@pytest.mark.parametrize("spec, values", [
    ("10", [10.0]), ("10,20, 30", [10.0, 20.0, 30.0]), ("10:30:10", [10.0, 20.0, 30.0]),
    ("30,10:20:10", [30.0, 10.0, 20.0]), ("0:1:0.25", [0.0, 0.25, 0.5, 0.75, 1.0]),
    ("5:5:1", [5.0]), ("1e1,2E1", [10.0, 20.0]),
])
def test_lists_and_inclusive_ranges_in_the_order_given(spec, values):
    assert ANGLES.parse(spec) == values


def test_a_range_is_start_plus_k_steps_as_numpy_arange():
    got = inclusive_range(380.0, 780.0, 0.1)
    np.testing.assert_array_equal(got, 380.0 + 0.1 * np.arange(4001))


@pytest.mark.parametrize("spec, what", [
    ("90", "90 deg is outside [0, 90)"), ("-1,10", "-1 deg is outside [0, 90)"),
    ("inf", "inf deg is outside [0, 90)"), ("nan", "'nan' is not a number"),
    ("10:20", "'10:20' is not a number or START:STOP:STEP"),
    ("10:70:7", "a multiple of STEP"), ("10:70:0", "needs STEP > 0"),
    ("0:80:1e-9", "'0:80:1e-9' holds 8e+10 values, more than 100000"),
    ("10,", "item 2 is empty"),
])
def test_bad_lists(spec, what):
    with pytest.raises(InputError) as info:
        ANGLES.parse(spec, path="m.bsdf")
    line = info.value.format()
    assert line.startswith(f"m.bsdf: --theta-i-deg {spec!r}: ") and what in line
    assert info.value.fix == ("numbers or START:STOP:STEP ranges separated by commas, in deg "
                              "within [0, 90), e.g. --theta-i-deg 10:70:10")


def test_one_range_options_take_one_range_and_say_how_many_values():
    grid = NumberList("--grid-nm", "380:780:10", unit="nm", lo=0.0, lo_open=True, hi=1e5,
                      one_range=True, max_count=4001, noun="samples")
    assert grid.parse("380:400:10") == [380.0, 390.0, 400.0]
    for spec, what in [("380,390", "is not one START:STOP:STEP range"),
                       ("380:780:1e-300", "holds 4e+302 samples, more than 4001"),
                       ("0:10:1", "0 nm is outside (0, 100000]")]:
        with pytest.raises(InputError, match=re.escape(what)) as info:
            grid.parse(spec)
        assert info.value.fix == ("one START:STOP:STEP range, in nm within (0, 100000], at "
                                  "most 4001 samples, e.g. --grid-nm 380:780:10")
