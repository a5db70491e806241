"""The smooth measured reference (gonio_cli.render.measured_smooth) against independent
truth: a measurement sampled from seed 000's eq. 5 (a known smooth BRDF) on seed 000's
goniometer geometry, interpolated back; the crease metric (gonio_cli.render.crease) on
spheres of the analytic model, the smooth reference and the four-nearest one."""

from __future__ import annotations

import numpy as np
import pytest

from gonio_cli.geometry import cosines, in_plane_cosines, in_plane_directions
from gonio_cli.render import Light
from gonio_cli.render.crease import away_from_terminators, crease_ratio, lightness
from gonio_cli.render.measured import MeasuredMaterial, measured_material
from gonio_cli.render.measured_smooth import (MEASURED_RADIUS_DEG, SmoothMeasured,
                                              direction_coordinates)
from gonio_cli.render.shade import shade
from gonio_cli.render.surface import Surface
from gonio_cli.schemas import Measurement
from gonio_cli.spectra import illuminant
from gonio_cli.synthetic import paper_geometry

from test_render_shade import WL, ink, sphere_gbuffer

MODEL = ink(0.3, 620.0)
TI, TO = paper_geometry(5.0)               # θi 20…70°, θo every 5°, no retro-reflection
MEAS = Measurement(WL, TI, TO, MODEL.evaluate(in_plane_cosines(TI, TO)))
N = np.array([0.0, 0.0, 1.0])


@pytest.fixture(scope="module")
def smooth():
    return SmoothMeasured(MEAS)


def hemisphere(rng, k):
    v = rng.normal(size=(k, 3))
    v[:, 2] = np.abs(v[:, 2])
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def test_matches_the_sampled_brdf_between_samples(smooth):
    """In the plane, half-way between measured θi rows and θo steps (inside the measured
    range: the retro-reflection gap is out): measured relative RMS 1.1 %, max 3.0 % (the
    smoothing allows the default 2 % noise, so a noise-free measurement is smoothed that
    much); asserted 2 % / 6 %. (The four-nearest rule: RMS 2.3 %, max 13 %.)"""
    ti = np.array([25.0, 35.0, 45.0, 55.0, 62.5])[:, None] * np.ones((1, 25))
    to = np.linspace(-60.0, 60.0, 25)[None, :] * np.ones((5, 1))
    wi, wo = in_plane_directions(ti.ravel(), to.ravel())
    th, sg, _, _ = direction_coordinates(wi, wo, np.broadcast_to(N, wi.shape))
    inside = ~smooth.outside(th, sg)
    assert inside.sum() >= 50
    ref = MODEL.evaluate(in_plane_cosines(ti.ravel(), to.ravel()))[inside]
    rel = np.abs(smooth.evaluate_directions(wi, wo, N)[inside] / ref - 1.0)
    assert np.sqrt(np.mean(rel ** 2)) < 0.02 and rel.max() < 0.06


def test_matches_the_sampled_brdf_out_of_the_plane(smooth):
    """Random direction pairs inside the measured range with σ ≤ 70°: eq. 5 is a function
    of (θh, σ), so only the interpolation errs: measured RMS 2.3 %, p99 8.3 %, max 13 %
    (at the narrow peak); asserted 4 % / 12 %. The four-nearest rule's symmetry about the
    mirror direction gives RMS 130 % there (shows the test can fail). Grazing both ways
    (σ → 80°) the sweep ends and the error grows to ~45 %: docs/render.md says so."""
    rng = np.random.default_rng(3)
    wi, wo = hemisphere(rng, 4000), hemisphere(rng, 4000)
    th, sg, _, _ = direction_coordinates(wi, wo, np.broadcast_to(N, wi.shape))
    keep = ~smooth.outside(th, sg) & (sg <= 70.0)
    assert keep.sum() > 1000
    ref = MODEL.evaluate(cosines(wi, wo))[keep]
    for m, rms_max, p99_max in ((smooth, 0.04, 0.12), (MeasuredMaterial(MEAS), None, None)):
        rel = np.abs(m.evaluate_directions(wi, wo, N)[keep] / ref - 1.0)
        rms = np.sqrt(np.mean(rel ** 2))
        if rms_max is None:
            assert rms > 0.5
        else:
            assert rms < rms_max and np.percentile(rel, 99) < p99_max


