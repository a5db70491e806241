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

Here: the constants and the lobes themselves (eqs. 1-3). Each step has its module, which
its callers import it from: choosing exponents (seed 001 §3.2, eq. 4):
:func:`.basis.select_basis`; fitting weights (seed 001 §4, eqs. 5-6):
:func:`.solve.fit_weights` with a solver of :data:`.solvers.WEIGHT_SOLVERS`; samples (seed
001 §4): :data:`.samples.SAMPLE_SETS`; angle-dependent weights (seed 001 §5.2):
:func:`.solve.fit_weight_table`, one fit per view angle, a table the renderer
interpolates; what the lobes hold against the material: :mod:`.energy`. ``gonio lobes``
as library calls: :mod:`.run`.

Rendering with prefiltered maps (docs/conventions.md: P_E is the *normalised* average
∫ L max(0, r·ω)^E dω / ∫ max(0, r·ω)^E dω, and ∫_sphere max(0, r·ω)^E dω = 2π/(E+1)):

    L_o = K_D π P_1(N) + (R·N) Σ K_DD,i 2π/(E_i+1) P_Ei(R) + Σ K_G,i 2π/(E_i+1) P_Ei(R)

(seed 001 eqs. 7-9 with the normalisation written out).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..schemas import EXPONENT_RANGE

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

#: Lights per view of the ``hemisphere`` sample set: ~3.9° apart (median; 8° from the
#: farthest direction) on the half hemisphere, finer than the narrowest lobe the demo's
#: materials need (E ≈ 70, half-width 8°) but not than a glossy paint's (E ≈ 1e3, 2°).
HEMISPHERE_POINTS = 200

#: The diffuse column (L·N) whose largest value over the samples is below this is "not
#: seen": its weight would be undetermined (any value fits), so the sample set is refused.
UNSEEN_COLUMN = 1e-300

#: A lobe is *resolved* by a view's samples when its largest value over them is at least
#: this fraction of its peak (1, on its axis): some sample lies within the lobe's
#: half-width at half maximum, acos(2^(-1/E)) ≈ sqrt(2 ln 2 / E) rad (0.67° at E = 1e4,
#: 2.1° at 1e3, 8° at 70), of its axis. A lobe the samples see only in its tail gets the
#: data divided by that tail as its weight: 1e-17 at every sample (E = 1e4, nearest
#: sample 5° off its axis) lets any weight up to ~1e17 fit, and a fit put 4.5e13 there.
#: At half maximum a sample's value pins the weight to within a factor 2 of the peak it
#: implies. Such a lobe is left out of that view's fit (weight 0, with a warning).
LOBE_RESOLVED_MIN = 0.5

#: What the fitted lobes hold, against the material's directional albedo (per view angle
#: and channel; their integrals as the renderer uses them, π K_D + Σ (K_G + cos θv K_DD)
#: 2π/(E+1), against ∫ f cos θi dω of the material). A sound fit holds about 1× (hemisphere
#: samples: 0.96-1.24 on the demo's inks and paint and two measured materials). In-plane
#: samples (seed 001 §4) see no light across the plane, so at oblique views their round
#: lobes stand for a gloss far narrower across it: 2.3-2.4× on the demo's inks, 4.7× on its
#: paint, 21-40× at 80° on glossy clear coats (measured) — seed 001's own limitation, a
#: warning above ENERGY_EXCESS_WARN. A weight extrapolated from a lobe's tail holds
#: 1e6-1e14× (4.5e13 in the issue): refused above ENERGY_EXCESS_MAX (``--max-energy-ratio``),
#: 25× above the worst in-plane figure, 1000× below the blow-ups.
ENERGY_EXCESS_WARN = 10.0
ENERGY_EXCESS_MAX = 1000.0

#: Channels darker than this fraction of the view's brightest channel are compared with
#: that fraction instead (a dark band's albedo near 0 would make any lobe look excessive;
#: 1 % of the peak is below what a rendered colour shows).
ALBEDO_FLOOR_REL = 0.01

#: Mirror-dense hemisphere (``--mirror-dense``): rings of lights around the mirror
#: direction of each view, merged with the spiral by a smooth partition of unity so the
#: sum Σ w f is a quadrature of ∫ f dω over the half hemisphere. Panels in θ (the angle
#: from the mirror direction) double from MIRROR_RING_INNER_DEG, a third of the
#: half-width of the narrowest lobe (E = 1e4, 0.67°), to the blend's outer edge; each
#: panel has MIRROR_RING_GAUSS Gauss–Legendre radii in u = 1 − cos θ (a lobe is ≈ exp(−E u):
#: 3 points per doubling integrate it to < 0.3 % for every E, measured).
MIRROR_RING_INNER_DEG = 0.2
MIRROR_RING_RATIO = 2.0
MIRROR_RING_GAUSS = 3
#: The rings take the whole weight within MIRROR_BLEND_DEG[0] of the mirror direction and
#: hand it to the spiral by MIRROR_BLEND_DEG[1] (a smoothstep between). A lobe narrower
#: than the spiral's spacing (E ≳ 200, 1/sqrt(E) ≤ 4°) has its mass within 3/sqrt(E) ≤ 12°
#: of its axis, so the rings alone integrate it; wider lobes pass through the blend, which
#: spans ~4 spiral spacings so that each rule integrates a smooth function. Measured on
#: lobes E = 1 … 1e4 (tests/test_lobes_quadrature.py): < 0.5 % error at every view 0-80°;
#: blending over 6-20° instead cost 2.4 %, a hard edge 1.5 %.
MIRROR_BLEND_DEG = (15.0, 30.0)
#: Azimuthal spacing of the lights along a ring (deg of arc, ~1.5 spiral spacings: the
#: spiral shares the blend's outer rings), with at least MIRROR_RING_AZIMUTHS per half
#: ring: the midpoint rule on 4 azimuths integrates the cos ψ … cos 7ψ terms of a BRDF
#: that is not round about R (a peak elongated across the plane) exactly. ~340 lights per
#: view in all (~190 of the spiral's 200 keep some weight; ~150 on the rings).
MIRROR_RING_SPACING_DEG = 6.0
MIRROR_RING_AZIMUTHS = 4

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
    lo, hi = EXPONENT_RANGE
    bad = e[~(np.isfinite(e) & (e >= lo) & (e <= hi))]
    if bad.size:
        raise InputError(f"{where}: exponent {bad[0]:g} is outside [{lo:g}, {hi:g}]",
                         fix="a cosine-lobe exponent E is at least 1 (the diffuse lobe, "
                             "seed 001 eq. 2) and at most 1e6")
    return e
