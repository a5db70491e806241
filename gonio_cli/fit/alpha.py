"""The α search every fit shares (:func:`minimize_log_alpha`): a coarse scan of the
profile cost over the whole admissible log α range, then a local refinement by the chosen
optimiser (each fitter's ``OPTIMIZERS``; nlopt's, :data:`LOG_ALPHA_ALGORITHMS`).
:mod:`.common` has the data and the constants of the range."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from ..errors import InputError
from ..names import OPTIMIZER_NAMES, choices_fix
from .common import ALPHA_MAX, ALPHA_MIN, ALPHA_SCAN_POINTS, FD_STEP_LOG_ALPHA, LOG_ALPHA_XTOL

#: The nlopt algorithm of :func:`minimize_log_alpha`, by ``--optimizer`` name. The nlopt
#: names refine the 1-D profile cost in log α after the coarse scan; a fitter whose
#: ``scipy-least-squares`` solves the joint problem (α and every per-wavelength parameter,
#: as one nonlinear least-squares problem) still searches 1-D profiles (seed 000's step 1)
#: with BOBYQA. Each fitter's own ``OPTIMIZERS`` dict says which names it accepts;
#: justification in docs/fit.md.
LOG_ALPHA_ALGORITHMS = {
    "nlopt-bobyqa": "LN_BOBYQA",     # derivative-free, bounded
    "nlopt-lbfgs": "LD_LBFGS",       # gradient by central differences
    "scipy-least-squares": "LN_BOBYQA",
}
DEFAULT_OPTIMIZER = "nlopt-bobyqa"

#: A cost the optimisers can hold when a trial α gives a non-finite profile (never kept).
_BAD_COST = 1e300


def choose_optimizer(model: str, optimizers: dict[str, Any], name: str | None):
    """``(name, optimizers[name])`` for ``--optimizer name`` of ``--model model``; ``None``
    is the fitter's default (its first key). A name the fitter lacks is an
    :class:`~gonio_cli.errors.InputError` listing the ones it has."""
    if name is None:
        name = next(iter(optimizers))
    if name not in optimizers:
        if name not in OPTIMIZER_NAMES:
            raise InputError(f"--optimizer {name!r} is unknown",
                             fix=choices_fix(name, optimizers, f"--model {model} takes"))
        raise InputError(f"--optimizer {name} does not apply to --model {model}",
                         fix=f"use one of {', '.join(optimizers)}")
    return name, optimizers[name]


@dataclass
class AlphaSearch:
    """Outcome of :func:`minimize_log_alpha` (like scipy's ``OptimizeResult``)."""

    alpha: float
    cost: float
    evaluations: int
    optimizer: str
    success: bool
    message: str
    at_bound: bool


def scan_log_alpha(cost: Callable[[float], float], lo: float = np.log(ALPHA_MIN),
                   hi: float = np.log(ALPHA_MAX), points: int = ALPHA_SCAN_POINTS,
                   costs: Callable[[np.ndarray], np.ndarray] | None = None):
    """Evaluate the profile cost on a log-α grid (all at once with ``costs`` if given).

    Returns (grid, costs, index of the best point).
    """
    grid = np.linspace(lo, hi, points)
    values = costs(grid) if costs is not None else np.array([cost(g) for g in grid])
    values = np.where(np.isfinite(values), values, _BAD_COST)
    return grid, values, int(np.argmin(values))


def _finite_cost(cost: Callable[[float], float], log_alpha: float) -> float:
    value = float(cost(float(log_alpha)))
    return value if np.isfinite(value) else _BAD_COST


def minimize_log_alpha(cost: Callable[[float], float], optimizer: str = DEFAULT_OPTIMIZER,
                       lo: float = np.log(ALPHA_MIN), hi: float = np.log(ALPHA_MAX),
                       points: int = ALPHA_SCAN_POINTS,
                       costs: Callable[[np.ndarray], np.ndarray] | None = None) -> AlphaSearch:
    """Minimise a profile cost over log α in [lo, hi]: coarse scan, then local refinement.

    ``cost(log_alpha)`` returns the (weighted) sum of squared residuals with every other
    parameter optimal for that α. The scan brackets the global minimum among its points;
    the refinement runs inside the two neighbouring scan cells with an nlopt optimiser
    (:data:`LOG_ALPHA_ALGORITHMS`: ``scipy-least-squares`` searches with BOBYQA here, the
    joint problem is the fitter's).
    ``costs(log_alphas)``, if given, evaluates the scan in one vectorised call.
    """
    grid, values, i = scan_log_alpha(cost, lo, hi, points, costs)
    evaluations = len(grid)
    a, b = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
    import nlopt

    NLOPT_STOPS = nlopt_stops()
    algorithm = getattr(nlopt, LOG_ALPHA_ALGORITHMS[optimizer])
    counter = {"n": 0}
    seen = {"x": float(grid[i]), "f": float(values[i])}   # best point nlopt evaluated

    def objective(x, grad):
        counter["n"] += 1
        f = _finite_cost(cost, x[0])
        if f < seen["f"]:
            seen["x"], seen["f"] = float(x[0]), f
        if grad.size:
            h = FD_STEP_LOG_ALPHA
            counter["n"] += 2
            grad[0] = (_finite_cost(cost, x[0] + h) - _finite_cost(cost, x[0] - h)) / (2 * h)
        return f

    opt = nlopt.opt(algorithm, 1)
    opt.set_min_objective(objective)
    opt.set_lower_bounds([a])
    opt.set_upper_bounds([b])
    opt.set_xtol_abs(LOG_ALPHA_XTOL)
    opt.set_maxeval(200)
    x0 = float(np.clip(grid[i], a, b))
    success, message = True, "converged"
    try:
        x = opt.optimize([x0])[0]
        best = opt.last_optimum_value()
        code = opt.last_optimize_result()
        message = _NLOPT_MESSAGES.get(code, f"nlopt result {code}")
        success = code > 0
    except tuple(NLOPT_STOPS) as exc:  # an early stop of the search itself, not of the cost:
        # what it reached is still the best point it evaluated (and never worse than the
        # scan's). Anything else (an error in the cost function, nlopt's invalid argument,
        # out of memory) surfaces.
        x, best = seen["x"], seen["f"]
        message = (f"nlopt stopped ({NLOPT_STOPS[type(exc)]}); kept the best alpha it "
                   "evaluated")
        success = True
    if best > seen["f"]:  # never worse than any point evaluated (the scan's best included)
        x, best = seen["x"], seen["f"]
    evaluations += counter["n"]
    at_bound = bool(np.isclose(x, lo, atol=1e-6) or np.isclose(x, hi, atol=1e-6))
    if best >= _BAD_COST:
        success, message = False, "no α in the admissible range gives a finite cost"
    return AlphaSearch(float(np.exp(x)), float(best), evaluations, optimizer, success,
                       message, at_bound)


def nlopt_stops() -> dict[type, str]:
    """The exceptions of an nlopt search that end it early but leave its best point valid,
    with what each means (nlopt's C++ wrapper turns result codes into them): the
    round-off-limited stop (NLOPT_ROUNDOFF_LIMITED, e.g. LBFGS near a zero cost) and
    LBFGS's generic failure (NLOPT_FAILURE, ``nlopt.runtime_error``: its line search finds
    no descent along a central-difference gradient at the minimum). The search's caller
    catches exactly these; an error raised by the cost function is not among them."""
    import nlopt

    return {nlopt.RoundoffLimited: "round-off limited",
            nlopt.runtime_error: "no descent found, NLOPT_FAILURE"}


_NLOPT_MESSAGES = {1: "converged", 2: "stopped at stopval", 3: "converged (ftol)",
                   4: "converged (xtol)", 5: "stopped at maxeval", 6: "stopped at maxtime"}


