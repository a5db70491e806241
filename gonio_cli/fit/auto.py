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
    #: True when its folds were not fitted: it could not win (:func:`can_win`)
    not_held_out: bool = False
    #: ``FitOptions.stages`` after its fit to all the data: what its folds start from
    stages: dict = field(default_factory=dict, repr=False, compare=False)

    def to_dict(self) -> dict[str, Any]:
        def num(v):
            return float(v) if np.isfinite(v) else None
        return {"model": self.model, "held_out_delta_e2000_mean": num(self.held_out_delta_e),
                "delta_e2000_mean": num(self.in_sample_delta_e), "time_s": self.time_s,
                "status": (self.fit.result.status if self.fit else "failed"),
                "mirror_peaks_match": self.peaks_match, "not_held_out": self.not_held_out,
                "notes": self.notes}


def _score(data: FitData, rows: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Per-configuration error of predictions ``f`` on ``rows``: CIEDE2000 where colour
    can be judged, else the RMS relative error with the compressive residual's floor."""
    if covers_colour(data.wavelength_nm):
        return colour_errors(data.wavelength_nm, data.theta_i_deg[rows],
                             data.theta_o_deg[rows], data.y[rows], f).delta_e
    y = data.y[rows]
    return np.sqrt(np.mean(((f - y) / (np.abs(y) + compressive_floor(data.y))) ** 2, axis=1))


def _full(model: str, data: FitData, options: FitOptions, fit_one, scheme: str) -> Candidate:
    """One candidate's fit to all the data, its in-sample colour error and mirror peaks
    (its held-out error is :func:`_held_out`'s; with nothing to hold out, the in-sample)."""
    sw = Stopwatch()
    try:
        full = fit_one(data, model, options)
    except GonioError as exc:
        return Candidate(model, None, notes=[exc.message])
    cand = Candidate(model, full, stages=dict(options.stages or {}))
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
    if scheme == "in-sample":
        cand.held_out_delta_e = cand.in_sample_delta_e
    cand.time_s = sw.lap()
    return cand


def _fold(cand: Candidate, data: FitData, options: FitOptions, fit_one, label: str,
          rows: np.ndarray):
    """The candidate refitted without fold ``rows``: the CIEDE2000 per held-out
    configuration, or the note why it could not be fitted (str)."""
    # each fold searches near the fit to all the data (FitOptions.warm)
    near = (replace(options, warm=dict(cand.fit.params)) if cand.fit.result.success
            else options)
    try:
        part = fit_one(data.subset(~rows), cand.model, near)
    except GonioError as exc:
        return f"without {label}: {exc.message}"
    return _score(data, rows, evaluate(cand.model, data.subset(rows).cos, part.params))


def _held_out(cand: Candidate, folds_done: list, seconds: float) -> None:
    """Set the candidate's held-out error from its folds (:func:`_fold`'s results)."""
    notes = [r for r in folds_done if isinstance(r, str)]
    if notes:
        cand.notes.append(notes[0])
    else:
        cand.held_out_delta_e = float(np.mean(np.concatenate(folds_done)))
    cand.time_s += seconds


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


#: What the forked processes of :func:`_in_processes` run: (function, items), set before
#: the fork (inherited, never pickled) and cleared after.
_SHARED: tuple | None = None


def _run_item(i: int):
    fn, items = _SHARED
    return fn(items[i])


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


def _in_processes(fn, items: list, jobs: int) -> list:
    """``[fn(item) for item in items]``, in ``jobs`` forked processes (in this one if 1, if
    there is one item, or if :func:`can_fork_workers` says no). Every fit is deterministic
    and each item starts from nothing another item left (its own ``FitOptions.stages``),
    so the figures do not depend on ``jobs``. A process that dies is a one-line error, not
    a wait without end."""
    global _SHARED
    jobs = min(int(jobs), len(items))
    if jobs <= 1 or not can_fork_workers():
        return [fn(item) for item in items]
    import multiprocessing
    import os
    from concurrent.futures import ProcessPoolExecutor
    from concurrent.futures.process import BrokenProcessPool

    _SHARED = (fn, items)
    pool = ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context("fork"),
                               initializer=_child_start, initargs=(os.getpid(),))
    try:
        return list(pool.map(_run_item, range(len(items))))
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


