"""Make ``sample_data/sky.exr``: a small, deterministic, physically plausible HDR sky.

256 × 128 lat-long map (docs/conventions.md: Mitsuba 3 ``envmap`` layout, +y up, row 0 the zenith),
linear sRGB radiance:

- sky: blue zenith brightening towards a whiter horizon (a Perez-like gradient), with a
  circumsolar glow (forward scattering around the sun);
- sun: a disc of 0.6° radius (larger than the real 0.27° so that it covers most of a texel at
  this size) of radiance SUN_TO_SKY × the mean sky radiance, at 35° elevation; its edge is
  anti-aliased by SUPERSAMPLE² samples per texel, so the total sun power does not depend on
  where the disc falls on the grid;
- ground: a grey-brown Lambertian plane of albedo GROUND_ALBEDO lit by the sun and the sky,
  radiance = albedo × irradiance / π, slightly darker towards the nadir.

Run: ``python sample_data/make_sky.py [OUT.exr]`` (default ``sample_data/sky.exr``).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from gonio_cli import envmap
from gonio_cli.imageio import write_exr

WIDTH, HEIGHT = 256, 128
#: Sun radiance over the mean sky radiance (the target's "about 1e5").
SUN_TO_SKY = 1.0e5
SUN_RADIUS_DEG = 0.6
SUN_ELEVATION_DEG = 35.0
SUN_AZIMUTH_DEG = 120.0
#: Samples per texel side used to anti-alias the sun's disc.
SUPERSAMPLE = 8
GROUND_ALBEDO = np.array([0.22, 0.18, 0.14])
ZENITH_RGB = np.array([0.25, 0.45, 1.0])
HORIZON_RGB = np.array([0.85, 0.9, 1.0])
SUN_RGB = np.array([1.0, 0.95, 0.86])


def sun_direction() -> np.ndarray:
    return envmap.spherical_to_direction(np.radians(90.0 - SUN_ELEVATION_DEG),
                                         np.radians(SUN_AZIMUTH_DEG))


def sky_radiance(directions: np.ndarray) -> np.ndarray:
    """(..., 3) radiance of the clear sky above the horizon (no sun disc)."""
    up = np.clip(directions[..., 1], 0.0, 1.0)[..., None]
    gradient = HORIZON_RGB + (ZENITH_RGB - HORIZON_RGB) * np.sqrt(up)
    cos_gamma = np.clip(directions @ sun_direction(), -1.0, 1.0)[..., None]
    glow = 1.0 + 2.0 * np.exp(-3.0 * np.arccos(cos_gamma)) + 0.3 * cos_gamma ** 2
    return gradient * glow


def sun_fraction() -> np.ndarray:
    """(H, W) fraction of each texel covered by the sun's disc (supersampled)."""
    offsets = (np.arange(SUPERSAMPLE) + 0.5) / SUPERSAMPLE - 0.5
    theta = np.pi * (np.arange(HEIGHT)[:, None] + 0.5 + offsets[None, :]) / HEIGHT
    phi = 2 * np.pi * (np.arange(WIDTH)[:, None] + 0.5 + offsets[None, :]) / WIDTH
    d = envmap.spherical_to_direction(theta[:, None, :, None], phi[None, :, None, :])
    inside = d @ sun_direction() > np.cos(np.radians(SUN_RADIUS_DEG))
    # weight sub-samples by sin θ (their solid angle) within each texel
    weight = np.sin(theta)[:, None, :, None]
    return (inside * weight).sum(axis=(2, 3)) / weight.sum(axis=(2, 3))


def make_sky() -> np.ndarray:
    """(HEIGHT, WIDTH, 3) float32 radiance."""
    d = envmap.pixel_directions(HEIGHT, WIDTH)
    omega = envmap.solid_angles(HEIGHT, WIDTH)
    above = d[..., 1] > 0.0
    sky = np.where(above[..., None], sky_radiance(d), 0.0)
    mean_sky = (sky * omega[..., None])[above].sum(0) / omega[above].sum()
    sun_l = SUN_TO_SKY * mean_sky.mean() * SUN_RGB
    frac = sun_fraction() * above
    sky = sky * (1.0 - frac[..., None]) + frac[..., None] * sun_l
    # irradiance on the horizontal ground from everything above it: ∫ L cos θ dω
    irradiance = (sky * (omega * np.clip(d[..., 1], 0.0, None))[..., None]).sum((0, 1))
    ground = GROUND_ALBEDO * irradiance / np.pi
    shade = 0.8 + 0.2 * (1.0 - np.clip(-d[..., 1], 0.0, 1.0))[..., None]  # darker at nadir
    return np.where(above[..., None], sky, ground * shade).astype(np.float32)


#: The header date of the tracked ``sky.exr`` (2026-11-23 15:42:23 UTC), written again on
#: every run so that the script reproduces the tracked file byte for byte (the writer
#: would otherwise stamp the current time).
SKY_DATE_EPOCH = 1795448543


def main() -> None:
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).with_name("sky.exr")
    write_exr(out, make_sky(), {"source": "sample_data/make_sky.py",
                                "sun_to_sky": SUN_TO_SKY}, source_date_epoch=SKY_DATE_EPOCH)
    print(out)


if __name__ == "__main__":
    main()
