"""Seed 000 eq. (5) plus what real surfaces add: a Lambertian term and a clear coat.

Models (in :mod:`gonio_cli.brdf`):

- ``goniochromatic-diffuse``: f = ρ_d(λ)/π + eq. 5(α, ρ(λ), c(λ)) — paper, binder or a
  base coat under the structural-colour layer.
- ``goniochromatic-coat``: the same plus an achromatic clear coat, a Torrance–Sparrow lobe
  (GGX α_coat, Smith G, Schlick F with one F0_coat for every wavelength) scaled by k_coat.
- ``goniochromatic-undercoat``: the same three terms with eq. 5 and ρ_d *under* the coat,
  seen through it: at the angles refracted into it and times its Fresnel transmission in
  and out (:func:`gonio_cli.brdf.goniochromatic_undercoat`). Both depend only on the
  geometry, so the fit is the coat's with other columns.
- ``goniochromatic-two-lobe``: eq. 5, ρ_d(λ) and a second GGX lobe of its own roughness
  α_2 and colour ρ_2(λ) (:func:`gonio_cli.brdf.goniochromatic_two_lobe`): for fixed α and
  α_2 the second lobe is a third non-negative column beside ρ_d and ρ
  (:func:`~.separable.profile_c_columns`, :func:`~.separable.nnls3`); the outer search is
  2-D, (log α, log α_2).

The fit keeps the separable structure of the default model. For fixed roughnesses (α and,
with a coat, α_coat, k_coat and F0_coat) the coat is a known offset o(θ), and each wavelength is

    min over c, ρ_d ≥ 0, ρ ≥ 0 of Σ_n w (ρ_d/π + ρ D(θh; α)/4 · e^{c x} + o − y)²,

a two-column non-negative least-squares problem in (ρ_d, ρ) with a closed form for any c,
and a 1-D search in c (:func:`~.separable.profile_c`): a scan of all wavelengths at once
(three matrix products) and safeguarded parabolic steps inside the best cell. The roughnesses are then
an outer search of 1 (diffuse) or 4 (coat) variables: a coarse scan and nlopt BOBYQA.

Residuals are linear in f with the weights :func:`~.common.prepare` made (compressive by
default; log residuals are taken to first order, (f − y)/y, since log f is not linear in
the parameters of a sum of lobes).
"""

from __future__ import annotations

import numpy as np

from ..brdf import (UNDERCOAT_INDEX, coat_transmission, evaluate, ggx_lobe,
                    goniochromatic_d4, goniochromatic_exponent_arg, opposition_surge,
                    torrance_sparrow)
from ..geometry import refracted_cosines
from .alpha import choose_optimizer, minimize_log_alpha
from .common import check_alpha, ALPHA_MAX, ALPHA_MIN, BestPoint, FitData
from .results import FitOptions, FitReport, ModelFit, Stopwatch, error_figures, nm_list
from .separable import C_LIMIT, nnls2, profile_c_columns
from .separable import CScan
from .warm import WARM_STEP, WARM_XTOL, log_alpha_window, near

#: The clear coat's F0 for a dielectric of refractive index 1.5 ((n − 1)/(n + 1))², the
#: start of its search.
F0_COAT_START = 0.04

#: F0_coat is searched in [F0_COAT_MIN, 1]: 0.02 is water (n = 1.33), below any coat
#: material. Without this floor the fit trades a tiny F0 (a Fresnel factor that grows
#: 20-fold towards grazing) against k_coat, and overshoots the grazing peaks of real
#: coated samples by 2× (measured on an RGL vinyl wrap).
F0_COAT_MIN = 0.02

#: Bounds of the opposition effect's amplitude B0 and width h
#: (:func:`gonio_cli.brdf.opposition_surge`). B0 ≤ 1 is shadow hiding's own limit (Hapke
#: 2012 §9.5: B0 = 1 when the particles are opaque); h from 0.01 (a surge a degree wide,
#: finer than any goniometer's angular step) to 2 (a surge wider than the hemisphere: the
#: term then tilts the whole body reflection towards the light).
B0_MAX = 1.0
H_MIN, H_MAX = 0.01, 2.0

#: (B0, h) tried from the coated fit before the 6-D refinement: none, a narrow and a
#: broad surge.
BACKSCATTER_STARTS = ((0.0, 0.1), (0.5, 0.05), (0.5, 0.3), (0.5, 1.0))

#: Evaluations allowed to the 6-D BOBYQA refinement with the opposition effect.
BACKSCATTER_MAXEVAL = 400

