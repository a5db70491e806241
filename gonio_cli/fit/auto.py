"""``--model auto``: every applicable model, judged on configurations it did not see.

Each candidate (:data:`CANDIDATES`) is fitted to all the data, then once per *fold* with
that fold left out; the left-out configurations are predicted and their colour error
measured (CIEDE2000 as in :mod:`.verdict`). The candidate with the lowest mean held-out
colour error is kept (a tie keeps the earlier, simpler one). Judging on held-out data, not
on the data each model was fitted to, keeps a model with more parameters from winning only
because it can bend to the noise.

The folds (:func:`folds`) are the angles of incidence when there are at least
:data:`MIN_THETA_I_FOR_ANGLE_FOLDS` of them (leave one θi out: a model must predict a whole
angle of incidence it did not see, between or beside the others). With fewer, leaving one
θi out is an extrapolation from 15° to 45° and back (a multi-angle instrument's two
angles), which says little about how well a model *interpolates* the configurations it
is asked for; then configurations are held out instead, in :data:`CONFIGURATION_FOLDS`
folds stratified by θi, each holding out only configurations with a fitted detector
angle on either side (interpolation, as a fit is used). The scheme that judged is named
in each candidate's notes and in ``fit.auto.criterion``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Callable

import numpy as np

from ..brdf import evaluate
from ..errors import GonioError
from .common import FitData, compressive_floor
from .results import FitOptions, ModelFit, Stopwatch
from .verdict import THRESHOLDS, colour_errors, covers_colour, fit_colour_errors

#: Models ``auto`` tries, cheapest first (a tie keeps the earlier, simpler one).
CANDIDATES = ("goniochromatic", "goniochromatic-diffuse", "torrance-sparrow",
              "cook-torrance", "cook-torrance-2", "cook-torrance-3", "goniochromatic-coat",
              "goniochromatic-undercoat", "goniochromatic-two-lobe",
              "goniochromatic-backscatter", "sheen", "tabulated-colour")


#: Held-out colour errors closer than this (CIEDE2000) are a tie, kept by the earlier,
#: simpler candidate: a fold's search stops within ~1e-3 of its optimum's error
#: (:data:`.warm.WARM_XTOL`), and nested models (the coat model with no coat, the
#: backscatter model with no surge) reach the same fit to within that.
HELD_OUT_TIE = 0.005

#: With at least this many angles of incidence, auto leaves one θi out at a time; with
#: fewer, one θi left out leaves one (or none) to fit, so the test is an extrapolation
#: across the whole angular range rather than the interpolation a fit is used for.
MIN_THETA_I_FOR_ANGLE_FOLDS = 3

#: Folds over configurations (fewer angles of incidence). Only *interior* configurations
#: are held out, those with a fitted detector angle on either side at the same θi: the end
#: of a sweep left out is an extrapolation past the measured range, which neither the
#: verdict nor a renderer asks of the fit. Fold j takes every k-th interior configuration
#: of each θi (ordered by θo), so each fold holds out one configuration per θi when a θi has
#: at most this many interior ones (a 12-geometry multi-angle instrument has 4 per θi:
#: leave one out within each θi); more folds would refit more often for the same test.
CONFIGURATION_FOLDS = 4


def folds(data: FitData) -> tuple[str, list[tuple[str, np.ndarray]]]:
    """(scheme, [(label, boolean rows held out)]) of the held-out test (module doc).

    ``scheme`` is ``"theta_i"``, ``"configurations"`` or ``"in-sample"`` (no θi has a
    configuration between two others: nothing can be held out and interpolated)."""
    groups = data.theta_i_groups()
    if len(groups) >= MIN_THETA_I_FOR_ANGLE_FOLDS:
        return "theta_i", [(f"theta_i {t:g}", rows) for t, rows in groups]
    interior = []
    for _, rows in groups:
        idx = np.flatnonzero(rows)
        interior.append(idx[np.argsort(data.theta_o_deg[idx], kind="stable")][1:-1])
    k = min(CONFIGURATION_FOLDS, max(idx.size for idx in interior))
    if k < 1:
        return "in-sample", []
    fold = np.full(data.n_configurations, -1)
    for idx in interior:
        fold[idx] = np.arange(idx.size) % k
    return "configurations", [(f"fold {j + 1} of {k}", fold == j) for j in range(k)]


#: What judged, by scheme of :func:`folds`: each candidate's note and ``fit.auto.criterion``.
SCHEME_NOTES = {
    "theta_i": "held out: each angle of incidence in turn",
    "configurations": (f"held out: configurations between two others at the same angle of "
                       f"incidence, in up to {CONFIGURATION_FOLDS} folds (fewer than "
                       f"{MIN_THETA_I_FOR_ANGLE_FOLDS} angles of incidence)"),
    "in-sample": ("nothing to hold out (no configuration between two others at an angle "
                  "of incidence): judged in sample"),
}


def criterion(data: FitData) -> str:
    """``fit.auto.criterion`` of the material: the error auto minimised and how."""
    return "mean CIEDE2000; " + SCHEME_NOTES[folds(data)[0]]


@dataclass
class Candidate:
    model: str
    fit: ModelFit | None
    held_out_delta_e: float = float("inf")
    in_sample_delta_e: float = float("inf")
    time_s: float = 0.0
    notes: list[str] = field(default_factory=list)
    #: the in-sample mirror peaks within the verdict's 0.75-1.33 (None: no mirror measured)
    peaks_match: bool | None = None

    def to_dict(self) -> dict[str, Any]:
        def num(v):
            return float(v) if np.isfinite(v) else None
        return {"model": self.model, "held_out_delta_e2000_mean": num(self.held_out_delta_e),
                "delta_e2000_mean": num(self.in_sample_delta_e), "time_s": self.time_s,
                "status": (self.fit.result.status if self.fit else "failed"),
                "mirror_peaks_match": self.peaks_match, "notes": self.notes}


def _score(data: FitData, rows: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Per-configuration error of predictions ``f`` on ``rows``: CIEDE2000 where colour
    can be judged, else the RMS relative error with the compressive residual's floor."""
    if covers_colour(data.wavelength_nm):
        return colour_errors(data.wavelength_nm, data.theta_i_deg[rows],
                             data.theta_o_deg[rows], data.y[rows], f).delta_e
    y = data.y[rows]
    return np.sqrt(np.mean(((f - y) / (np.abs(y) + compressive_floor(data.y))) ** 2, axis=1))


