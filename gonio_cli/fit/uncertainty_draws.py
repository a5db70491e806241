"""Draws from a fit's Gaussian (``fit.intervals.covariance``, :mod:`.uncertainty`) and
the model moved by them: what ``gonio eval``'s colour band propagates (docs/fit.md).

Spectral elements at two wavelengths are independent given the scalars (the precision
matrix of :mod:`.uncertainty` has no block between them), so a draw takes the scalar block
first, then each wavelength's elements from their Gaussian given the scalars.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..brdf import MODELS, evaluate
from .uncertainty import at_bound, jacobian
from .uncertainty_table import conditional, table_columns


def _sqrt_psd(c: np.ndarray) -> np.ndarray:
    """A square root L (L Lᵀ = C) of positive semi-definite matrices (..., k, k)."""
    vals, vecs = np.linalg.eigh(c)
    return vecs * np.sqrt(np.maximum(vals, 0.0))[..., None, :]


def draw(record: dict[str, Any], n: int, seed: int = 0):
    """``n`` deviations drawn from the fit's Gaussian (``fit.intervals.covariance``):
    (n, s') of the scalar block (the scalars, then the log-gains) and (n, L, k) of the
    spectral elements (None without spectral parameters), each element on its own scale.
    Scalars first, then each wavelength's elements from their distribution given the
    scalars (module doc)."""
    cov = record["covariance"]
    rng = np.random.default_rng(seed)
    m = len(cov["scalar_names"])
    css = np.asarray(cov["scalar"], dtype=float).reshape(m, m)
    xs = rng.standard_normal((n, m)) @ _sqrt_psd(css).T if m else np.zeros((n, 0))
    if not cov["spectral_names"]:
        return xs, None
    if "spectral" in cov:
        cll = np.asarray(cov["spectral"], dtype=float)                # (L, k, k)
        reg, cond = conditional(cll, cov["cross"], css)
        root = _sqrt_psd(cond)
    else:               # the table's model: the blocks given the scalars, as a factor
        root = np.asarray(cov["conditional_factor"], dtype=float)     # (L, k, r)
        reg, _ = conditional(np.zeros(root.shape[:2] + root.shape[1:2]), cov["cross"], css)
    e = rng.standard_normal((n,) + root.shape[:1] + root.shape[2:])
    return xs, np.einsum("lkb,nb->nlk", reg, xs) + np.einsum("lkj,nlj->nlk", root, e)


def propagate(record: dict[str, Any], model: str, cos, params: dict, n: int,
              seed: int = 0):
    """The model at ``cos`` for ``n`` parameter sets drawn from the fit's Gaussian, by the
    delta method: f + J δu (J from :func:`jacobian`, δu from :func:`draw`), (n, N, L); and
    the drawn log-gain deviations (n, G) (None without gains). Linear in δu, like the
    Gaussian itself: parameters that trade off (ρ against ρ_d, kd against ks …) move f
    together as the data allow, where pushing each far draw through the model would leave
    the region in which the Gaussian means anything."""
    cov = record["covariance"]
    f = evaluate(model, cos, params)
    sides = {}
    for name in MODELS[model].scalar_params + MODELS[model].spectral_params:
        side = at_bound(name, params[name])
        one = np.zeros(side.shape, bool)
        one[record["parameters"][name].get("one_sided_at", [])] = True
        sides[name] = np.where(one, side, 0)
    js, jl = jacobian(model, cos, params, sides)
    xs, xl = draw(record, n, seed)
    names = cov["scalar_names"]
    idx = [names.index(nm) for nm in MODELS[model].scalar_params]
    out = f[None] + np.einsum("na,a...->n...", xs[:, idx], js)
    if xl is not None:
        k = jl.shape[0]
        out = out + np.einsum("nlk,k...l->n...l", xl[..., :k], jl)
        if "table_shape" in cov:          # the table's nodes, f linear in them
            out = out + np.einsum("nlj,...j->n...l", xl[..., k:],
                                  table_columns(model, cos, params))
    g = [j for j, nm in enumerate(names) if nm.startswith("log_gain_")]
    return out, (xs[:, g] if g else None)
