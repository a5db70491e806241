"""``gonio fit``: the thin shell over :mod:`gonio_cli.fit`."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

MODELS = ("goniochromatic", "torrance-sparrow", "cook-torrance")
OPTIMIZER_NAMES = ("nlopt-bobyqa", "nlopt-lbfgs", "scipy-least-squares")


def fit(
    measurement: Path = typer.Argument(..., metavar="MEASUREMENT.json", show_default=False,
                                      help="A gonio.measurement file (gonio ingest)."),
    output: Path = typer.Option(..., "--output", "-o", metavar="MATERIAL.json",
                                help="The gonio.material file to write."),
    model: str = typer.Option("goniochromatic", "--model", "-m", metavar="NAME",
                              help=f"One of: {', '.join(MODELS)}."),
    refine: bool = typer.Option(True, "--refine/--no-refine",
                                help="Fit alpha, rho, c jointly after seed 000's two steps."),
    step2: str = typer.Option("mirror", "--step2", metavar="mirror|all",
                              help="Configurations of the paper's step 2: mirror (eq. 7) or all."),
    exclude_theta_i: List[float] = typer.Option(
        [], "--exclude-theta-i", metavar="DEG", help="Leave out an angle of incidence (deg); repeatable."),
    residuals: str = typer.Option("log", "--residuals", metavar="log|linear", help="log (multiplicative noise) or linear."),
    std_weights: bool = typer.Option(True, "--std-weights/--no-std-weights",
                                     help="Weight by brdf_std of the repeats when present."),
    optimizer: str = typer.Option("nlopt-bobyqa", "--optimizer", metavar="NAME",
                                  help=f"One of: {', '.join(OPTIMIZER_NAMES)}."),
    alpha: Optional[float] = typer.Option(None, "--alpha", metavar="ALPHA",
                                          help="Fix the roughness instead of fitting it."),
    plot: Optional[Path] = typer.Option(None, "--plot", metavar="FIT.png",
                                        help="Also draw seed 000 Figure 4 for this fit (PNG)."),
    on_failure: str = typer.Option(
        "error", "--on-failure", metavar="error|write",
        help="error: exit 2 and write nothing; write: write the material with status failed."),
) -> None:
    """Fit a reflectance model to a measurement (seed 000 eqs. 1-7; seed 004 eqs. 9-14).

    \b
    Example:
      gonio fit red.measurement.json -o red.material.json --exclude-theta-i 70 --plot red.png
      gonio fit red.measurement.json -o red.ts.json --model torrance-sparrow
    """
    from .. import log
    from ..errors import FitError, InputError
    from ..fit import fit as run_fit
    from ..fit import to_material
    from ..fit.common import FitOptions, check_optimizer, prepare
    from ..schemas import read_measurement, write_material
    from . import require_files

    require_files([measurement], missing_fix="check the path or make it with gonio ingest")
    if on_failure not in ("error", "write"):
        raise InputError(f"--on-failure {on_failure!r} is unknown", fix="use error or write")
    check_optimizer(optimizer)
    m = read_measurement(measurement)
    with log.timer() as t:
        data = prepare(m, residuals=residuals, exclude_theta_i_deg=exclude_theta_i,
                       use_std=std_weights, path=measurement)
        result = run_fit(data, model, FitOptions(refine=refine, step2=step2,
                                                 optimizer=optimizer, alpha=alpha))
    material = to_material(result)
    final = result.result
    if not final.success:
        if on_failure == "error":
            raise FitError(f"{measurement}: the {model} fit cannot be trusted: {final.message}",
                           fix="see --on-failure write to keep it anyway")
        log.warn(f"{output}: written with status failed: {final.message}")
    if data.excluded.get("non_positive_values"):
        log.warn(f"{measurement}: {data.excluded['non_positive_values']} non-positive values "
                 "left out of the log-residual fit")
    parameters = {"model": model, "refine": refine, "step2": step2,
                  "exclude_theta_i_deg": list(exclude_theta_i), "residuals": residuals,
                  "std_weights": std_weights, "optimizer": optimizer, "alpha": alpha,
                  "on_failure": on_failure}
    write_material(output, material, inputs=[measurement], parameters=parameters,
                   time_s=t["time_s"])
    if plot is not None:
        from ..fit.plot import plot_fit

        plot_fit(plot, m, material, title=f"{Path(measurement).name}: {model}",
                 excluded_theta_i_deg=exclude_theta_i)
    log.info(summary_line(output, result))


def summary_line(output: Path, result) -> str:
    """One line per method: α (if any), errors and time, so a user sees what each bought."""
    parts = []
    for name, r in result.reports.items():
        if not r.params:
            parts.append(f"{name}: {r.status} ({r.message})")
            continue
        a = f"alpha={r.params['alpha']:.4g} " if "alpha" in r.params else ""
        spread = r.extra.get("alpha_std_percent_of_mean")
        spread = f"(per-theta_i spread {spread:.1f}%) " if spread is not None else ""
        parts.append(f"{name}: {a}{spread}log-RMSE={r.errors.get('log_rmse', float('nan')):.4f} "
                     f"rel-RMSE={r.errors.get('relative_rmse_percent', float('nan')):.2f}% "
                     f"{1e3 * r.time_s:.1f} ms")
    return f"{output}: " + "; ".join(parts)


EXAMPLE = ("gonio fit red.measurement.json -o red.material.json --exclude-theta-i 70 "
           "--plot red.png")


SHORT_HELP = "Fit a reflectance model to a measurement (seeds 000 and 004)."


def register(app: typer.Typer) -> None:
    app.command("fit", short_help=SHORT_HELP)(fit)
