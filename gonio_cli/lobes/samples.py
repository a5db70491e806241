"""Sample sets of the cosine-lobe fit (seed 001 §4) and the target they sample (eq. 6's b).

:data:`SAMPLE_SETS` (in-plane patterns and the hemisphere), custom CSV sets
(:func:`read_sample_csv`), the view angles of the weight table (:func:`parse_view_angles`)
and :func:`target_values`, the material's f cos θi at the samples. Re-exported by
:mod:`gonio_cli.lobes`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..csvio import THETA_I, THETA_O, read_columns
from ..errors import InputError
from ..geometry import cosines, in_plane_directions, reflect
from ..names import choices_fix, pick
from ..numbers import NumberList
from ..spectra import spectrum_to_xyz
from . import (GLOBAL_VIEW_ANGLES_DEG, HEMISPHERE_POINTS, HORIZON_DEG, MIRROR_BLEND_DEG,
               MIRROR_RING_AZIMUTHS, MIRROR_RING_GAUSS, MIRROR_RING_INNER_DEG,
               MIRROR_RING_RATIO, MIRROR_RING_SPACING_DEG)

# -------------------------------------------------------------------- sample sets --

@dataclass(frozen=True)
class Samples:
    """In-plane sample configurations grouped by view angle (seed 001 §4).

    Attributes
    ----------
    light_deg : (N,) float, the light's signed in-plane angle φ: ωi = (−sin φ, 0, cos φ),
        so φ ≥ 0 is the conventions' θi and φ < 0 puts the light on the detector's side.
    view_deg : (N,) float, the detector's θo (docs/conventions.md): ωo = (sin θo, 0, cos θo);
        the mirror configuration is φ = θo.
    view_index : (N,) int, index of each sample's row in ``view_angle_deg``.
    view_angle_deg : (V,) float, the view angles of the weight table.
    role : (N,) str, "diffuse", "directional" or "mirror" (informative).
    name : the sample set's name (registry key or CSV path).
    wi, wo : (N, 3) light and view directions, for sets off the plane (hemisphere).
    weight : (N,) float sr or None: the solid angle each light stands for, so that
        Σ weight · g is a quadrature of ∫ g dω_i over the half hemisphere of its view
        (``hemisphere`` with ``mirror_dense``, whose lights are not equal-area). None:
        every sample counts the same (the in-plane sets, and the plain ``hemisphere``
        set whose lights are equal-area).
    """

    light_deg: np.ndarray
    view_deg: np.ndarray
    view_index: np.ndarray
    view_angle_deg: np.ndarray
    role: np.ndarray
    name: str
    wi: np.ndarray | None = None    # (N, 3) light directions off the plane (hemisphere set)
    wo: np.ndarray | None = None    # (N, 3) view directions, given with ``wi``
    weight: np.ndarray | None = None  # (N,) sr, quadrature weights (see above)

    @property
    def n_samples(self) -> int:
        return int(self.light_deg.size)

    def directions(self) -> tuple[np.ndarray, np.ndarray]:
        """ωi, ωo (N, 3)."""
        if self.wi is not None:
            return self.wi, self.wo
        return in_plane_directions(self.light_deg, self.view_deg)

    def cos_theta_i(self) -> np.ndarray:
        return np.clip(self.directions()[0][:, 2], 0.0, 1.0)

    def cos_rv(self) -> np.ndarray:
        """R·V (N,) with R the mirror of ωi about +z: cos(θo − φ) in plane."""
        wi, wo = self.directions()
        return np.sum(reflect(wi) * wo, axis=-1)

    def view(self, k: int) -> "Samples":
        """The samples of the k-th view angle only."""
        rows = self.view_index == k
        return Samples(self.light_deg[rows], self.view_deg[rows], np.zeros(rows.sum(), int),
                       self.view_angle_deg[k:k + 1], self.role[rows], self.name,
                       None if self.wi is None else self.wi[rows],
                       None if self.wo is None else self.wo[rows],
                       None if self.weight is None else self.weight[rows])

    def mirror_offset_deg(self) -> np.ndarray:
        """(V,) the angle (deg) between each view's mirror direction and its nearest
        sample: acos(max R·V) over the view's samples (0 when a sample is on it)."""
        c = self.cos_rv()
        best = [np.max(c[self.view_index == k], initial=-1.0)
                for k in range(self.view_angle_deg.size)]
        return np.degrees(np.arccos(np.clip(best, -1.0, 1.0)))


