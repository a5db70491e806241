"""``gonio lobes basis`` and ``gonio lobes fit``: the thin shell over :mod:`gonio_cli.lobes`."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from .. import log
from ..errors import InputError
from ..names import (BASIS_SOLVER_NAMES, CHANNEL_NAMES, SAMPLE_SET_NAMES, WEIGHT_SOLVER_NAMES,
                     metavar)
from ..numbers import NumberList
from ..outputs import declare
from . import read_as

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
    # lazy: gonio --help and the other commands do not load lobes.run (benchmarks/bench_startup.py)
    from ..lobes import run as stage

    options = stage.BasisOptions(max_lobes, samples, mirror_dense, channels, solver)
    stage.check_basis_options(options)
    declare({"-o": output, "--plot": plot}, materials)
    result = stage.basis(materials, options, progress=lambda counts: log.progress(
        counts, "lobe basis", total=len(counts)))
    stage.write_basis(output, result)
    for note in result.notes:
        log.warn(f"{output}: {note}")
    if plot is not None:
        # lazy: matplotlib only when a plot is asked for
        from ..lobes.plot import plot_basis

        plot_basis(plot, result.result)
    log.info(f"{output}: {result.summary()}")


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
    # lazy: gonio --help and the other commands do not load lobes.run (benchmarks/bench_startup.py)
    from ..lobes import run as stage
    from ..schemas import read_lobe_basis  # lazy: schemas loads numpy

    options = stage.FitOptions(samples, mirror_dense, view_angles, channels, solver, compare,
                               max_energy_ratio, time_limit_s, n_lobes)
    stage.check_fit_options(options)
    if (basis_path is None) == (exponents is None):
        raise InputError("give exactly one of --basis BASIS.json and --exponents E1,E2,...",
                         fix="e.g. --basis basis.json")
    stage.check_fit_limits(options)
    declare({"-o": output}, [material, basis_path])
    inputs = [material]
    if basis_path is not None:
        e = read_as("--basis", read_lobe_basis, basis_path).exponents(n_lobes, path=basis_path)
        inputs.append(basis_path)
    else:
        e = EXPONENTS.parse(exponents)
    result = stage.fit(material, e, options,
                       where="--exponents" if basis_path is None else str(basis_path))
    stage.write_fit(output, result, inputs)
    for note in result.notes:
        log.warn(f"{output}: {note}")
    log.info(f"{output}: {result.summary()}")


EXAMPLE = "gonio lobes basis red.material.json blue.material.json -o basis.json --plot basis.png"


def register(app: typer.Typer) -> None:
    app.add_typer(sub, name="lobes")
