"""Failure is honest: around nlopt only its round-off-limited stop is caught (the best
point evaluated then stands, with a note); an error in a cost function surfaces instead
of becoming ``success=True`` with a note."""

from __future__ import annotations

import nlopt
import numpy as np
import pytest

from gonio_cli.fit import fit
from gonio_cli.fit import goniochromatic as gc
from gonio_cli.fit.alpha import minimize_log_alpha
from gonio_cli.fit.common import prepare
from gonio_cli.fit.results import FitOptions
from gonio_cli.synthetic import ink_spectra, paper_geometry, synthetic_measurement


def parabola(log_alphas):
    """A profile cost with its minimum at α = 0.2 (vectorised: the scan)."""
    return (np.asarray(log_alphas, dtype=float) - np.log(0.2)) ** 2


def test_a_cost_function_that_raises_surfaces():
    def cost(log_alpha):          # a bug in a cost function, seen only by the refinement
        raise ZeroDivisionError("a bug in the cost")

    with pytest.raises(ZeroDivisionError, match="a bug in the cost"):
        minimize_log_alpha(cost, costs=parabola)


@pytest.mark.parametrize("stop, words", [
    (lambda: nlopt.RoundoffLimited(), "round-off"),
    (lambda: nlopt.runtime_error("nlopt failure"), "NLOPT_FAILURE"),
])
def test_an_early_stop_of_the_search_keeps_the_best_point(stop, words):
    calls = []

    def cost(log_alpha):          # a few good evaluations, then nlopt gives up
        calls.append(log_alpha)
        if len(calls) > 3:
            raise stop()
        return float(parabola([log_alpha])[0])

    search = minimize_log_alpha(cost, costs=parabola)
    assert search.success and words in search.message
    best = min(calls[:3] + [float(g) for g in np.linspace(np.log(1e-3), 0.0, 5)],
               key=lambda g: parabola([g])[0])
    # never worse than the best point evaluated (the scan's included)
    assert search.cost <= parabola([best])[0] + 1e-300
    assert search.cost == pytest.approx(parabola([np.log(search.alpha)])[0], abs=1e-15)


def test_a_fit_whose_cost_raises_fails_loudly(monkeypatch):
    rho, c = ink_spectra("red")
    ti, to = paper_geometry(10.0)
    m = synthetic_measurement("goniochromatic", {"alpha": 0.19, "rho": rho, "c": c},
                              ti, to, noise=0.0, seed=0)

    def broken(self, log_alpha):
        raise RuntimeError("cost failed")

    monkeypatch.setattr(gc.Step2, "cost", broken)
    with pytest.raises(RuntimeError, match="cost failed"):
        fit(prepare(m), "goniochromatic", FitOptions())
