"""``gonio export --to mitsuba`` joins the export reports: the plugin it wrote, evaluated
by Mitsuba itself (scalar_rgb) at the configurations the other targets are judged at,
against the material (gonio_cli/export/mitsuba_judge.py).

The plugin ports each model's equations to Dr.Jit, so the truth is the material itself:
every model's report must be round-off (CIEDE2000 < 0.01), and a plugin whose parameters
are off must be caught by the same report (the judge can fail)."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("mitsuba", reason="mitsuba is not installed (make test installs it)")

from gonio_cli.export.mitsuba import supported_models  # noqa: E402
from gonio_cli.export.mitsuba_judge import directions, judge_mitsuba  # noqa: E402
from gonio_cli.geometry import cosines, in_plane_directions  # noqa: E402
from gonio_cli.schemas import write_material  # noqa: E402
from test_export_mitsuba import furnace_material, write_scene  # noqa: E402

#: CIEDE2000 a port that is whole stays under: single-precision round-off is ~1e-5.
PORT_DE = 0.01


@pytest.mark.parametrize("model", supported_models())
def test_every_exported_model_reports_round_off_against_its_material(run_gonio, tmp_path,
                                                                     model):
    write_material(tmp_path / "m.json", furnace_material(model))
    out = tmp_path / "mitsuba"
    r = run_gonio("export", tmp_path / "m.json", "-o", out, "--to", "mitsuba",
                  "--scene", write_scene(tmp_path, 16))
    assert r.exit_code == 0, r.stderr
    rep = json.loads((out / "report.json").read_text())
    assert rep["schema"] == "gonio.export-report" and rep["target"] == "mitsuba"
    assert rep["delta_e2000_worst"] < PORT_DE, (model, rep["delta_e2000_worst"])
    assert len(rep["delta_e2000"]) == len(rep["theta_i_deg"]) > 100  # the in-plane grid
    assert "gonio export: mitsuba: Mitsuba keeps mean CIEDE2000 0.0" in r.stderr


def test_a_plugin_whose_parameters_are_off_is_caught(run_gonio, tmp_path):
    write_material(tmp_path / "m.json", furnace_material("goniochromatic"))
    out = tmp_path / "mitsuba"
    r = run_gonio("-q", "export", tmp_path / "m.json", "-o", out, "--to", "mitsuba",
                  "--scene", write_scene(tmp_path, 16))
    assert r.exit_code == 0, r.stderr
    params = json.loads((out / "bsdf_params.json").read_text())
    params["spectral_params"]["rho"] = [1.5 * v for v in params["spectral_params"]["rho"]]
    (out / "bsdf_params.json").write_text(json.dumps(params))
    _, rep = judge_mitsuba(furnace_material("goniochromatic"), tmp_path / "m.json",
                           out)
    assert rep["delta_e2000_mean"] > 1.0


def test_directions_carry_the_cosines_they_are_made_from():
    """The judge hands Mitsuba directions rebuilt from a configuration's cosines: in and
    out of the plane of incidence, they give the same four cosines back."""
    rng = np.random.default_rng(7)
    ti, to = rng.uniform(0, 85, 200), rng.uniform(-85, 85, 200)
    wi, wo = in_plane_directions(ti, to)
    phi = rng.uniform(0, 2 * np.pi, 200)  # turn ωo about the normal: out of the plane
    wo = np.stack([wo[:, 0] * np.cos(phi), wo[:, 0] * np.sin(phi), wo[:, 2]], axis=-1)
    cos = cosines(wi, wo)
    again = cosines(*directions(cos))
    for a, b in zip(cos, again):
        np.testing.assert_allclose(b, a, atol=1e-9)
