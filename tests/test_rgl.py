"""RGL measured BSDFs in (``gonio ingest MATERIAL.bsdf``, :mod:`gonio_cli.ingest.rgl`).

Truth is independent of the code under test: Mitsuba's own ``measured`` plugin driven
here with directions written from docs/conventions.md, Mitsuba's own tensor reader, the
known model the synthetic samples encode (sample_data/make_rgl_wrap.py), its
piecewise-linear interpolant written here from measured.cpp's parameterisation, and
colour-science's Mallett–Yuksel basis. Tests that need Mitsuba skip without it (``make
test`` installs it).
"""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from bad_inputs import refused_ingest_line
from gonio_cli.brdf import evaluate
from gonio_cli.geometry import in_plane_cosines
from gonio_cli.ingest.tensorfile import read_tensor_file, write_tensor_file
from gonio_cli.schemas import read_measurement

SAMPLE = Path(__file__).resolve().parent.parent / "sample_data"
SPEC = SAMPLE / "rgl_wrap_spec.bsdf"
RGB = SAMPLE / "rgl_wrap_rgb.bsdf"

#: Mitsuba's scalar variants compute in float32 (eps 6e-8) and store the table in float32;
#: a value passes through ~20 float32 operations (the half vector, its elevation and
#: azimuth, the bilinear and parameter weights), so agreement to 1e-5 relative is float
#: precision. A convention error moves values by far more: dividing by cos θi instead of
#: cos θo, or flipping the sign of θo, fails every comparison below (tried by breaking
#: gonio_cli/ingest/rgl.py that way).
FLOAT_RTOL = 1e-5

#: Absolute floor of the comparisons, sr⁻¹: float32 round-off of the largest values (≈ 2
#: sr⁻¹ near the mirror peak, 2 × 6e-8 × a few), far below the smallest values (≈ 0.01).
FLOAT_ATOL = 1e-6


