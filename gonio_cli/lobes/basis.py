"""The exponent basis search of the cosine-lobe fit (seed 001 §3.2, eq. 4) by nlopt.

:func:`select_basis` adds one lobe at a time, minimising :func:`basis_objective` over
log E (nlopt, imported here only).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from ..errors import InputError
from . import EXPONENT_MAX, EXPONENT_MIN, LOBE_RESOLVED_MIN, design_matrix
from .samples import Samples
from .solve import fit_weights, lobe_columns, resolved_lobes
from .solvers import relative_weights

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
    """The search's bases, one per lobe count. ``exponent_range``: the (min, max) searched,
    the max lowered to :func:`resolvable_exponent` where the samples cannot resolve
    sharper lobes; ``mirror_offset_deg``: (V,) the nearest sample's angle from each view's
    mirror direction (:meth:`Samples.mirror_offset_deg`)."""

    steps: list[BasisStep] = field(default_factory=list)
    solver: str = "nnls"
    n_samples: int = 0
    time_s: float = 0.0
    exponent_range: tuple = (EXPONENT_MIN, EXPONENT_MAX)
    mirror_offset_deg: np.ndarray | None = None


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

#: An exponent within this of a bound in log E (1 %, ten times the search's xtol) is "at
#: the bound": the search pressed against it and would have gone further.
BASIS_PIN_LOG = 1e-2
#: The error "does not fall as lobes are added" when the largest basis's is above
#: (1 − BASIS_FLAT_REL) × the one-lobe basis's: 1 %, below any difference a render shows.
BASIS_FLAT_REL = 0.01


def resolvable_exponent(samples: Samples) -> float:
    """The largest E every view of ``samples`` resolves (:data:`LOBE_RESOLVED_MIN`): with
    θ the nearest sample's angle from a view's mirror direction, cos θ^E ≥ 1/2 ⇔
    E ≤ ln(1/2) / ln cos θ; inf when a sample lies on every mirror direction."""
    offset = np.radians(np.max(samples.mirror_offset_deg()))
    c = np.cos(offset)
    return float(np.log(LOBE_RESOLVED_MIN) / np.log(c)) if c < 1.0 else float("inf")


def basis_objective(log_exponents, cos_theta_i, cos_rv, groups, targets: Sequence[np.ndarray],
                    solver: str = "nnls", weight=None):
    """Seed 001 eq. 4: max_i Error(E, B_i) + mean_i Error(E, B_i).

    The weights are fitted per group of samples (one view angle each, as
    :func:`fit_weight_table` will use them, seed 001 §5.2: lobes a group's samples do not
    resolve are left out of it, quadrature weights are used), and Error(E, B_i) is the
    relative RMS sqrt(Σ w r² / Σ w b²) of material i over every group, sample and channel
    (w = 1 without quadrature weights), so bright and dark materials count alike.

    Parameters
    ----------
    log_exponents : (m,) log E ; cos_theta_i, cos_rv, groups : (N,) ; targets : n arrays
    (N, C); weight : (N,) quadrature weights or None. Returns (f, per-material errors (n,)).
    """
    M = design_matrix(cos_theta_i, cos_rv, np.exp(np.asarray(log_exponents, dtype=float)))
    w = np.ones(M.shape[0])
    parts = []
    for g in groups:
        Mg = M[g]
        resolved = resolved_lobes(Mg)[1]
        if not resolved.all():
            Mg = Mg[:, lobe_columns(resolved)]
        if weight is not None:
            w[g] = relative_weights(np.asarray(weight, dtype=float)[g])
        parts.append((g, Mg, None if weight is None else w[g]))
    errs = np.empty(len(targets))
    for i, B in enumerate(targets):
        sse = 0.0
        for g, Mg, wg in parts:
            r = Mg @ fit_weights(Mg, B[g], solver, weight=wg).weights - B[g]
            sse += float(np.sum(r * r if wg is None else wg[:, None] * r * r))
        total = float(np.sum(B * B if weight is None else w[:, None] * B * B))
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
    lo, hi, top = _search_bounds(targets, samples, max_lobes, solver, exponent_range)
    result = BasisResult(solver=solver, n_samples=samples.n_samples,
                         exponent_range=(float(exponent_range[0]), top),
                         mirror_offset_deg=samples.mirror_offset_deg())
    cos_theta_i, cos_rv, weight = samples.cos_theta_i(), samples.cos_rv(), samples.weight
    groups = [samples.view_index == k for k in range(samples.view_angle_deg.size)]

    def objective(x):
        return basis_objective(x, cos_theta_i, cos_rv, groups, targets, solver, weight)

    start_all = time.perf_counter()
    log_e = np.empty(0)
    counts = range(1, int(max_lobes) + 1)
    for m in (progress(counts) if progress else counts):
        t0 = time.perf_counter()
        best, evaluations, message = _search_count(objective, log_e, lo, hi)
        log_e = np.sort(best["x"])
        errs = best["errs"]
        if result.steps and best["f"] > result.steps[-1].error:
            message += "; error rose from the previous count (LP vertex jump; use nnls)"
        result.steps.append(BasisStep(m, np.exp(log_e), best["f"], float(errs.max()),
                                      float(errs.mean()), [float(v) for v in errs],
                                      evaluations, time.perf_counter() - t0, message))
    result.time_s = time.perf_counter() - start_all
    return result


def _search_bounds(targets, samples: Samples, max_lobes: int, solver: str,
                   exponent_range) -> tuple[float, float, float]:
    """(lo, hi) of the search in log E and the largest exponent the samples resolve, after
    checking :func:`select_basis`'s arguments (InputError naming the option)."""
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
    sharpest = resolvable_exponent(samples)
    if sharpest <= exponent_range[0] * np.exp(BASIS_XTOL_LOG):
        raise InputError(f"sample set {samples.name}: no view has a sample within the "
                         f"widest lobe's half-width of its mirror direction (the nearest is "
                         f"{np.max(samples.mirror_offset_deg()):.3g} deg away), so no lobe "
                         f"can be fitted",
                         fix="use samples near the mirror direction, e.g. --samples seed001")
    return lo, min(hi, np.log(sharpest)), float(min(exponent_range[1], sharpest))


