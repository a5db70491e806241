"""Cosine-lobe approximation of BRDFs (seed 001, Shimizu & Meyer): the core of ``gonio lobes``.

Representation (seed 001 §3.1). With L the light, V the view, N the normal and
R = 2 (N·L) N − L the mirror direction of the light, the reflected radiance per unit
incident radiance and solid angle is

    f cos θi = K_D (L·N)                                   (eq. 1, diffuse)
             + (L·N) Σ_i K_DD,i (R·V)^E_i                  (eq. 3, directional diffuse)
             + Σ_i K_G,i (R·V)^E_i                         (eq. 2, gloss)

so every weight is in sr⁻¹ and the quantity fitted is the **cosine-weighted** BRDF
f · cos θi of the target (the BRDF itself never includes cos θi, docs/conventions.md; the
seed's equations are written for reflected light, which does). A pure Lambertian
f = ρ/π is exactly K_D = ρ/π with every lobe weight 0. Negative dot products are clamped
to zero, as seed 001 notes under eq. 1: (R·V) ≤ 0 gives a lobe value of exactly 0.

Choosing exponents (seed 001 §3.2, eq. 4): :func:`select_basis`. Fitting weights
(seed 001 §4, eqs. 5-6): :func:`fit_weights` with a solver of :data:`WEIGHT_SOLVERS`.
Samples (seed 001 §4): :data:`SAMPLE_SETS`. Angle-dependent weights (seed 001 §5.2):
:func:`fit_weight_table`, one fit per view angle, a table the renderer interpolates.

Rendering with prefiltered maps (docs/conventions.md: P_E is the *normalised* average
∫ L max(0, r·ω)^E dω / ∫ max(0, r·ω)^E dω, and ∫_sphere max(0, r·ω)^E dω = 2π/(E+1)):

    L_o = K_D π P_1(N) + (R·N) Σ K_DD,i 2π/(E_i+1) P_Ei(R) + Σ K_G,i 2π/(E_i+1) P_Ei(R)

(seed 001 eqs. 7-9 with the normalisation written out).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from ..errors import FitError, InputError
from ..geometry import cosines, in_plane_directions, reflect

# ------------------------------------------------------------------------ constants --

#: Floor of a cosine before its log: exp(E log 1e-300) underflows cleanly to 0 for every
#: E ≥ 1 instead of log(0) = −inf giving NaN at E·(−inf) when E = 0 is mistyped.
COS_LOG_FLOOR = 1e-300

#: Admissible exponents. E = 1 is the widest lobe the renderer's diffuse map uses (seed
#: 001 eq. 9); at E = 1e4 the lobe is ~0.8° wide (half maximum), finer than any
#: goniometer aperture or the near-mirror samples (1° apart), so wider ones are not seen.
EXPONENT_MIN = 1.0
EXPONENT_MAX = 1e4

#: Samples whose light or view is more than this many degrees from the normal are left
#: out: the target models are 0 or unreliable at grazing (Smith G → 0, cos θi → 0).
HORIZON_DEG = 85.0

#: Lights per view of the ``hemisphere`` sample set: ~3.7° apart on the half hemisphere,
#: finer than the narrowest lobe the demo's materials need (E ≈ 70, ~7° wide).
HEMISPHERE_POINTS = 200

#: A lobe column whose largest value over the samples is below this is "not seen": its
#: weight would be undetermined (any value fits), so the sample set is refused.
UNSEEN_COLUMN = 1e-300

#: Default view angles (deg) of the weight table (seed 001 §5.2), interpolated by the
#: renderer; 10° steps resolve the colour shift of the sample inks (c ≤ 6, seed 000).
DEFAULT_VIEW_ANGLES_DEG = (0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0)

#: View angles (deg) whose samples together form the "global" set used to choose the
#: basis (seed 001 Figure 4 shows 10, 40 and 70°): ~60 samples with ``seed001``.
GLOBAL_VIEW_ANGLES_DEG = (10.0, 40.0, 70.0)

#: Default time limit of one LP (s, one view angle, all channels): seed 001 §4 asks for
#: one so a slow solve cannot stall an interactive design session; a ~20 × 17 LP over 41
#: channels takes ~1-2 ms (``lp``) to ~50 ms (``highs``).
LP_TIME_LIMIT_S = 1.0

#: The three components in the order of the design matrix's columns.
COMPONENTS = ("diffuse", "directional_diffuse", "gloss")


# ------------------------------------------------------------------ lobes, eqs. 1-3 --

def cosine_lobe(cos_rv, exponents) -> np.ndarray:
    """Phong cosine lobes max(0, R·V)^E (seed 001 eqs. 2-3), evaluated as exp(E log cos).

    Parameters
    ----------
    cos_rv : (...,) float
        R·V, the cosine between the mirror direction of the light and the view.
    exponents : (m,) float
        Exponents E > 0 (1 … 1e4 in practice).

    Returns
    -------
    (..., m) float in [0, 1]: exactly 0 where R·V ≤ 0 (the clamp of seed 001 §3.1),
    1 at R·V = 1 for every E, and for E up to 1e4 never overflow or NaN: values that
    are below float64's range underflow to 0. NaN in ``cos_rv`` stays NaN.
    """
    c = np.asarray(cos_rv, dtype=float)[..., None]
    e = np.asarray(exponents, dtype=float)
    log_c = np.log(np.clip(c, COS_LOG_FLOOR, 1.0))
    with np.errstate(under="ignore"):
        value = np.exp(e * log_c)
    return np.where(c > 0.0, value, np.where(np.isnan(c), np.nan, 0.0))


def lobe_integral(exponents) -> np.ndarray:
    """∫ over the sphere of max(0, r·ω)^E dω = 2π/(E+1) (sr), the factor that turns a
    normalised prefiltered map P_E back into the lobe's integral (module docstring;
    seed 001 eqs. 7-8). ``exponents`` (...) → (...)."""
    return 2.0 * np.pi / (np.asarray(exponents, dtype=float) + 1.0)


def phong_normalisation(shininess) -> np.ndarray:
    """(n + 2)/(2π) (sr⁻¹): the factor of the normalised Phong lobe (seed 000 ref. 27), so
    that f = (n+2)/(2π) max(0, R·V)^n reflects all light at normal incidence."""
    return (np.asarray(shininess, dtype=float) + 2.0) / (2.0 * np.pi)


def phong_lobe(cos_rv, shininess: float) -> np.ndarray:
    """The normalised Phong lobe (n+2)/(2π) max(0, R·V)^n (sr⁻¹, no cos θi factor),
    (...,) for R·V (...,): :func:`cosine_lobe` (its clamp and underflow guard) times
    :func:`phong_normalisation`. The dim substrate of seed 000 Figure 8."""
    return phong_normalisation(shininess) * cosine_lobe(cos_rv, [shininess])[..., 0]


def design_matrix(cos_theta_i, cos_rv, exponents) -> np.ndarray:
    """Columns of seed 001 eqs. 1-3 (and eq. 6) for weights [K_D, K_DD,1..m, K_G,1..m].

    Parameters
    ----------
    cos_theta_i : (N,) float, L·N of each sample (clamped to ≥ 0).
    cos_rv : (N,) float, R·V of each sample.
    exponents : (m,) float > 0.

    Returns
    -------
    M : (N, 1 + 2m) float. M @ x is f cos θi (sr⁻¹ × cosine) of the lobe model with
    weights x: column 0 = L·N (eq. 1), columns 1..m = (L·N)(R·V)^E_i (eq. 3),
    columns m+1..2m = (R·V)^E_i (eq. 2).
    """
    ci = np.clip(np.asarray(cos_theta_i, dtype=float), 0.0, 1.0)
    lobes = cosine_lobe(cos_rv, exponents)
    return np.concatenate([ci[:, None], ci[:, None] * lobes, lobes], axis=1)


def split_weights(x: np.ndarray, n_lobes: int) -> dict[str, np.ndarray]:
    """Weights (1 + 2m, ...) → {"diffuse": (...), "directional_diffuse": (m, ...),
    "gloss": (m, ...)} in the column order of :func:`design_matrix`."""
    return dict(zip(COMPONENTS, (x[0], x[1:1 + n_lobes], x[1 + n_lobes:1 + 2 * n_lobes])))


def check_exponents(exponents, where: str = "basis") -> np.ndarray:
    """Validate exponents (m,): at least one, each in schemas.EXPONENT_RANGE [1, 1e6].
    Raises InputError naming them."""
    e = np.asarray(exponents, dtype=float).ravel()
    if e.size == 0:
        raise InputError(f"{where}: the basis is empty (no exponents)",
                         fix="choose one with gonio lobes basis or pass --exponents 1,10,100")
    from ..schemas import EXPONENT_RANGE

    lo, hi = EXPONENT_RANGE
    bad = e[~(np.isfinite(e) & (e >= lo) & (e <= hi))]
    if bad.size:
        raise InputError(f"{where}: exponent {bad[0]:g} is outside [{lo:g}, {hi:g}]",
                         fix="a cosine-lobe exponent E is at least 1 (the diffuse lobe, "
                             "seed 001 eq. 2) and at most 1e6")
    return e


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
    if kind not in CHANNELS:
        raise InputError(f"--channels {kind!r} is unknown", fix=f"use one of {', '.join(CHANNELS)}")
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


# -------------------------------------------------------------------- weight solvers --

#: Outcomes of a weight solve (``WeightFit.status``, and per view in the artifact).
#: Only ``failed`` of the solver whose weights are written is an error; everything else,
#: and every outcome of a comparison solver, is recorded as it is.
STATUSES = {
    "optimal": "the solver's problem solved to optimality",
    "time_limit": "stopped at the time limit: the weights are the best point the solver "
                  "had (feasible, x >= 0) but not the optimum",
    "clamped": "least squares with its negative weights set to 0 (optimal for nothing)",
    "failed": "the solver gave no solution (weights 0)",
}
#: Statuses of a solve that finished its own problem (a ``WeightFit`` with ``success``).
FINISHED = ("optimal", "clamped")


@dataclass
class WeightFit:
    """One weight fit (seed 001 eqs. 5-6), like scipy's ``OptimizeResult``.

    weights : (K, C) float ≥ 0, K = 1 + 2m in :func:`design_matrix` order.
    l1 : Σ over samples and channels of |M x − b| (what the LP minimises).
    rms : sqrt(mean (M x − b)²); rms_relative : sqrt(Σ r² / Σ b²) (scale-free).
    time_s : wall time of the solve; status : a key of :data:`STATUSES`; message : how
    the solver ended. ``success`` is status ≠ failed and ≠ time_limit.
    """

    solver: str
    weights: np.ndarray
    l1: float
    rms: float
    rms_relative: float
    time_s: float
    status: str = "optimal"
    message: str = "solved"

    @property
    def success(self) -> bool:
        return self.status in FINISHED


def _highs(M: np.ndarray, B: np.ndarray, time_limit_s: float = LP_TIME_LIMIT_S):
    """min Σ|M x − b| s.t. x ≥ 0 for every column of B, as one LP (seed 001 §4), by HiGHS.

    The L1 objective through slack variables ([Gas84] in seed 001): M x + u − v = b,
    u, v ≥ 0, minimise Σ (u + v); at the optimum u_n v_n = 0, so Σ(u + v) = Σ|r|. All C
    channels are one block-diagonal LP: one HiGHS call, no per-call overhead per channel.
    At the time limit the weights are HiGHS's last point if it has one, else x = 0 (every
    x ≥ 0 is feasible here), with status ``time_limit``.
    """
    from scipy import sparse
    from scipy.optimize import linprog

    N, K = M.shape
    C = B.shape[1]
    block = sparse.hstack([sparse.csr_array(M), sparse.eye_array(N), -sparse.eye_array(N)])
    A = sparse.kron(sparse.eye_array(C), block, format="csc")
    cost = np.tile(np.concatenate([np.zeros(K), np.ones(2 * N)]), C)
    res = linprog(cost, A_eq=A, b_eq=B.T.ravel(), bounds=(0, None), method="highs",
                  options={"time_limit": float(time_limit_s), "presolve": True})
    X = (np.zeros((K, C)) if res.x is None
         else np.maximum(res.x.reshape(C, K + 2 * N)[:, :K].T, 0.0))
    if res.status == 0 and res.x is not None:
        return X, "optimal", "optimal (HiGHS)"
    if res.status == 1:
        return X, "time_limit", (f"HiGHS stopped at its time limit of {time_limit_s:g} s "
                                 f"({res.message.strip()}); "
                                 f"{'its last point' if res.x is not None else 'x = 0'} kept")
    return X, "failed", f"HiGHS failed: {res.message.strip()}"


#: Samples per view above which ``lp`` hands the LP to HiGHS: the dense tableau's work
#: grows ~N³ (N pivots of an N × (K + 2N) tableau), HiGHS's far slower. Measured per view
#: (41 channels, 8 lobes): 19 samples (seed001) 2 ms against HiGHS's 50 ms, 58 (dense)
#: 20 ms against 190 ms, 200 (hemisphere) over 1 s against 0.5 s.
WARM_SIMPLEX_MAX_SAMPLES = 80


def _lp_warm(M: np.ndarray, B: np.ndarray, time_limit_s: float = LP_TIME_LIMIT_S):
    """The LP by the warm-started exact simplex of :mod:`gonio_cli.lobes.simplex` (numpy:
    no compiler to load; the channels share M, so each starts from the last optimal
    basis). A channel the simplex cannot certify is re-solved by HiGHS, and so is the
    whole LP when a view has more than :data:`WARM_SIMPLEX_MAX_SAMPLES` samples."""
    from .simplex import lp_l1_warm

    if M.shape[0] > WARM_SIMPLEX_MAX_SAMPLES:
        X, status, message = _highs(M, B, time_limit_s)
        return X, status, (f"{message}; by HiGHS: {M.shape[0]} samples per view is above "
                           f"the warm simplex's {WARM_SIMPLEX_MAX_SAMPLES}")
    start = time.perf_counter()
    X, iterations, status = lp_l1_warm(M, B, deadline=start + time_limit_s)
    message = (f"warm-started simplex, {int(iterations.sum())} pivots, "
               f"{int(np.count_nonzero(iterations))} of {B.shape[1]} channels pivoted")
    return _finish_simplex(M, B, X, status, message, start, time_limit_s,
                           "the last optimal basis, clamped to >= 0")


def _lp_simplex(M: np.ndarray, B: np.ndarray, time_limit_s: float = LP_TIME_LIMIT_S):
    """The same LP by the compiled dense simplex of :mod:`gonio_cli.lobes.simplex`
    (numba, ~20 µs per channel once loaded); a channel that hits its iteration cap
    (cycling on a degenerate problem) is re-solved by HiGHS."""
    from .simplex import lp_l1_simplex

    start = time.perf_counter()
    X, iterations, status = lp_l1_simplex(M, B, deadline=start + time_limit_s)
    message = f"dense simplex, {int(iterations.max())} pivots at most"
    return _finish_simplex(M, B, X, status, message, start, time_limit_s, "x = 0")


def _finish_simplex(M, B, X, status, message, start, time_limit_s, unsolved: str):
    """Shared ending of the simplex solvers: channels with status 2 (cap or numerics) go to
    HiGHS with the time left; status 1 (deadline) makes the whole solve ``time_limit``,
    ``unsolved`` saying what those channels' weights are."""
    outcome = "optimal"
    failed = status == 2
    if failed.any():
        left = max(time_limit_s - (time.perf_counter() - start), 1e-3)
        X[:, failed], outcome, note = _highs(M, B[:, failed], left)
        message += f"; {int(failed.sum())} channels re-solved by HiGHS ({note})"
    late = int(np.count_nonzero(status == 1))
    if late:
        return X, "time_limit", (f"stopped at the time limit of {time_limit_s:g} s with "
                                 f"{late} of {B.shape[1]} channels unsolved (their weights: "
                                 f"{unsolved}); {message}")
    return X, outcome, f"{outcome} ({message})"


