"""Choose a standard material for a gonio material: a least-squares fit of its own BRDF.

A standard material (glTF 2.0's, OpenPBR Surface's) cannot hold a spectral,
goniochromatic BRDF, so ``gonio export`` chooses the parameters whose reflectance is
closest to the material's over the hemisphere (:func:`fit_standard`), rather than mapping
one parameter onto another. Every target gives a :class:`Space` (its parameter vector,
bounds, starts and BRDF); the loop here is the same for all:

* **Where.** :func:`hemisphere_directions`: lights at θi = 0–80°, and for each a fan of
  half vectors (θh from 0 to 75°, dense near 0 where a clear coat's peak is a degree
  wide; five azimuths over the half plane y ≥ 0, the materials being symmetric about the
  plane of incidence); the viewer is the light mirrored about the half vector. In-plane
  configurations are the φh = 0 and 180° rows, and in-plane viewers every 5°.
* **What.** Both BRDFs as linear sRGB reflectance factors R = π f under D65 (the
  material's spectrum through the same weights as the Mitsuba export's RGB variants,
  :func:`gonio_cli.export.mitsuba.rgb_weights`; the standards' colours are linear sRGB).
* **How close.** L*a*b* differences with CIE94's chroma weight, each configuration scaled
  by 1 / max(1, Y) of the material's R (a highlight counts by its relative error, as the
  judgement's CIEDE2000 does); ``scipy.optimize.least_squares`` (trust region, bounded,
  the Jacobian by :meth:`Problem.jacobian`) from the space's fixed starts, the best
  polished on CIEDE2000 itself (:meth:`Problem.solve`), then a target's thin film
  (:class:`FilmStage`, :func:`with_film`): deterministic.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from ..geometry import Cosines, cosines, in_plane_directions
from ..spectra import delta_e_2000, xyz_to_lab, xyz_to_linear_srgb_matrix
from .mitsuba import rgb_weights

#: Residuals are colour differences in units of this (10 → 1): only for the solver's
#: scaling, the optimum does not depend on it.
DE_UNIT = 10.0
#: Evaluations of the last step, the best start polished on CIEDE2000 itself (not smooth
#: where a difference is 0, so the smooth stand-in does the search).
POLISH_NFEV = 60
#: Steps of every start before the best are chosen, when a target screens its starts
#: (:meth:`Problem.solve`; a start's basin shows by then).
SCREEN_NFEV = 25
#: Steps allowed per start (each a Jacobian and a trial step).
START_NFEV = 400
#: CIE94's (and CIEDE2000's) chroma weight: S_C = 1 + 0.045 C* (CIE 116-1995).
CHROMA_WEIGHT = 0.045

#: Light angles θi (degrees) of the fit's sample set.
THETA_I_DEG = (0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0)
#: Half-vector polar angles θh (degrees): dense near the mirror for sharp lobes.
THETA_H_DEG = (0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.5, 6.5, 9.0, 12.0, 16.0, 21.0, 27.0,
               34.0, 42.0, 51.0, 62.0, 75.0)
#: Half-vector azimuths (degrees) from the plane of incidence, towards +y.
PHI_H_DEG = (0.0, 45.0, 90.0, 135.0, 180.0)
#: In-plane viewers (degrees, signed as docs/conventions.md) added for every θi: the
#: plane a goniometer measures in, where the export is judged (:mod:`.judge`).
THETA_O_DEG = tuple(float(t) for t in range(-85, 86, 5))
#: A viewer closer to the horizon than this (cos θo) is left out of the fit (86°; an
#: instrument's last angle is 85°).
COS_O_MIN = float(np.cos(np.radians(86.0)))


@dataclass(frozen=True)
class Space:
    """A target's parameter vector: ``names`` with bounds ``lower``/``upper`` (arrays of
    the same length), ``starts(base)`` the fixed starting vectors given a first guess
    ``base`` (3,) of the diffuse colour, ``brdf(cos, x)`` f (..., 3) linear sRGB in sr⁻¹,
    and ``to_material(x)`` the target's parameter object. ``channels``: triplets of
    indices (r, g, b) of colour parameters each of which changes its own channel of f
    only, so that one evaluation gives the three Jacobian columns (:class:`Problem`)."""

    names: tuple
    lower: np.ndarray
    upper: np.ndarray
    starts: Callable[[np.ndarray], Sequence[np.ndarray]]
    brdf: Callable[[Cosines, np.ndarray], np.ndarray]
    to_material: Callable[[np.ndarray], Any]
    channels: tuple = ()


def hemisphere_directions() -> tuple[np.ndarray, np.ndarray]:
    """(ωi, ωo), each (N, 3): the fit's sample set (module docstring), light on the −x
    side as in docs/conventions.md, viewers below :data:`COS_O_MIN` left out."""
    ti = np.radians(np.asarray(THETA_I_DEG))[:, None, None]
    th = np.radians(np.asarray(THETA_H_DEG))[None, :, None]
    ph = np.radians(np.asarray(PHI_H_DEG))[None, None, :]
    ti, th, ph = np.broadcast_arrays(ti, th, ph)
    wi = np.stack([-np.sin(ti), np.zeros_like(ti), np.cos(ti)], axis=-1)
    wh = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=-1)
    wo = 2.0 * np.sum(wi * wh, axis=-1, keepdims=True) * wh - wi
    pi, po = in_plane_directions(np.asarray(THETA_I_DEG)[:, None], np.asarray(THETA_O_DEG))
    wi = np.concatenate([wi.reshape(-1, 3), pi.reshape(-1, 3)])
    wo = np.concatenate([wo.reshape(-1, 3), po.reshape(-1, 3)])
    keep = wo[:, 2] > COS_O_MIN
    return wi[keep], wo[keep]


def material_rgb(material) -> Callable[[Cosines], np.ndarray]:
    """f (..., 3) of a :class:`gonio_cli.schemas.Material` as linear sRGB under D65."""
    w = rgb_weights(np.asarray(material.wavelength_nm, dtype=float)).T     # (n_λ, 3)
    return lambda cos: material.evaluate(cos) @ w


def rgb_to_xyz(rgb) -> np.ndarray:
    """XYZ (..., 3) of linear sRGB (..., 3) (the inverse of the conventions' matrix)."""
    return np.asarray(rgb, dtype=float) @ np.linalg.inv(xyz_to_linear_srgb_matrix()).T


def perceived(r_ref) -> Callable[[np.ndarray], np.ndarray]:
    """L*a*b* (..., 3) of linear-sRGB reflectance factors, each configuration scaled by
    1 / max(1, Y) of ``r_ref`` (..., 3) there (the judgement's scaling of a highlight,
    as `gonio fit`'s verdict does), white D65 (sRGB's (1, 1, 1))."""
    scale = (1.0 / np.maximum(1.0, rgb_to_xyz(r_ref)[..., 1]))[..., None]
    white = rgb_to_xyz(np.ones(3))
    return lambda rgb: xyz_to_lab(rgb_to_xyz(rgb) * scale, white)


@dataclass
class ExportFit:
    """The fitted standard material and how it was obtained (STYLE 9)."""

    material: Any
    success: bool
    message: str
    evaluations: int
    rms_residual: float         # RMS of the residuals at the optimum, in DE_UNIT
    samples: int
    starts: int
    time_s: float
    #: Other materials the fit found (glTF: the same without its film), judged beside
    #: :attr:`material` by the export, which writes the one closer to the material.
    alternatives: list = field(default_factory=list)

    def to_dict(self) -> dict:
        return {"success": self.success, "message": self.message,
                "evaluations": self.evaluations, "rms_residual": self.rms_residual,
                "samples": self.samples, "starts": self.starts, "time_s": self.time_s,
                "optimizer": "scipy.optimize.least_squares (trf, bounded)"}


def first_base_colour(cos: Cosines, r_t: np.ndarray) -> np.ndarray:
    """A Lambertian base colour's first guess (3,): the material's median R far off the
    mirror (40° < θh < 60°), or mid-grey."""
    far = (cos.cos_theta_h < np.cos(np.radians(40.0))) & (cos.cos_theta_h > 0.5)
    return np.clip(np.median(r_t[far], axis=0) if far.any() else np.full(3, 0.5), 0.0, 1.0)


class Problem:
    """The fit's target at its sample set: the material's L*a*b* (:func:`perceived`) at
    ``directions`` and the smooth loss of the module docstring; :meth:`solve` runs the
    bounded least squares in a :class:`Space` from given starts."""

    def __init__(self, target_rgb: Callable[[Cosines], np.ndarray], directions=None):
        wi, wo = directions if directions is not None else hemisphere_directions()
        self.cos = cosines(wi, wo)
        self.r_t = np.pi * np.asarray(target_rgb(self.cos), dtype=float)       # (N, 3)
        self.lab = perceived(self.r_t)
        self.lab_t = self.lab(self.r_t)
        # CIE94's chroma weighting S_C = 1 + 0.045 C* of the material's colour on a* and
        # b*: a smooth stand-in for CIEDE2000, which discounts chroma differences of
        # vivid colours
        self.w = np.ones_like(self.lab_t)
        self.w[:, 1:] = 1.0 / (1.0 + CHROMA_WEIGHT * np.hypot(self.lab_t[:, 1],
                                                              self.lab_t[:, 2]))[:, None]
        self.evaluations = 0          # BRDF evaluations at the sample set

    @property
    def samples(self) -> int:
        return int(self.cos.cos_theta_i.size)

    def first_base(self) -> np.ndarray:
        return first_base_colour(self.cos, self.r_t)

    def brdf(self, space: Space, x) -> np.ndarray:
        """f (N, 3) of ``x`` at the sample set (counted in :attr:`evaluations`)."""
        self.evaluations += 1
        return space.brdf(self.cos, x)

    def _of_f(self, f) -> np.ndarray:
        return (self.w * (self.lab(np.pi * f) - self.lab_t) / DE_UNIT).ravel()

    def residuals(self, space: Space, x) -> np.ndarray:
        """The smooth residuals (3N,) of ``x``, in :data:`DE_UNIT`."""
        return self._of_f(self.brdf(space, x))

    def _de_of_f(self, f) -> np.ndarray:
        return delta_e_2000(self.lab_t, self.lab(np.pi * f)) / DE_UNIT

    def jacobian(self, space: Space, x, of_f=None) -> np.ndarray:
        """Forward differences (3N, n) of :meth:`residuals`, one BRDF evaluation for each
        triplet of ``space.channels`` (its three columns from one perturbed f), one per
        other parameter; a step that would leave the bounds goes the other way.
        ``of_f``: the residuals of an f (default the smooth ones)."""
        of_f = self._of_f if of_f is None else of_f
        x = np.asarray(x, dtype=float)
        h = np.sqrt(np.finfo(float).eps) * np.maximum(1.0, np.abs(x))
        h = np.where(x + h > space.upper, -h, h)
        f0 = self.brdf(space, x)
        r0 = of_f(f0)
        jac = np.empty((r0.size, x.size))
        grouped = {i for g in space.channels for i in g}
        for group in space.channels:
            xp = x.copy()
            xp[list(group)] += h[list(group)]
            fp = self.brdf(space, xp)
            for c, i in enumerate(group):
                f = f0.copy()
                f[..., c] = fp[..., c]
                jac[:, i] = (of_f(f) - r0) / h[i]
        for i in range(x.size):
            if i not in grouped:
                xp = x.copy()
                xp[i] += h[i]
                jac[:, i] = (of_f(self.brdf(space, xp)) - r0) / h[i]
        return jac

    def delta_e(self, space: Space, x) -> np.ndarray:
        """CIEDE2000 (N,) of ``x`` at the sample set."""
        return delta_e_2000(self.lab_t, self.lab(np.pi * self.brdf(space, x)))

    def _run(self, space: Space, x0, max_nfev: int):
        from scipy.optimize import least_squares

        return least_squares(lambda x: self.residuals(space, x),
                             np.clip(x0, space.lower, space.upper),
                             jac=lambda x: self.jacobian(space, x),
                             bounds=(space.lower, space.upper), method="trf",
                             x_scale="jac", max_nfev=max_nfev)

    def solve(self, space: Space, starts, keep: int | None = None,
              max_nfev: int = START_NFEV, polish: int = 1):
        """The best ``least_squares`` result from ``starts``, each run for ``max_nfev``
        steps (with ``keep``, every start runs :data:`SCREEN_NFEV` steps first and only
        the ``keep`` best are continued), then :meth:`polish`-ed: the ``polish`` lowest
        in the smooth loss, and of those the lowest mean CIEDE2000 (starts that reach
        one smooth optimum can leave it along different flat directions)."""
        if keep is None:
            done = [self._run(space, x0, max_nfev) for x0 in starts]
        else:
            screened = sorted((self._run(space, x0, SCREEN_NFEV) for x0 in starts),
                              key=lambda r: r.cost)
            done = [r if r.status != 0 else self._run(space, r.x, max_nfev)
                    for r in screened[:keep]]
        polished = [self.polish(space, r.x)
                    for r in sorted(done, key=lambda r: r.cost)[:polish]]
        return min(polished, key=lambda r: float(np.mean(self.delta_e(space, r.x))))

    def polish(self, space: Space, x):
        """``x`` polished on CIEDE2000 itself (:data:`POLISH_NFEV` steps, the Jacobian
        as :meth:`jacobian`'s)."""
        from scipy.optimize import least_squares

        return least_squares(lambda v: self._de_of_f(self.brdf(space, v)), x,
                             jac=lambda v: self.jacobian(space, v, self._de_of_f),
                             bounds=(space.lower, space.upper), method="trf",
                             x_scale="jac", max_nfev=POLISH_NFEV)


def fit_standard(target_rgb: Callable[[Cosines], np.ndarray], space: Space,
                 directions=None, keep: int | None = None, max_nfev: int = START_NFEV,
                 polish: int = 1, film: FilmStage | None = None) -> ExportFit:
    """The parameters of ``space`` whose BRDF is closest to ``target_rgb`` (f (..., 3)
    linear sRGB, sr⁻¹) over ``directions`` ((ωi, ωo), default
    :func:`hemisphere_directions`); ``keep``, ``max_nfev``, ``polish``:
    :meth:`Problem.solve`'s; then ``film`` (:func:`with_film`); module docstring."""
    t0 = time.perf_counter()
    problem = Problem(target_rgb, directions)
    starts = space.starts(problem.first_base())
    best = problem.solve(space, starts, keep, max_nfev, polish)
    if film is not None:
        return with_film(problem, space, best, film, len(starts), t0)
    return finished(problem, space, best, len(starts), t0)


@dataclass(frozen=True)
class FilmStage:
    """A thin film fitted after a target's first stage: ``space`` is the target's space
    with (weight, film index, thickness) appended; the films of ``grid_ior`` ×
    ``grid_thickness`` (weight 1) are tried on each of ``variants(x)`` (the first
    stage's vector and others made from it), the ``starts`` best by the smooth loss run
    :data:`SCREEN_NFEV` steps, the ``keep`` best of those to ``max_nfev``."""

    space: Space
    grid_ior: tuple
    grid_thickness: tuple
    variants: Callable[[np.ndarray], list]
    starts: int = 6
    keep: int = 2
    max_nfev: int = START_NFEV
    gain: float = 0.05          # mean CIEDE2000 at the sample set the film must win by


def with_film(problem: Problem, space: Space, best, stage: FilmStage, starts: int,
              t0: float) -> ExportFit:
    """The first stage's ``best`` in ``space``, or with the film of ``stage`` when that
    lowers the mean CIEDE2000 at the sample set by ``stage.gain`` (the film-less
    material then an ``alternative``: the export writes the closer as judged)."""
    tried = [np.array([*v, 1.0, n, d]) for v in stage.variants(best.x)
             for n in stage.grid_ior for d in stage.grid_thickness]
    cost = [float(np.sum(problem.residuals(stage.space, v) ** 2)) for v in tried]
    chosen = [tried[k] for k in np.argsort(cost)[:stage.starts]]
    filmed = problem.solve(stage.space, chosen, stage.keep, stage.max_nfev, polish=stage.keep)
    starts += len(chosen)
    if (problem.delta_e(stage.space, filmed.x).mean()
            < problem.delta_e(space, best.x).mean() - stage.gain):
        return finished(problem, stage.space, filmed, starts, t0, [space.to_material(best.x)])
    return finished(problem, space, best, starts, t0)


def finished(problem: Problem, space: Space, res, starts: int, t0: float,
             alternatives: Sequence = ()) -> ExportFit:
    """The :class:`ExportFit` of a ``least_squares`` result ``res`` in ``space``."""
    rms = float(np.sqrt(2.0 * res.cost / res.fun.size))
    return ExportFit(space.to_material(res.x), bool(res.success), str(res.message),
                     problem.evaluations, rms, problem.samples, starts,
                     time.perf_counter() - t0, list(alternatives))
