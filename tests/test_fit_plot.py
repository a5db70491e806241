"""The fit plot (``gonio fit --plot``, ``gonio eval --plot``): which curves it draws for
each instrument layout, and that the curves are the model (checked against seed 000
eq. 7 at the mirror configuration, a formula the plot does not use).

Layouts: a goniometer's θo sweep per θi (seed 000 Figure 4), a multi-angle
spectrophotometer's 12 aspecular geometries (the MA-T12 fixture, tests/fixtures/real),
and mirror-only data (θo = θi at every θi), which must show as a curve over θi rather
than one dot per θi.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from gonio_cli.brdf import goniochromatic_mirror
from gonio_cli.fit import plot as fit_plot
from gonio_cli.fit.plot import curve_groups, plot_fit
from gonio_cli.schemas import Material, read_measurement
from gonio_cli.spectra import parse_grid
from gonio_cli.synthetic import ink_spectra, paper_geometry, synthetic_measurement

FIXTURES = Path(__file__).resolve().parent / "fixtures" / "real"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
ALPHA = 0.2


def material_on(grid) -> Material:
    rho, c = ink_spectra("green", grid)
    return Material("goniochromatic", np.asarray(grid, float),
                    {"alpha": ALPHA, "rho": rho, "c": c})


def mirror_measurement(theta_i=np.arange(10.0, 75.0, 5.0), noise=0.02):
    mat = material_on(parse_grid())
    m = synthetic_measurement("goniochromatic", mat.params, theta_i, theta_i, noise=noise)
    return m, mat


@pytest.fixture
def multi_angle(run_gonio, tmp_path):
    """The 12-geometry MA-T12 fixture as a measurement (θi = 15° and 45°, 6 each)."""
    out = tmp_path / "ma.json"
    r = run_gonio("ingest", FIXTURES / "ma_t12_clean.csv", "-o", out,
                  "--quantity", "reflectance-factor", "--grid-nm", "400:700:10")
    assert r.exit_code == 0, r.stderr
    return read_measurement(out)


@pytest.fixture
def drawn(monkeypatch):
    """plot_fit with its figure kept (``plt.close`` is recorded, the figure stays open)
    and every warning an error: returns ``draw(path, measurement, material, **kw)`` →
    the matplotlib Figure."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    kept = []
    real_close = plt.close
    monkeypatch.setattr(plt, "close", lambda fig=None: kept.append(fig))

    def draw(path, measurement, material, **kw):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            plot_fit(path, measurement, material, **kw)
        assert Path(path).read_bytes()[:8] == PNG_MAGIC
        return kept[-1]

    yield draw
    for fig in kept:
        real_close(fig)


# ------------------------------------------------------------------------ layouts --

def test_mirror_only_data_is_one_curve_over_theta_i():
    ti = np.array([60.0, 20.0, 40.0 + 1e-9, 30.0])   # unsorted, with float noise
    layout, groups = curve_groups(ti, ti)
    assert layout == "theta_i"
    assert [(g.key, g.rows.tolist()) for g in groups] == [(0.0, [1, 3, 2, 0])]


def test_goniometer_sweep_keeps_seed_000_axes():
    ti, to = paper_geometry(5.0)
    layout, groups = curve_groups(ti, to)
    assert layout == "theta_o"
    assert [g.key for g in groups] == [20.0, 30.0, 40.0, 50.0, 60.0, 65.0, 70.0]
    for g in groups:
        assert np.all(ti[g.rows] == g.key) and np.all(np.diff(to[g.rows]) > 0)
    assert sum(g.rows.size for g in groups) == ti.size


def test_multi_angle_layout_is_drawn_per_theta_i(multi_angle):
    """12 geometries: 2 θi × 6 aspecular angles (9 distinct): per θi wins, 6 points each."""
    layout, groups = curve_groups(multi_angle.theta_i_deg, multi_angle.theta_o_deg)
    assert layout == "theta_o"
    assert [(g.key, g.rows.size) for g in groups] == [(15.0, 6), (45.0, 6)]


