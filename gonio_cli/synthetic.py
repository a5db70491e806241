"""Synthetic measurements from known parameters: the ground truth of tests and benchmarks.

Geometry follows seed 000's goniometer (θi = 20…70°, a θo sweep on both sides, the light's
side only from θi = 40° on, nothing within 10° of retro-reflection where the detector
would block the source); spectra follow the shape of seed 000 Figure 4 (a reflectance
band in the ink's colour, c larger below the band: the colour shifts to shorter
wavelengths at grazing angles). Noise is multiplicative log-normal, as a spectrometer's.
"""

from __future__ import annotations

import numpy as np

from .brdf import evaluate
from .geometry import measurement_cosines
from .schemas import Measurement
from .spectra import parse_grid

#: Seed 000's angles of incidence (degrees).
PAPER_THETA_I_DEG = (20.0, 30.0, 40.0, 50.0, 60.0, 65.0, 70.0)

#: Half-width (deg) around retro-reflection (θo = −θi) where the detector shadows the light.
RETRO_BLOCK_DEG = 10.0

#: Centre wavelength (nm) of each ink's reflectance band.
INK_PEAK_NM = {"red": 630.0, "green": 540.0, "blue": 460.0}


def paper_geometry(step_deg: float = 5.0, theta_i_deg=PAPER_THETA_I_DEG,
                   theta_o_max_deg: float = 80.0, near_side_from_deg: float = 40.0):
    """In-plane configurations (θi, θo) in degrees, each (N,)."""
    ti_all, to_all = [], []
    for ti in theta_i_deg:
        lo = -theta_o_max_deg if ti >= near_side_from_deg else 0.0
        for to in np.arange(lo, theta_o_max_deg + 1e-9, step_deg):
            if abs(to + ti) < RETRO_BLOCK_DEG:
                continue
            ti_all.append(ti)
            to_all.append(to)
    return np.array(ti_all, dtype=float), np.array(to_all, dtype=float)


def ink_spectra(ink: str = "red", grid_nm=None):
    """(ρ(λ), c(λ)) of a structural-colour ink, shaped like seed 000 Figure 4. (L,) each."""
    wl = parse_grid() if grid_nm is None else np.asarray(grid_nm, dtype=float)
    peak = INK_PEAK_NM[ink]
    rho = 0.02 + 0.25 * np.exp(-0.5 * ((wl - peak) / 40.0) ** 2)
    c = 1.0 + 2.5 * (1.0 + np.tanh((peak - 20.0 - wl) / 40.0))
    return rho, c


def synthetic_measurement(model: str, params: dict, theta_i_deg, theta_o_deg,
                          grid_nm=None, noise: float = 0.02, seed: int = 0,
                          repeats: int = 1, phi_o_deg=None) -> Measurement:
    """A :class:`Measurement` of a registered model with multiplicative noise.

    ``noise`` is the standard deviation of log(value) per reading; with ``repeats`` > 1
    each configuration is read that many times and averaged, with its sample std kept.
    ``phi_o_deg`` (one per configuration, or None in plane) places the detector out of the
    plane of incidence (docs/conventions.md).
    """
    wl = parse_grid() if grid_nm is None else np.asarray(grid_nm, dtype=float)
    f = evaluate(model, measurement_cosines(theta_i_deg, theta_o_deg, phi_o_deg), params)
    rng = np.random.default_rng(seed)
    reads = f[None] * np.exp(noise * rng.standard_normal((repeats,) + f.shape))
    std = reads.std(axis=0, ddof=1) if repeats > 1 else None
    return Measurement(wl, theta_i_deg, theta_o_deg, reads.mean(axis=0), std,
                       np.full(np.shape(theta_i_deg), repeats), "brdf",
                       {"synthetic": {"model": model, "noise": noise, "seed": seed}},
                       None if phi_o_deg is None else np.broadcast_to(
                           np.asarray(phi_o_deg, dtype=float), np.shape(theta_i_deg)))
