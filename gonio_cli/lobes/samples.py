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

from ..errors import InputError
from ..names import pick
from ..geometry import cosines, in_plane_directions, reflect
from . import GLOBAL_VIEW_ANGLES_DEG, HEMISPHERE_POINTS, HORIZON_DEG

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
    """

    light_deg: np.ndarray
    view_deg: np.ndarray
    view_index: np.ndarray
    view_angle_deg: np.ndarray
    role: np.ndarray
    name: str
    wi: np.ndarray | None = None    # (N, 3) light directions off the plane (hemisphere set)
    wo: np.ndarray | None = None    # (N, 3) view directions, given with ``wi``

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
                       None if self.wo is None else self.wo[rows])


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


@dataclass(frozen=True)
class HemispherePattern:
    """Lights spread evenly over the hemisphere (a golden-angle spiral, uniform in solid
    angle, up to :data:`HORIZON_DEG`) at each view angle, folded onto the y ≥ 0 half: an
    isotropic BRDF is symmetric about the plane of incidence, so the other half repeats it.

    Seed 001 §4 samples only the plane of incidence; its round lobes then fit the in-plane
    cut but come out ~2× too wide across it at oblique views, which environment lighting
    sees (mean CIEDE2000 6–8 against brute-force integration, against < 2 from this set).
    """

    points: int
    description: str

    def samples(self, view_angle_deg: Sequence[float], name: str) -> Samples:
        k = np.arange(self.points) + 0.5
        z_min = np.cos(np.radians(HORIZON_DEG))
        z = 1.0 - k / self.points * (1.0 - z_min)          # uniform in solid angle
        phi = np.pi * (1.0 + np.sqrt(5.0)) * k              # golden-angle spiral
        r = np.sqrt(1.0 - z * z)
        lights = np.stack([r * np.cos(phi), r * np.abs(np.sin(phi)), z], axis=-1)
        views = np.asarray(view_angle_deg, dtype=float)
        tv = np.radians(np.repeat(views, self.points))
        wo = np.stack([np.sin(tv), np.zeros_like(tv), np.cos(tv)], axis=-1)
        wi = np.tile(lights, (views.size, 1))
        n = wi.shape[0]
        return Samples(np.degrees(np.arccos(wi[:, 2])), np.degrees(tv),
                       np.repeat(np.arange(views.size), self.points), views,
                       np.array(["hemisphere"] * n, dtype=object), name, wi, wo)


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
    alone). Read by :func:`gonio_cli.ingest.read_columns`, the reader of every small CSV.
    """
    from ..ingest import THETA_I, THETA_O, read_columns

    angles, _ = read_columns(path, (THETA_I, THETA_O), "the sample set", allow_empty=True)
    return angles[:, 0].copy(), angles[:, 1].copy()


def sample_set(name: str, view_angle_deg: Sequence[float] | None = None) -> Samples:
    """The sample set ``name`` (a key of :data:`SAMPLE_SETS` or a CSV path).

    ``view_angle_deg``: the table's view angles (deg, in [0, 90)); ``None`` gives
    :data:`GLOBAL_VIEW_ANGLES_DEG` (basis selection). A CSV's view angles are its distinct
    θo values (``view_angle_deg`` is then ignored). Samples beyond :data:`HORIZON_DEG`
    are dropped; an empty set is an InputError.
    """
    if name in SAMPLE_SETS:
        views = GLOBAL_VIEW_ANGLES_DEG if view_angle_deg is None else view_angle_deg
        views = np.asarray(views, dtype=float).ravel()
        bad = views[~((views >= 0) & (views < 90))]
        if bad.size:
            raise InputError(f"view angle {bad[0]:g} deg is outside [0, 90)",
                             fix="e.g. --view-angles-deg 0:80:10")
        samples = SAMPLE_SETS[name].samples(views, name)
    elif str(name).lower().endswith(".csv"):
        light, view = read_sample_csv(name)
        keep = (np.abs(light) <= HORIZON_DEG) & (np.abs(view) <= HORIZON_DEG)
        light, view = light[keep], view[keep]
        views, index = np.unique(view, return_inverse=True)
        samples = Samples(light, view, index.astype(int).ravel(), views,
                          np.array(["custom"] * light.size, dtype=object), str(name))
    else:
        raise InputError(f"sample set {name!r} is unknown",
                         fix=f"use one of {', '.join(SAMPLE_SETS)} or a CSV file "
                             "with columns theta_i_deg,theta_o_deg")
    if samples.n_samples == 0:
        raise InputError(f"sample set {name}: no sample within {HORIZON_DEG:g} deg of the "
                         "normal, so there is nothing to fit",
                         fix="use light and view angles inside (-85, 85) deg")
    return samples


def parse_view_angles(spec: str) -> np.ndarray:
    """``"0:80:10"`` (inclusive) or ``"10,40,70"`` → (V,) degrees."""
    text = str(spec).strip()
    try:
        if ":" in text:
            start, stop, step = (float(p) for p in text.split(":"))
            if step <= 0 or stop < start:
                raise ValueError
            values = np.arange(start, stop + 0.5 * step, step)
        else:
            values = np.array([float(p) for p in text.split(",") if p.strip()])
    except ValueError:
        raise InputError(f"--view-angles-deg {spec!r} is not START:STOP:STEP or a list",
                         fix="e.g. --view-angles-deg 0:80:10 or --view-angles-deg 10,40,70"
                         ) from None
    if values.size == 0:
        raise InputError("--view-angles-deg is empty", fix="e.g. --view-angles-deg 0:80:10")
    return values


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
        from ..spectra import spectrum_to_xyz

        return spectrum_to_xyz(b, material.wavelength_nm), ["X", "Y", "Z"]
    return b, [float(w) for w in material.wavelength_nm]