def load_generator():
    spec = importlib.util.spec_from_file_location("make_rgl_wrap", SAMPLE / "make_rgl_wrap.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


FX = load_generator()


def ingest(run_gonio, tmp_path, path, *options, name="m.json"):
    out = tmp_path / name
    res = run_gonio("ingest", path, "-o", out, *options)
    assert res.exit_code == 0, res.stderr
    return read_measurement(out), json.loads(out.read_text()), res


def mitsuba_in_plane(mi, variant, path, theta_i_deg, theta_o_deg, channels, phi_o_deg=None):
    """Mitsuba's measured plugin at goniometer configurations, written from
    docs/conventions.md: ωi = (−sin θi, 0, cos θi), ωo = (sin θo cos φo, sin θo sin φo,
    cos θo) (φo = 0 unless given: in plane); returns
    eval (f·cos θo) / cos θo, (n, n_channels). ωi's 0 is written −0.0: Mitsuba 3.9.1
    leaves the plugin's symmetry reduction uninitialised for isotropic files
    (github.com/mitsuba-renderer/mitsuba3/pull/1850), so with +0.0 its value at the
    mirror configuration depends on leftover memory (seen here: 3.4e-5 either side of
    the model, depending on the tests run before)."""
    previous = mi.variant()
    mi.set_variant(variant)
    try:
        bsdf = mi.load_dict({"type": "measured", "filename": str(path)})
        si = mi.SurfaceInteraction3f()
        ctx = mi.BSDFContext()
        out = []
        phi = np.zeros(len(theta_i_deg)) if phi_o_deg is None else phi_o_deg
        for ti, to, po in zip(np.radians(theta_i_deg), np.radians(theta_o_deg),
                              np.radians(phi)):
            si.wi = mi.Vector3f(-np.sin(ti), -0.0, np.cos(ti))
            wo = mi.Vector3f(np.sin(to) * np.cos(po), np.sin(to) * np.sin(po), np.cos(to))
            row = []
            if variant == "scalar_rgb":
                v = bsdf.eval(ctx, si, wo)
                row = [v[0], v[1], v[2]]
            else:
                for w in channels:  # one wavelength per call (all four lanes the same)
                    si.wavelengths = mi.Spectrum([w] * 4)
                    row.append(bsdf.eval(ctx, si, wo)[0])
            out.append(np.asarray(row, dtype=float) / np.cos(to))
        return np.array(out)
    finally:
        if previous is not None:
            mi.set_variant(previous)


@pytest.fixture
def mi():
    return pytest.importorskip("mitsuba", reason="Mitsuba 3 (gonio[mitsuba]) not installed")


# ------------------------------------------------------------------ the file format --

def test_tensor_file_reads_back_through_mitsubas_own_reader(tmp_path, mi):
    """write_tensor_file writes what Mitsuba's tensor_io.read reads, and our reader agrees."""
    from mitsuba import tensor_io

    rng = np.random.default_rng(7)
    fields = {"text": "héllo", "u8": np.arange(5, dtype=np.uint8),
              "f32": rng.random((3, 4, 5)).astype(np.float32),
              "f64": rng.random(7), "i32": np.array([[-1, 2], [3, -4]], np.int32)}
    write_tensor_file(tmp_path / "t.bsdf", fields)
    theirs = tensor_io.read(str(tmp_path / "t.bsdf"))
    ours = read_tensor_file(tmp_path / "t.bsdf")
    assert set(theirs) == set(ours) == set(fields)
    for name, value in fields.items():
        expect = (np.frombuffer(value.encode(), np.uint8) if isinstance(value, str)
                  else value)
        for got in (theirs[name], ours[name]):
            assert got.dtype == expect.dtype and got.shape == expect.shape, name
            assert np.array_equal(got, expect), name


def test_samples_regenerate_byte_for_byte_and_are_small(tmp_path):
    FX.main(tmp_path)
    for path in (SPEC, RGB):
        assert (tmp_path / path.name).read_bytes() == path.read_bytes(), path.name
        assert path.stat().st_size < 200_000


def test_samples_are_the_format_mitsuba_loads(mi):
    for path, variant in ((SPEC, "scalar_spectral"), (RGB, "scalar_rgb")):
        mi.set_variant(variant)
        bsdf = mi.load_dict({"type": "measured", "filename": str(path)})
        assert "Measured" in str(bsdf)


# ------------------------------------------------------- the same as Mitsuba's eval --

def test_spectral_measurement_is_mitsubas_evaluation_over_cos_theta_o(run_gonio, tmp_path,
                                                                      mi):
    """Default goniometer grid, working grid 380:780:10 (between the file's 50 nm samples
    Mitsuba interpolates linearly in λ, as the resampling onto the grid does): the
    in-plane grid and, per θi, the mirror ring at 1, 2, 3° (in plane both sides, across)."""
    m, doc, _ = ingest(run_gonio, tmp_path, SPEC)
    assert np.array_equal(np.unique(m.theta_i_deg), np.arange(10.0, 71.0, 10.0))
    coarse = (m.phi_o_deg == 0) & (np.mod(m.theta_o_deg, 5.0) == 0)
    assert np.array_equal(np.unique(m.theta_o_deg[coarse]), np.arange(-80.0, 86.0, 5.0))
    assert coarse.sum() == 7 * 34 and m.n_configurations == 7 * (34 + 9)
    assert m.quantity == "brdf" and (m.phi_o_deg > 0).sum() == 7 * 3
    truth = mitsuba_in_plane(mi, "scalar_spectral", SPEC, m.theta_i_deg, m.theta_o_deg,
                             m.wavelength_nm, m.phi_o_deg)
    np.testing.assert_allclose(m.brdf, truth, rtol=FLOAT_RTOL, atol=FLOAT_ATOL)
    assert doc["parameters"]["mitsuba_variant"] == "scalar_spectral"
    assert doc["parameters"]["rgb_to_spectrum"] is None


def test_rgb_measurement_is_mitsubas_evaluation_through_the_basis(run_gonio, tmp_path, mi):
    """RGB: Mitsuba's linear sRGB / cos θo, times colour-science's Mallett–Yuksel basis
    on the grid (no illuminant: a reflectance). The file's jacobian is 1 (ndf/(4 sigma) =
    2), which Mitsuba applies; gonio reads what Mitsuba returns."""
    import colour
    m, doc, res = ingest(run_gonio, tmp_path, RGB, "--theta-i-deg", "20,45,60",
                         "--theta-o-deg", "-70:80:10,44,46", "--summary")
    basis = colour.recovery.MSDS_BASIS_FUNCTIONS_sRGB_MALLETT2019
    b = np.stack([np.interp(m.wavelength_nm, basis.wavelengths, basis.values[:, k])
                  for k in range(3)], axis=-1)
    rgb = mitsuba_in_plane(mi, "scalar_rgb", RGB, m.theta_i_deg, m.theta_o_deg, None)
    np.testing.assert_allclose(m.brdf, rgb @ b.T, rtol=FLOAT_RTOL, atol=FLOAT_ATOL)
    # the upsampling is recorded in the artifact and said in the summary
    assert "Mallett-Yuksel 2019" in doc["parameters"]["rgb_to_spectrum"]
    assert doc["parameters"]["kind"] == "rgb"
    assert doc["summary"]["files"][0]["rgb_to_spectrum"] == doc["parameters"]["rgb_to_spectrum"]
    assert "RGB to spectrum: Mallett-Yuksel 2019" in res.stdout
    assert doc["inputs"][0]["path"].endswith("rgl_wrap_rgb.bsdf")


def test_caller_mitsuba_variant_is_set_back(run_gonio, tmp_path, mi):
    mi.set_variant("scalar_rgb")
    ingest(run_gonio, tmp_path, SPEC, "--theta-i-deg", "30", "--theta-o-deg", "30")
    assert mi.variant() == "scalar_rgb"


def test_reading_a_bsdf_imports_mitsuba_and_nothing_heavy(tmp_path, mi):
    """Mitsuba is imported for a .bsdf (and only then: tests/test_cli.py checks CSV
    ingest never imports it); nothing else heavy comes with it."""
    import ast
    import subprocess

    from test_cli import HEAVY, SUBMODULES

    from gonio_cli.spectra import colour_tables

    colour_tables()  # the session's cache holds the colour tables, as after any first run
    for path in (SPEC, RGB):
        args = ["-q", "ingest", str(path), "-o", str(tmp_path / "m.json")]
        code = (f"import sys\nfrom gonio_cli import cli\ncode = cli.run({args!r})\n"
                "print(sorted({m.split('.')[0] for m in sys.modules}\n"
                f"             | (set({sorted(SUBMODULES)!r}) & set(sys.modules))))\n"
                "sys.exit(code)\n")
        r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           cwd=tmp_path, timeout=120)
        assert r.returncode == 0, r.stderr
        loaded = set(ast.literal_eval(r.stdout.strip().splitlines()[-1]))
        assert "mitsuba" in loaded
        assert not loaded & (HEAVY - {"mitsuba", "drjit"}), loaded & HEAVY


