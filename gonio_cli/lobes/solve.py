"""The cosine-lobe fit of one view (seed 001 §4, eqs. 5-6) and the weight table (§5.2).

The design checks (:func:`resolved_lobes`, :func:`check_design`), :func:`fit_weights` for
one view with a solver of :data:`~gonio_cli.lobes.solvers.WEIGHT_SOLVERS`, and
:func:`fit_weight_table` for every view angle, checked by
:func:`~gonio_cli.lobes.energy.check_energy`. Re-exported by :mod:`gonio_cli.lobes`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..errors import FitError
from . import (ENERGY_EXCESS_MAX, LOBE_RESOLVED_MIN, LP_TIME_LIMIT_S, UNSEEN_COLUMN,
               check_exponents, design_matrix, split_weights)
from .energy import check_energy, lobe_energy
from .samples import Samples, directional_albedo, target_values
from .solvers import (DEFAULT_SOLVER, WEIGHT_SOLVERS, WeightFit, check_solver,
                      relative_weights, residual_errors)

# ---------------------------------------------------------------- one view (§4) --

def lobe_half_width_deg(exponents) -> np.ndarray:
    """The angle (deg) from its axis at which a lobe (R·V)^E falls to
    :data:`LOBE_RESOLVED_MIN` of its peak: acos(LOBE_RESOLVED_MIN^(1/E)) (the half-width
    at half maximum, ≈ sqrt(2 ln 2 / E) rad). ``exponents`` (...) → (...)."""
    e = np.asarray(exponents, dtype=float)
    return np.degrees(np.arccos(np.exp(np.log(LOBE_RESOLVED_MIN) / e)))


def resolved_lobes(M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Which lobes a view's samples resolve (:data:`LOBE_RESOLVED_MIN`).

    M : (N, 1 + 2m), :func:`design_matrix` of one view: its gloss columns are the lobes'
    values (R·V)^E themselves. Returns (peak (m,): each lobe's largest value over the
    samples, in [0, 1]; resolved (m,) bool: peak ≥ LOBE_RESOLVED_MIN)."""
    m = (M.shape[1] - 1) // 2
    peak = (M[:, 1 + m:].max(axis=0) if M.shape[0] else np.zeros(m))
    return peak, peak >= LOBE_RESOLVED_MIN


def lobe_columns(resolved: np.ndarray) -> np.ndarray:
    """Column indices of :func:`design_matrix` kept when only the ``resolved`` (m,) lobes
    are fitted: the diffuse column and each resolved lobe's two columns."""
    m = resolved.size
    idx = np.flatnonzero(resolved)
    return np.concatenate([[0], 1 + idx, 1 + m + idx]).astype(int)


def check_design(M: np.ndarray, exponents, where: str = "",
                 offset_deg: float | None = None) -> np.ndarray:
    """Refuse a view whose samples leave the fit undetermined, and say which lobes they
    resolve (:func:`resolved_lobes`).

    Refused (FitError): no sample; the diffuse column zero everywhere (no light above the
    horizon); no lobe resolved at all (no sample within the widest lobe's half-width of
    the mirror direction: the fit would have no gloss). ``offset_deg``: the nearest
    sample's angle from the mirror direction, for the message. Returns resolved (m,) bool.
    """
    if M.shape[0] == 0:
        raise FitError(f"{where}the sample set is empty", fix="use a sample set with samples")
    if not np.max(np.abs(M[:, 0])) > UNSEEN_COLUMN:
        raise FitError(f"{where}no sample sees the diffuse term (every light is below the "
                       "horizon), so the fit cannot determine its weight",
                       fix="use lights above the horizon (theta_i_deg inside (-85, 85))")
    e = np.asarray(exponents, dtype=float)
    _, resolved = resolved_lobes(M)
    if not resolved.any():
        widest = float(e.min())
        near = "" if offset_deg is None else f" (the nearest is {offset_deg:.3g} deg away)"
        raise FitError(f"{where}no sample sees any lobe within its half-width of the mirror "
                       f"direction{near}: the widest, E={widest:g}, needs one within "
                       f"{float(lobe_half_width_deg(widest)):.2g} deg, so no lobe weight "
                       "can be determined",
                       fix="add samples near the mirror direction (R.V near 1), e.g. "
                           "--samples seed001 or --samples hemisphere --mirror-dense")
    return resolved


