"""The measured reference material (gonio_cli.render.measured): exact at the
measurements, continuous between them, isotropic, and close to the model it samples."""

from __future__ import annotations

import numpy as np
import pytest

from gonio_cli.geometry import in_plane_cosines, in_plane_directions
from gonio_cli.render.measured import MeasuredMaterial
from gonio_cli.render.shade import shade
from gonio_cli.render.surface import Surface
from gonio_cli.schemas import Measurement

from test_render_shade import WL, delta_e, ink, lights_two, sphere_gbuffer

THETA_I = np.arange(20.0, 75.0, 10.0)            # seed 000 measured 20° … 70°
THETA_O = np.arange(-80.0, 85.0, 5.0)


def measurement_of(material) -> Measurement:
    ti, to = np.meshgrid(THETA_I, THETA_O, indexing="ij")
    ti, to = ti.ravel(), to.ravel()
    brdf = material.evaluate(in_plane_cosines(ti, to))
    return Measurement(WL, ti, to, brdf)


MODEL = ink(0.3, 620.0)
MEAS = measurement_of(MODEL)


def rotation(seed):
    """A random rotation matrix (3, 3)."""
    q, _ = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))


def test_exact_at_measured_configurations():
    m = MeasuredMaterial(MEAS)
    wi, wo = in_plane_directions(MEAS.theta_i_deg, MEAS.theta_o_deg)
    f = m.evaluate_directions(wi, wo, np.array([0.0, 0.0, 1.0]))
    np.testing.assert_allclose(f, MEAS.brdf, rtol=1e-12, atol=0)
    # isotropic: the same configurations in any frame (rotated normal and azimuth)
    r = rotation(1)
    f_rot = m.evaluate_directions(wi @ r.T, wo @ r.T, np.array([0.0, 0.0, 1.0]) @ r.T)
    np.testing.assert_allclose(f_rot, MEAS.brdf, rtol=1e-9)


def test_continuous_between_measurements_and_out_of_plane():
    """In the plane: linear between neighbours (values bracketed, no jumps). Out of the
    plane: d_y → 0 from either side meets the in-plane value."""
    m = MeasuredMaterial(MEAS)
    n = np.array([0.0, 0.0, 1.0])
    to = np.linspace(-70.0, 70.0, 2801)                        # 0.05° steps
    for ti in (25.0, 40.0, 47.0):
        wi, wo = in_plane_directions(np.full(to.size, ti), to)
        f = m.evaluate_directions(wi, wo, n)[:, 20]            # 580 nm
        assert np.all(np.isfinite(f)) and np.all(f >= 0)
        step = np.abs(np.diff(f))
        assert step.max() < 0.05 * f.max()                    # no jump beyond the slope
    wi, wo = in_plane_directions(40.0, 30.0)
    base = m.evaluate_directions(wi, wo, n)
    for eps in (1e-3, -1e-3):
        w = wo + np.array([0.0, eps, 0.0])
        w /= np.linalg.norm(w)
        np.testing.assert_allclose(m.evaluate_directions(wi, w, n), base, rtol=2e-2)


def test_interpolation_close_to_the_sampled_model():
    """Half-way between measured configurations the interpolant is within the linear
    interpolation error of the smooth model: at 5° θo spacing and 10° θi rows on an
    α = 0.3 ink, measured relative RMS 7.2 %; asserted < 10 %."""
    m = MeasuredMaterial(MEAS)
    ti = np.array([25.0, 35.0, 45.0, 55.0, 65.0])[:, None] * np.ones((1, 30))
    to = np.linspace(-62.5, 62.5, 30)[None, :] * np.ones((5, 1))
    wi, wo = in_plane_directions(ti.ravel(), to.ravel())
    got = m.evaluate_directions(wi, wo, np.array([0.0, 0.0, 1.0]))
    ref = MODEL.evaluate(in_plane_cosines(ti.ravel(), to.ravel()))
    rel = np.sqrt(np.mean((got - ref) ** 2) / np.mean(ref ** 2))
    assert rel < 0.10


