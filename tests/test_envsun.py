"""The sun split off an HDR sky (gonio_cli/envsun.py) against synthetic skies of known truth.

Each synthetic map is a smooth sky, constant over each texel, plus a disc sun of known
direction s, angular radius α and radiance L: texel j holds sky_j + L · c_j, with c_j the
share of the texel the disc covers (supersampled, :func:`disc_coverage`). The disc's
irradiance at normal incidence is L · 2π (1 − cos α) in closed form, and Σ_j L c_j Ω_j on
the map (the two agree within the supersampling's error, checked below).
"""

from __future__ import annotations

import numpy as np
import pytest

from gonio_cli import envmap, envsun
from gonio_cli.errors import InputError

SUN_RGB = np.array([3.0e4, 2.6e4, 2.0e4])   # a clear-sky sun, ~10⁴ × the sky below

#: Sub-samples per disc radius for the disc's coverage (at least 48 per texel side). The
#: edge is then placed to ~1/SAMPLES_PER_RADIUS of the radius, and the disc integral is
#: within 0.3 % of the closed form (test_disc_fixture_is_true).
SAMPLES_PER_RADIUS = 40


def smooth_sky(h: int, w: int, ground: float = 0.3) -> np.ndarray:
    """(H, W, 3) radiance: a blue sky brighter towards the horizon and with azimuth, a dim
    ground below θ = 90° (a step on the texel edge between rows H/2 − 1 and H/2)."""
    theta = envmap.pixel_theta(h)[:, None, None]
    phi = envmap.pixel_phi(w)[None, :, None]
    base = np.array([0.35, 0.55, 1.0])
    sky = base * (1.0 + 0.8 * np.sin(theta) ** 2) * (1.0 + 0.2 * np.cos(phi))
    return np.where(theta < np.pi / 2, sky, ground * base[::-1] * (1.0 + 0.2 * np.cos(phi)))


def disc_coverage(h: int, w: int, sun_dir, alpha: float, above_horizon: bool = False):
    """(H, W) share of each texel's solid angle inside the cap of half-angle α about
    ``sun_dir``, from n × n sub-texels each weighted by its exact solid angle;
    ``above_horizon``: only the part with θ < 90° (a setting sun, its lower part behind
    the ground). Only texels whose centre is within α + 2 texel pitches are sampled."""
    s = np.asarray(sun_dir, float) / np.linalg.norm(sun_dir)
    centres = envmap.pixel_directions(h, w) @ s
    rows, cols = np.nonzero(centres >= np.cos(min(alpha + 2 * np.pi / h, np.pi)))
    n = max(48, int(np.ceil(SAMPLES_PER_RADIUS * (np.pi / h) / alpha)))
    t_edges = np.pi * (rows[:, None] + np.arange(n + 1)[None, :] / n) / h     # (k, n + 1)
    theta = 0.5 * (t_edges[:, :-1] + t_edges[:, 1:])                         # (k, n)
    weight = np.cos(t_edges[:, :-1]) - np.cos(t_edges[:, 1:])                  # (k, n)
    phi = 2 * np.pi * (cols[:, None] + (np.arange(n)[None, :] + 0.5) / n) / w  # (k, n)
    d = envmap.spherical_to_direction(theta[:, :, None], phi[:, None, :])     # (k, n, n, 3)
    inside = (d @ s) >= np.cos(alpha)
    if above_horizon:
        inside &= (theta < np.pi / 2)[:, :, None]
    cov = np.zeros((h, w))
    cov[rows, cols] = (inside * weight[:, :, None]).sum(axis=(1, 2)) / (weight.sum(1) * n)
    return cov


def sun_map(h, w, theta_deg, phi_deg, alpha_deg, rgb=SUN_RGB, sky=None, **kw):
    """(map, sky, coverage, sun direction) of a sky with a disc sun."""
    s = envmap.spherical_to_direction(np.radians(theta_deg), np.radians(phi_deg))
    cov = disc_coverage(h, w, s, np.radians(alpha_deg), **kw)
    sky = smooth_sky(h, w) if sky is None else sky
    return sky + cov[..., None] * np.asarray(rgb, float), sky, cov, s


def angle_deg(a, b) -> float:
    return float(np.degrees(np.arccos(np.clip(np.dot(a, b), -1.0, 1.0))))