def test_reciprocal_positive_finite_and_zero_below_the_horizon(smooth):
    rng = np.random.default_rng(7)
    wi, wo = hemisphere(rng, 500), hemisphere(rng, 500)
    a = smooth.evaluate_directions(wi, wo, N)
    np.testing.assert_allclose(a, smooth.evaluate_directions(wo, wi, N), rtol=1e-12)
    assert np.all(np.isfinite(a)) and np.all(a > 0)
    # extremes: normal incidence, mirror (θh = 0), retro-reflection (ωo = ωi), grazing
    wi_x = np.array([[0, 0, 1.0], [-0.6, 0, 0.8], [-0.6, 0, 0.8], [-1.0, 0, 1e-9]])
    wo_x = np.array([[0, 0, 1.0], [0.6, 0, 0.8], [-0.6, 0, 0.8], [1.0, 0, 1e-9]])
    f = smooth.evaluate_directions(wi_x, wo_x, N)
    assert np.all(np.isfinite(f)) and np.all(f > 0)
    below = smooth.evaluate_directions(wi_x[1], np.array([0.3, 0.0, -0.95]), N)
    assert np.all(below == 0)


def test_outside_the_measured_range_is_counted_and_clamped(smooth):
    """Normal incidence and view (θh = 0, σ = 0) is 14° from the nearest configuration
    (θi = θo = 20° is at σ = 20°, θh = 0; θo = 0 at θi = 20° is at (10°, 10°)): outside,
    counted, and the value is the spline's at the nearest point of the hull, which lies
    on its edge between (±10°, 10°), i.e. at (0°, 10°) — the same as a query there."""
    before = smooth.outside_samples
    f0 = smooth.evaluate_directions(np.array([0, 0, 1.0]), np.array([0, 0, 1.0]), N)
    assert smooth.outside_samples == before + 1
    assert smooth.outside(np.array([0.0]), np.array([0.0]))[0]
    assert not smooth.outside(np.array([0.0]), np.array([20.0 - MEASURED_RADIUS_DEG / 2]))[0]
    np.testing.assert_allclose(np.exp(smooth.log_lookup(np.array([0.0]), np.array([0.0]))),
                               np.exp(smooth.log_lookup(np.array([0.0]), np.array([10.0]))),
                               rtol=1e-3)          # the cubic B-spline's reach: 1e-3
    assert np.all(np.isfinite(f0)) and np.all(f0 > 0)


def sphere_lightness(material, n_px, light_dir):
    """L* (n, n) of an orthographic n × n sphere under one directional D65 light."""
    g = sphere_gbuffer(n_px)
    light = Light("directional", illuminant("D65", WL), direction=light_dir, irradiance=3.0,
                  name="key")
    kw = {"spectral": "exact"} if material is MODEL else {}
    return lightness(shade(g, [Surface(material=material)], [light], WL, **kw), 1.0), g


def test_no_crease_on_a_sphere(smooth):
    """The crease ratio (max |Δ²L*| / its running median along rows) of a 160² sphere lit
    like Figure 5's key light, judged away from the terminator, from the point where the
    normal meets the light (eq. 6's cos((θi + θo)/2) has a cone at θi = 0: 4.9 on the
    analytic model itself, and the smooth reference keeps it) and outside the measured range (clamped: documented slope
    break); likewise at θo = 0, the centre of the sphere (3.3 on the model). Measured:
    eq. 5 itself 0.9, smooth 1.4, four-nearest 54. Asserted < 3 (issue
    27) for the model and the smooth reference, > 3 for the four-nearest one."""
    d = np.array([-1.0, 1.0, 1.2]) / np.linalg.norm([-1.0, 1.0, 1.2])
    n_px = 160
    c = (np.arange(n_px) + 0.5) / n_px * 2.0 - 1.0
    x, y = np.meshgrid(c, -c)
    normal = np.stack([x, y, np.sqrt(np.clip(1.0 - x * x - y * y, 0.0, 1.0))], axis=-1)
    h = normal.reshape(-1, 3)
    th, sg, _, _ = direction_coordinates(np.broadcast_to(d, h.shape),
                                         np.broadcast_to(N, h.shape), h)
    judged = (away_from_terminators(normal, d[None])
              & (normal @ d < np.cos(np.radians(5.0))) & (normal[..., 2] < np.cos(np.radians(5.0)))
              & ~smooth.outside(th, sg).reshape(n_px, n_px))
    ratios = {}
    for name, m in (("model", MODEL), ("smooth", smooth), ("old", MeasuredMaterial(MEAS))):
        lstar, g = sphere_lightness(m, n_px, d)
        assert np.all(np.isfinite(lstar))
        ratios[name] = crease_ratio(lstar, g.object_id >= 0, judged)
    assert ratios["model"] < 3.0 and ratios["smooth"] < 3.0, ratios
    assert ratios["old"] > 3.0, ratios


def test_registry_default_and_unknown_name():
    assert isinstance(measured_material(MEAS), SmoothMeasured)
    assert isinstance(measured_material(MEAS, interpolation="four-nearest"), MeasuredMaterial)
    from gonio_cli.errors import InputError

    with pytest.raises(InputError, match="smooth, four-nearest"):
        measured_material(MEAS, interpolation="linear")