def _nnls(M: np.ndarray, B: np.ndarray, time_limit_s: float = LP_TIME_LIMIT_S):
    """Non-negative least squares per channel (scipy.optimize.nnls, Lawson–Hanson)."""
    from scipy.optimize import nnls

    X = np.empty((M.shape[1], B.shape[1]))
    for c in range(B.shape[1]):
        X[:, c] = nnls(M, B[:, c])[0]
    return X, "optimal", "optimal (Lawson-Hanson)"


def _lsq_clamp(M: np.ndarray, B: np.ndarray, time_limit_s: float = LP_TIME_LIMIT_S):
    """Least squares, then negative weights clamped to 0 (as [KM00]; seed 001 §4 explains
    why it fails: the clamped lobes' error is never corrected by the others)."""
    X = np.linalg.lstsq(M, B, rcond=None)[0]
    clamped = int(np.sum(X < 0))
    return np.maximum(X, 0.0), "clamped", f"{clamped} negative weights clamped to 0"


def _load_compiled_simplex() -> None:
    """Load the numba kernel (disk cache) before the clock and the time limit start."""
    from .simplex import warm_up

    warm_up()


@dataclass(frozen=True)
class WeightSolver:
    """A weight solver: ``solve(M, B, time_limit_s) → (X, status, message)``; ``prepare``
    (optional) runs once before timing (loading a compiled kernel is not solving)."""

    solve: Callable
    description: str
    prepare: Callable | None = None


