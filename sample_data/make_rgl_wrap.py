"""Make the synthetic RGL ``.bsdf`` samples: a known BRDF written as Mitsuba tensor files.

No file of the RGL material database is shipped (their licence is not ours to grant, and
the tests run offline), so these stand in for one: the layout is the database's (the
fields Mitsuba's ``measured`` plugin reads, ``src/bsdfs/measured.cpp``), the values a
known analytic BRDF, gonio's ``goniochromatic-diffuse`` model (seed 000 eq. 5 plus a
Lambertian term) with the parameters below, a colour-shifting "wrap".

The warps are trivial: ``vndf``, ``luminance``, ``ndf`` and ``sigma`` are constant, so
Mitsuba's VNDF warp is the identity and the table is looked up directly at the half
vector's unit coordinates (u_θ, u_φ) = (√(2θm/π), (φm − φi + π)/2π), φ relative to the
light (isotropic: one ``phi_i``). Each table entry holds what the plugin's ``eval``
returns, f·cos θo (Mitsuba's convention), for ωo the mirror of ωi about the half vector
(0 below the horizon). Isotropic, θi nodes 10…70° by 10° (Mitsuba holds the end rows
beyond them), 23 × 23 (u_φ, u_θ) nodes: odd, so u_φ = ½ (the in-plane half vectors on the
light's side of the mirror direction) is a node, as is u_φ = 0 (the far side).

- ``rgl_wrap_spec.bsdf``: spectral, 380–780 nm by 50 nm (9 wavelengths), ``jacobian`` 0.
- ``rgl_wrap_rgb.bsdf``: RGB (linear sRGB channels with their own parameters), ``jacobian``
  1 with ``ndf`` = 2 and ``sigma`` = 1/4, so the plugin multiplies the table by
  ndf / (4 sigma) = 2 and the table holds f·cos θo / 2.

Between nodes Mitsuba interpolates linearly (in u_θ, u_φ, θi and λ), so the file encodes
the model exactly at the nodes and its piecewise-linear interpolant between them; the
coarse u_θ spacing costs up to ~18 % near grazing (tests/test_rgl.py checks both). The
sizes keep the files small (~170 and ~80 kB). Run
``python sample_data/make_rgl_wrap.py [FOLDER]`` from the top of the clone; the files are
rewritten byte for byte (into sample_data/ unless FOLDER is given).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))  # the clone, when run as a script

from gonio_cli.brdf import evaluate  # noqa: E402
from gonio_cli.geometry import cosines  # noqa: E402
from gonio_cli.ingest.tensorfile import write_tensor_file  # noqa: E402

MODEL = "goniochromatic-diffuse"
ALPHA = 0.3

#: Table nodes: θi (degrees), the (u_φ, u_θ) resolution, the spectral file's wavelengths.
THETA_I_DEG = np.arange(10.0, 71.0, 10.0)
RESOLUTION = 23
WAVELENGTH_NM = np.arange(380.0, 781.0, 50.0)

#: The RGB file's per-channel parameters (R, G, B).
RGB_PARAMS = {"alpha": ALPHA, "rho": np.array([0.30, 0.25, 0.08]),
              "c": np.array([2.0, 0.0, -2.0]), "rho_d": np.array([0.03, 0.05, 0.10])}

#: The RGB file's jacobian factor ndf / (4 sigma) (module docstring).
RGB_NDF, RGB_SIGMA = 2.0, 0.25


def spectral_params(wavelength_nm) -> dict:
    """The spectral file's parameters at ``wavelength_nm`` (n,): a green-yellow structural
    colour ρ whose colour shifts to red at large angles (c rising with λ) over a bluish
    diffuse base ρ_d."""
    w = np.asarray(wavelength_nm, dtype=float)
    return {"alpha": ALPHA,
            "rho": 0.05 + 0.35 * np.exp(-((w - 560.0) / 60.0) ** 2),
            "c": 4.0 * (w - 580.0) / 200.0,
            "rho_d": 0.04 + 0.06 * np.exp(-((w - 450.0) / 50.0) ** 2)}


def u_nodes() -> np.ndarray:
    """(RESOLUTION,) unit coordinates of the table's nodes, 0…1 on both axes."""
    return np.linspace(0.0, 1.0, RESOLUTION)


def table(params: dict) -> np.ndarray:
    """f·cos θo of the model at every node: (n_θi, n_channels, n_uφ, n_uθ) float64.

    The half vector of node (u_φ, u_θ) has θm = u_θ² π/2 and φm = (2u_φ − 1)π relative to
    the light (measured.cpp's u2theta, u2phi); ωo = 2(ωi·m)m − ωi.
    """
    ti = np.radians(THETA_I_DEG)[:, None, None]
    u = u_nodes()
    theta_m = (u ** 2 * np.pi / 2)[None, None, :]
    phi_m = ((2 * u - 1) * np.pi)[None, :, None]
    shape = np.broadcast_shapes(ti.shape, theta_m.shape, phi_m.shape)
    wi = np.stack(np.broadcast_arrays(np.sin(ti), 0 * ti, np.cos(ti)), axis=-1)
    wi = np.broadcast_to(wi, shape + (3,))
    m = np.stack(np.broadcast_arrays(np.sin(theta_m) * np.cos(phi_m),
                                     np.sin(theta_m) * np.sin(phi_m),
                                     np.cos(theta_m) + 0 * phi_m), axis=-1)
    m = np.broadcast_to(m, shape + (3,))
    wo = 2 * np.sum(wi * m, axis=-1, keepdims=True) * m - wi
    above = wo[..., 2] > 0
    f = evaluate(MODEL, cosines(wi, wo), params)          # (n_θi, n_uφ, n_uθ, n_channels)
    value = np.where(above[..., None], f * np.maximum(wo[..., 2], 0.0)[..., None], 0.0)
    return np.moveaxis(value, -1, 1)


def fields(values: np.ndarray, **extra) -> dict:
    """The tensor file's fields around a (n_θi, n_c, n, n) table of values."""
    n_ti, _, n, _ = values.shape
    ones = np.ones((1, n_ti, n, n), np.float32)
    out = {"description": "gonio synthetic wrap (sample_data/make_rgl_wrap.py)",
           "jacobian": np.array([0], np.uint8),
           "theta_i": np.radians(THETA_I_DEG).astype(np.float32),
           "phi_i": np.array([0.0], np.float32),
           "ndf": np.ones((n, n), np.float32), "sigma": np.ones((n, n), np.float32),
           "vndf": ones, "luminance": ones}
    out.update(extra)
    return out


def main(folder: Path = HERE) -> None:
    """Write ``rgl_wrap_spec.bsdf`` and ``rgl_wrap_rgb.bsdf`` into ``folder``."""
    folder = Path(folder)
    spec = table(spectral_params(WAVELENGTH_NM))[None].astype(np.float32)
    write_tensor_file(folder / "rgl_wrap_spec.bsdf",
                      fields(spec[0], wavelengths=WAVELENGTH_NM.astype(np.float32),
                             spectra=spec))
    factor = RGB_NDF / (4 * RGB_SIGMA)
    rgb = (table(RGB_PARAMS)[None] / factor).astype(np.float32)
    n = RESOLUTION
    write_tensor_file(folder / "rgl_wrap_rgb.bsdf",
                      fields(rgb[0], rgb=rgb, jacobian=np.array([1], np.uint8),
                             ndf=np.full((n, n), RGB_NDF, np.float32),
                             sigma=np.full((n, n), RGB_SIGMA, np.float32)))


if __name__ == "__main__":
    main(*sys.argv[1:2])
