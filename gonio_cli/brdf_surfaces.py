"""The equations of the models for real surfaces that seed 000 and seed 004 lack: a
fabric's sheen and a tabulated angular colour (the models themselves, and their registry
entries, are in :mod:`gonio_cli.brdf`: ``sheen`` and ``tabulated-colour``).

- The "Charlie" sheen of Estevez & Kulla 2017 ("Production Friendly Microfacet Sheen
  BRDF", SIGGRAPH course *Physically Based Shading*): an inverted Gaussian-like
  distribution of fibres, D(θh) = (2 + 1/r) sin^(1/r) θh / (2π), with the visibility of
  Neubelt & Pettineo 2013 ("Crafting a Next-Gen Material Pipeline for The Order: 1886"),
  V = 1 / (4 (cos θi + cos θo − cos θi cos θo)), exactly as the glTF 2.0 extension
  ``KHR_materials_sheen`` defines them (its r is glTF's sheenRoughness², which the
  extension calls α_g): f_sheen = s(λ) D V.
- A table of colour over the half angle θh and the difference angle θd (Rusinkiewicz
  1998, "A New Change of Variables for Efficient BRDF Representation"), as X-Rite AxF's
  car-paint model holds one (AxF CPA2: a colour table over θh and θd that multiplies the
  flake and coat lobes). Seed 000 eq. 5 is one analytic form of such a colour shift,
  exp(c(λ)(1 − cos((θi + θo)/2))), a function of θd alone in plane; the table lets any
  smooth function of (θh, θd) take its place. Nodes in degrees, bilinear between them
  (hat functions), constant beyond the first and the last node.

Inputs as in :mod:`gonio_cli.brdf`: :class:`~gonio_cli.geometry.Cosines` (...,), spectra
(..., n_λ) wavelength last; values in sr⁻¹ without the cos θi factor.
"""

from __future__ import annotations

import numpy as np

from .geometry import Cosines

#: The parameters of ``tabulated-colour`` that are neither scalars nor spectra: the table
#: T (n_h, n_d, n_λ) and its nodes in degrees (:attr:`gonio_cli.brdf.Model.table_params`).
TABLE_PARAMS = ("colour_table", "theta_h_nodes_deg", "theta_d_nodes_deg")

#: F0 of the ``sheen`` model's specular lobe (a Torrance–Sparrow lobe, Schlick's Fresnel,
#: achromatic): a fibre's surface is a dielectric of index ~1.5 (polyester, nylon, silk
#: 1.53-1.57; wool 1.55), ((n − 1)/(n + 1))² = 0.04; its growth towards grazing is what
#: lifts a fabric's highlight at 60-70° (RGL cardboard: mean CIEDE2000 5.1 → 3.5).
FIBRE_F0 = np.array([0.04])

#: Floor of V's denominator 4 (1 − (1 − cos θi)(1 − cos θo)): it is 0 only when both
#: directions graze, where :func:`charlie_sheen` sets the lobe to 0 anyway.
V_FLOOR = 1e-300


def charlie_d(cos_theta_h, r) -> np.ndarray:
    """The Charlie sheen distribution (Estevez & Kulla 2017; glTF ``KHR_materials_sheen``),
    in sr⁻¹: D = (2 + 1/r) sin^(1/r) θh / (2π).

    ``cos_theta_h``: (...,); ``r`` in (0, 1] the sheen roughness (glTF's sheenRoughness²).
    Normalised so that ∫ D cos θh dω = (2 + 1/r) ∫₀^{π/2} sin^(1/r + 1) θ cos θ dθ = 1 over
    the hemisphere; 0 at θh = 0 (the fibres seen end on), peaked at θh = 90°.
    """
    ch = np.clip(np.asarray(cos_theta_h, dtype=float), 0.0, 1.0)
    inv = 1.0 / float(r)
    sin_h = np.sqrt((1.0 - ch) * (1.0 + ch))
    return (2.0 + inv) * sin_h ** inv / (2.0 * np.pi)


