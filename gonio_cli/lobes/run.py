"""``gonio lobes basis`` and ``gonio lobes fit`` as library calls: material files in, a
``gonio.lobe_basis`` or ``gonio.lobes`` artifact out.

:func:`basis` runs the exponent search (seed 001 §3.2, eq. 4) over a database of materials
and :func:`fit` the weight table (seed 001 §4, eqs. 5-6, §5.2) of one material; each
returns its result with the sentences a user should read (``notes``, warnings) and one
summary line, and raises :class:`gonio_cli.errors.GonioError`. :func:`write_basis` and
:func:`write_fit` write the artifacts. The shell :mod:`gonio_cli.commands.lobes` parses the
options, declares the outputs and calls these.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable, Sequence

from ..errors import GonioError, InputError
from ..schemas import LobeBasis, Lobes, read_material, write_lobe_basis, write_lobes
from . import ENERGY_EXCESS_MAX, check_exponents
from .basis import BasisResult, basis_notes, select_basis
from .energy import energy_note
from .samples import Samples, check_channels, parse_view_angles, sample_set, target_values
from .solve import WeightTable, default_time_limit_s, fit_weight_table, unresolved_notes
from .solvers import FINISHED, WEIGHT_SOLVERS, check_solver


@dataclass(kw_only=True)
class StageRun:
    """What either command records and says: the artifact's parameters, the time (s) and
    the sentences to warn about (``notes``)."""

    parameters: dict
    time_s: float
    notes: list[str] = field(default_factory=list)


# ------------------------------------------------------------------------- basis --

@dataclass(frozen=True)
class BasisOptions:
    """The options of ``gonio lobes basis`` (their help is the shell's)."""

    max_lobes: int = 11
    samples: str = "seed001"
    mirror_dense: bool = False
    channels: str = "xyz"
    solver: str = "nnls"


@dataclass
class BasisRun(StageRun):
    """What :func:`basis` found: the artifact, the search's result, the sample set and the
    material files."""

    document: LobeBasis
    result: BasisResult
    samples: Samples
    inputs: list

    def summary(self) -> str:
        """The line a run ends with (after the output's name)."""
        last = self.result.steps[-1]
        return (f"{len(self.result.steps)} bases from {len(self.inputs)} materials, "
                f"{self.samples.n_samples} samples; {last.n_lobes} lobes: error "
                f"{last.error:.4g} (max {last.max_error:.4g}, mean {last.mean_error:.4g}); "
                f"{self.time_s:.1f} s")


def check_basis_options(options: BasisOptions) -> None:
    """Refuse a bad choice before anything is read or written."""
    check_channels(options.channels)


def basis(materials: Sequence[str | os.PathLike], options: BasisOptions = BasisOptions(),
          progress: Callable | None = None) -> BasisRun:
    """Choose exponents for 1 … ``options.max_lobes`` lobes over the materials (seed 001
    §3.2, eq. 4; :func:`gonio_cli.lobes.basis.select_basis`).

    Parameters
    ----------
    materials : paths of ``gonio.material`` files, the database of eq. 4.
    options : :class:`BasisOptions`.
    progress : optional wrapper of the lobe-count loop, ``progress(counts)``.
    """
    check_basis_options(options)
    mats = [read_material(p) for p in materials]
    s = sample_set(options.samples, mirror_dense=options.mirror_dense)
    start = time.perf_counter()
    targets = [target_values(m, s, options.channels)[0] for m in mats]
    result = select_basis(targets, s, options.max_lobes, solver=options.solver,
                          progress=progress)
    time_s = time.perf_counter() - start
    bases = [{"n_lobes": st.n_lobes, "exponents": st.exponents, "error": st.error,
              "max_error": st.max_error, "mean_error": st.mean_error,
              "per_material": st.per_material, "evaluations": st.evaluations,
              "time_s": st.time_s, "message": st.message} for st in result.steps]
    doc = LobeBasis(bases, [{"path": str(p), "model": m.model} for p, m in zip(materials, mats)],
                    s.name, options.channels, options.solver,
                    [float(v) for v in result.exponent_range],
                    [float(v) for v in s.view_angle_deg])
    return BasisRun(doc, result, s, list(materials), parameters=asdict(options),
                    time_s=time_s, notes=basis_notes(result))


def write_basis(output: Path, run: BasisRun) -> None:
    """Write the ``gonio.lobe_basis`` artifact of :func:`basis`."""
    write_lobe_basis(output, run.document, inputs=run.inputs, time_s=run.time_s,
                     parameters=run.parameters)


# --------------------------------------------------------------------------- fit --

@dataclass(frozen=True)
class FitOptions:
    """The options of ``gonio lobes fit`` (their help is the shell's). ``n_lobes`` is the
    lobe count of the basis the exponents were taken from (recorded only);
    ``time_limit_s`` None is :func:`gonio_cli.lobes.solve.default_time_limit_s`."""

    samples: str = "seed001"
    mirror_dense: bool = False
    view_angles: str = "0:80:10"
    channels: str = "spectral"
    solver: str = "lp"
    compare: bool = False
    max_energy_ratio: float = ENERGY_EXCESS_MAX
    time_limit_s: float | None = None
    n_lobes: int | None = None


@dataclass
class LobesFit(StageRun):
    """What :func:`fit` made: the artifact and the weight table."""

    lobes: Lobes
    table: WeightTable

    def summary(self) -> str:
        """The line a run ends with (after the output's name)."""
        t = self.table
        return (f"{t.exponents.size} lobes, {len(t.view_angle_deg)} view angles, "
                f"{len(t.channels)} channels; " + error_text(t.errors, self.lobes.sample_set))


def check_fit_options(options: FitOptions) -> None:
    """Refuse a bad choice before anything is read or written."""
    check_channels(options.channels)
    check_solver(options.solver)


def check_fit_limits(options: FitOptions) -> None:
    """Refuse a time limit or an energy ratio that cannot be meant."""
    if options.time_limit_s is not None and not (options.time_limit_s > 0):
        raise InputError(f"--time-limit-s {options.time_limit_s:g} is not positive")
    if not (options.max_energy_ratio >= 1):
        raise InputError(f"--max-energy-ratio {options.max_energy_ratio:g} is below 1",
                         fix="a sound fit holds about 1x the material's albedo; e.g. "
                             "--max-energy-ratio 1000 (default) or inf for no check")


def fit(material: str | os.PathLike, exponents: Sequence[float],
        options: FitOptions = FitOptions(), where: str = "--exponents") -> LobesFit:
    """Fit non-negative cosine-lobe weights of a material at each view angle (seed 001 §4,
    eqs. 5-6, §5.2; :func:`gonio_cli.lobes.solve.fit_weight_table`).

    Parameters
    ----------
    material : path of a ``gonio.material`` file.
    exponents : (m,) the lobes' exponents; ``where`` names them in an error (the option
        or the basis file they came from).
    options : :class:`FitOptions`.

    Raises
    ------
    GonioError
        A bad option or exponent, or a refused fit (named after the material).
    """
    check_fit_options(options)
    check_fit_limits(options)
    e = check_exponents(exponents, where=where)
    mat = read_material(material)
    s = sample_set(options.samples, parse_view_angles(options.view_angles),
                   options.mirror_dense)
    time_limit_s = (options.time_limit_s if options.time_limit_s is not None
                    else default_time_limit_s(s))
    others = tuple(WEIGHT_SOLVERS) if options.compare else ()
    start = time.perf_counter()
    try:
        table = fit_weight_table(mat, e, s, options.channels, options.solver, compare=others,
                                 time_limit_s=time_limit_s,
                                 max_energy_ratio=options.max_energy_ratio)
    except GonioError as exc:              # a refused fit names the material
        if exc.path is None:
            exc.path = str(material)
        raise
    time_s = time.perf_counter() - start
    lobes = Lobes(table.exponents, options.channels, table.channels, table.view_angle_deg,
                  table.diffuse, table.directional_diffuse, table.gloss, table.errors,
                  options.solver, s.name, table.n_samples)
    parameters = {"lobes": options.n_lobes, "exponents": [float(v) for v in e],
                  "samples": options.samples, "mirror_dense": options.mirror_dense,
                  "view_angles": options.view_angles, "channels": options.channels,
                  "solver": options.solver, "compare": options.compare,
                  "time_limit_s": time_limit_s,
                  # JSON holds no inf: null is "no check"
                  "max_energy_ratio": (options.max_energy_ratio
                                       if options.max_energy_ratio < math.inf else None)}
    return LobesFit(lobes, table, parameters=parameters, time_s=time_s,
                    notes=fit_notes(table, options.samples, options.solver))


def fit_notes(table: WeightTable, samples: str, solver: str) -> list[str]:
    """The warnings of a weight table: lobes left out, energy held, solves that did not
    finish."""
    notes = list(unresolved_notes(table, samples))
    note = energy_note(table)
    if note is not None:
        notes.append(note)
    for name, r in table.errors.items():
        stopped = [k for k, st in enumerate(r["status"]) if st not in FINISHED]
        if stopped:
            views = ", ".join(f"{table.view_angle_deg[k]:g}" for k in stopped)
            what = ("the weights written are not optimal there" if name == solver
                    else "a comparison only: the weights written are not affected")
            notes.append(f"{name} did not finish at view angle(s) {views} deg "
                         f"({r['message'][stopped[0]]}); {what}; the status per view is in "
                         "the file")
    return notes


def write_fit(output: Path, result: LobesFit, inputs: Sequence) -> None:
    """Write the ``gonio.lobes`` artifact of :func:`fit`; ``inputs``: the material and the
    basis file the exponents came from, if any."""
    write_lobes(output, result.lobes, inputs=list(inputs), time_s=result.time_s,
                parameters=result.parameters)


def error_text(errors: dict, sample_set: str) -> str:
    """Each solver's worst-view error, said with its scale: rel-RMS sqrt(Σ r² / Σ b²) of
    the lobes against f cos θi over a view's samples is 0 when exact and 1 when no better
    than no lobes at all; a figure of the sample set, so comparable between solvers and
    lobe counts, not between sample sets (hemisphere samples score higher than in-plane
    ones, yet render better off the plane: docs/lobes.md)."""
    parts = [f"{name}{' (written)' if k == 0 and len(errors) > 1 else ''} "
             f"{max(r['rms_relative']):.3g} "
             f"({1e3 * sorted(r['time_s'])[len(r['time_s']) // 2]:.2f} ms/view, median)"
             for k, (name, r) in enumerate(errors.items())]
    return (f"how far the lobes miss f cos theta_i at the worst view, rel-RMS (0 exact, 1 no "
            f"better than no lobes; over the {sample_set} samples: compare solvers and lobe "
            f"counts on them, not sample sets): " + "; ".join(parts))