#: Start values of eq. 5's α tried with each coat start, beside the α of the fit without a
#: coat: that fit gives its lobe the sharpest peak in the data, which may be the coat's, and
#: BOBYQA from there does not swap the two lobes (on eq. 5 α 0.15 under a coat α 0.03 with
#: an opposition surge it ended at α 0.036, α_coat 0.19 with 24 % RMS error).
ALPHA_STARTS = (0.03, 0.1, 0.3)

#: Start values of α_coat and k_coat scanned before the 4-D refinement.
ALPHA_COAT_STARTS = (0.003, 0.01, 0.03, 0.1, 0.3)
K_COAT_STARTS = (0.1, 1.0)

#: Bounds of k_coat: 0 (no coat) to 10 (a coat ten times a smooth dielectric's, which
#: no real sample reaches; the bound only keeps the search finite).
K_COAT_MAX = 10.0

#: Scan points over log α of the diffuse model's 1-D search (every 33 % in α): each
#: evaluation is a search in c per wavelength, and the profile is smooth at that scale.
LAYERED_ALPHA_POINTS = 25

#: Evaluations allowed to the 4-D BOBYQA refinement of (log α, log α_coat, k_coat, F0_coat).
COAT_MAXEVAL = 300

#: Start values of ``goniochromatic-two-lobe``'s α_2 scanned with each α start (eq. 5's α
#: of the fit without the second lobe and :data:`ALPHA_STARTS`), beside that α itself:
#: the second lobe sharper or broader than the first, either lobe the one the data's
#: sharpest peak belongs to.
ALPHA_2_STARTS = (0.01, 0.03, 0.1, 0.3)

#: Evaluations allowed to the 2-D BOBYQA refinement of (log α, log α_2).
TWO_LOBE_MAXEVAL = 150


