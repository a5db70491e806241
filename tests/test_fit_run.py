"""The fit stage as a library call (gonio_cli.fit.run): ``gonio fit``, ``gonio report``'s
in-memory fits and plain Python make the same material, status and verdict."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from gonio_cli.errors import FitError, InputError, PoorFitError
from gonio_cli.fit.run import RunOptions, run, write
from gonio_cli.ingest import ingest
from gonio_cli.report.inputs import fit_models
from gonio_cli.samples import demo_fit_options, demo_inks
from gonio_cli.schemas import read_material, write_measurement


@pytest.fixture(scope="module")
def red():
    ink = next(i for i in demo_inks() if i.name == "red")
    return ingest(list(ink.files), **ink.ingest)


def _same_material(a, b):
    assert a.model == b.model and a.status == b.status
    assert a.fit["verdict"]["verdict"] == b.fit["verdict"]["verdict"]
    assert a.fit["verdict"]["reasons"] == b.fit["verdict"]["reasons"]
    assert a.fit["verdict"]["delta_e2000_mean"] == pytest.approx(
        b.fit["verdict"]["delta_e2000_mean"], rel=1e-12)
    assert sorted(a.params) == sorted(b.params)
    for k in a.params:
        np.testing.assert_allclose(a.params[k], b.params[k], rtol=1e-12, atol=0, err_msg=k)


def test_report_fits_as_gonio_fit_does(red, run_gonio, tmp_path):
    """Each model report fits in memory is the material ``gonio fit`` writes with the same
    exclusions: same parameters, same status, same verdict."""
    path = tmp_path / "red.measurement.json"
    write_measurement(path, red)
    exclude = demo_fit_options()["exclude_theta_i_deg"]
    in_memory = fit_models(red, exclude)
    assert set(in_memory) == {"goniochromatic", "torrance-sparrow"}
    for model, material in in_memory.items():
        out = tmp_path / f"red.{model}.material.json"
        flags = [a for t in exclude for a in ("--exclude-theta-i-deg", f"{t:g}")]
        res = run_gonio("fit", path, "-o", out, "--model", model, *flags,
                        "--on-failure", "write")
        assert res.exit_code == 0, res.stderr
        assert "verdict" in material.fit               # judged, as gonio fit judges
        _same_material(read_material(out), material)


def test_run_takes_a_path_or_a_measurement_and_write_writes_what_it_returned(red, tmp_path):
    path = tmp_path / "red.measurement.json"
    write_measurement(path, red)
    options = RunOptions(exclude_theta_i_deg=[70.0])
    from_file = run(path, options)
    in_memory = run(red, options)
    _same_material(from_file.material, in_memory.material)
    assert from_file.path == path and in_memory.path is None
    assert from_file.verdict == from_file.material.status
    write(from_file, tmp_path / "red.material.json")
    _same_material(read_material(tmp_path / "red.material.json"), from_file.material)


def test_run_refuses_bad_options_before_reading(tmp_path):
    with pytest.raises(InputError, match="--on-failure"):
        RunOptions(on_failure="ignore")
    options = RunOptions()
    options.jobs = 0
    with pytest.raises(InputError, match="--jobs 0"):
        run(tmp_path / "missing.json", options)      # the options first: no file read


def test_the_failure_policy_is_the_library_s(red):
    """max_error given and the verdict poor: PoorFitError; a failed fit raises unless
    on_failure is "write" (then it is returned, status failed)."""
    with pytest.raises(PoorFitError, match="the goniochromatic fit is poor"):
        run(red, RunOptions(exclude_theta_i_deg=[70.0], max_error=1e-6))
    zero = replace(red, brdf=np.zeros_like(red.brdf), brdf_std=None)
    with pytest.raises(FitError, match="^zero.json: the goniochromatic fit cannot be trusted"):
        run(zero, RunOptions(), path="zero.json")
    kept = run(zero, RunOptions(on_failure="write"))
    assert kept.failed and kept.material.status == "failed" == kept.verdict