@dataclass(frozen=True)
class SamplePattern:
    """Light offsets δ = φ − θv (deg) from the mirror configuration, per view angle θv.

    ``mirror``: near-mirror samples (shape and height of the gloss, seed 001 §4);
    ``directional``: off-specular samples (the directional-diffuse lobes, like the
    aspecular angles of multi-angle instruments); ``diffuse``: the one sample lit 45°
    from the mirror direction (seed 001 §4: lit at 45°, seen at the normal).
    """

    mirror: tuple[float, ...]
    directional: tuple[float, ...]
    diffuse: tuple[float, ...]
    description: str

    def samples(self, view_angle_deg: Sequence[float], name: str) -> Samples:
        """All samples of the pattern at each view angle, beyond-horizon ones dropped."""
        views = np.asarray(view_angle_deg, dtype=float)
        light, view, index, role = [], [], [], []
        for k, tv in enumerate(views):
            for kind, offsets in (("mirror", self.mirror), ("directional", self.directional),
                                  ("diffuse", self.diffuse)):
                for d in offsets:
                    if abs(tv + d) <= HORIZON_DEG:
                        light.append(tv + d)
                        view.append(tv)
                        index.append(k)
                        role.append(kind)
        return Samples(np.array(light, float), np.array(view, float), np.array(index, int),
                       views, np.array(role, dtype=object), name)


def _smoothstep_down(t: np.ndarray) -> np.ndarray:
    """1 at t ≤ 0, 0 at t ≥ 1, 1 − 3t² + 2t³ between (C¹): the partition of unity that
    hands the mirror rings' weight to the spiral."""
    t = np.clip(t, 0.0, 1.0)
    return 1.0 - t * t * (3.0 - 2.0 * t)