class Layered:
    """The separable problem of one data set: (ρ_d, ρ, c)(λ) for any fixed roughnesses."""

    def __init__(self, data: FitData, coat: bool = False, backscatter: bool = False,
                 undercoat: bool = False, second: bool = False):
        self.data, self.coat, self.backscatter = data, coat, backscatter
        self.second = second
        # eq. 5's geometry: the measured angles, or those refracted into the coat
        self.lobe_cos = (refracted_cosines(data.cos, UNDERCOAT_INDEX) if undercoat
                         else data.cos)
        #: the share the coat lets through, in and out (1 without one over the layer)
        self.through = coat_transmission(data.cos) if undercoat else None
        self.x = goniochromatic_exponent_arg(self.lobe_cos.cos_theta_i,
                                             self.lobe_cos.cos_theta_o)
        #: e^{c x} of the c search, made once for every roughness tried
        self.scan = CScan(self.x)
        # every wavelength with some weighted signal can be fitted
        self.signal = np.any((data.w > 0) & (data.y > 0), axis=0)
        # log residuals to first order: (f − y)/y, i.e. linear ones weighted by 1/y²
        self.w = (np.where(data.positive, data.w / np.where(data.positive, data.y, 1.0) ** 2,
                           0.0) if data.residuals == "log" else data.w)

    def coat_term(self, alpha_coat: float, k_coat: float, f0_coat: float) -> np.ndarray:
        """The clear coat's BRDF (N,): k · Torrance–Sparrow with an achromatic F0."""
        return k_coat * torrance_sparrow(self.data.cos, alpha_coat, np.array([f0_coat]))[:, 0]

    def solve(self, alpha: float, coat: tuple[float, float, float] | None = None,
              back: tuple[float, float] | None = None, alpha_2: float | None = None):
        """Returns (params dict, cost (L,), ok (L,)) for fixed roughnesses; ``coat`` is
        (α_coat, k_coat, F0_coat) for the coated model, ``back`` (B0, h) of the opposition
        effect for ``goniochromatic-backscatter`` (the diffuse column's shape 1 + B),
        ``alpha_2`` the second lobe's α for ``goniochromatic-two-lobe`` (its column)."""
        d = self.data
        t = d.y
        params: dict = {"alpha": float(alpha)}
        if self.coat:
            alpha_coat, k_coat, f0_coat = coat
            t = d.y - self.coat_term(alpha_coat, k_coat, f0_coat)[:, None]
            params.update(alpha_coat=float(alpha_coat), k_coat=float(k_coat),
                          f0_coat=float(f0_coat))
        shape = self.through
        if self.backscatter:
            b0, h = back
            shape = 1.0 + opposition_surge(d.cos.cos_theta_d, b0, h)
            params.update(b0=float(b0), h=float(h))
        g = goniochromatic_d4(self.lobe_cos.cos_theta_h, alpha)
        if self.through is not None:
            g = g * self.through
        extra = ggx_lobe(d.cos, alpha_2) if self.second else None
        rho_d, rho, c, cost, rho_2 = profile_c_columns(self.x, g, t, self.w, diffuse=True,
                                                       diffuse_shape=shape, extra=extra,
                                                       scan=self.scan)
        bound = np.abs(c) >= C_LIMIT * (1 - 1e-6)
        if np.any(bound & self.signal):
            # eq. 5's colour term ran to its bound: its lobe is not wanted there (the body,
            # or the second lobe, carries that wavelength, and a vanishing ρ e^{c x} bends
            # to the last grazing point). The best fit without it, if no worse than the
            # failure it replaces (ρ = ρ_d = c = 0 there)
            rd0, r20, cost0 = self._without_lobe(t, shape, extra)
            take = bound & self.signal & np.isfinite(cost0)
            rho, c = np.where(take, 0.0, rho), np.where(take, 0.0, c)
            rho_d, rho_2 = np.where(take, rd0, rho_d), np.where(take, r20, rho_2)
            cost = np.where(take, cost0, cost)
        ok = self.signal & np.isfinite(cost) & (np.abs(c) < C_LIMIT * (1 - 1e-6))
        params.update(rho=np.where(ok, rho, 0.0), c=np.where(ok, c, 0.0),
                      rho_d=np.where(ok, rho_d, 0.0))
        if self.second:
            params.update(alpha_2=float(alpha_2), rho_2=np.where(ok, rho_2, 0.0))
        return params, cost, ok

    def _without_lobe(self, t, shape, extra):
        """(ρ_d, ρ_2, cost) (L,) each of the targets ``t`` by the body (angular ``shape``,
        1 if None) and, with ``extra``, the second lobe alone: eq. 5's lobe left out."""
        a = (np.ones(t.shape[0]) if shape is None else np.asarray(shape, float))[:, None] / np.pi
        e = (np.zeros(t.shape[0]) if extra is None else np.asarray(extra, float))[:, None]
        w = self.w
        return nnls2(np.sum(w * a * a, axis=0), np.sum(w * a * e, axis=0),
                     np.sum(w * e * e, axis=0), np.sum(w * a * t, axis=0),
                     np.sum(w * e * t, axis=0), np.sum(w * t * t, axis=0))

    def cost(self, alpha, coat=None, back=None, alpha_2=None) -> float:
        """Total cost over the wavelengths with signal (a c at its bound still counts:
        leaving it out would make the worst roughness look the best)."""
        _, cost, _ = self.solve(alpha, coat, back, alpha_2)
        return float(np.sum(cost[self.signal]))


def _coat(v) -> tuple[float, tuple[float, float, float]]:
    """(α, (α_coat, k_coat, F0_coat)) of a search point (log α, log α_coat, k_coat,
    F0_coat, …), the coat never rougher than eq. 5's lobe: α_coat = min(α_coat, α). The
    clear coat is the smooth, achromatic surface over a rougher coloured layer; left free,
    a search can swap the two, a broad grey "coat" over a sharp coloured lobe: on a car
    paint of a coat α 0.015 over red flakes α 0.25 (benchmarks/glossy_bench.py,
    paint_ml_red) it ended at α 0.016, α_coat 0.24, F0_coat 0.27 and greyed the flakes."""
    alpha = float(np.exp(v[0]))
    return alpha, (min(float(np.exp(v[1])), alpha), float(v[2]), float(v[3]))