# ------------------------------------------------------------ the known function --

#: The samples' table nodes along u_θ = √(2θm/π) (measured.cpp's theta2u).
U_NODES = np.linspace(0.0, 1.0, FX.RESOLUTION)


def node_theta_o_deg(theta_i_deg: float) -> np.ndarray:
    """θo whose in-plane half vector lies exactly on a u_θ node, both sides of the mirror
    (θo = θi ± 2θm, θm = u² · 90°), within (−90, 90)."""
    theta_m = U_NODES ** 2 * 90.0
    to = np.concatenate([theta_i_deg + 2 * theta_m, theta_i_deg - 2 * theta_m[1:]])
    return np.sort(to[np.abs(to) < 89.9])


def model_spectral(theta_i_deg, theta_o_deg) -> np.ndarray:
    """The model the spectral sample encodes, f in sr⁻¹ at its own wavelengths."""
    return evaluate(FX.MODEL, in_plane_cosines(theta_i_deg, theta_o_deg),
                    FX.spectral_params(FX.WAVELENGTH_NM))


#: At the mirror configuration the half vector is the normal, but Mitsuba's float32
#: normalisation leaves it up to 1 ulp (2⁻²³) off, θm ≈ 1e-7 rad instead of 0, and the
#: square root of the parameterisation makes that u_θ = √(2θm/π) ≈ 2.8e-4 (measured.cpp's
#: theta2u): the value moves towards the next node by that fraction of a node step.
MIRROR_DU = np.sqrt(2 * 2.0 ** -23 / np.pi)