def test_outside_measured_range_and_horizon():
    m = MeasuredMaterial(MEAS)
    n = np.array([0.0, 0.0, 1.0])
    # θi = 5° is below the first row (20°): the nearest row at the same deviation u
    wi, wo = in_plane_directions(5.0, 5.0)                   # mirror: u = 0
    wi20, wo20 = in_plane_directions(20.0, 20.0)
    np.testing.assert_allclose(m.evaluate_directions(wi, wo, n),
                               m.evaluate_directions(wi20, wo20, n), rtol=1e-12)
    below = np.array([0.3, 0.0, -0.95])
    assert np.all(m.evaluate_directions(wi, below, n) == 0)
    # normal incidence: the frame follows the view (no NaN)
    f = m.evaluate_directions(np.array([0.0, 0.0, 1.0]), wo20, n)
    assert np.all(np.isfinite(f)) and np.all(f > 0)


def test_measured_sphere_close_to_model_sphere():
    """Seed 000 Figure 5: the measured reference beside the model it was sampled from.

    In the plane of incidence the reference is the model up to linear interpolation; out
    of it, it assumes the BRDF depends on the deviation only through ‖d‖ (symmetry about
    the mirror direction), which eq. 5 obeys only roughly (D depends on sin θh =
    ‖d‖ / ‖ωi + ωo‖ and the colour term on θi + θo). Measured on this sphere: mean
    CIEDE2000 5.4, median 5.7, p99 15, luminance ~26 % low off the highlight — the
    imperfection seed 000 Table 1 reports for its own measured spheres (RMSE ~0.1).
    Asserted: mean < 7, p99 < 20 (deterministic; a regression such as clamping the far
    side of the 70° row, which spread the mirror peak over the sphere, gave mean 19).
    """
    g = sphere_gbuffer(32)
    lights = lights_two()
    ref = shade(g, [Surface(material=MODEL)], lights, WL, spectral="exact")
    got = shade(g, [Surface(material=MeasuredMaterial(MEAS))], lights, WL)
    lit = g.covered & (ref[..., 1] > 1e-3 * ref[..., 1].max())
    de = delta_e(got[lit], ref[lit], ref[lit, 1].max())
    assert de.mean() < 7.0
    assert np.percentile(de, 99) < 20.0


def test_symmetric_brdf_is_reproduced_out_of_plane():
    """Independent truth for the out-of-plane rule: a BRDF that *is* a function of θi and
    ‖d‖ only (f = (1 + cos θi) exp(−‖d‖²/0.1)) is reproduced off the plane up to the
    interpolation error of its in-plane samples (measured max 1.5 % of the peak; asserted
    < 5 %)."""
    def f_sym(ti_deg, dist):
        return ((1 + np.cos(np.radians(ti_deg))) * np.exp(-dist ** 2 / 0.1))[..., None] \
            * np.ones(WL.size)

    ti, to = np.meshgrid(THETA_I, np.arange(-80.0, 81.0, 2.0), indexing="ij")
    u = np.sin(np.radians(to)) - np.sin(np.radians(ti))
    m = MeasuredMaterial(Measurement(WL, ti.ravel(), to.ravel(), f_sym(ti, np.abs(u)).reshape(-1, WL.size)))
    rng = np.random.default_rng(5)
    n = np.array([0.0, 0.0, 1.0])
    t_i = rng.uniform(25, 65, 400)
    wi = np.stack([-np.sin(np.radians(t_i)), 0 * t_i, np.cos(np.radians(t_i))], -1)
    wo = rng.normal(size=(400, 3)) * [0.4, 0.4, 0.0] + [0.5, 0.0, 0.0] + [0, 0, 1.0]
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    wr = wi * [-1, -1, 1]
    d = np.hypot(wo[:, 0] - wr[:, 0], wo[:, 1] - wr[:, 1])
    got = m.evaluate_directions(wi, wo, n)[:, 0]
    ref = f_sym(t_i, d)[:, 0]
    assert np.max(np.abs(got - ref)) < 0.05 * ref.max()


@pytest.mark.parametrize("shape", [(6,), (2, 3)])
def test_broadcasts_over_leading_axes(shape):
    m = MeasuredMaterial(MEAS)
    wi, wo = in_plane_directions(np.full(shape, 40.0), np.full(shape, 10.0))
    f = m.evaluate_directions(wi, wo, np.array([0.0, 0.0, 1.0]))
    assert f.shape == shape + (WL.size,)
    np.testing.assert_allclose(f.reshape(-1, WL.size)[0], f.reshape(-1, WL.size)[-1])