#: Weight solvers by name. ``lp`` (the default) and ``highs`` solve the same LP; ``highs``
#: is the reference the exact simplex solvers are tested against.
WEIGHT_SOLVERS: dict[str, WeightSolver] = {
    "lp": WeightSolver(_lp_warm, "min Σ|Mx − b|, x ≥ 0 (seed 001 §4) by an exact simplex "
                                 "warm-started across channels (numpy), ~1-2 ms per view "
                                 "of seed001's set; by HiGHS above 80 samples per view"),
    "highs": WeightSolver(_highs, "the same LP by scipy's HiGHS (the reference), ~10-50 ms "
                                  "per view, mostly set-up"),
    "lp-simplex": WeightSolver(_lp_simplex, "the same LP by a compiled (numba) dense "
                                            "simplex: fastest per call, ~0.5 s to load",
                               _load_compiled_simplex),
    "nnls": WeightSolver(_nnls, "min Σ(Mx − b)², x ≥ 0: scipy nnls"),
    "lsq-clamp": WeightSolver(_lsq_clamp, "least squares, negatives clamped to 0 (the failure "
                                          "seed 001 §4 describes)"),
}
DEFAULT_SOLVER = "lp"


def check_solver(name: str) -> str:
    if name not in WEIGHT_SOLVERS:
        raise InputError(f"--solver {name!r} is unknown",
                         fix=f"use one of {', '.join(WEIGHT_SOLVERS)}")
    return name


