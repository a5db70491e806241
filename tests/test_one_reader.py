"""One reader for gonio's small CSV files and each light/colour equation once.

A spectrum CSV ``gonio ingest`` accepts (as a white standard) is accepted by
``gonio render`` as a light, with the same numbers and the same errors naming the CSV's
line; a sample-set CSV for ``gonio lobes`` is read by the same reader. The light
normalisation Σ S ȳ / Σ ȳ = 1 and the cmf / Σ ȳ weights live in ``gonio_cli.spectra`` only.
"""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

from gonio_cli.lobes.samples import sample_set
from gonio_cli.errors import InputError
from gonio_cli.csvio import read_spectrum
from gonio_cli.render.scene import load_scene
from gonio_cli.schemas import Material, read_measurement, write_material
from gonio_cli.spectra import (cmf_weights, cmfs, illuminant, luminance, parse_grid,
                               reflectance_to_xyz, unit_luminance)

GRID = parse_grid()                                   # 380-780 nm, 10 nm

#: A lamp's relative power on the working grid (no resampling: the comparison is exact).
LAMP = 0.5 + 0.4 * np.sin(GRID / 50.0) ** 2


def plain_csv(values) -> str:
    return "wavelength_nm,value\n" + "".join(f"{w:g},{float(v)!r}\n" for w, v in zip(GRID, values))


def export_csv(values) -> bytes:
    """The same spectrum as a spreadsheet in a decimal-comma locale exports it: UTF-8 BOM,
    CRLF, ';' delimiter, decimal commas, a comment line and a blank row."""
    rows = [f"{w:g};{repr(float(v)).replace('.', ',')}" for w, v in zip(GRID, values)]
    lines = ["# lamp, relative power", "WAVELENGTH_NM;Value", *rows[:5], "", *rows[5:]]
    return b"\xef\xbb\xbf" + "\r\n".join(lines).encode() + b"\r\n"


def scene_with_light(folder, spectrum_file: str) -> str:
    n = GRID.size
    write_material(folder / "red.json", Material(
        "goniochromatic", GRID, {"alpha": 0.2, "rho": np.full(n, 0.1), "c": np.full(n, 1.0)}))
    path = folder / "scene.toml"
    path.write_text(textwrap.dedent(f"""
        [camera]
        eye = [0.0, 0.0, 4.0]
        target = [0.0, 0.0, 0.0]
        fov_deg = 35.0
        width = 8
        height = 8
        [[object]]
        mesh = "builtin:sphere"
        material = "red.json"
        [[light]]
        type = "directional"
        direction = [0.0, 0.0, 1.0]
        irradiance = 1.0
        spectrum = "{spectrum_file}"
        """))
    return path


def test_a_spectrum_ingest_accepts_is_a_light_render_accepts(run_gonio, tmp_path):
    (tmp_path / "plain.csv").write_text(plain_csv(LAMP))
    (tmp_path / "export.csv").write_bytes(export_csv(LAMP))
    # ingest takes the export as a white standard …
    data = tmp_path / "ink.csv"
    data.write_text("theta_i_deg,theta_o_deg,wavelength_nm,value\n" + "".join(
        f"{ti},{to},{w:g},0.3\n" for ti, to in ((20, 10), (20, 30), (40, 30)) for w in GRID))
    out = tmp_path / "m.json"
    r = run_gonio("ingest", data, "--quantity", "ratio-to-white", "--white-reflectance",
                  tmp_path / "export.csv", "-o", out)
    assert r.exit_code == 0, r.stderr
    # ratio 0.3 to a white of reflectance LAMP: BRDF = 0.3 · LAMP / π (seed 004 eq. 7); the
    # CSV holds repr()s of the floats, so only the conversion's round-off can differ
    np.testing.assert_allclose(read_measurement(out).brdf, np.tile(0.3 * LAMP / np.pi, (3, 1)),
                               rtol=1e-14)
    # … and render takes it as a light, equal to the plain file's, with Y = 1
    plain = load_scene(scene_with_light(tmp_path, "plain.csv")).lights[0].spectrum
    export = load_scene(scene_with_light(tmp_path, "export.csv")).lights[0].spectrum
    np.testing.assert_array_equal(export, plain)
    ybar = cmfs(GRID)[:, 1]
    assert plain @ ybar / ybar.sum() == pytest.approx(1.0, rel=1e-14)
    ratio = plain / LAMP                                  # a constant factor: no resampling
    np.testing.assert_allclose(ratio, ratio[0], rtol=1e-14)