def _candidate(model: str, data: FitData, options: FitOptions, fit_one, scheme: str,
               held_out) -> Candidate:
    """One candidate: its fit to all the data and its held-out error."""
    sw = Stopwatch()
    try:
        full = fit_one(data, model, options)
    except GonioError as exc:
        return Candidate(model, None, notes=[exc.message])
    cand = Candidate(model, full)
    all_rows = np.ones(data.n_configurations, dtype=bool)
    f = evaluate(model, data.cos, full.params)
    colour = fit_colour_errors(data, f)       # what _score gives on all rows, and the peaks
    cand.in_sample_delta_e = float(np.mean(colour.delta_e if colour is not None
                                           else _score(data, all_rows, f)))
    if colour is not None and colour.peak_ratio:
        ratios = list(colour.peak_ratio.values())
        lo, hi = THRESHOLDS["peak_ratio_min"], THRESHOLDS["peak_ratio_max"]
        cand.peaks_match = not colour.peaks_off
        if not cand.peaks_match:
            cand.notes.append(f"mirror peak x{min(ratios):.2f}-{max(ratios):.2f} of the data, "
                              f"outside {lo:g}-{hi:.2f}: ranked after the candidates within")
    if not full.result.success:
        cand.notes.append(f"fit failed: {full.result.message}")
    cand.notes.append(SCHEME_NOTES[scheme])
    if not held_out:
        cand.held_out_delta_e = cand.in_sample_delta_e
    else:
        errors = []
        # each fold searches near the fit to all the data (FitOptions.warm)
        near = replace(options, warm=dict(full.params)) if full.result.success else options
        for label, rows in held_out:
            try:
                part = fit_one(data.subset(~rows), model, near)
            except GonioError as exc:
                cand.notes.append(f"without {label}: {exc.message}")
                errors = []
                break
            sub = data.subset(rows)
            errors.append(_score(data, rows, evaluate(model, sub.cos, part.params)))
        if errors:
            cand.held_out_delta_e = float(np.mean(np.concatenate(errors)))
    cand.time_s = sw.lap()
    return cand


#: Candidates fitted one after the other in one process: the second starts from the
#: searches the first left in ``FitOptions.stages`` (the same α and coat, :mod:`.layered`;
#: the two-lobe model's search starts from the diffuse model's α).
TOGETHER = (("goniochromatic-coat", "goniochromatic-backscatter"),
            ("goniochromatic-diffuse", "goniochromatic-two-lobe"))

#: Rough cost of each candidate's fits, relative (measured on an MA-T12 matte pigment and
#: an RGL wrap, all folds: the layered models with a coat search 1.8-3.5 s each, the
#: two-lobe model's 2-D search 1.9-2.2 s, the others 0.02-0.6 s; unlisted: 0.5; on RGL
#: cardboard, CPU s with one BLAS thread: the coat 2.4, tabulated-colour 1.4, sheen 0.2):
#: the costliest go first, so the processes end together.
COST = {"goniochromatic-coat": 3.0, "goniochromatic-backscatter": 2.5,
        "goniochromatic-undercoat": 3.0, "goniochromatic-two-lobe": 2.0,
        "tabulated-colour": 1.8}