def residual_errors(M: np.ndarray, X: np.ndarray, B: np.ndarray) -> tuple[float, float, float]:
    """(L1, RMS, relative RMS) of M X − B over every sample and channel."""
    r = M @ X - B
    total = float(np.sum(B * B))
    return (float(np.sum(np.abs(r))), float(np.sqrt(np.mean(r * r))),
            float(np.sqrt(np.sum(r * r) / total)) if total > 0 else 0.0)


def check_design(M: np.ndarray, exponents, where: str = "") -> None:
    """Refuse a sample set that leaves a weight undetermined: a column of M (a lobe the
    samples never see, R·V ≤ 0 or underflowing everywhere) with no non-zero value."""
    if M.shape[0] == 0:
        raise FitError(f"{where}the sample set is empty", fix="use a sample set with samples")
    seen = np.max(np.abs(M), axis=0) > UNSEEN_COLUMN
    if not seen.all():
        k = int(np.argmin(seen))
        m = (M.shape[1] - 1) // 2
        what = "the diffuse term" if k == 0 else (
            f"the {'directional-diffuse' if k <= m else 'gloss'} lobe "
            f"E={np.asarray(exponents)[(k - 1) % m]:g}")
        raise FitError(f"{where}no sample sees {what} (its column of seed 001 eq. 6 is "
                       "zero), so the LP cannot determine its weight",
                       fix="add samples near the mirror direction (R·V > 0)")