@pytest.mark.parametrize("theta_i", [10.0, 30.0, 40.0, 70.0])
def test_at_table_nodes_the_values_are_the_model(run_gonio, tmp_path, mi, theta_i):
    """Where the half vector lies on a node, the file holds the model exactly (in float32),
    so the measurement is the model: cosine, angles, side of θo and units all checked.
    On the file's own wavelengths (--grid-nm 380:780:50), no λ interpolation."""
    to = node_theta_o_deg(theta_i)
    m, _, _ = ingest(run_gonio, tmp_path, SPEC, "--theta-i-deg", f"{theta_i:g}",
                     "--theta-o-deg", ",".join(f"{t:.6f}" for t in to),
                     "--grid-nm", "380:780:50")
    assert m.n_configurations == to.size > 25
    truth = model_spectral(m.theta_i_deg, m.theta_o_deg)
    mirror = np.abs(m.theta_o_deg - theta_i) < 1e-9
    assert mirror.sum() == 1
    np.testing.assert_allclose(m.brdf[~mirror], truth[~mirror], rtol=FLOAT_RTOL,
                               atol=FLOAT_ATOL)
    # the mirror: at most MIRROR_DU of a node step towards the first node on either side
    # (θo = θi ± 2θm of the first node), relative to the value: the bound, plus float32
    first = node_theta_o_deg(theta_i)[np.searchsorted(to, theta_i) + np.array([-1, 1])]
    g = lambda t: model_spectral(theta_i, t) * np.cos(np.radians(t))  # noqa: E731
    step = np.max(np.abs(np.stack([g(t) for t in first]) / g(theta_i) - 1), axis=0)
    bound = MIRROR_DU * (FX.RESOLUTION - 1) * step + FLOAT_RTOL
    assert np.all(np.abs(m.brdf[mirror][0] / truth[mirror][0] - 1) <= bound), bound


def test_between_nodes_the_values_are_the_tables_linear_interpolant(run_gonio, tmp_path,
                                                                   mi):
    """At the default in-plane grid (no mirror ring), the value is the model's f·cos θo at
    the two bracketing u_θ nodes, interpolated linearly in u_θ (measured.cpp: θm = u² π/2,
    u_φ = 0 on the far side of the mirror, ½ on the light's side), divided by cos θo."""
    m, _, _ = ingest(run_gonio, tmp_path, SPEC, "--grid-nm", "380:780:50",
                     "--mirror-deg", "none")
    ti, to = m.theta_i_deg, m.theta_o_deg
    theta_m = np.abs(to - ti) / 2.0                        # degrees, in plane
    u = np.sqrt(theta_m / 90.0)
    k = np.minimum(np.floor(u * (FX.RESOLUTION - 1)).astype(int), FX.RESOLUTION - 2)
    side = np.where(to >= ti, 1.0, -1.0)                   # far side: θo = θi + 2θm

    def g(node):  # f·cos θo at node ``node`` on the configuration's side; 0 below horizon
        t_node = ti + side * 2.0 * U_NODES[node] ** 2 * 90.0
        inside = np.abs(t_node) < 90.0
        f = model_spectral(ti, np.where(inside, t_node, 0.0))
        return np.where(inside[:, None], f * np.cos(np.radians(t_node))[:, None], 0.0)

    w = (u - U_NODES[k]) / (U_NODES[k + 1] - U_NODES[k])
    expect = ((1 - w)[:, None] * g(k) + w[:, None] * g(k + 1)) / np.cos(np.radians(to))[:, None]
    np.testing.assert_allclose(m.brdf, expect, rtol=1e-4, atol=FLOAT_ATOL)
    # rtol 1e-4, not 1e-5: near grazing (θo = 85°) dividing by cos θo = 0.087 amplifies
    # Mitsuba's float32 round-off of f·cos θo ~10×, and at the mirror the value moves by
    # up to MIRROR_DU of a node step (≤ 4e-5 here, see above). The linear interpolant is
    # what the file encodes; it departs from the smooth model itself by up to ~20 % near
    # grazing (coarse u_θ nodes), and this shows the comparison can tell them apart:
    smooth = model_spectral(ti, to)
    assert np.max(np.abs(m.brdf / smooth - 1)) > 0.05