def _groups(candidates) -> list[tuple[str, ...]]:
    """The candidates as groups to fit in one process each (:data:`TOGETHER`), costliest
    first (:data:`COST`)."""
    groups: list[tuple[str, ...]] = []
    for model in candidates:
        together = next((t for t in TOGETHER if model in t), (model,))
        group = tuple(m for m in together if m in candidates)
        if group not in groups:
            groups.append(group)
    return sorted(groups, key=lambda g: -sum(COST.get(m, 0.5) for m in g))


#: What the forked processes of :func:`_fit_groups` fit: (groups, work), set before the
#: fork (inherited, never pickled) and cleared after.
_SHARED: tuple | None = None


def _fit_group(i: int) -> list[Candidate]:
    groups, (data, options, fit_one, scheme, held_out) = _SHARED
    return [_candidate(m, data, options, fit_one, scheme, held_out) for m in groups[i]]


#: prctl(2) option: the signal a process gets when its parent dies (Linux).
PR_SET_PDEATHSIG = 1


def _child_start(parent: int) -> None:
    """A forked process ignores Ctrl-C (the parent stops it: one line, no traceback)
    and is killed with its parent (a ``kill`` or ``make`` stopping ``gonio fit`` leaves
    no process fitting on, nor its tracebacks when the parent is gone)."""
    import ctypes
    import os
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        ctypes.CDLL(None).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    except (OSError, AttributeError):
        pass
    if os.getppid() != parent:                 # the parent died before prctl took effect
        os._exit(1)


def can_fork_workers() -> bool:
    """Whether this process may fit in forked processes: Linux's ``fork`` (cheap: the
    children have numpy, scipy and the data already; elsewhere forking a process that
    has loaded system frameworks is unsafe) and not a daemonic process (a Dask worker
    of ``gonio batch``, which has its own core and may not have children)."""
    import multiprocessing
    import sys

    return sys.platform.startswith("linux") and not multiprocessing.current_process().daemon


def _fit_groups(groups, work, jobs: int) -> list[Candidate]:
    """Every group's candidates, in ``jobs`` forked processes (in this one if 1, if there
    is one group, or if :func:`can_fork_workers` says no). A fit is deterministic, so the
    figures do not depend on ``jobs``. A process that dies is a one-line error, not a
    wait without end."""
    global _SHARED
    jobs = min(int(jobs), len(groups))
    if jobs <= 1 or not can_fork_workers():
        data, options, fit_one, scheme, held_out = work
        return [_candidate(m, data, options, fit_one, scheme, held_out)
                for g in groups for m in g]
    import multiprocessing
    import os
    from concurrent.futures import ProcessPoolExecutor
    from concurrent.futures.process import BrokenProcessPool

    _SHARED = (groups, work)
    pool = ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context("fork"),
                               initializer=_child_start, initargs=(os.getpid(),))
    try:
        done = list(pool.map(_fit_group, range(len(groups))))
    except BrokenProcessPool:
        raise GonioError("a process fitting --model auto's candidates died (out of "
                         "memory, or killed)", fix="run again, or with --jobs 1") from None
    except BaseException:                      # Ctrl-C: the candidates' processes go too
        for child in multiprocessing.active_children():
            child.kill()
        raise
    finally:
        pool.shutdown(wait=False, cancel_futures=True)
        _SHARED = None
    return [c for group in done for c in group]


def fit_auto(data: FitData, options: FitOptions,
             fit_one: Callable[[FitData, str, FitOptions], ModelFit],
             candidates=CANDIDATES, jobs: int = 1) -> tuple[ModelFit, list[Candidate]]:
    """The best candidate's fit by held-out error, and every candidate's figures.

    ``jobs`` > 1 fits the candidates in that many processes (:func:`_fit_groups`); the
    figures are the same as with one, only sooner."""
    scheme, held_out = folds(data)
    options = replace(options, stages={})   # shared by the candidates' fits of each fold
    work = (data, options, fit_one, scheme, held_out)
    groups = _groups(candidates)
    found = {c.model: c for c in _fit_groups(groups, work, jobs)}
    results = [found[m] for m in candidates]
    usable = [c for c in results if c.fit is not None and c.fit.result.success
              and np.isfinite(c.held_out_delta_e)]
    if not usable:
        usable = [c for c in results if c.fit is not None]
    if not usable:
        raise GonioError("no model could be fitted: " + "; ".join(
            f"{c.model}: {' '.join(c.notes)}" for c in results))
    # a highlight off by more than the verdict allows is not one to render: such a
    # candidate wins only if no candidate matches the mirror peaks; among the rest, the
    # first (simplest) within HELD_OUT_TIE of the lowest held-out error
    peaks_off = min(c.peaks_match is False for c in usable)
    usable = [c for c in usable if (c.peaks_match is False) == peaks_off]
    lowest = min(c.held_out_delta_e for c in usable)
    best = next(c for c in usable if c.held_out_delta_e <= lowest + HELD_OUT_TIE)
    return best.fit, results