def fit_weights(M: np.ndarray, B: np.ndarray, solver: str = DEFAULT_SOLVER,
                time_limit_s: float = LP_TIME_LIMIT_S) -> WeightFit:
    """Non-negative weights x (K, C) with M x ≈ B (seed 001 eqs. 5-6).

    Parameters
    ----------
    M : (N, K) float, :func:`design_matrix`; B : (N, C) float, :func:`target_values`.
    solver : a key of :data:`WEIGHT_SOLVERS`; time_limit_s : the LP's time limit.

    Never raises for a solver's outcome: a time limit or a failure is the result's
    ``status`` (:data:`STATUSES`) and ``message``.
    """
    check_solver(solver)
    if not np.all(np.isfinite(B)):
        raise FitError("the target holds NaN or inf at some sample",
                       fix="check the material's parameters")
    entry = WEIGHT_SOLVERS[solver]
    if entry.prepare is not None:
        entry.prepare()
    start = time.perf_counter()
    X, status, message = entry.solve(M, B, time_limit_s)
    elapsed = time.perf_counter() - start
    l1, rms, rel = residual_errors(M, X, B)
    return WeightFit(solver, X, l1, rms, rel, elapsed, status, message)


# --------------------------------------------------------------- weight table (§5.2) --

@dataclass
class WeightTable:
    """Weights per view angle (seed 001 §5.2) and every solver's errors.

    exponents : (m,) ; view_angle_deg : (V,) ; channels : labels (C,)
    diffuse : (V, C) ; directional_diffuse, gloss : (V, m, C), all ≥ 0, sr⁻¹.
    errors : {solver: {"l1", "rms", "rms_relative", "time_s", "status", "message": (V,)
        lists}}, the written solver first, then the comparisons; status per view is a key
        of :data:`STATUSES`.
    n_samples : (V,) samples per view angle.
    """

    exponents: np.ndarray
    view_angle_deg: np.ndarray
    channels: list
    diffuse: np.ndarray
    directional_diffuse: np.ndarray
    gloss: np.ndarray
    errors: dict[str, dict[str, list]]
    n_samples: list
    solver: str
    time_s: float = 0.0