def _search_coat(problem: Layered, alpha0: float, sharpest: float | None = None,
                 warm: dict | None = None):
    """(α, (α_coat, k_coat, F0_coat), evaluations, message) minimising the profile cost:
    a coarse look at the coat from ``alpha0`` (the fit without it), then BOBYQA in
    (log α, log α_coat, k_coat, F0_coat). The look includes the coat as sharp as the
    sharpest peak in the data (``sharpest``, in the measured angles; default ``alpha0``)
    under each broader lobe: that peak is most often the coat's (a car paint's clear coat
    over its flakes)."""
    sharpest = alpha0 if sharpest is None else sharpest
    lo = np.array([np.log(ALPHA_MIN), np.log(ALPHA_MIN), 0.0, F0_COAT_MIN])
    hi = np.array([np.log(ALPHA_MAX), np.log(ALPHA_MAX), K_COAT_MAX, 1.0])
    if warm is not None:                    # a fold of auto: near the fit to all the data
        return _search_coat_warm(problem, warm)
    search = BestPoint(lambda v: problem.cost(*_coat(v)))
    for a in (alpha0,) + ALPHA_STARTS:
        for ac in ALPHA_COAT_STARTS + ((sharpest,) if a > sharpest else ()):
            for k in K_COAT_STARTS:
                search([np.log(a), np.log(ac), k, F0_COAT_START])
    message = search.bobyqa(lo, hi, [0.3, 0.5, 0.1, 0.02], COAT_MAXEVAL,
                            xtol_abs=[1e-6, 1e-6, 1e-7, 1e-7])
    return (*_coat(search.x), search.n, message)


def _coat_ratio(v) -> tuple[float, tuple[float, float, float]]:
    """:func:`_coat` of a warm search point (log α, log(α_coat/α) ≤ 0, k_coat, F0_coat,
    …): the same models, the coat never rougher than eq. 5's lobe, by a bound instead of
    a clamp. BOBYQA's quadratic model cannot follow the clamp's kink, where the coat of a
    matte sample ends (α_coat = α: 230-300 evaluations per fold on RGL cardboard, against
    60-120 with the bound)."""
    alpha = float(np.exp(v[0]))
    return alpha, (max(alpha * float(np.exp(v[1])), ALPHA_MIN), float(v[2]), float(v[3]))


def _ratio_point(p: dict) -> list[float]:
    """The warm search point (:func:`_coat_ratio`) of a fit's coat parameters ``p``."""
    return [np.log(p["alpha"]), min(np.log(p["alpha_coat"] / p["alpha"]), 0.0),
            p["k_coat"], p["f0_coat"]]


#: Bounds of (log α, log(α_coat/α), k_coat, F0_coat) of a warm coat search.
_RATIO_LO = np.array([np.log(ALPHA_MIN), np.log(ALPHA_MIN / ALPHA_MAX), 0.0, F0_COAT_MIN])
_RATIO_HI = np.array([np.log(ALPHA_MAX), 0.0, K_COAT_MAX, 1.0])


def _search_coat_warm(problem: Layered, warm: dict):
    """:func:`_search_coat` of a fold of ``--model auto``: BOBYQA from the fit to all the
    data (``warm``), by :func:`_coat_ratio`, with :data:`~.warm.WARM_STEP` first steps and
    :data:`~.warm.WARM_XTOL`."""
    search = BestPoint(lambda v: problem.cost(*_coat_ratio(v)))
    search(np.clip(_ratio_point(warm), _RATIO_LO, _RATIO_HI))
    message = search.bobyqa(_RATIO_LO, _RATIO_HI, WARM_STEP * np.array([0.3, 0.5, 0.1, 0.02]),
                            COAT_MAXEVAL, xtol_abs=WARM_XTOL * np.array([1, 1, 0.1, 0.1]))
    return (*_coat_ratio(search.x), search.n, message)


def _search_backscatter(problem: Layered, alpha0: float, coat0, warm: dict | None = None):
    """(α, coat, (B0, h), evaluations, message): from the coated fit (``alpha0``, ``coat0``),
    a look at :data:`BACKSCATTER_STARTS`, then BOBYQA in (log α, log α_coat, k_coat,
    F0_coat, B0, log h)."""
    lo = np.array([np.log(ALPHA_MIN), np.log(ALPHA_MIN), 0.0, F0_COAT_MIN, 0.0, np.log(H_MIN)])
    hi = np.array([np.log(ALPHA_MAX), np.log(ALPHA_MAX), K_COAT_MAX, 1.0, B0_MAX, np.log(H_MAX)])
    step = np.array([0.2, 0.3, 0.1, 0.02, 0.1, 0.5])
    xtol = np.array([1e-6, 1e-6, 1e-7, 1e-7, 1e-6, 1e-6])
    if warm is not None:                    # a fold of auto: near the fit to all the data,
        # or the coat of this fold without a surge, by _coat_ratio
        to_coat = _coat_ratio
        lo, hi = np.r_[_RATIO_LO, lo[4:]], np.r_[_RATIO_HI, hi[4:]]
        starts = [_ratio_point(dict(alpha=alpha0, alpha_coat=coat0[0], k_coat=coat0[1],
                                    f0_coat=coat0[2])) + [0.0, np.log(BACKSCATTER_STARTS[0][1])],
                  _ratio_point(warm) + [warm["b0"], np.log(warm["h"])]]
        step, xtol = WARM_STEP * step, xtol * WARM_XTOL / 1e-6
    else:
        to_coat = _coat
        starts = [[np.log(alpha0), np.log(coat0[0]), coat0[1], coat0[2], b0, np.log(h)]
                  for b0, h in BACKSCATTER_STARTS]
    search = BestPoint(lambda v: problem.cost(*to_coat(v), (float(v[4]), float(np.exp(v[5])))))
    for v in starts:
        search(np.clip(v, lo, hi))
    message = search.bobyqa(lo, hi, step, BACKSCATTER_MAXEVAL, xtol_abs=xtol)
    v = search.x
    return (*to_coat(v), (float(v[4]), float(np.exp(v[5]))), search.n, message)