def fit_weights(M: np.ndarray, B: np.ndarray, solver: str = DEFAULT_SOLVER,
                time_limit_s: float = LP_TIME_LIMIT_S, weight=None) -> WeightFit:
    """Non-negative weights x (K, C) with M x ≈ B (seed 001 eqs. 5-6).

    Parameters
    ----------
    M : (N, K) float, :func:`design_matrix`; B : (N, C) float, :func:`target_values`.
    solver : a key of :data:`WEIGHT_SOLVERS`; time_limit_s : the LP's time limit.
    weight : (N,) quadrature weights (:attr:`Samples.weight`) or None. With weights the
        solver minimises Σ w |r|^p, a quadrature of ∫ |r|^p dω (rows scaled by w, or
        sqrt(w) for least squares: :attr:`WeightSolver.norm`), and the errors are the
        weighted ones of :func:`residual_errors`.

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
    w = relative_weights(weight)
    if w is None:
        Ms, Bs = M, B
    else:
        scale = (w if entry.norm == 1 else np.sqrt(w))[:, None]
        Ms, Bs = M * scale, B * scale
    start = time.perf_counter()
    X, status, message = entry.solve(Ms, Bs, time_limit_s)
    elapsed = time.perf_counter() - start
    l1, rms, rel = residual_errors(M, X, B, w)
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
    unresolved : (V, m) bool, lobes left out of a view's fit (weight 0) because no sample
        resolves them (:func:`resolved_lobes`); lobe_peak : (V, m) each lobe's largest
        value over the view's samples; mirror_offset_deg : (V,) the nearest sample's angle
        from each view's mirror direction.
    albedo : (V, C) the material's directional albedo (:func:`directional_albedo`);
        energy_terms : (V, 1 + 2m, C) what each written weight holds (:func:`lobe_energy`),
        energy : (V, C) their sum.
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
    unresolved: np.ndarray | None = None
    lobe_peak: np.ndarray | None = None
    mirror_offset_deg: np.ndarray | None = None
    albedo: np.ndarray | None = None
    energy: np.ndarray | None = None
    energy_terms: np.ndarray | None = None


def unresolved_notes(table: WeightTable, sample_set_name: str) -> list[str]:
    """One sentence per lobe left out of some view's fit (``table.unresolved``): its
    exponent, the view angles, its half-width and the nearest sample's distance from the
    mirror direction, and the fix for this kind of sample set. Empty when none was."""
    if table.unresolved is None or not table.unresolved.any():
        return []
    notes = []
    for i in np.flatnonzero(table.unresolved.any(axis=0)):
        e = float(table.exponents[i])
        views = np.flatnonzero(table.unresolved[:, i])
        angles = ", ".join(f"{table.view_angle_deg[k]:g}" for k in views)
        near = np.asarray(table.mirror_offset_deg)[views]
        width = float(lobe_half_width_deg(e))
        if str(sample_set_name).lower().endswith(".csv"):
            fix = (f"add samples within {width:.2g} deg of the mirror configuration "
                   f"(theta_i_deg = theta_o_deg) at those views to {sample_set_name}")
        elif str(sample_set_name) == "hemisphere":
            fix = "add --mirror-dense (lights down to 0.07 deg from the mirror direction)"
        else:
            fix = "use samples nearer the mirror direction (--samples seed001)"
        nearest = (f"{near.min():.2g}" if f"{near.min():.2g}" == f"{near.max():.2g}"
                   else f"{near.min():.2g}-{near.max():.2g}")
        notes.append(f"lobe E={e:g} left out (weight 0) at view angle(s) {angles} deg: no "
                     f"sample lies within its half-width {width:.2g} deg of the mirror "
                     f"direction (nearest {nearest} deg), so the "
                     f"samples cannot fix its weight; {fix}, or use fewer, wider lobes "
                     "(--lobes N or --exponents)")
    return notes


#: Samples per view per :data:`LP_TIME_LIMIT_S` of the default time limit: HiGHS takes
#: ~0.5 s for 200 samples × 41 channels and ~0.7-1.5 s for the ~340 of ``--mirror-dense``
#: (measured on 2 busy cores), so 100 per second leaves it twice that.
TIME_LIMIT_SAMPLES_PER_S = 100


def default_time_limit_s(samples: Samples) -> float:
    """The LP's default time limit per view: :data:`LP_TIME_LIMIT_S` per
    :data:`TIME_LIMIT_SAMPLES_PER_S` samples of the largest view, at least LP_TIME_LIMIT_S
    (seed001's ~20 samples: 1 s; hemisphere 2 s; with ``--mirror-dense`` ~3.4 s)."""
    per_view = np.bincount(samples.view_index).max() if samples.n_samples else 0
    return LP_TIME_LIMIT_S * max(1.0, per_view / TIME_LIMIT_SAMPLES_PER_S)


def fit_weight_table(material, exponents, samples: Samples, channels: str = "spectral",
                     solver: str = DEFAULT_SOLVER, compare: Sequence[str] = (),
                     time_limit_s: float = LP_TIME_LIMIT_S,
                     max_energy_ratio: float = ENERGY_EXCESS_MAX) -> WeightTable:
    """Fit the weights at every view angle of ``samples`` (seed 001 §4 and §5.2).

    ``solver`` gives the weights written; every solver in ``compare`` (none by default) is
    also run on the same samples and its errors, time and status reported. A time limit
    reached, by ``solver`` or a comparison, is a status per view (``time_limit``), never
    an error. A lobe the view's samples do not resolve (:func:`resolved_lobes`) is left
    out of that view's fit (weight 0; ``unresolved``, and noted in the view's message).
    Samples with quadrature weights are fitted and measured with them (:func:`fit_weights`).

    Raises FitError if a view's samples leave the fit undetermined (:func:`check_design`),
    ``solver`` itself returns no solution (``failed``), or the weights hold more than
    ``max_energy_ratio`` × the material's albedo (:func:`check_energy`; inf: no check).
    Above :data:`ENERGY_EXCESS_WARN` × it is only a note (:func:`energy_note`).
    """
    e = check_exponents(exponents)
    check_solver(solver)
    for s in compare:
        check_solver(s)
    b_all, labels = target_values(material, samples, channels)
    M_all = design_matrix(samples.cos_theta_i(), samples.cos_rv(), e)
    V, m, C = samples.view_angle_deg.size, e.size, b_all.shape[1]
    X = np.zeros((V, 1 + 2 * m, C))
    unresolved = np.zeros((V, m), bool)
    peaks = np.zeros((V, m))
    offsets = samples.mirror_offset_deg() if samples.n_samples else np.zeros(V)
    solvers = [solver] + [s for s in compare if s != solver]
    keys = ("l1", "rms", "rms_relative", "time_s", "status", "message")
    errors = {s: {key: [] for key in keys} for s in solvers}
    counts = []
    start = time.perf_counter()
    for k, tv in enumerate(samples.view_angle_deg):
        rows = samples.view_index == k
        where = f"view angle {tv:g} deg: "
        M, B = M_all[rows], b_all[rows]
        weight = None if samples.weight is None else samples.weight[rows]
        resolved = check_design(M, e, where, float(offsets[k]) if rows.any() else None)
        peaks[k], unresolved[k] = resolved_lobes(M)[0], ~resolved
        cols = lobe_columns(resolved)
        note = ("" if resolved.all() else "; left out (unresolved, weight 0): E=" +
                ", ".join(f"{v:g}" for v in e[~resolved]))
        counts.append(int(rows.sum()))
        for s in solvers:
            r = fit_weights(M[:, cols], B, s, time_limit_s, weight)
            if s == solver:
                if r.status == "failed":
                    raise FitError(f"{where}the {s} weight solver failed ({r.message})",
                                   fix="try another --solver (e.g. highs)")
                X[k][cols] = r.weights
            r.message += note
            for key in keys:
                errors[s][key].append(getattr(r, key))
    parts = split_weights(np.moveaxis(X, 0, 1), m)            # leading axis K → parts
    table = WeightTable(e, samples.view_angle_deg, labels, parts["diffuse"],
                        np.moveaxis(parts["directional_diffuse"], 0, 1),
                        np.moveaxis(parts["gloss"], 0, 1), errors, counts, solver,
                        time.perf_counter() - start, unresolved, peaks, offsets)
    table.energy_terms = lobe_energy(e, table.view_angle_deg, table.diffuse,
                                     table.directional_diffuse, table.gloss)
    table.energy = table.energy_terms.sum(axis=1)
    table.albedo = directional_albedo(material, table.view_angle_deg, channels)
    check_energy(table, max_energy_ratio)
    return table