def fit_weight_table(material, exponents, samples: Samples, channels: str = "spectral",
                     solver: str = DEFAULT_SOLVER, compare: Sequence[str] = (),
                     time_limit_s: float = LP_TIME_LIMIT_S) -> WeightTable:
    """Fit the weights at every view angle of ``samples`` (seed 001 §4 and §5.2).

    ``solver`` gives the weights written; every solver in ``compare`` (none by default) is
    also run on the same samples and its errors, time and status reported. A time limit
    reached, by ``solver`` or a comparison, is a status per view (``time_limit``), never
    an error. Raises FitError if a view's samples leave a weight undetermined
    (:func:`check_design`) or ``solver`` itself returns no solution (``failed``).
    """
    e = check_exponents(exponents)
    check_solver(solver)
    for s in compare:
        check_solver(s)
    b_all, labels = target_values(material, samples, channels)
    M_all = design_matrix(samples.cos_theta_i(), samples.cos_rv(), e)
    V, m, C = samples.view_angle_deg.size, e.size, b_all.shape[1]
    X = np.zeros((V, 1 + 2 * m, C))
    solvers = [solver] + [s for s in compare if s != solver]
    keys = ("l1", "rms", "rms_relative", "time_s", "status", "message")
    errors = {s: {key: [] for key in keys} for s in solvers}
    counts = []
    start = time.perf_counter()
    for k, tv in enumerate(samples.view_angle_deg):
        rows = samples.view_index == k
        where = f"view angle {tv:g} deg: "
        M, B = M_all[rows], b_all[rows]
        check_design(M, e, where)
        counts.append(int(rows.sum()))
        for s in solvers:
            r = fit_weights(M, B, s, time_limit_s)
            if s == solver:
                if r.status == "failed":
                    raise FitError(f"{where}the {s} weight solver failed ({r.message})",
                                   fix="try another --solver (e.g. highs)")
                X[k] = r.weights
            for key in keys:
                errors[s][key].append(getattr(r, key))
    parts = split_weights(np.moveaxis(X, 0, 1), m)            # leading axis K → parts
    return WeightTable(e, samples.view_angle_deg, labels, parts["diffuse"],
                       np.moveaxis(parts["directional_diffuse"], 0, 1),
                       np.moveaxis(parts["gloss"], 0, 1), errors, counts, solver,
                       time.perf_counter() - start)