def max_principle_bound(sky, mask, omega):
    """|Σ (sky − fill) Ω| over the removed texels is at most Ω_removed × the range of the
    sky over them and the texels around them: the harmonic fill is a weighted mean of the
    surrounding texels (the maximum principle), the sky behind the sun lies in that range."""
    near = envsun.dilate(mask, 1)
    spread = sky[near].max(axis=0) - sky[near].min(axis=0)
    return omega[mask].sum() * spread


# --------------------------------------------------------------------- the fixture --

@pytest.mark.parametrize("theta_deg,phi_deg,alpha_deg",
                         [(60.0, 100.0, 2.0), (1.0, 40.0, 2.0), (45.0, 0.2, 2.0), (70.0, 300.0, 0.27)])
def test_disc_fixture_is_true(theta_deg, phi_deg, alpha_deg):
    h, w, alpha = 128, 256, np.radians(alpha_deg)
    _, _, cov, _ = sun_map(h, w, theta_deg, phi_deg, alpha_deg)
    exact = 2 * np.pi * (1 - np.cos(alpha))
    # supersampled edge texels: within 0.3 % (SAMPLES_PER_RADIUS); fails if the cap is misplaced
    assert (cov * envmap.solid_angles(h, w)).sum() == pytest.approx(exact, rel=3e-3)


# --------------------------------------------------------------------- recovery --

CASES = {   # name: (H, W, θ°, φ°, α°)
    "mid-sky": (128, 256, 60.0, 100.0, 2.0),
    "phi-seam": (128, 256, 45.0, 0.2, 2.0),          # straddles φ = 0 / 2π
    "zenith": (128, 256, 1.0, 40.0, 2.0),            # covers the pole: row 0 on both sides
    "sub-texel": (128, 256, 70.0, 300.0, 0.27),      # the real sun's size, < one texel
    "pole-edge": (128, 256, 0.5, 40.0, 0.7),         # its edge crosses the pole by 0.2°
    "fine": (256, 512, 30.0, 200.0, 1.0),
}


@pytest.mark.parametrize("name", CASES)
def test_sun_is_recovered(name):
    h, w, theta, phi, alpha = CASES[name]
    env, sky, cov, s = sun_map(h, w, theta, phi, alpha)
    residual, sun = envsun.split_sun(env)
    assert sun is not None
    omega = envmap.solid_angles(h, w)
    mask = envsun.find_sun_region(env).mask
    assert mask[cov > 0].all()                      # every texel the disc touches is removed
    # direction: within one texel's angular size π/H (the brief's bar)
    assert angle_deg(sun.direction, s) < 180.0 / h
    # irradiance: the map's own disc integral up to the fill's error (max principle) ...
    truth_map = SUN_RGB * (cov * omega).sum()
    bound = max_principle_bound(sky, mask, omega)
    assert np.all(np.abs(sun.irradiance_rgb - truth_map) <= bound + 1e-9 * truth_map)
    # ... and the closed form within the fixture's 0.3 % plus that bound
    exact = SUN_RGB * 2 * np.pi * (1 - np.cos(np.radians(alpha)))
    assert np.all(np.abs(sun.irradiance_rgb - exact) <= 3e-3 * exact + bound)
    assert bound.max() < 1e-3 * truth_map.min()     # the bound is tight enough to mean much
    # the residual near the sun holds no texel above the surrounding sky
    near = envsun.dilate(mask, 1)
    assert np.all(residual[mask] <= sky[near].max(axis=0) + 1e-12)
    assert np.array_equal(residual[~mask], env[~mask])
    assert sun.texels == int(mask.sum())
    assert sun.solid_angle_sr == pytest.approx(omega[mask].sum(), rel=1e-12)


@pytest.mark.parametrize("name", ["mid-sky", "zenith", "fine"])
def test_resolved_disc_has_its_diameter(name):
    # A disc wider than two texels fully covers some texel, whose net radiance is L: the
    # equivalent disc E_Y / L_peak is then the disc, up to the fixture's 0.3 % in E
    # (0.15 % in diameter) and the fill's error in L_peak (≤ the sky's range, 1e-4 of L).
    h, w, theta, phi, alpha = CASES[name]
    env, _, _, s = sun_map(h, w, theta, phi, alpha)
    _, sun = envsun.split_sun(env)
    assert sun.angular_diameter_deg == pytest.approx(2 * alpha, rel=2e-3)
    # its direction: the texel centres weighted by the areas covered average to the disc's
    # centre up to the grid's discreteness at the edge (measured ≤ 0.02 texel)
    assert angle_deg(sun.direction, s) < 0.05 * 180.0 / h