@pytest.mark.parametrize("text, expect", [
    ("wavelength_nm,value\n380,1\n390,x\n", ["lamp.csv:3:", "column value", "'x' is not a number"]),
    ("wavelength_nm,value\n380,1\n370,1\n", ["lamp.csv:3:", "wavelength 370 nm decreases"]),
    ("wavelength_nm,value\n380,1\n390,nan\n", ["lamp.csv:3:", "not finite"]),
    ("wavelength_nm;value\n380;1\n390;1\n400;-0,5\n", ["lamp.csv:4:", "-0.5", "negative"]),
    ("nm,W\n380,1\n", ["lamp.csv:1:", "wavelength_nm,value"]),
])
def test_a_bad_light_csv_is_named_by_its_line(run_gonio, tmp_path, text, expect):
    (tmp_path / "lamp.csv").write_text(text)
    path = scene_with_light(tmp_path, "lamp.csv")
    with pytest.raises(InputError) as exc:
        load_scene(path)
    message = exc.value.format()
    assert all(e in message for e in expect), message
    r = run_gonio("render", path, "-o", tmp_path / "out.png")
    assert r.exit_code == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not (tmp_path / "out.png").exists()


def test_the_white_standard_reader_names_the_row_of_a_bad_wavelength(tmp_path):
    p = tmp_path / "w.csv"
    p.write_text("wavelength_nm,value\n380,0.9\n# comment\n390,0.9\n390,0.9\n")
    with pytest.raises(InputError, match="repeats") as exc:
        read_spectrum(p, "white standard")
    assert exc.value.format().startswith(f"{p}:5: column wavelength_nm:")


def test_a_sample_set_reads_like_any_gonio_csv(tmp_path):
    plain, export = tmp_path / "a.csv", tmp_path / "b.csv"
    plain.write_text("theta_i_deg,theta_o_deg\n30,30\n20,30\n45,10\n")
    export.write_bytes(b"\xef\xbb\xbf# light, view\r\ntheta_i_deg;theta_o_deg\r\n30;30\r\n"
                       b"\r\n20,0;30\r\n45;10\r\n")
    a, b = sample_set(str(plain)), sample_set(str(export))
    np.testing.assert_array_equal(a.light_deg, [30.0, 20.0, 45.0])
    np.testing.assert_array_equal(b.light_deg, a.light_deg)
    np.testing.assert_array_equal(b.view_angle_deg, a.view_angle_deg)
    export.write_text("theta_i_deg,theta_o_deg\n30,30\n20,inf\n")
    with pytest.raises(InputError) as exc:
        sample_set(str(export))
    assert exc.value.format().startswith(f"{export}:3: column theta_o_deg:")


# ------------------------------------------------------------ normalisation, once --

def test_light_normalisation_and_cmf_weights():
    cm = cmfs(GRID)
    np.testing.assert_allclose(cmf_weights(GRID), cm / cm[:, 1].sum(), rtol=1e-15)
    s = unit_luminance(3.0 * LAMP, GRID)
    assert s @ cm[:, 1] / cm[:, 1].sum() == pytest.approx(1.0, rel=1e-14)
    np.testing.assert_allclose(s / LAMP, s[0] / LAMP[0], rtol=1e-14)
    # leading axes broadcast (STYLE 6)
    many = unit_luminance(np.stack([LAMP, 2.0 * LAMP]), GRID)
    np.testing.assert_allclose(many, [s, s], rtol=1e-14)
    np.testing.assert_allclose(luminance(np.stack([LAMP, 2.0 * LAMP]), GRID),
                               np.array([1.0, 2.0]) * luminance(LAMP, GRID), rtol=1e-14)
    # every illuminant is normalised so; a perfect white under D65 has Y = 1 for both
    # observers (the CIE 10° one's own ȳ)
    assert luminance(illuminant("A", GRID), GRID) == pytest.approx(1.0, rel=1e-14)
    for observer in (2, 10):
        assert reflectance_to_xyz(np.ones(GRID.size), GRID, observer=observer)[1] == \
            pytest.approx(1.0, rel=1e-14)
