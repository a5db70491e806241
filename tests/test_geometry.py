"""gonio_cli.geometry against closed forms of the in-plane goniometer (docs/conventions.md).

In the plane y = 0 the light is at −θi and the detector at +θo (signed, about +z), so the
angle between ωi and ωo is θi + θo and the half vector sits at (θo − θi)/2:
cos θh = cos((θo − θi)/2) and cos θd = cos((θi + θo)/2), written from the angles only.
"""

from __future__ import annotations

import numpy as np
import pytest

from gonio_cli import geometry as geo

#: Directions and cosines are a handful of float64 operations (sin, cos, a sum, a norm):
#: a few ulp (~1e-16) each. 1e-14 absolute allows ~100 ulp and is still ten orders of
#: magnitude below any wrong sign, axis or factor (errors of order 1e-3 or more).
TOL = 1e-14

#: Eq. (6) from cosines is ill conditioned near θ = 0: cos θ is rounded to δ ≈ 1.1e-16, and
#: √(1 − cos θ) turns that into δ / (2 sin θ). For polar angles ≥ 0.01° (sin θ ≥ 1.7e-4) the
#: error is ≤ 3.2e-13; 1e-11 is that bound with margin (θ = 0 exactly has no error).
EQ6_TOL = 1e-11


def random_unit(rng, n, upper=True) -> np.ndarray:
    """n random unit vectors (n, 3), isotropic; on the upper hemisphere if ``upper``."""
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    if upper:
        v[:, 2] = np.abs(v[:, 2])
    return v


# ---------------------------------------------------------------- in-plane conventions --

def test_in_plane_directions_follow_conventions():
    # Light on the −x side, detector on the +x (far, specular) side for θo > 0.
    wi, wo = geo.in_plane_directions(30.0, 60.0)
    half, root3 = 0.5, np.sqrt(3.0) / 2.0
    np.testing.assert_allclose(wi, [-half, 0.0, root3], atol=TOL)
    np.testing.assert_allclose(wo, [root3, 0.0, half], atol=TOL)
    # θo < 0 is the light's side: θo = −θi is back-scatter, ωo = ωi.
    wi, wo = geo.in_plane_directions(40.0, -40.0)
    np.testing.assert_allclose(wo, wi, atol=TOL)


@pytest.mark.parametrize("theta_deg", [0.0, 10.0, 45.0, 70.0, 89.9])
def test_mirror_configuration_has_half_vector_on_the_normal(theta_deg):
    wi, wo = geo.in_plane_directions(theta_deg, theta_deg)
    np.testing.assert_allclose(geo.half_vector(wi, wo), [0.0, 0.0, 1.0], atol=TOL)
    cos = geo.in_plane_cosines(theta_deg, theta_deg)
    ct = np.cos(np.radians(theta_deg))
    np.testing.assert_allclose(
        [cos.cos_theta_h, cos.cos_theta_i, cos.cos_theta_o, cos.cos_theta_d],
        [1.0, ct, ct, ct], atol=TOL)


def test_half_vector_is_unit_length_and_bisects(rng):
    wi, wo = random_unit(rng, 2000), random_unit(rng, 2000)
    wh = geo.half_vector(wi, wo)
    np.testing.assert_allclose(np.linalg.norm(wh, axis=-1), 1.0, atol=TOL)
    # ωh bisects: equal angles to ωi and ωo (seed 000 eq. 1).
    np.testing.assert_allclose(np.sum(wh * wi, -1), np.sum(wh * wo, -1), atol=TOL)


def in_plane_sweep(rng):
    """Seeded θi in [0, 89.9], signed θo in [−89.9, 89.9] (degrees), plus the corners."""
    ti = np.concatenate([[0.0, 0.0, 89.9, 89.9, 45.0], rng.uniform(0.0, 89.9, 500)])
    to = np.concatenate([[0.0, -89.9, 89.9, -89.9, -45.0], rng.uniform(-89.9, 89.9, 500)])
    return ti, to


def test_in_plane_cos_theta_h_and_d_from_angles(rng):
    ti, to = in_plane_sweep(rng)
    cos = geo.in_plane_cosines(ti, to)
    ri, ro = np.radians(ti), np.radians(to)
    np.testing.assert_allclose(cos.cos_theta_h, np.cos((ro - ri) / 2.0), atol=TOL)
    np.testing.assert_allclose(cos.cos_theta_d, np.cos((ri + ro) / 2.0), atol=TOL)
    np.testing.assert_allclose(cos.cos_theta_i, np.cos(ri), atol=TOL)
    np.testing.assert_allclose(cos.cos_theta_o, np.cos(ro), atol=TOL)