def test_sub_texel_sun_is_at_most_a_few_texels_across():
    # A 0.54° sun on a 1.4° texel grid cannot be resolved: its equivalent disc is about
    # the texel block it lands in, never smaller than the true disc
    h, w, theta, phi, alpha = CASES["sub-texel"]
    env, *_ = sun_map(h, w, theta, phi, alpha)
    _, sun = envsun.split_sun(env)
    assert 2 * alpha <= sun.angular_diameter_deg <= 2 * 2 * 180.0 / h


def test_energy_is_conserved_and_shares_add_up():
    h, w, theta, phi, alpha = CASES["mid-sky"]
    env, sky, cov, _ = sun_map(h, w, theta, phi, alpha)
    residual, sun = envsun.split_sun(env)
    omega = envmap.solid_angles(h, w)[..., None]
    total = (env * omega).sum(axis=(0, 1))
    assert np.allclose((residual * omega).sum(axis=(0, 1)) + sun.irradiance_rgb, total,
                       rtol=1e-13, atol=0)          # round-off only: residual + sun = map
    y_total = float(envsun.luminance(env * omega).sum())
    assert sun.flux_share == pytest.approx(sun.irradiance_rgb @ envsun.SRGB_LUMINANCE / y_total,
                                           rel=1e-12)
    # the fill holds the sky behind the removed texels
    mask = envsun.find_sun_region(env).mask
    fill = float(envsun.luminance(residual)[mask] @ omega[mask, 0]) / y_total
    assert sun.fill_share == pytest.approx(fill, rel=1e-12)
    assert 0 < sun.fill_share < 1e-3 * sun.flux_share


def test_setting_sun_on_the_horizon():
    # the lower part of the disc is behind the ground: the fill spans the sky/ground step
    h, w = 128, 256
    env, sky, cov, s = sun_map(h, w, 90.5, 250.0, 2.0, above_horizon=True)
    residual, sun = envsun.split_sun(env)
    omega = envmap.solid_angles(h, w)
    mask = envsun.find_sun_region(env).mask
    truth = SUN_RGB * (cov * omega).sum()
    bound = max_principle_bound(sky, mask, omega)   # here the sky-to-ground range
    assert np.all(np.abs(sun.irradiance_rgb - truth) <= bound)
    visible = (cov[..., None] * omega[..., None] * envmap.pixel_directions(h, w)).sum((0, 1))
    assert angle_deg(sun.direction, visible / np.linalg.norm(visible)) < 180.0 / h
    assert sun.theta_deg < 90.0 < np.degrees(np.arccos(s[1]))   # above the horizon, disc's centre below


def test_red_sun_on_blue_sky_takes_no_negative_blue():
    h, w = 128, 256
    env, sky, _, _ = sun_map(h, w, 75.0, 30.0, 1.0, rgb=[2.0e3, 4.0e2, 0.0])
    residual, sun = envsun.split_sun(env)
    omega = envmap.solid_angles(h, w)
    mask = envsun.find_sun_region(env).mask
    assert np.all(sun.irradiance_rgb >= 0.0) and np.all(residual >= 0.0)
    assert sun.irradiance_rgb[2] <= max_principle_bound(sky, mask, omega)[2]


def test_brightest_of_two_suns_is_taken():
    h, w = 128, 256
    env, sky, cov, s = sun_map(h, w, 50.0, 80.0, 1.5)
    dim = disc_coverage(h, w, envmap.spherical_to_direction(np.radians(70), np.radians(260)),
                        np.radians(1.5))
    env = env + dim[..., None] * 0.1 * SUN_RGB      # a tenth as bright, opposite side
    residual, sun = envsun.split_sun(env)
    assert angle_deg(sun.direction, s) < 180.0 / h
    assert np.array_equal(residual[dim > 0], env[dim > 0])   # the dim one stays in the map


def test_sun_on_a_black_sky():
    # sky level 0: every lit texel is above the threshold, the peak is ∞ × the sky
    h, w = 64, 128
    env, _, cov, s = sun_map(h, w, 40.0, 120.0, 3.0, sky=np.zeros((h, w, 3)))
    residual, sun = envsun.split_sun(env)
    assert sun.peak_to_sky == np.inf
    assert np.all(residual == 0.0)
    assert sun.flux_share == pytest.approx(1.0, rel=1e-12)
    assert angle_deg(sun.direction, s) < 180.0 / h


# --------------------------------------------------------------------- no sun --

def no_sun_reason(env) -> str:
    residual, sun = envsun.split_sun(env)
    assert sun is None
    assert np.array_equal(residual, env)
    return envsun.find_sun_region(env).reason