# ------------------------------------------------------------ basis selection (§3.2) --

@dataclass
class BasisStep:
    """The best basis of one lobe count (seed 001 Figures 2 and 3).

    exponents : (m,) sorted ; error : eq. 4, max + mean relative RMS over the database ;
    max_error, mean_error : its two terms ; per_material : relative RMS per material ;
    evaluations : objective evaluations ; time_s ; message : how the search ended.
    """

    n_lobes: int
    exponents: np.ndarray
    error: float
    max_error: float
    mean_error: float
    per_material: list
    evaluations: int
    time_s: float
    message: str


@dataclass
class BasisResult:
    steps: list[BasisStep] = field(default_factory=list)
    solver: str = "nnls"
    n_samples: int = 0
    time_s: float = 0.0


#: Solvers the basis search may use inside eq. 4. ``nnls`` minimises the very RMS that
#: eq. 4 measures, so the objective is continuous in E and can only fall when a lobe is
#: added; ``lp-simplex`` (seed 001's LP, the fast exact solver: HiGHS would take minutes
#: over thousands of evaluations) gives vertex solutions that jump with E.
BASIS_SOLVERS = ("nnls", "lp-simplex")

#: nlopt settings of the exponent search (log E): stop when log E moves < 1e-3 (0.1 % in
#: E, far below what changes a prefiltered map) or the objective < 1e-6 relative.
BASIS_XTOL_LOG = 1e-3
BASIS_FTOL_REL = 1e-6
#: Objective evaluations per exponent being searched (the search is m-dimensional).
BASIS_EVALS_PER_LOBE = 150


def basis_objective(log_exponents, cos_theta_i, cos_rv, groups, targets: Sequence[np.ndarray],
                    solver: str = "nnls"):
    """Seed 001 eq. 4: max_i Error(E, B_i) + mean_i Error(E, B_i).

    The weights are fitted per group of samples (one view angle each, as
    :func:`fit_weight_table` will use them, seed 001 §5.2), and Error(E, B_i) is the
    relative RMS sqrt(Σ r² / Σ b²) of material i over every group, sample and channel,
    so bright and dark materials count alike.

    Parameters
    ----------
    log_exponents : (m,) log E ; cos_theta_i, cos_rv, groups : (N,) ; targets : n arrays
    (N, C). Returns (f, per-material errors (n,)).
    """
    M = design_matrix(cos_theta_i, cos_rv, np.exp(np.asarray(log_exponents, dtype=float)))
    errs = np.empty(len(targets))
    for i, B in enumerate(targets):
        sse = sum(np.sum((M[g] @ fit_weights(M[g], B[g], solver).weights - B[g]) ** 2)
                  for g in groups)
        total = float(np.sum(B * B))
        errs[i] = np.sqrt(sse / total) if total > 0 else 0.0
    return float(errs.max() + errs.mean()), errs