def test_aspecular_groups_of_a_mirror_and_an_offset_sweep():
    """θi sweeps at the mirror and 15° off it: two curves over θi, keyed θi − θo."""
    ti = np.tile(np.arange(20.0, 61.0, 10.0), 2)
    to = np.concatenate([ti[:5], ti[5:] - 15.0])
    layout, groups = curve_groups(ti, to)
    assert layout == "theta_i"
    assert [(g.key, g.rows.size) for g in groups] == [(0.0, 5), (15.0, 5)]


# --------------------------------------------------------------------- the drawing --

def test_mirror_only_plot_draws_the_model_as_a_curve_over_theta_i(drawn, tmp_path):
    m, mat = mirror_measurement()
    fig = drawn(tmp_path / "mirror.png", m, mat)
    top = fig.axes[0]
    assert top.get_xlabel() == "θi (°)"
    lines = top.get_lines()
    dots = [l for l in lines if l.get_marker() == "o"]
    curves = [l for l in lines if l.get_linestyle() == "-" and l.get_marker() in ("None", "")]
    assert len(dots) == 1 and len(dots[0].get_xdata()) == m.n_configurations
    assert len(curves) == 1
    x, y = (np.asarray(v, float) for v in curves[0].get_data())
    # a curve, not a dot: it spans the data's θi at 4 samples per degree
    assert x[0] == 10.0 and x[-1] == 70.0 and x.size == 60 * fit_plot.CURVE_SAMPLES_PER_DEG + 1
    # it is the model at the mirror: seed 000 eq. 7 (which the plot does not call),
    # averaged over λ; equal to float round-off (eq. 5 with cos θh = 1 is eq. 7)
    truth = goniochromatic_mirror(np.cos(np.radians(x)), ALPHA, mat.params["rho"],
                                  mat.params["c"]).mean(axis=1)
    np.testing.assert_allclose(y, truth, rtol=1e-12)
    assert "mirror" in top.get_legend().get_texts()[0].get_text()


def test_mirror_only_plot_marks_excluded_theta_i_hollow(drawn, tmp_path):
    m, mat = mirror_measurement()
    fig = drawn(tmp_path / "mirror.png", m, mat, excluded_theta_i_deg=[65.0, 70.0])
    hollow = [l for l in fig.axes[0].get_lines()
              if l.get_marker() == "o" and isinstance(l.get_markerfacecolor(), str)
              and l.get_markerfacecolor() == "none"
              and len(l.get_xdata())]
    assert len(hollow) == 1 and sorted(hollow[0].get_xdata()) == [65.0, 70.0]
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert "excluded θi" in labels


def test_multi_angle_plot_draws_a_curve_per_theta_i(drawn, multi_angle, tmp_path):
    mat = material_on(multi_angle.wavelength_nm)
    fig = drawn(tmp_path / "ma.png", multi_angle, mat)
    top = fig.axes[0]
    assert top.get_xlabel() == "θo (°)"
    curves = [l for l in top.get_lines() if l.get_marker() in ("None", "")]
    assert len(curves) == 2
    for curve, ti in zip(curves, (15.0, 45.0)):
        x = np.asarray(curve.get_xdata(), float)
        to = multi_angle.theta_o_deg[multi_angle.theta_i_deg == ti]
        assert x[0] == to.min() and x[-1] == to.max() and x.size > 100
    labels = [t.get_text() for t in top.get_legend().get_texts()]
    assert labels == ["θi = 15°", "θi = 45°"]


def test_a_single_configuration_is_drawn_as_the_models_value(drawn, tmp_path):
    """A θi with one configuration among sweeps: its model value as a bar, no
    zero-length curve (and no warning)."""
    ti, to = paper_geometry(10.0, theta_i_deg=(20.0, 40.0))
    ti, to = np.append(ti, 55.0), np.append(to, 55.0)
    mat = material_on(parse_grid())
    m = synthetic_measurement("goniochromatic", mat.params, ti, to, noise=0.0)
    fig = drawn(tmp_path / "one.png", m, mat)
    bars = [l for l in fig.axes[0].get_lines() if l.get_marker() == "_"]
    assert len(bars) == 1 and list(bars[0].get_xdata()) == [55.0]
    f = goniochromatic_mirror(np.cos(np.radians(55.0)), ALPHA, mat.params["rho"],
                              mat.params["c"]).mean()
    assert bars[0].get_ydata()[0] == pytest.approx(f, rel=1e-12)