def mirror_rings(view_angle_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Lights in rings about the mirror direction of one view, with their solid angles.

    For a view at θv (ωo = (sin θv, 0, cos θv)) the lobes (R·V)^E are round about the
    light Lm = (−sin θv, 0, cos θv), R·V = L·Lm. Radii θ from Lm: panels doubling from
    :data:`MIRROR_RING_INNER_DEG` to ``MIRROR_BLEND_DEG[1]`` (equal ratios, at most
    :data:`MIRROR_RING_RATIO`), :data:`MIRROR_RING_GAUSS`
    Gauss–Legendre points per panel in u = 1 − cos θ (dω = du dψ); azimuths ψ ∈ [0, ψmax]
    on the y ≥ 0 half (midpoint rule), ψmax cutting the ring exactly at the
    :data:`HORIZON_DEG` horizon. Each weight is multiplied by the blend χ(θ) (1 inside
    ``MIRROR_BLEND_DEG[0]``, 0 beyond ``[1]``); the spiral takes 1 − χ.

    Returns (wi (n, 3), weight (n,) sr).
    """
    tv = np.radians(view_angle_deg)
    axis = np.array([-np.sin(tv), 0.0, np.cos(tv)])
    t1 = np.array([np.cos(tv), 0.0, np.sin(tv)])       # in plane, away from the normal
    t2 = np.array([0.0, 1.0, 0.0])
    inner, (b0, b1) = np.radians(MIRROR_RING_INNER_DEG), np.radians(MIRROR_BLEND_DEG)
    n_panels = int(np.ceil(np.log(b1 / inner) / np.log(MIRROR_RING_RATIO)))
    edges = np.concatenate([[0.0], np.geomspace(inner, b1, n_panels + 1)])  # ratio ≤ RATIO
    u_edges = 1.0 - np.cos(edges)
    x, w = np.polynomial.legendre.leggauss(MIRROR_RING_GAUSS)
    half = 0.5 * np.diff(u_edges)[:, None]
    u = (0.5 * (u_edges[:-1] + u_edges[1:])[:, None] + half * x).ravel()
    w_u = (half * w).ravel()
    theta = np.arccos(1.0 - u)
    z_min = np.cos(np.radians(HORIZON_DEG))
    lights, weights = [], []
    for th, wu in zip(theta, w_u):
        # z(ψ) = cos θ Lm_z + sin θ cos ψ t1_z ≥ z_min  ⇔  cos ψ ≥ c
        c = ((z_min - np.cos(th) * axis[2]) / (np.sin(th) * t1[2]) if t1[2] > 0 else -np.inf)
        psi_max = np.pi if c <= -1.0 else (0.0 if c >= 1.0 else float(np.arccos(c)))
        if psi_max <= 0.0:
            continue
        n = max(MIRROR_RING_AZIMUTHS,
                int(np.ceil(np.degrees(psi_max * np.sin(th)) / MIRROR_RING_SPACING_DEG)))
        psi = (np.arange(n) + 0.5) * psi_max / n
        lights.append(np.cos(th) * axis + np.sin(th) * (np.cos(psi)[:, None] * t1
                                                         + np.sin(psi)[:, None] * t2))
        chi = _smoothstep_down((th - b0) / (b1 - b0))
        weights.append(np.full(n, wu * psi_max / n * chi))
    wi, weight = np.concatenate(lights), np.concatenate(weights)
    wi[:, 1] = np.abs(wi[:, 1])                         # ψ = 0 or π: y = ±0 → +0
    keep = weight > 0.0
    return wi[keep], weight[keep]


@dataclass(frozen=True)
class HemispherePattern:
    """Lights spread evenly over the hemisphere (a golden-angle spiral, uniform in solid
    angle, up to :data:`HORIZON_DEG`) at each view angle, folded onto the y ≥ 0 half: an
    isotropic BRDF is symmetric about the plane of incidence, so the other half repeats it.

    Seed 001 §4 samples only the plane of incidence; its round lobes then fit the in-plane
    cut but come out ~2× too wide across it at oblique views, which environment lighting
    sees (mean CIEDE2000 6–8 against brute-force integration, against < 2 from this set).

    With ``mirror_dense`` each view also gets :func:`mirror_rings` (lights down to 0.07°
    from its mirror direction, where every lobe has its axis), merged with the spiral by a
    smooth partition of unity: the samples carry solid angles (``Samples.weight``) and
    integrate lobes of every E from 1 to 1e4 (the spiral alone misses half of an E = 1e3
    lobe and all of an E = 1e4 one).
    """

    points: int
    description: str

    def spiral(self) -> np.ndarray:
        """The spiral's lights (points, 3), equal-area on the half hemisphere."""
        k = np.arange(self.points) + 0.5
        z_min = np.cos(np.radians(HORIZON_DEG))
        z = 1.0 - k / self.points * (1.0 - z_min)          # uniform in solid angle
        phi = np.pi * (1.0 + np.sqrt(5.0)) * k              # golden-angle spiral
        r = np.sqrt(1.0 - z * z)
        return np.stack([r * np.cos(phi), r * np.abs(np.sin(phi)), z], axis=-1)

    def samples(self, view_angle_deg: Sequence[float], name: str,
                mirror_dense: bool = False) -> Samples:
        lights = self.spiral()
        views = np.asarray(view_angle_deg, dtype=float)
        if not mirror_dense:
            tv = np.radians(np.repeat(views, self.points))
            wo = np.stack([np.sin(tv), np.zeros_like(tv), np.cos(tv)], axis=-1)
            wi = np.tile(lights, (views.size, 1))
            n = wi.shape[0]
            return Samples(np.degrees(np.arccos(wi[:, 2])), np.degrees(tv),
                           np.repeat(np.arange(views.size), self.points), views,
                           np.array(["hemisphere"] * n, dtype=object), name, wi, wo)
        area = np.pi * (1.0 - np.cos(np.radians(HORIZON_DEG)))      # the half hemisphere
        b0, b1 = MIRROR_BLEND_DEG
        wi, weight, index, role = [], [], [], []
        for k, tv in enumerate(np.radians(views)):
            axis = np.array([-np.sin(tv), 0.0, np.cos(tv)])
            theta = np.degrees(np.arccos(np.clip(lights @ axis, -1.0, 1.0)))
            w_spiral = area / self.points * (1.0 - _smoothstep_down((theta - b0) / (b1 - b0)))
            ring, w_ring = mirror_rings(np.degrees(tv))
            kept = w_spiral > 0.0
            wi += [ring, lights[kept]]
            weight += [w_ring, w_spiral[kept]]
            index.append(np.full(ring.shape[0] + int(kept.sum()), k))
            role += ["mirror"] * ring.shape[0] + ["hemisphere"] * int(kept.sum())
        wi = np.concatenate(wi)
        index = np.concatenate(index)
        tv = np.radians(views[index])
        wo = np.stack([np.sin(tv), np.zeros_like(tv), np.cos(tv)], axis=-1)
        return Samples(np.degrees(np.arccos(wi[:, 2])), np.degrees(tv), index, views,
                       np.array(role, dtype=object), f"{name}+mirror", wi, wo,
                       np.concatenate(weight))


#: Sample patterns by name (seed 001 §4 is the default). Each gives ~20 samples per view
#: angle (seed001) or ~60 (dense); the global set (basis selection) is the union over
#: :data:`GLOBAL_VIEW_ANGLES_DEG`, ~60 samples for seed001.
SAMPLE_SETS: dict[str, SamplePattern | HemispherePattern] = {
    "seed001": SamplePattern(
        mirror=(0.0, -1.0, 1.0, -2.0, 2.0, -4.0, 4.0, -7.0, 7.0),
        directional=(-10.0, 10.0, -15.0, 15.0, -25.0, 25.0, -35.0, 35.0, -50.0, -65.0),
        diffuse=(-45.0,),
        description="seed 001 §4: one diffuse sample lit 45° off the mirror, ten "
                    "off-specular (10-65°) and nine near-mirror (0-7°) per view"),
    "dense": SamplePattern(
        mirror=tuple(float(d) for d in (0, -1, 1, -2, 2, -3, 3, -4, 4)),
        directional=tuple(float(d) for d in np.r_[-80:-4:2.5, 5:80:2.5]),
        diffuse=(-45.0,),
        description="every 2.5° of light angle from the mirror to the horizon, 1° near "
                    "the mirror: a check of the sparse set, ~3× the samples"),
    "hemisphere": HemispherePattern(
        points=HEMISPHERE_POINTS,
        description="lights over the whole hemisphere (half by symmetry) per view: lobes "
                    "that also hold across the plane of incidence, for environment light"),
}


def read_sample_csv(path) -> tuple[np.ndarray, np.ndarray]:
    """A custom sample set: CSV with header ``theta_i_deg,theta_o_deg`` (one row each).

    θi is the light's signed angle φ (the conventions' θi when ≥ 0; < 0 on the detector's
    side), θo the detector. Returns (φ, θo) in degrees, (N,) each (N = 0 for a header
    alone). Read by :func:`gonio_cli.csvio.read_columns`, the reader of every small CSV.
    """
    angles, _ = read_columns(path, (THETA_I, THETA_O), "the sample set", allow_empty=True)
    return angles[:, 0].copy(), angles[:, 1].copy()


def sample_set(name: str, view_angle_deg: Sequence[float] | None = None,
               mirror_dense: bool = False) -> Samples:
    """The sample set ``name`` (a key of :data:`SAMPLE_SETS` or a CSV path).

    ``view_angle_deg``: the table's view angles (deg, in [0, 90)); ``None`` gives
    :data:`GLOBAL_VIEW_ANGLES_DEG` (basis selection). A CSV's view angles are its distinct
    θo values (``view_angle_deg`` is then ignored). Samples beyond :data:`HORIZON_DEG`
    are dropped; an empty set is an InputError. ``mirror_dense`` (``hemisphere`` only)
    adds :func:`mirror_rings` and quadrature weights (:class:`HemispherePattern`).
    """
    if mirror_dense and not isinstance(SAMPLE_SETS.get(name), HemispherePattern):
        raise InputError(f"--mirror-dense applies to --samples hemisphere, not {name}",
                         fix="the in-plane sets already have a sample on the mirror "
                             "direction; drop --mirror-dense or use --samples hemisphere")
    if name in SAMPLE_SETS:
        views = GLOBAL_VIEW_ANGLES_DEG if view_angle_deg is None else view_angle_deg
        views = np.asarray(views, dtype=float).ravel()
        bad = views[~((views >= 0) & (views < 90))]
        if bad.size:
            raise InputError(f"view angle {bad[0]:g} deg is outside [0, 90)",
                             fix="e.g. --view-angles-deg 0:80:10")
        pattern = SAMPLE_SETS[name]
        samples = (pattern.samples(views, name, mirror_dense=True) if mirror_dense
                   else pattern.samples(views, name))
    elif str(name).lower().endswith(".csv"):
        light, view = read_sample_csv(name)
        keep = (np.abs(light) <= HORIZON_DEG) & (np.abs(view) <= HORIZON_DEG)
        light, view = light[keep], view[keep]
        views, index = np.unique(view, return_inverse=True)
        samples = Samples(light, view, index.astype(int).ravel(), views,
                          np.array(["custom"] * light.size, dtype=object), str(name))
    else:
        raise InputError(f"sample set {name!r} is unknown",
                         fix=choices_fix(name, SAMPLE_SETS) + " or a CSV file with columns "
                             "theta_i_deg,theta_o_deg")
    if samples.n_samples == 0:
        raise InputError(f"sample set {name}: no sample within {HORIZON_DEG:g} deg of the "
                         "normal, so there is nothing to fit",
                         fix="use light and view angles inside (-85, 85) deg")
    return samples


#: ``--view-angles-deg``: the weight table's view angles.
VIEW_ANGLES_DEG = NumberList("--view-angles-deg", "0:80:10", unit="deg", lo=0.0, hi=90.0,
                             hi_open=True)


def parse_view_angles(spec: str) -> np.ndarray:
    """``"0:80:10"`` (inclusive) or ``"10,40,70"`` → (V,) degrees (:data:`VIEW_ANGLES_DEG`)."""
    return np.asarray(VIEW_ANGLES_DEG.parse(spec))


# ------------------------------------------------------------------------- channels --

#: Channel kinds: spectral bands of the material's grid, or CIE XYZ (docs/conventions.md).
CHANNELS = {"spectral": "one channel per wavelength of the working grid",
            "xyz": "CIE 1931 XYZ = Σ f cmf / Σ ȳ (docs/conventions.md)"}


def check_channels(kind: str) -> str:
    pick(CHANNELS, kind, "--channels")
    return kind


def target_values(material, samples: Samples, channels: str = "spectral"):
    """The target b of seed 001 eq. 6: f cos θi of ``material`` at the samples.

    Parameters
    ----------
    material : :class:`gonio_cli.schemas.Material` (any registered model).
    samples : :class:`Samples` (N samples).
    channels : "spectral" or "xyz".

    Returns
    -------
    b : (N, C) float, sr⁻¹ × cosine, C = n_λ (spectral) or 3 (XYZ of f cos θi, the same
        linear map on every sample, so lobe weights in XYZ are XYZ of spectral weights).
    labels : list, the wavelengths (nm, float) or ["X", "Y", "Z"].
    """
    check_channels(channels)
    wi, wo = samples.directions()
    f = material.evaluate(cosines(wi, wo))                     # (N, n_λ) sr⁻¹
    b = f * samples.cos_theta_i()[:, None]
    if channels == "xyz":
        return spectrum_to_xyz(b, material.wavelength_nm), ["X", "Y", "Z"]
    return b, [float(w) for w in material.wavelength_nm]


def directional_albedo(material, view_angle_deg: Sequence[float],
                       channels: str = "spectral") -> np.ndarray:
    """∫ f cos θi dω_i over the hemisphere (to :data:`HORIZON_DEG`) at each view angle.

    The light ``material`` reflects towards a view at θv under unit radiance from every
    direction (by reciprocity its directional albedo at θv), by the mirror-dense quadrature
    of ``hemisphere`` (:func:`mirror_rings`): its sharp gloss is integrated, not missed.
    Both halves of the hemisphere count (2 × the y ≥ 0 half: isotropic BRDF).

    Returns (V, C) float (unitless), in the channels of :func:`target_values`.
    """
    views = np.asarray(view_angle_deg, dtype=float).ravel()
    s = SAMPLE_SETS["hemisphere"].samples(views, "hemisphere", mirror_dense=True)
    b, _ = target_values(material, s, channels)
    albedo = np.zeros((views.size, b.shape[1]))
    np.add.at(albedo, s.view_index, 2.0 * s.weight[:, None] * b)
    return albedo