def can_win(cand: Candidate, leader: Candidate) -> bool:
    """Whether ``cand`` could still be chosen once ``leader``'s held-out error is known: a
    candidate whose fit to all the data (the fit a material carries) already misses the
    data by more than the leader misses configurations it never saw, beyond a tie
    (:data:`HELD_OUT_TIE`), or that misses the mirror peaks where the leader matches
    them, cannot be (:func:`choose`); its folds are not fitted."""
    if cand.peaks_match is False and leader.peaks_match is not False:
        return False
    return cand.in_sample_delta_e <= leader.held_out_delta_e + HELD_OUT_TIE


def _leader(cands: list[Candidate]) -> Candidate | None:
    """The candidate most likely to win: matching the mirror peaks, then the lowest
    in-sample error; None if no fit succeeded."""
    ok = [c for c in cands if c.fit is not None and c.fit.result.success]
    return min(ok, key=lambda c: (c.peaks_match is False, c.in_sample_delta_e),
               default=None)


def _judge(candidates, work, jobs: int, prune: bool) -> list[Candidate]:
    """Every candidate fitted to all the data and, if it could win (:func:`can_win`,
    with ``prune``), judged on the folds. The leader's folds go first, in parallel; then
    the folds of the candidates that could beat it, in parallel over groups
    (:data:`TOGETHER`) and folds."""
    data, options, fit_one, scheme, held_out = work
    groups = _groups(candidates)

    def full_group(group):
        opts = replace(options, stages={})     # shared by the group's fits (TOGETHER)
        return [_full(m, data, opts, fit_one, scheme) for m in group]

    found = {c.model: c for g in _in_processes(full_group, groups, jobs) for c in g}
    if not held_out:
        return [found[m] for m in candidates]
    leader = _leader(list(found.values())) if prune else None
    if leader is not None:
        sw = Stopwatch()
        _held_out(leader, _in_processes(
            lambda f: _fold(leader, data, replace(options, stages=dict(leader.stages)),
                            fit_one, *f), held_out, jobs), sw.lap())
    for c in found.values():
        if (c.fit is not None and c is not leader and leader is not None
                and np.isfinite(leader.held_out_delta_e) and not can_win(c, leader)):
            c.not_held_out = True
            c.notes.append(f"not held out: its fit to all the data misses by "
                           f"{c.in_sample_delta_e:.2f}, more than {leader.model} misses "
                           f"the configurations it did not see "
                           f"({leader.held_out_delta_e:.2f})")

    def group_fold(item):
        group, fold = item
        memo = {}
        for m in group:
            memo.update(found[m].stages)
        opts = replace(options, stages=memo)   # a group's fits of one fold share searches
        out = []
        for m in group:
            sw = Stopwatch()
            out.append((m, _fold(found[m], data, opts, fit_one, *fold), sw.lap()))
        return out

    rest = [tuple(m for m in grp if found[m].fit is not None and found[m] is not leader
                  and not found[m].not_held_out) for grp in groups]
    # one process item per group and fold (not per group: a lone candidate that could
    # win would keep one process busy with all its folds while the other waits)
    items = [(g, f) for g in rest if g for f in held_out]
    done: dict[str, tuple[list, float]] = {}
    for part in _in_processes(group_fold, items, jobs):
        for m, result, seconds in part:
            results, total = done.get(m, ([], 0.0))
            done[m] = (results + [result], total + seconds)
    for m, (results, seconds) in done.items():
        _held_out(found[m], results, seconds)
    return [found[m] for m in candidates]


def choose(results: list[Candidate]) -> Candidate:
    """The candidate kept: among those that match the mirror peaks (all, if none does),
    the first (simplest) within :data:`HELD_OUT_TIE` of the lowest held-out error."""
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
    return next(c for c in usable if c.held_out_delta_e <= lowest + HELD_OUT_TIE)


def fit_auto(data: FitData, options: FitOptions,
             fit_one: Callable[[FitData, str, FitOptions], ModelFit],
             candidates=CANDIDATES, jobs: int = 1,
             prune: bool = True) -> tuple[ModelFit, list[Candidate]]:
    """The best candidate's fit by held-out error, and every candidate's figures.

    ``jobs`` > 1 fits in that many processes (:func:`_in_processes`); the figures are the
    same as with one, only sooner. ``prune`` leaves out the folds of the candidates that
    cannot win (:func:`can_win`): the choice is the same as without whenever no
    candidate's held-out error falls below its own in-sample error (its fit to all the data
    is the optimum of those data; measured on the nine real materials of docs/fit.md: the
    same choice, and no held-out error below its in-sample one by more than the tie)."""
    scheme, held_out = folds(data)
    work = (data, options, fit_one, scheme, held_out)
    results = _judge(candidates, work, jobs, prune)
    return choose(results).fit, results