#: The key of :attr:`FitOptions.stages` under which the first ``goniochromatic-two-lobe``
#: search of a run leaves its (α, α_2) for the later ones (:func:`_search_second`).
SECOND_NEAR = "goniochromatic-two-lobe: near"


def _search_second(problem: Layered, alpha0: float, near=None):
    """(α, α_2, evaluations, message) of ``goniochromatic-two-lobe`` minimising the
    profile cost: a look at α from ``alpha0`` (the fit without the second lobe) and
    :data:`ALPHA_STARTS`, each with α_2 at :data:`ALPHA_2_STARTS` and at ``alpha0``, then
    BOBYQA in (log α, log α_2). With ``near`` (α, α_2) of a fit to most of the same data
    (``--model auto``'s fit to all of it, for each fold), the look is only there and at
    (``alpha0``, its α_2)."""
    lo, hi = np.full(2, np.log(ALPHA_MIN)), np.full(2, np.log(ALPHA_MAX))
    search = BestPoint(lambda v: problem.cost(float(np.exp(v[0])),
                                              alpha_2=float(np.exp(v[1]))))
    starts = ([near, (alpha0, near[1])] if near is not None else
              [(a, a2) for a in (alpha0,) + ALPHA_STARTS
               for a2 in ALPHA_2_STARTS + ((alpha0,) if a != alpha0 else ())])
    for a, a2 in starts:
        search([np.log(a), np.log(a2)])
    message = search.bobyqa(lo, hi, [0.3, 0.3], TWO_LOBE_MAXEVAL, xtol_abs=[1e-6, 1e-6])
    return float(np.exp(search.x[0])), float(np.exp(search.x[1])), search.n, message


def _stage_key(data: FitData, options: FitOptions, coat: str) -> bytes:
    """The key of :attr:`FitOptions.stages` for the searches before the opposition
    effect's (α, then the coat): a digest of everything they depend on, the data and
    weights, the geometry, the residuals, ``--alpha``, ``--optimizer`` and the coat (none,
    over or under the layer). ``--model auto`` fits ``goniochromatic-coat`` and then
    ``goniochromatic-backscatter`` on the same data (all of it, then each fold): the second
    starts where the first ended instead of repeating its search."""
    import hashlib

    h = hashlib.blake2b(digest_size=20)
    for a in (data.y, data.w, data.theta_i_deg, data.theta_o_deg, *data.cos):
        h.update(np.ascontiguousarray(a, dtype=float).tobytes())
    h.update(repr((data.residuals, options.alpha, options.optimizer, coat)).encode())
    return h.digest()


#: ``--optimizer``: the search of the layer-free α (the coat's own search is BOBYQA);
#: the first is the default.
OPTIMIZERS = {
    "nlopt-bobyqa": minimize_log_alpha,
    "nlopt-lbfgs": minimize_log_alpha,
}


