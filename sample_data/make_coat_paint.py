"""Regenerate ``coat_paint.csv``: a synthetic clear-coated blue paint with known truth.

A blue paint under a clear coat, as a car's: gonio's ``goniochromatic-coat`` model
(:func:`gonio_cli.brdf.goniochromatic_coat`: a Lambertian body, seed 000 eq. 5's lobe
and an achromatic GGX coat of index 1.5, F0 = 0.04) with the parameters below, measured in
plane as a goniometer would with a sharp peak in mind: θi = 15 … 75° by 15°, θo every
5° from −80 to 85° and at 0.5, 1, 2, 3 and 5° either side of the mirror direction, BRDF in
sr⁻¹ with 1 % multiplicative noise (σ of log). The demo fits it back
(``pipelines/carpaint.mk``) and renders it under a real sky (``sample_data/scenes/
paint_sky.toml``); the true parameters stand in the file's header.

    python sample_data/make_coat_paint.py           # into sample_data/
    python sample_data/make_coat_paint.py DIR       # elsewhere (the CSV byte for byte)

It also writes ``scenes/floor.material.json``, the grey concrete floor of the demo's
scenes: a material made from known parameters, not fitted (Cook–Torrance, seed 004
eq. 11, kd 0.3 flat, a faint broad sheen).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from gonio_cli.brdf import goniochromatic_coat
from gonio_cli.geometry import in_plane_cosines

SEED = 2026
WAVELENGTH_NM = np.arange(380.0, 781.0, 10.0)
THETA_I_DEG = (15.0, 30.0, 45.0, 60.0, 75.0)
#: Offsets from the mirror angle where a goniometer looks closer (degrees).
NEAR_MIRROR_DEG = (0.0, 0.5, 1.0, 2.0, 3.0, 5.0)
NOISE_SIGMA = 0.01


def gaussian(peak_nm: float, width_nm: float) -> np.ndarray:
    return np.exp(-0.5 * ((WAVELENGTH_NM - peak_nm) / width_nm) ** 2)


#: The truth: a deep blue body, a blue-violet eq. 5 flake lobe shifting to cyan at grazing
#: angles (c < 0 below 480 nm, > 0 above), and a smooth clear coat.
TRUTH = {
    "alpha": 0.3,
    "rho": 0.02 + 0.35 * gaussian(455.0, 35.0),
    "c": np.interp(WAVELENGTH_NM, [380.0, 480.0, 780.0], [-1.0, 0.5, 2.0]),
    "rho_d": 0.015 + 0.22 * gaussian(465.0, 40.0),
    "alpha_coat": 0.02,
    "k_coat": 1.0,
    "f0_coat": 0.04,
}


def configurations() -> tuple[np.ndarray, np.ndarray]:
    ti, to = [], []
    for t in THETA_I_DEG:
        near = {round(t + s * d, 1) for d in NEAR_MIRROR_DEG for s in (-1, 1)}
        grid = set(np.arange(-80.0, 85.01, 5.0).round(1)) | near
        for o in sorted(x for x in grid if -85.0 < x < 88.0 and abs(x + t) >= 10.0):
            ti.append(t)
            to.append(o)
    return np.array(ti), np.array(to)


#: The floor: matte grey with a faint, broad sheen (Cook–Torrance, seed 004 eq. 11).
FLOOR = {"kd": 0.30, "ks": 0.02, "m": 0.35, "f0": 0.04}


def write_floor(path: Path) -> None:
    from gonio_cli.schemas import Material, write_material

    n = WAVELENGTH_NM.size
    write_material(path, Material("cook-torrance", WAVELENGTH_NM,
                                  {k: np.full(n, v) for k, v in FLOOR.items()},
                                  fit={"final": "hand-made: sample_data/make_coat_paint.py"}),
                   parameters={"made_by": "sample_data/make_coat_paint.py", **FLOOR})


def main(folder: Path) -> Path:
    ti, to = configurations()
    f = goniochromatic_coat(in_plane_cosines(ti, to), **TRUTH)
    rng = np.random.default_rng(SEED)
    f = f * np.exp(NOISE_SIGMA * rng.standard_normal(f.shape))
    truth = ", ".join(f"{k} {v:g}" for k, v in TRUTH.items() if np.ndim(v) == 0)
    lines = ["# gonio sample data (synthetic): a clear-coated blue paint, goniochromatic-coat "
             f"({truth}; rho, c, rho_d in make_coat_paint.py); quantity brdf (sr^-1), "
             f"{NOISE_SIGMA:.0%} noise",
             "# regenerate with: python sample_data/make_coat_paint.py",
             "theta_i_deg,theta_o_deg,wavelength_nm,value"]
    for k in range(ti.size):
        for j, wl in enumerate(WAVELENGTH_NM):
            lines.append(f"{ti[k]:g},{to[k]:g},{wl:g},{f[k, j]:.6g}")
    path = folder / "coat_paint.csv"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    (folder / "scenes").mkdir(exist_ok=True)
    write_floor(folder / "scenes" / "floor.material.json")
    return path


if __name__ == "__main__":
    print(main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent))