def test_clear_sky_without_sun_gives_none():
    assert "no texel is brighter" in no_sun_reason(smooth_sky(64, 128))


def test_overcast_and_black_maps_give_none():
    assert "no texel" in no_sun_reason(np.full((32, 64, 3), 0.7))
    assert "no texel" in no_sun_reason(np.zeros((32, 64, 3)))


def test_a_window_is_not_a_sun():
    # 50 × the sky over a cap of radius 10° (0.8 % of the sphere, below the 1 % the sky
    # level ignores): above the threshold, but 10° > MAX_SUN_RADIUS_DEG from its centre
    h, w = 128, 256
    env, *_ = sun_map(h, w, 80.0, 90.0, 10.0, rgb=[40.0, 40.0, 40.0])
    assert "not a small source" in no_sun_reason(env)


def test_lamps_of_an_interior_are_not_a_sun():
    # five equal lamps in five directions: the brightest holds ~20 % of their light
    h, w = 64, 128
    env = np.full((h, w, 3), 0.5)
    for k in range(5):
        d = envmap.spherical_to_direction(np.radians(20 + 25 * k), np.radians(72 * k))
        env = env + disc_coverage(h, w, d, np.radians(2.0))[..., None] * 1e3
    assert "several lights, no one sun" in no_sun_reason(env)


# --------------------------------------------------------------------- the sphere --

def test_labels_wrap_in_phi_and_meet_at_the_poles():
    h, w = 8, 16
    m = np.zeros((h, w), bool)
    m[4, 0] = m[5, w - 1] = True          # diagonal across the seam
    m[0, 3] = m[0, 11] = True             # both at the zenith
    m[h - 1, 2] = True                    # alone at the nadir
    labels, n = envsun.label_sphere(m)
    assert n == 3
    assert labels[4, 0] == labels[5, w - 1] != labels[0, 3] == labels[0, 11]


def test_dilate_crosses_the_seam_and_the_pole():
    m = np.zeros((8, 16), bool)
    m[0, 0] = True
    grown = envsun.dilate(m, 1)
    assert grown[0, 15] and grown[1, 15] and grown[1, 1]
    assert grown[0, 7] and grown[0, 8] and grown[0, 9]       # across the zenith: φ + π
    assert grown.sum() == 9


def test_harmonic_fill_keeps_a_constant_and_its_range():
    h, w = 32, 64
    mask = np.zeros((h, w), bool)
    mask[:3, 10:20] = True                # touches the pole
    mask[12:15, [0, 1, w - 1]] = True     # straddles the seam
    const = np.full((h, w, 3), 2.5)
    assert np.allclose(envsun.harmonic_fill(const, mask), 2.5, rtol=1e-12)
    rng = np.random.default_rng(7)
    env = rng.uniform(0.1, 3.0, (h, w, 3))
    filled = envsun.harmonic_fill(env, mask)
    ring = envsun.dilate(mask, 1) & ~mask
    assert np.array_equal(filled[~mask], env[~mask])
    assert np.all(filled[mask] >= env[ring].min(axis=0) - 1e-12)
    assert np.all(filled[mask] <= env[ring].max(axis=0) + 1e-12)


def test_luminance_weights_are_the_srgb_matrix():
    from gonio_cli.spectra import xyz_to_linear_srgb_matrix

    y_row = np.linalg.inv(xyz_to_linear_srgb_matrix())[1]   # RGB → Y
    assert np.allclose(envsun.SRGB_LUMINANCE, y_row, atol=1e-4)   # the standard's 4 decimals


# --------------------------------------------------------------------- bad input --

@pytest.mark.parametrize("value,shown", [(np.nan, "nan"), (np.inf, "inf"), (-0.5, "-0.5")])
def test_invalid_texels_are_input_errors(value, shown):
    env = smooth_sky(16, 32)
    env[3, 5, 1] = value
    env[9, 2, 0] = value
    with pytest.raises(InputError) as err:
        envsun.split_sun(env)
    message = str(err.value)
    assert "\n" not in message
    assert f"texel (row 3, col 5) is {shown}" in message and "2 texels" in message


@pytest.mark.parametrize("shape", [(16, 32), (16, 32, 4), (16, 1, 3), (0, 32, 3)])
def test_wrong_shapes_are_input_errors(shape):
    with pytest.raises(InputError, match=r"not \(H, W, 3\)"):
        envsun.split_sun(np.ones(shape))
