"""``gonio lobes basis`` and ``gonio lobes fit``: the thin shell over :mod:`gonio_cli.lobes`."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from ..names import (BASIS_SOLVER_NAMES, CHANNEL_NAMES, SAMPLE_SET_NAMES, WEIGHT_SOLVER_NAMES,
                     metavar)
from ..numbers import NumberList

#: ``lobes fit --exponents``: the lobes' exponents (their range is checked by the core).
EXPONENTS = NumberList("--exponents", "1,10,100")

SAMPLE_SET_HELP = ("seed001 (default, seed 001 §4), dense, hemisphere (lights off the plane too: "
                   "use it for lobes rendered under an environment), or a CSV with "
                   "theta_i_deg,theta_o_deg.")


def _samples_option():
    return typer.Option("seed001", "--samples", metavar=metavar(SAMPLE_SET_NAMES + ("FILE.csv",)),
                        help=SAMPLE_SET_HELP)


def _mirror_dense_option():
    return typer.Option(False, "--mirror-dense",
                        help="With --samples hemisphere: add rings of lights down to 0.07 deg "
                             "from each view's mirror direction, weighted by solid angle, so "
                             "lobes up to E=1e4 are resolved (a glossy paint's sharp gloss) "
                             "and the fit conserves the material's energy.")


def _choice_option(flag: str, default: str, choices, help: str):
    """A string option whose metavar lists its choices (validated by the core's registry)."""
    return typer.Option(default, flag, metavar=metavar(choices), help=help)

sub = typer.Typer(help="Cosine-lobe approximation of BRDFs (seed 001): choose exponents, "
                       "fit weights.", no_args_is_help=True, add_completion=False,
                  pretty_exceptions_enable=False, rich_markup_mode=None)


@sub.command("basis")
def basis(
    materials: List[Path] = typer.Argument(..., metavar="MATERIAL.json...", show_default=False,
                                           help="gonio.material files: the database of eq. 4."),
    output: Path = typer.Option(..., "--output", "-o", metavar="BASIS.json",
                                help="The gonio.lobe_basis file to write."),
    max_lobes: int = typer.Option(11, "--max-lobes", metavar="N",
                                  help="Choose exponents for 1 ... N lobes."),
    samples: str = _samples_option(),
    mirror_dense: bool = _mirror_dense_option(),
    channels: str = _choice_option("--channels", "xyz", CHANNEL_NAMES,
                                   "Colour channels the errors are measured in."),
    solver: str = _choice_option("--solver", "nnls", BASIS_SOLVER_NAMES,
                                 "Weights inside eq. 4 (nnls: continuous, monotone)."),
    plot: Optional[Path] = typer.Option(None, "--plot", metavar="BASIS.png",
                                        help="Draw error and exponents against lobe count."),
) -> None:
    """Choose cosine-lobe exponents for 1...N lobes (seed 001 §3.2, eq. 4, Figures 2-3).

    \b
    Example:
      gonio lobes basis red.material.json green.material.json --max-lobes 11 -o basis.json
    """
    from .. import lobes as core
    from .. import log
    from ..schemas import LobeBasis, read_material, write_lobe_basis

    core.check_channels(channels)
    from ..outputs import declare
    declare({"-o": output, "--plot": plot}, materials)
    mats = [read_material(p) for p in materials]
    s = core.sample_set(samples, mirror_dense=mirror_dense)
    with log.timer() as t:
        targets = [core.target_values(m, s, channels)[0] for m in mats]
        result = core.select_basis(
            targets, s, max_lobes, solver=solver,
            progress=lambda counts: log.progress(counts, "lobe basis", total=len(counts)))
    bases = [{"n_lobes": st.n_lobes, "exponents": st.exponents, "error": st.error,
              "max_error": st.max_error, "mean_error": st.mean_error,
              "per_material": st.per_material, "evaluations": st.evaluations,
              "time_s": st.time_s, "message": st.message} for st in result.steps]
    doc = LobeBasis(bases, [{"path": str(p), "model": m.model} for p, m in zip(materials, mats)],
                    s.name, channels, solver, [float(v) for v in result.exponent_range],
                    [float(v) for v in s.view_angle_deg])
    write_lobe_basis(output, doc, inputs=materials, time_s=t["time_s"],
                     parameters={"max_lobes": max_lobes, "samples": samples,
                                 "mirror_dense": mirror_dense, "channels": channels,
                                 "solver": solver})
    for note in core.basis_notes(result):
        log.warn(f"{output}: {note}")
    if plot is not None:
        from ..lobes.plot import plot_basis

        plot_basis(plot, result)
    last = result.steps[-1]
    log.info(f"{output}: {len(result.steps)} bases from {len(mats)} materials, "
             f"{s.n_samples} samples; {last.n_lobes} lobes: error {last.error:.4g} "
             f"(max {last.max_error:.4g}, mean {last.mean_error:.4g}); {t['time_s']:.1f} s")


@sub.command("fit")
def fit(
    material: Path = typer.Argument(..., metavar="MATERIAL.json", show_default=False,
                                    help="A gonio.material file (gonio fit)."),
    output: Path = typer.Option(..., "--output", "-o", metavar="LOBES.json",
                                help="The gonio.lobes file to write."),
    basis_path: Optional[Path] = typer.Option(None, "--basis", metavar="BASIS.json",
                                              help="A gonio.lobe_basis file (gonio lobes basis)."),
    n_lobes: Optional[int] = typer.Option(None, "--lobes", metavar="N",
                                          help="Which lobe count of the basis (default: largest)."),
    exponents: Optional[str] = typer.Option(None, "--exponents", metavar="E1,E2,...",
                                            help="Exponents given directly instead of --basis."),
    samples: str = _samples_option(),
    mirror_dense: bool = _mirror_dense_option(),
    view_angles: str = typer.Option("0:80:10", "--view-angles-deg", "--view-angles",
                                    metavar="START:STOP:STEP|LIST",
                                    help="View angles of the weight table (deg, seed 001 §5.2)."),
    channels: str = _choice_option("--channels", "spectral", CHANNEL_NAMES,
                                   "Weights per wavelength of the grid, or per XYZ."),
    solver: str = _choice_option("--solver", "lp", WEIGHT_SOLVER_NAMES,
                                 "Solver of the weights written (lp: exact simplex; highs: "
                                 "the same LP by HiGHS, the reference)."),
    compare: bool = typer.Option(False, "--compare",
                                 help="Also run every other solver on the same samples and "
                                      "record its error, time and status (not its weights)."),
    max_energy_ratio: float = typer.Option(
        1000.0, "--max-energy-ratio", metavar="R",
        help="Refuse weights whose lobes hold more than R times the light the material "
             "reflects (its directional albedo) at some view angle and channel: a render "
             "would be that much too bright (above 10 times it is a warning). inf: no "
             "check."),
    time_limit_s: Optional[float] = typer.Option(
        None, "--time-limit-s", metavar="S", show_default=False,
        help="Time limit of one LP (one view angle; default 1 s per 100 samples of a view, "
             "at least 1 s); a solve stopped by it is recorded as status time_limit, not "
             "an error."),
) -> None:
    """Fit non-negative cosine-lobe weights at each view angle (seed 001 §4, eqs. 5-6, §5.2).

    \b
    Example:
      gonio lobes fit red.material.json --basis basis.json -o red.lobes.json
    """
    from .. import lobes as core
    from .. import log
    from ..errors import InputError
    from ..schemas import Lobes, read_lobe_basis, read_material, write_lobes
    from . import read_as

    core.check_channels(channels)
    core.check_solver(solver)
    if (basis_path is None) == (exponents is None):
        raise InputError("give exactly one of --basis BASIS.json and --exponents E1,E2,...",
                         fix="e.g. --basis basis.json")
    if time_limit_s is not None and not (time_limit_s > 0):
        raise InputError(f"--time-limit-s {time_limit_s:g} is not positive")
    if not (max_energy_ratio >= 1):
        raise InputError(f"--max-energy-ratio {max_energy_ratio:g} is below 1",
                         fix="a sound fit holds about 1x the material's albedo; e.g. "
                             "--max-energy-ratio 1000 (default) or inf for no check")
    from ..outputs import declare
    declare({"-o": output}, [material, basis_path])
    inputs = [material]
    if basis_path is not None:
        e = read_as("--basis", read_lobe_basis, basis_path).exponents(n_lobes, path=basis_path)
        inputs.append(basis_path)
    else:
        e = EXPONENTS.parse(exponents)
    e = core.check_exponents(e, where="--exponents" if basis_path is None else str(basis_path))
    mat = read_material(material)
    s = core.sample_set(samples, core.parse_view_angles(view_angles), mirror_dense)
    if time_limit_s is None:
        time_limit_s = core.default_time_limit_s(s)
    others = tuple(core.WEIGHT_SOLVERS) if compare else ()
    from ..errors import GonioError
    with log.timer() as t:
        try:
            table = core.fit_weight_table(mat, e, s, channels, solver, compare=others,
                                          time_limit_s=time_limit_s,
                                          max_energy_ratio=max_energy_ratio)
        except GonioError as exc:              # a refused fit names the material
            if exc.path is None:
                exc.path = str(material)
            raise
    lobes = Lobes(table.exponents, channels, table.channels, table.view_angle_deg,
                  table.diffuse, table.directional_diffuse, table.gloss, table.errors,
                  solver, s.name, table.n_samples)
    write_lobes(output, lobes, inputs=inputs, time_s=t["time_s"],
                parameters={"lobes": n_lobes, "exponents": [float(v) for v in e],
                            "samples": samples, "mirror_dense": mirror_dense,
                            "view_angles": view_angles,
                            "channels": channels, "solver": solver, "compare": compare,
                            "time_limit_s": time_limit_s,
                            # JSON holds no inf: null is "no check"
                            "max_energy_ratio": (max_energy_ratio if max_energy_ratio
                                                 < float("inf") else None)})
    for note in core.unresolved_notes(table, samples):
        log.warn(f"{output}: {note}")
    note = core.energy_note(table)
    if note is not None:
        log.warn(f"{output}: {note}")
    for name, r in table.errors.items():
        stopped = [k for k, st in enumerate(r["status"]) if st not in core.FINISHED]
        if stopped:
            views = ", ".join(f"{table.view_angle_deg[k]:g}" for k in stopped)
            what = ("the weights written are not optimal there" if name == solver
                    else "a comparison only: the weights written are not affected")
            log.warn(f"{output}: {name} did not finish at view angle(s) {views} deg "
                     f"({r['message'][stopped[0]]}); {what}; the status per view is in "
                     "the file")
    log.info(f"{output}: {e.size} lobes, {len(table.view_angle_deg)} view angles, "
             f"{len(table.channels)} channels; " + error_text(table.errors, s.name))


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


EXAMPLE = "gonio lobes basis red.material.json blue.material.json -o basis.json --plot basis.png"


def register(app: typer.Typer) -> None:
    app.add_typer(sub, name="lobes")