def _search_count(objective: Callable, log_e: np.ndarray, lo: float, hi: float):
    """One lobe added to ``log_e``: the best point nlopt's LN_SBPLX evaluated over log E
    in [lo, hi] (``{"x", "f", "errs"}``), the number of evaluations and how it ended."""
    import nlopt

    m = log_e.size + 1
    best = {"x": None, "f": np.inf, "errs": None}
    evals = {"n": 0}

    def f(x):
        evals["n"] += 1
        value, errs = objective(x)
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
    return best, evals["n"], message


def basis_notes(result: BasisResult) -> list[str]:
    """What a user should know about the bases found, one sentence each (the shell warns
    with them): an exponent pressed against a bound of the search (and why: the lobe put
    there added nothing, the samples resolve nothing sharper, the material's gloss is
    sharper than any lobe, or wider), and an error that does not fall as lobes are added.
    Empty when neither happened."""
    notes = []
    lo, hi = result.exponent_range
    errors = {st.n_lobes: st.error for st in result.steps}
    for bound, name in ((hi, "upper"), (lo, "lower")):
        counts = [st.n_lobes for st in result.steps
                  if np.any(np.abs(np.log(st.exponents) - np.log(bound)) < BASIS_PIN_LOG)]
        if not counts:
            continue
        first = counts[0]
        gain = (1.0 - errors[first] / errors[first - 1]
                if errors.get(first - 1, 0.0) > 0 else None)
        if gain is not None and gain < BASIS_FLAT_REL:
            why = (f"the lobe put there at {first} lobes lowered the error by only "
                   f"{gain:.2%}: it adds nothing, and {first - 1} lobes do as well")
        elif name == "lower":
            why = ("the material has a part wider than the widest lobe (E=1, the diffuse "
                   "map's), e.g. grazing retro-reflection, which the lobes only approximate")
        elif bound < EXPONENT_MAX * (1 - BASIS_PIN_LOG):
            offset = float(np.max(result.mirror_offset_deg))
            why = (f"it is the sharpest lobe these samples resolve (a view's nearest sample "
                   f"is {offset:.2g} deg from its mirror direction) and the material's gloss "
                   "is sharper; use --samples hemisphere --mirror-dense (or seed001) to "
                   f"resolve lobes up to E={EXPONENT_MAX:g}")
        else:
            why = ("the material's gloss is sharper than any lobe the basis may hold "
                   "(near-mirror), and that lobe stands for all of it")
        shown = f"{bound:.0f}" if bound >= 10 else f"{bound:g}"       # 174, 10000, 1
        notes.append(f"an exponent sits at the {name} bound E={shown} of the search in "
                     f"the {_counts_text(counts)} basis(es): {why}")
    steps = result.steps
    if len(steps) > 1 and steps[-1].error > (1.0 - BASIS_FLAT_REL) * steps[0].error:
        notes.append(f"the error stays at {steps[0].error:.4g} from 1 to {steps[-1].n_lobes} "
                     f"lobes (falls less than {BASIS_FLAT_REL:.0%}): more lobes do not help "
                     "on these samples; a lobe count of 1 is as good, or the lobes cannot "
                     "represent the material's shape")
    return notes


def _counts_text(counts: list[int]) -> str:
    """[1, 2, 3, 5] → "1-3, 5-lobe"."""
    runs, start = [], counts[0]
    for a, b in zip(counts, counts[1:] + [None]):
        if b != a + 1:
            runs.append(f"{start}" if start == a else f"{start}-{a}")
            start = b
    return ", ".join(runs) + "-lobe"