# ------------------------------------------------------------------------ refused --

@pytest.fixture
def refuse(tmp_path, run_gonio):
    """``refuse(path, *options, expect=[...])``: ingest fails with exit 2 and one line
    naming every ``expect`` text and a fix; nothing is written."""

    def _refuse(*inputs_and_options, expect=()):
        out = tmp_path / "out" / "m.json"
        res = run_gonio("ingest", *inputs_and_options, "-o", out)
        line = refused_ingest_line(res, tmp_path, out)
        for text in expect:
            assert text in line, line
        return line

    return _refuse


def write(tmp_path, name, data: bytes) -> Path:
    p = tmp_path / name
    p.write_bytes(data)
    return p


def test_missing_mitsuba_names_the_extra(refuse, monkeypatch):
    monkeypatch.setitem(sys.modules, "mitsuba", None)  # import mitsuba raises ImportError
    refuse(SPEC, expect=["rgl_wrap_spec.bsdf: reading an RGL .bsdf needs Mitsuba 3",
                         "not installed", "pip install 'gonio[mitsuba]'"])


@pytest.mark.parametrize("cut", [8, 20, 200, 100_000])
def test_truncated_file(refuse, tmp_path, cut):
    p = write(tmp_path, "cut.bsdf", SPEC.read_bytes()[:cut])
    refuse(p, expect=["cut.bsdf: "] + (["not an RGL .bsdf"] if cut < 12 else ["truncated"]))


@pytest.mark.parametrize("data, what", [
    (b"", "(empty)"),
    (b"theta_i_deg,theta_o_deg,380\n20,10,0.1\n", "(no 'tensor_file' header)"),
    (b"\x89PNG\r\n\x1a\n" + bytes(64), "(PNG image)"),
    (b"tensor_fila\0" + bytes(64), "(no 'tensor_file' header)"),
])
def test_not_a_bsdf(refuse, tmp_path, data, what):
    p = write(tmp_path, "x.bsdf", data)
    refuse(p, expect=["x.bsdf: is not an RGL .bsdf file", what, "rgl.epfl.ch"])


def test_unknown_version(refuse, tmp_path):
    data = bytearray(SPEC.read_bytes())
    data[12] = 2
    refuse(write(tmp_path, "v.bsdf", bytes(data)), expect=["v.bsdf: ", "version 2.0"])


def sample_fields(path=SPEC) -> dict:
    return {k: np.array(v) for k, v in read_tensor_file(path).items()}


def test_missing_field(refuse, tmp_path):
    fields = sample_fields()
    del fields["luminance"]
    write_tensor_file(tmp_path / "f.bsdf", fields)
    refuse(tmp_path / "f.bsdf", expect=["f.bsdf: has no field 'luminance'"])


def test_a_tensor_file_of_something_else(refuse, tmp_path):
    write_tensor_file(tmp_path / "t.bsdf", {"image": np.zeros((4, 4), np.float32)})
    refuse(tmp_path / "t.bsdf", expect=["t.bsdf: has no field 'description'"])


def test_wrong_shapes_and_types(refuse, tmp_path):
    fields = sample_fields()
    fields["luminance"] = fields["luminance"][..., :-1]       # not square
    write_tensor_file(tmp_path / "s.bsdf", fields)
    refuse(tmp_path / "s.bsdf", expect=["s.bsdf: field 'luminance' has shape"])
    fields = sample_fields()
    fields["theta_i"] = fields["theta_i"].astype(np.float64)
    write_tensor_file(tmp_path / "d.bsdf", fields)
    refuse(tmp_path / "d.bsdf", expect=["d.bsdf: field 'theta_i' is 1-D float64",
                                        "needs 1-D float32"])