def _gap_starts(log_e: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Candidate log-exponents for a new lobe: midpoints of the gaps between the lobes
    already found and the bounds (seed 001 Fig. 2: exponents spread evenly in log E)."""
    points = np.sort(np.concatenate([[lo, hi], log_e]))
    return 0.5 * (points[:-1] + points[1:])


def select_basis(targets: Sequence[np.ndarray], samples: Samples, max_lobes: int = 11,
                 solver: str = "nnls", exponent_range=(EXPONENT_MIN, EXPONENT_MAX),
                 progress: Callable | None = None) -> BasisResult:
    """Choose exponents for 1 … ``max_lobes`` lobes by nlopt over log E (seed 001 §3.2).

    Parameters
    ----------
    targets : n arrays (N, C), each material's b at ``samples`` (the database).
    samples : :class:`Samples`; weights are fitted per view angle (eq. 4's Error).
    max_lobes : the largest lobe count; solver : one of :data:`BASIS_SOLVERS`.
    progress : optional wrapper of the lobe-count loop (a progress bar).

    One lobe is added at a time; each search starts from the lobes already found plus
    the best gap midpoint (:func:`_gap_starts`), and keeps the best point it evaluated,
    so with ``nnls`` (whose residual cannot grow when a column is added) the error never
    rises with the lobe count. nlopt LN_SBPLX (Subplex: derivative-free, robust to the
    kinks the max in eq. 4 makes) on log E within ``exponent_range``.
    """
    import nlopt

    if solver not in BASIS_SOLVERS:
        raise InputError(f"--solver {solver!r} is not usable for the basis search",
                         fix=f"use one of {', '.join(BASIS_SOLVERS)}")
    if not targets:
        raise InputError("no material to choose a basis for", fix="pass MATERIAL.json files")
    if int(max_lobes) < 1:
        raise InputError(f"--max-lobes {max_lobes} is below 1", fix="e.g. --max-lobes 11")
    lo, hi = np.log(exponent_range[0]), np.log(exponent_range[1])
    if not (np.isfinite(lo) and np.isfinite(hi) and hi > lo):
        raise InputError(f"exponent range {exponent_range} is not 0 < min < max")
    result = BasisResult(solver=solver, n_samples=samples.n_samples)
    cos_theta_i, cos_rv = samples.cos_theta_i(), samples.cos_rv()
    groups = [samples.view_index == k for k in range(samples.view_angle_deg.size)]
    start_all = time.perf_counter()
    log_e = np.empty(0)
    counts = range(1, int(max_lobes) + 1)
    for m in (progress(counts) if progress else counts):
        t0 = time.perf_counter()
        best = {"x": None, "f": np.inf, "errs": None}
        evals = {"n": 0}

        def f(x):
            evals["n"] += 1
            value, errs = basis_objective(x, cos_theta_i, cos_rv, groups, targets, solver)
            if value < best["f"]:
                best.update(x=np.array(x, dtype=float), f=value, errs=errs)
            return value

        for s in _gap_starts(log_e, lo, hi):
            f(np.append(log_e, s))
        x0 = best["x"].copy()
        opt = nlopt.opt(nlopt.LN_SBPLX, m)
        opt.set_min_objective(lambda x, grad: f(x))
        opt.set_lower_bounds([lo] * m)
        opt.set_upper_bounds([hi] * m)
        opt.set_xtol_abs(BASIS_XTOL_LOG)
        opt.set_ftol_rel(BASIS_FTOL_REL)
        opt.set_maxeval(BASIS_EVALS_PER_LOBE * m)
        opt.set_initial_step(0.5)
        try:
            opt.optimize(x0)
            code = opt.last_optimize_result()
            message = {3: "converged (ftol)", 4: "converged (xtol)",
                       5: "stopped at maxeval"}.get(code, f"nlopt result {code}")
        except nlopt.RoundoffLimited:  # round-off stops: the best point evaluated stands
            message = "nlopt stopped (round-off limited); kept the best point"
        log_e = np.sort(best["x"])
        errs = best["errs"]
        if result.steps and best["f"] > result.steps[-1].error:
            message += "; error rose from the previous count (LP vertex jump; use nnls)"
        result.steps.append(BasisStep(m, np.exp(log_e), best["f"], float(errs.max()),
                                      float(errs.mean()), [float(v) for v in errs],
                                      evals["n"], time.perf_counter() - t0, message))
    result.time_s = time.perf_counter() - start_all
    return result
