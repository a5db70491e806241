"""Lat-long geometry (docs/conventions.md: Mitsuba 3 ``envmap``) against closed forms and inverses."""

from __future__ import annotations

import numpy as np
import pytest

from gonio_cli import envmap

SIZES = [(1, 2), (3, 7), (16, 32), (64, 128), (50, 100)]


@pytest.mark.parametrize("h,w", SIZES)
def test_solid_angles_sum_to_4pi(h, w):
    omega = envmap.solid_angles(h, w)
    assert omega.shape == (h, w)
    assert np.all(omega > 0.0)
    assert omega.sum() == pytest.approx(4.0 * np.pi, rel=1e-12)  # exact band integrals


def test_solid_angles_approach_the_midpoint_rule():
    # sin θ Δθ Δφ is the midpoint rule of the same integral: O(Δθ²) apart
    h, w = 512, 1024
    mid = np.sin(envmap.pixel_theta(h)) * (np.pi / h) * (2 * np.pi / w)
    assert np.allclose(envmap.row_solid_angles(h, w), mid, rtol=1e-5)


def test_pixel_centres_follow_the_convention():
    # H = 2, W = 4: texel (0, 0) has θ = π/4, φ = π/4 → (sin θ sin φ, cos θ, −sin θ cos φ)
    d = envmap.pixel_directions(2, 4)
    assert d.shape == (2, 4, 3)
    assert np.allclose(d[0, 0], [0.5, np.sqrt(0.5), -0.5])
    assert d[0, :, 1].min() > 0.0 and d[1, :, 1].max() < 0.0  # row 0 is the upper half
    assert np.allclose(np.linalg.norm(d, axis=-1), 1.0)
    # column 1 is centred on φ = 3π/4: +x and +z
    assert d[0, 1, 0] > 0 and d[0, 1, 2] > 0


@pytest.mark.parametrize("h,w", SIZES)
def test_direction_to_pixel_inverts_pixel_directions(h, w):
    rc = envmap.direction_to_pixel(envmap.pixel_directions(h, w), h, w)
    rows, cols = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    assert np.allclose(rc[..., 0], rows, atol=1e-9)
    assert np.allclose(rc[..., 1], cols, atol=1e-9)


def test_pixel_to_direction_round_trip_of_random_directions(rng):
    d = rng.normal(size=(1000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    h, w = 37, 80
    rc = envmap.direction_to_pixel(d, h, w)
    theta = np.pi * (rc[:, 0] + 0.5) / h
    phi = 2 * np.pi * (rc[:, 1] + 0.5) / w
    assert np.allclose(envmap.spherical_to_direction(theta, phi), d, atol=1e-12)


def test_lookup_returns_texels_at_centres_and_interpolates(rng):
    img = rng.random((8, 16, 3))
    got = envmap.lookup(img, envmap.pixel_directions(8, 16))
    assert np.allclose(got, img)
    # halfway between two columns: their mean
    theta = envmap.pixel_theta(8)[3]
    phi = 2 * np.pi * 5.0 / 16  # between the centres of columns 4 and 5
    mid = envmap.lookup(img, envmap.spherical_to_direction(theta, phi))
    assert np.allclose(mid, 0.5 * (img[3, 4] + img[3, 5]))


def test_lookup_wraps_in_phi_and_clamps_at_the_poles(rng):
    img = rng.random((8, 16))
    theta = envmap.pixel_theta(8)[2]
    seam = envmap.lookup(img, envmap.spherical_to_direction(theta, 0.0))  # φ = 0 = 2π
    assert seam == pytest.approx(0.5 * (img[2, 0] + img[2, 15]))
    pole = envmap.lookup(img, np.array([0.0, 1.0, 0.0]))
    assert np.isfinite(pole)
    assert img[0].min() <= pole <= img[0].max()


@pytest.mark.parametrize("factor", [1, 2, 4])
def test_downsample_keeps_the_integral(rng, factor):
    img = rng.random((16, 32, 3)) ** 4
    small = envmap.downsample(img, factor)
    assert small.shape == (16 // factor, 32 // factor, 3)
    fine = (img * envmap.solid_angles(16, 32)[..., None]).sum((0, 1))
    coarse = (small * envmap.solid_angles(*small.shape[:2])[..., None]).sum((0, 1))
    assert np.allclose(fine, coarse, rtol=1e-12)
    assert np.allclose(envmap.downsample(np.full((16, 32), 2.5), factor), 2.5)


def test_downsample_weights_rows_by_solid_angle():
    # two rows merged: the one nearer the equator (larger solid angle) weighs more
    img = np.zeros((4, 2))
    img[1] = 1.0  # row 1 of 4, next to the equator
    small = envmap.downsample(img, 2)
    omega = envmap.row_solid_angles(4, 2)
    assert small[0, 0] == pytest.approx(omega[1] / (omega[0] + omega[1]))
    with pytest.raises(ValueError):
        envmap.downsample(np.zeros((6, 12)), 4)