def test_non_finite_values(refuse, tmp_path):
    fields = sample_fields()
    fields["spectra"][0, 2, 3, 4, 5] = np.nan
    write_tensor_file(tmp_path / "n.bsdf", fields)
    refuse(tmp_path / "n.bsdf", expect=["n.bsdf: field 'spectra' holds nan",
                                        "(0, 2, 3, 4, 5)"])


@pytest.mark.parametrize("option, value, expect", [
    ("--theta-i-deg", "90", "90 deg is outside [0, 90)"),
    ("--theta-i-deg", "-10,20", "-10 deg is outside [0, 90)"),
    ("--theta-o-deg", "-90:0:10", "-90 deg is outside (-90, 90)"),
    ("--theta-o-deg", "ten", "'ten' is not a number"),
    ("--theta-o-deg", "10:20", "'10:20' is not a number or START:STOP:STEP"),
    ("--theta-i-deg", "10:70:0", "needs STEP > 0"),
    ("--theta-i-deg", "10:70:7", "a multiple of STEP"),
    ("--theta-i-deg", "70:10:10", "START <= STOP"),
    ("--theta-o-deg", "nan", "'nan' is not a number"),
    ("--theta-o-deg", "", "is empty"),
])
def test_bad_angle_grids(refuse, option, value, expect):
    refuse(SPEC, option, value, expect=["rgl_wrap_spec.bsdf: ", f"{option} {value!r}: ",
                                        expect])


def test_grid_outside_the_files_wavelengths(refuse):
    refuse(SPEC, "--grid-nm", "360:780:10",
           expect=["rgl_wrap_spec.bsdf: column wavelengths: its wavelengths 380-780 nm do "
                   "not cover the working grid 360-780 nm", "--grid-nm 380:780:10"])
    refuse(RGB, "--grid-nm", "380:800:10", expect=["rgl_wrap_rgb.bsdf: ", "Mallett-Yuksel",
                                                   "380-780 nm"])


def test_csv_options_with_a_bsdf_and_bsdf_options_with_a_csv(refuse):
    refuse(SPEC, "--quantity", "brdf",
           expect=["rgl_wrap_spec.bsdf: --quantity is for CSV input", "drop --quantity"])
    refuse(SAMPLE / "ink_red.csv", "--theta-i-deg", "20",
           expect=["ink_red.csv: --theta-i-deg is for an RGL .bsdf input"])


def test_one_bsdf_at_a_time(refuse):
    refuse(SPEC, RGB, expect=["2 inputs given with an RGL .bsdf", "one .bsdf"])
    refuse(SAMPLE / "ink_red.csv", SPEC, expect=["2 inputs given with an RGL .bsdf"])


# --------------------------------------------------------------------- the chain --

def test_ingest_fit_render_in_three_commands(run_gonio, tmp_path, mi):
    """docs/rgl.md's three commands: the fit (every model, ``auto``) picks the model the
    sample was made from and recovers its α, and the measurement renders as ``measured``
    beside the fitted material."""
    meas, mat, png = (tmp_path / n for n in ("w.measurement.json", "w.material.json",
                                              "w.png"))
    res = run_gonio("ingest", SPEC, "-o", meas, "--theta-i-deg", "20:60:20",
                    "--theta-o-deg", "-60:80:5")
    assert res.exit_code == 0, res.stderr
    res = run_gonio("fit", meas, "--model", "auto", "-o", mat)
    assert res.exit_code == 0, res.stderr
    doc = json.loads(mat.read_text())
    assert doc["model"] == FX.MODEL
    # The data are the model up to the table's linear interpolation (the fit's rel-RMSE
    # is ~0.7 %), which biases α by +0.6 % here (0.302); 3 % is five times that.
    assert doc["alpha"] == pytest.approx(FX.ALPHA, rel=0.03)
    res = run_gonio("render", SAMPLE / "scenes" / "measured_vs_fitted.toml", "-o", png,
                    "--var", f"measurement={meas}", "--var", f"material={mat}",
                    "--width", "64", "--height", "32")
    assert res.exit_code == 0, res.stderr
    assert png.stat().st_size > 0
