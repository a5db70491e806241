"""Geometry shared by every stage: directions, half vector and the cosines BRDFs use.

Conventions (``docs/conventions.md``): the sample normal is +z; the light is at polar angle
θi on the −x side, ωi = (−sin θi, 0, cos θi); the detector is at a signed in-plane angle
θo, ωo = (sin θo, 0, cos θo), so θo = θi is the mirror configuration and θo < 0 is the
light's side. Out of the plane of incidence the detector has an azimuth φo from the plane,
ωo = (sin θo cos φo, sin θo sin φo, cos θo) (φo = 0 is the in-plane form exactly), written
canonically (:func:`canonical_azimuth`). Angles are degrees at the boundary, radians and
cosines in here.

Every BRDF in :mod:`gonio_cli.brdf` is written in the four cosines of :class:`Cosines`,
so the fit (in-plane data) and the renderer (arbitrary 3-D directions) share one code path.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

#: Below this norm ωi + ωo is treated as zero (ωo = −ωi, the retro-grazing limit), where
#: the half vector is undefined; we then return the normal (cos θh = 1 would be wrong too,
#: but such pairs have cos θi = cos θo = 0 and every model here is zero or clamped there).
HALF_VECTOR_EPS = 1e-12


class Cosines(NamedTuple):
    """The cosines a BRDF needs, each of shape (...,), clamped to [0, 1].

    cos_theta_i : n·ωi ; cos_theta_o : n·ωo ; cos_theta_h : n·ωh (seed 000 eq. 1) ;
    cos_theta_d : ωi·ωh, the angle between light and half vector (Fresnel's angle).
    """

    cos_theta_i: np.ndarray
    cos_theta_o: np.ndarray
    cos_theta_h: np.ndarray
    cos_theta_d: np.ndarray


def in_plane_directions(theta_i_deg, theta_o_deg) -> tuple[np.ndarray, np.ndarray]:
    """ωi and ωo (..., 3) of in-plane goniometer configurations (docs/conventions.md)."""
    ti = np.radians(np.asarray(theta_i_deg, dtype=float))
    to = np.radians(np.asarray(theta_o_deg, dtype=float))
    ti, to = np.broadcast_arrays(ti, to)
    zero = np.zeros_like(ti)
    wi = np.stack([-np.sin(ti), zero, np.cos(ti)], axis=-1)
    wo = np.stack([np.sin(to), zero, np.cos(to)], axis=-1)
    return wi, wo


#: Below this |φo| (degrees) a configuration is in the plane of incidence.
AZIMUTH_TOL_DEG = 1e-6


def measurement_directions(theta_i_deg, theta_o_deg, phi_o_deg=None
                           ) -> tuple[np.ndarray, np.ndarray]:
    """ωi and ωo (..., 3) of goniometer configurations in or out of the plane of incidence.

    ωi = (−sin θi, 0, cos θi) and ωo = (sin θo cos φo, sin θo sin φo, cos θo)
    (docs/conventions.md, "Out of the plane of incidence"). ``phi_o_deg`` None (or 0)
    gives :func:`in_plane_directions` exactly, θo signed.
    """
    if phi_o_deg is None:
        return in_plane_directions(theta_i_deg, theta_o_deg)
    ti = np.radians(np.asarray(theta_i_deg, dtype=float))
    to = np.radians(np.asarray(theta_o_deg, dtype=float))
    po = np.radians(np.asarray(phi_o_deg, dtype=float))
    ti, to, po = np.broadcast_arrays(ti, to, po)
    zero = np.zeros_like(ti)
    wi = np.stack([-np.sin(ti), zero, np.cos(ti)], axis=-1)
    st = np.sin(to)
    wo = np.stack([st * np.cos(po), st * np.sin(po), np.cos(to)], axis=-1)
    return wi, wo


def measurement_cosines(theta_i_deg, theta_o_deg, phi_o_deg=None) -> Cosines:
    """:class:`Cosines` of configurations (θi, θo, φo) in degrees; ``phi_o_deg`` None is
    in plane (:func:`in_plane_cosines`, bit for bit). The one place a measurement's
    configurations become the cosines every model, fit, eval and export takes."""
    return cosines(*measurement_directions(theta_i_deg, theta_o_deg, phi_o_deg))


def canonical_azimuth(theta_o_deg, phi_o_deg) -> tuple[np.ndarray, np.ndarray]:
    """(θo, φo) in degrees spelled one way per detector direction (docs/conventions.md).

    φo is wrapped to (−180°, 180°]; a detector in the plane (φo = 0 or 180°) is written
    φo = 0 with θo signed (180° → −θo, today's in-plane form); out of the plane θo ≥ 0
    (θo < 0 at φo becomes −θo at φo ± 180°); at θo = 0 (the normal) φo is 0.
    """
    to = np.array(theta_o_deg, dtype=float, copy=True)
    po = np.asarray(phi_o_deg, dtype=float)
    to, po = np.broadcast_arrays(to, po)
    to, po = to.copy(), po.copy()
    flip = to < 0
    to[flip] = -to[flip]
    po[flip] = po[flip] + 180.0
    po = 180.0 - np.mod(180.0 - po, 360.0)                  # (−180, 180]
    back = np.abs(np.abs(po) - 180.0) <= AZIMUTH_TOL_DEG
    to[back] = -to[back]
    po[back | (np.abs(po) <= AZIMUTH_TOL_DEG) | (to == 0)] = 0.0
    return to, po


def reciprocal_configuration(theta_i_deg, theta_o_deg, phi_o_deg=None):
    """(θi', θo', φo') of the reverse configurations (light and detector swapped), canonical.

    Out of the plane (θo ≥ 0) the reverse of (θi, θo, φo) is (θo, θi, φo); in the plane
    (φo = 0, θo signed) that of (θi, θo) is (|θo|, θi · sign θo), as before: the
    detector at θo < 0 is at azimuth 180° and the swapped detector keeps that azimuth.
    ``phi_o_deg`` None gives None for φo'. For an isotropic BRDF f is the same at both.
    """
    ti = np.asarray(theta_i_deg, dtype=float)
    to = np.asarray(theta_o_deg, dtype=float)
    po = np.zeros_like(to) if phi_o_deg is None else np.asarray(phi_o_deg, dtype=float)
    ti, to, po = np.broadcast_arrays(ti, to, po)
    azimuth = np.where(to < 0, po + 180.0, po)
    ro, rp = canonical_azimuth(ti, azimuth)
    return np.abs(to), ro, (None if phi_o_deg is None else rp)


def half_vector(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """ωh = (ωi + ωo) / ‖ωi + ωo‖, seed 000 eq. (1); (..., 3) unit vectors in and out."""
    s = np.asarray(wi, dtype=float) + np.asarray(wo, dtype=float)
    norm = np.linalg.norm(s, axis=-1, keepdims=True)
    safe = ~(norm <= HALF_VECTOR_EPS)  # NaN stays NaN (propagates), never becomes +z
    n = np.zeros_like(s)
    n[..., 2] = 1.0
    return np.where(safe, s / np.where(safe, norm, 1.0), n)


#: ‖ωi + ωo‖² = 2 + 2 ωi·ωo below this is treated as ωo = −ωi, where the half vector is
#: undefined and the normal stands in for it (cos θh = 1, cos θd = cos θi). ωi·ωo carries
#: ~1e-16 round-off, so the square means nothing below ~1e-12 (|ωi + ωo| < 1e-6); such a
#: pair has cos θi ≈ −cos θo, so it is never lit and seen at once and its value is unused.
HALF_SQ_EPS = 1e-12


def cosines_from_dots(cos_i, cos_o, cos_io) -> Cosines:
    """:class:`Cosines` from the three dot products N·ωi, N·ωo and ωi·ωo (each (...,)).

    With the half vector of seed 000 eq. (1), ωh = (ωi + ωo)/‖ωi + ωo‖ and
    ‖ωi + ωo‖² = 2 + 2 ωi·ωo: N·ωh = (N·ωi + N·ωo)/‖ωi + ωo‖ and
    ωi·ωh = (1 + ωi·ωo)/‖ωi + ωo‖. The renderer calls it with one light direction per
    light (two matrix–vector products instead of (n, 3) arrays). :func:`cosines` forms the
    half vector instead: at the mirror configuration it gives cos θh = 1 exactly, where
    this form is off by ~1e-16, which a near-mirror GGX lobe (α ~ 1e-3) in a fit amplifies.
    NaN inputs give NaN, never a finite value.
    """
    cos_i = np.asarray(cos_i, dtype=float)
    cos_o = np.asarray(cos_o, dtype=float)
    sq = 2.0 + 2.0 * np.asarray(cos_io, dtype=float)
    safe = ~(sq <= HALF_SQ_EPS)                       # NaN stays NaN
    inv = 1.0 / np.sqrt(np.where(safe, sq, 1.0))
    cos_h = np.where(safe, (cos_i + cos_o) * inv, 1.0)
    cos_d = np.where(safe, (1.0 + cos_io) * inv, cos_i)
    clip = lambda v: np.clip(v, 0.0, 1.0)  # noqa: E731
    return Cosines(clip(cos_i), clip(cos_o), clip(cos_h), clip(cos_d))


def refracted_cosines(cos: Cosines, n: float) -> Cosines:
    """The :class:`Cosines` of both directions refracted into a smooth layer of index ``n``
    (Snell: sin θ' = sin θ / n, the azimuths kept), from the four cosines alone.

    The tangential parts of ωi and ωo shrink by 1/n, so ωi'·ωo' = (ωi·ωo − cos θi cos θo)/n²
    + cos θi' cos θo', with ωi·ωo = 2 cos²θd − 1 (θd is half the angle between them); then
    :func:`cosines_from_dots`. Shape (...,) as the input's.
    """
    ci = np.clip(np.asarray(cos.cos_theta_i, dtype=float), 0.0, 1.0)
    co = np.clip(np.asarray(cos.cos_theta_o, dtype=float), 0.0, 1.0)
    cd = np.asarray(cos.cos_theta_d, dtype=float)
    inv_n2 = 1.0 / (float(n) * float(n))
    ci_r = np.sqrt(1.0 - (1.0 - ci * ci) * inv_n2)
    co_r = np.sqrt(1.0 - (1.0 - co * co) * inv_n2)
    dot = (2.0 * cd * cd - 1.0 - ci * co) * inv_n2 + ci_r * co_r
    return cosines_from_dots(ci_r, co_r, dot)


def cosines_from_dots_into(cos_i, cos_o, cos_io, scratch, cos_d: bool = True) -> Cosines:
    """:func:`cosines_from_dots` (seed 000 eq. 1) in the inputs' dtype (float32 in the
    renderer's hot path, ~6× faster than the float64 form), into buffers from
    ``scratch(name, n)``: cos θh = (N·ωi + N·ωo)/‖ωi + ωo‖, cos θd = (1 + ωi·ωo)/‖ωi + ωo‖,
    ‖ωi + ωo‖² = 2 + 2 ωi·ωo, with the same guard (‖ωi + ωo‖² ≤ HALF_SQ_EPS: cos θh = 1,
    cos θd = cos θi) and clamps to [0, 1]. ``cos_d=False`` leaves cos θd out (None)."""
    m = cos_i.shape[0]
    one = cos_i.dtype.type(1)
    sq = np.multiply(cos_io, cos_i.dtype.type(2), out=scratch("sq", m))
    sq += cos_i.dtype.type(2)
    degenerate = sq <= HALF_SQ_EPS
    if degenerate.any():
        sq[degenerate] = one
    else:
        degenerate = None
    inv = np.sqrt(sq, out=sq)
    np.divide(one, inv, out=inv)
    ch = np.add(cos_i, cos_o, out=scratch("cos_h", m))
    ch *= inv
    cd = None
    if cos_d:
        cd = np.add(cos_io, one, out=scratch("cos_d", m))
        cd *= inv
    if degenerate is not None:
        ch[degenerate] = one
        if cd is not None:
            cd[degenerate] = cos_i[degenerate]
    clipped = []
    for name, v in (("cos_i", cos_i), ("cos_o", cos_o), ("", ch), ("", cd)):
        if v is not None:
            v = np.clip(v, 0, one, out=scratch(name, m) if name else v)
        clipped.append(v)
    return Cosines(*clipped)


def cosines(wi: np.ndarray, wo: np.ndarray, normal=(0.0, 0.0, 1.0)) -> Cosines:
    """The :class:`Cosines` of direction pairs (..., 3) about ``normal`` (..., 3)."""
    wi = np.asarray(wi, dtype=float)
    wo = np.asarray(wo, dtype=float)
    n = np.asarray(normal, dtype=float)
    wh = half_vector(wi, wo)
    dot = lambda a, b: np.clip(np.sum(a * b, axis=-1), 0.0, 1.0)  # noqa: E731
    return Cosines(dot(n, wi), dot(n, wo), dot(n, wh), dot(wi, wh))


def in_plane_cosines(theta_i_deg, theta_o_deg) -> Cosines:
    """:class:`Cosines` of in-plane configurations given in degrees (docs/conventions.md)."""
    return cosines(*in_plane_directions(theta_i_deg, theta_o_deg))


def cos_half_sum(cos_theta_i, cos_theta_o) -> np.ndarray:
    """cos((θi + θo)/2) from the two cosines, seed 000 eq. (6).

    θi and θo are polar angles in [0, π/2] (the first quadrant, as the paper notes), so
    an in-plane detector at signed θo enters as |θo|. Shape: broadcast of the inputs.
    """
    ci = np.clip(np.asarray(cos_theta_i, dtype=float), 0.0, 1.0)
    co = np.clip(np.asarray(cos_theta_o, dtype=float), 0.0, 1.0)
    return 0.5 * (np.sqrt((1.0 + ci) * (1.0 + co)) - np.sqrt((1.0 - ci) * (1.0 - co)))


def reflect(w: np.ndarray, n=(0.0, 0.0, 1.0)) -> np.ndarray:
    """Mirror direction R = 2 (n·w) n − w of unit vectors ``w`` (..., 3) about ``n`` (..., 3).
    """
    w = np.asarray(w, dtype=float)
    n = np.asarray(n, dtype=float)
    return 2.0 * np.sum(n * w, axis=-1, keepdims=True) * n - w