def fit_layered(data: FitData, options: FitOptions, coat: bool,
                backscatter: bool = False, undercoat: bool = False,
                second: bool = False) -> ModelFit:
    """Fit ``goniochromatic-diffuse`` (``coat=False``), ``goniochromatic-coat``, with
    ``backscatter`` ``goniochromatic-backscatter`` (the coat and the opposition effect),
    with ``undercoat`` ``goniochromatic-undercoat`` (the layer seen through the coat), or
    with ``second`` (and no coat) ``goniochromatic-two-lobe`` (a second coloured lobe)."""
    model = ("goniochromatic-two-lobe" if second else
             "goniochromatic-undercoat" if undercoat else
             "goniochromatic-backscatter" if backscatter else
             "goniochromatic-coat" if coat else "goniochromatic-diffuse")
    kind = "under" if undercoat else "over" if coat else "none"
    coat = coat or undercoat
    check_alpha(options.alpha)
    optimizer, search_alpha = choose_optimizer(model, OPTIMIZERS, options.optimizer)
    sw = Stopwatch()
    memo = options.stages if options.stages is not None else {}
    # a fold of auto: the α (and coat) searches start at the fit to all the data
    warm = near(options, "alpha", "alpha_coat", "k_coat", "f0_coat") if coat else \
        near(options, "alpha")
    key = _stage_key(data, options, kind)
    if key in memo:                         # this run fitted the same stages already
        alpha, coat_params, evaluations, message, success = memo[key]
    else:
        plain = Layered(data, undercoat=undercoat)
        if options.alpha is not None:
            alpha, evaluations, message, success = options.alpha, 0, "alpha fixed", True
        elif coat and warm is not None:     # the coat's search starts at the warm point
            alpha, evaluations, message, success = warm["alpha"], 0, "warm start", True
        else:
            lo, hi, points = np.log(ALPHA_MIN), np.log(ALPHA_MAX), LAYERED_ALPHA_POINTS
            if warm is not None and not second:
                lo, hi, points = log_alpha_window(warm["alpha"], lo, hi, points)
            search = search_alpha(lambda g: plain.cost(float(np.exp(g))), optimizer,
                                  lo=lo, hi=hi, points=points)
            alpha, evaluations, message, success = (search.alpha, search.evaluations,
                                                    search.message, search.success)
        coat_params = None
        if coat:
            # under the coat, eq. 5's α0 is a width in the refracted angles, which are
            # 1/n of the measured ones near the normal: the peak is n α0 wide outside
            alpha, coat_params, n, message = _search_coat(
                Layered(data, coat=True, undercoat=undercoat), alpha,
                alpha * UNDERCOAT_INDEX if undercoat else alpha, warm)
            evaluations += n
        memo[key] = (alpha, coat_params, evaluations, message, success)
    alpha_2 = None
    if second:
        # the diffuse model's α search above is shared with it (same key, ``auto`` fits
        # both in one process); the 2-D search has its own
        key_2 = _stage_key(data, options, "second")
        if key_2 not in memo:
            # the first two-lobe search of the run (auto: on all the data) starts each
            # later one (auto: each fold); the same order with any --jobs
            memo[key_2] = _search_second(Layered(data, second=True), alpha,
                                         memo.get(SECOND_NEAR))
            memo.setdefault(SECOND_NEAR, memo[key_2][:2])
        alpha, alpha_2, n, message = memo[key_2]
        evaluations += n
    back = None
    if backscatter:
        alpha, coat_params, back, n, message = _search_backscatter(
            Layered(data, coat=True, backscatter=True), alpha, coat_params,
            near(options, "alpha", "alpha_coat", "k_coat", "f0_coat", "b0", "h"))
        evaluations += n
    params, _, ok = Layered(data, coat=coat, backscatter=backscatter, undercoat=undercoat,
                            second=second).solve(alpha, coat_params, back, alpha_2)
    failed = [float(w) for w in data.wavelength_nm[~ok]]
    status = "success" if success and not failed else "failed"
    if failed:
        message = (f"no usable signal at {len(failed)} wavelength(s) ({nm_list(failed)}); "
                   f"rho = rho_d = c = 0 there. " + message)
    f = evaluate(model, data.cos, params)
    report = FitReport("refined", status, message, params, error_figures(data, f),
                       optimizer, evaluations, sw.lap(), failed)
    return ModelFit(model, data.wavelength_nm, {"refined": report}, "refined", data.excluded)


def fit_diffuse(data: FitData, options: FitOptions) -> ModelFit:
    return fit_layered(data, options, coat=False)


def fit_coat(data: FitData, options: FitOptions) -> ModelFit:
    return fit_layered(data, options, coat=True)


def fit_backscatter(data: FitData, options: FitOptions) -> ModelFit:
    return fit_layered(data, options, coat=True, backscatter=True)


def fit_undercoat(data: FitData, options: FitOptions) -> ModelFit:
    return fit_layered(data, options, coat=True, undercoat=True)


def fit_two_lobe(data: FitData, options: FitOptions) -> ModelFit:
    return fit_layered(data, options, coat=False, second=True)