def sheen_visibility(cos_theta_i, cos_theta_o) -> np.ndarray:
    """Neubelt & Pettineo's visibility as glTF ``KHR_materials_sheen`` uses it:
    V = 1 / (4 (cos θi + cos θo − cos θi cos θo)) (...,). The denominator is
    4 (1 − (1 − cos θi)(1 − cos θo)) ≥ 4 max(cos θi, cos θo): finite unless both are 0."""
    ci = np.clip(np.asarray(cos_theta_i, dtype=float), 0.0, 1.0)
    co = np.clip(np.asarray(cos_theta_o, dtype=float), 0.0, 1.0)
    return 1.0 / (4.0 * np.maximum(ci + co - ci * co, V_FLOOR))


def charlie_sheen(cos: Cosines, r, grazing: float) -> np.ndarray:
    """D V (...,) in sr⁻¹: the sheen lobe whose colour s(λ) multiplies it
    (f_sheen = s(λ) D V, glTF ``KHR_materials_sheen``); 0 where either cosine is at most
    ``grazing`` (:data:`gonio_cli.brdf.COS_EPS`, as the GGX lobe). Reciprocal: D depends
    on θh, V is symmetric in θi, θo."""
    ci, co = cos.cos_theta_i, cos.cos_theta_o
    valid = ~((ci <= grazing) | (co <= grazing))   # NaN cosines stay NaN, not 0
    return np.where(valid, charlie_d(cos.cos_theta_h, r) * sheen_visibility(ci, co), 0.0)


def half_difference_deg(cos: Cosines) -> tuple[np.ndarray, np.ndarray]:
    """(θh, θd) in degrees (...,) each: Rusinkiewicz's half and difference angles."""
    th = np.degrees(np.arccos(np.clip(np.asarray(cos.cos_theta_h, dtype=float), -1.0, 1.0)))
    td = np.degrees(np.arccos(np.clip(np.asarray(cos.cos_theta_d, dtype=float), -1.0, 1.0)))
    return th, td


def hat_weights(x, nodes) -> np.ndarray:
    """Linear interpolation weights (..., n) of ``x`` (...,) on increasing ``nodes`` (n,):
    two neighbours share 1, a value outside the nodes takes the end node's (constant
    extrapolation); NaN gives NaN weights. Σ weights = 1."""
    x = np.asarray(x, dtype=float)
    nodes = np.asarray(nodes, dtype=float)
    n = nodes.size
    if n == 1:
        return np.where(np.isnan(x), np.nan, 1.0)[..., None]
    xc = np.clip(x, nodes[0], nodes[-1])
    j = np.clip(np.searchsorted(nodes, xc, side="right") - 1, 0, n - 2)
    j = np.where(np.isnan(x), 0, j)
    t = (xc - nodes[j]) / (nodes[j + 1] - nodes[j])
    w = np.zeros(x.shape + (n,))
    np.put_along_axis(w, j[..., None], (1.0 - t)[..., None], axis=-1)
    np.put_along_axis(w, (j + 1)[..., None], t[..., None], axis=-1)
    return w


def table_weights(cos: Cosines, theta_h_nodes_deg, theta_d_nodes_deg) -> np.ndarray:
    """Bilinear weights (..., n_h, n_d) of the table's nodes at each configuration:
    T(θh, θd, λ) = Σ_ab weights[..., a, b] T[a, b, λ] (the fit's design columns)."""
    th, td = half_difference_deg(cos)
    wh = hat_weights(th, theta_h_nodes_deg)
    wd = hat_weights(td, theta_d_nodes_deg)
    return wh[..., :, None] * wd[..., None, :]


def table_colour(cos: Cosines, colour_table, theta_h_nodes_deg,
                 theta_d_nodes_deg) -> np.ndarray:
    """T(θh, θd, λ) (..., n_λ): the table (n_h, n_d, n_λ) interpolated bilinearly at each
    configuration's (θh, θd) (:func:`table_weights`)."""
    w = table_weights(cos, theta_h_nodes_deg, theta_d_nodes_deg)
    return np.einsum("...ab,abl->...l", w, np.asarray(colour_table, dtype=float))
