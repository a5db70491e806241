"""Warm starts: a fit that starts near the same model's fit to most of the same data.

``--model auto`` judges each candidate on held-out folds (:mod:`.auto`): the model is
fitted once to all the data, then once per fold to all but a θi (or a few
configurations). A fold's data are most of the full data, so its optimum lies near the
full fit's: the coarse starts that keep a search on all the data from a wrong basin
(the coat's 40 starts, the α scan over three decades) would only find that basin again.
With :attr:`FitOptions.warm <.results.FitOptions>` set (auto sets it to the full fit's
parameters for each fold), a fitter starts its local search there instead, with smaller
first steps. The fit to all the data, the one a material carries, never starts warm.
"""

from __future__ import annotations

import numpy as np

from .results import FitOptions

#: A warm search's first steps, as a fraction of a cold one's (BOBYQA's initial trust
#: region): a fold's optimum moves by a few percent in each roughness from the full fit's
#: (measured on RGL cardboard, satin and wrap: α 1-3 %, α_coat 2-13 %, k_coat 5-36 %), well
#: inside a third of a cold search's first step (30-65 % in α).
WARM_STEP = 0.3

#: A warm search stops when its steps in log roughness fall below this (0.01 % in α; a
#: cold search goes to 1e-6): a fold's fit only predicts the configurations held out,
#: whose colour error moves by < 1e-3 CIEDE2000 for such a step.
WARM_XTOL = 1e-4

#: A warm 1-D α search scans this many cells of the cold scan either side of the warm α.
WARM_CELLS = 2


def near(options: FitOptions, *keys: str) -> dict | None:
    """The warm parameters of ``options`` if they hold every one of ``keys`` (finite
    scalars), else None (a cold search)."""
    warm = options.warm
    if not warm or any(k not in warm or not np.isfinite(np.asarray(warm[k], float)).all()
                       for k in keys):
        return None
    return warm


def log_alpha_window(alpha: float, lo: float, hi: float, points: int) -> tuple[float, float, int]:
    """(lo, hi, points) of a warm scan over log α: :data:`WARM_CELLS` cells of the cold
    scan (``points`` over [lo, hi]) either side of ``alpha``, clipped to [lo, hi]."""
    cell = (hi - lo) / (points - 1)
    centre = float(np.clip(np.log(alpha), lo, hi))
    a, b = max(lo, centre - WARM_CELLS * cell), min(hi, centre + WARM_CELLS * cell)
    return a, b, max(3, int(round((b - a) / cell)) + 1)