# ------------------------------------------------------------------------------ eq. 6 --

def test_eq6_equals_cos_of_half_sum_on_a_sweep_including_0_and_90():
    deg = np.linspace(0.0, 90.0, 361)  # 0.25° steps, both ends included
    ti, to = np.meshgrid(np.radians(deg), np.radians(deg))
    got = geo.cos_half_sum(np.cos(ti), np.cos(to))
    np.testing.assert_allclose(got, np.cos((ti + to) / 2.0), rtol=0, atol=EQ6_TOL)
    assert got[0, 0] == 1.0  # θi = θo = 0
    assert got[-1, -1] == pytest.approx(0.0, abs=EQ6_TOL)  # θi = θo = 90°


def test_eq6_equals_cos_of_half_sum_on_random_polar_angles(rng):
    t = np.radians(rng.uniform(0.01, 90.0, size=(2, 20000)))
    got = geo.cos_half_sum(np.cos(t[0]), np.cos(t[1]))
    np.testing.assert_allclose(got, np.cos((t[0] + t[1]) / 2.0), rtol=0, atol=EQ6_TOL)


def test_eq6_takes_a_signed_in_plane_detector_as_its_polar_angle():
    # cos θo = cos |θo|: the light-side detector at −50° is the polar angle 50°.
    cos = geo.in_plane_cosines(20.0, -50.0)
    got = geo.cos_half_sum(cos.cos_theta_i, cos.cos_theta_o)
    assert got == pytest.approx(np.cos(np.radians(35.0)), abs=EQ6_TOL)


# ---------------------------------------------------------------------- degenerate ωh --

def test_opposite_directions_give_finite_cosines(rng):
    wi = np.concatenate([[[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], random_unit(rng, 200, False)])
    cos = geo.cosines(wi, -wi)
    wh = geo.half_vector(wi, -wi)
    assert np.all(np.isfinite(wh))
    np.testing.assert_allclose(np.linalg.norm(wh, axis=-1), 1.0, atol=TOL)
    for c in cos:
        assert np.all(np.isfinite(c)) and np.all((c >= 0.0) & (c <= 1.0))


def test_grazing_mirror_at_90_degrees_is_finite():
    # ωi + ωo = (0, 0, 2 cos 90°) ≈ 1.2e-16: the degenerate branch, not a division by ~0.
    cos = geo.in_plane_cosines(90.0, 90.0)
    assert all(np.isfinite(c) for c in cos)
    assert cos.cos_theta_i == pytest.approx(0.0, abs=TOL)


# ---------------------------------------------------------------------- broadcasting --

@pytest.mark.parametrize("shape", [(6,), (2, 3)])
def test_scalar_case_tiled_gives_identical_numbers(shape):
    one = geo.in_plane_cosines(35.0, -12.5)
    tiled = geo.in_plane_cosines(np.full(shape, 35.0), np.full(shape, -12.5))
    wi, wo = geo.in_plane_directions(35.0, -12.5)
    tiled_3d = geo.cosines(np.broadcast_to(wi, shape + (3,)), np.broadcast_to(wo, shape + (3,)))
    for a, b, c in zip(one, tiled, tiled_3d):
        assert b.shape == shape and c.shape == shape
        np.testing.assert_array_equal(b, np.full(shape, a))
        np.testing.assert_array_equal(c, np.full(shape, a))


def test_in_plane_angles_broadcast_against_each_other():
    ti = np.array([[10.0], [40.0]])
    to = np.array([-30.0, 0.0, 50.0])
    cos = geo.in_plane_cosines(ti, to)
    assert cos.cos_theta_h.shape == (2, 3)
    np.testing.assert_allclose(cos.cos_theta_h, np.cos(np.radians(to - ti) / 2.0), atol=TOL)


def test_nan_direction_propagates_to_the_half_vector():
    wi, wo = geo.in_plane_directions(30.0, np.nan)
    assert np.all(np.isnan(geo.half_vector(wi, wo)))
    assert np.isnan(geo.cosines(wi, wo).cos_theta_h)
