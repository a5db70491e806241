"""``gonio fit``: the thin shell over :func:`gonio_cli.fit.run.run` (options → run → write
and the console lines)."""

from __future__ import annotations

from pathlib import Path
from typing import Iterator, List, Optional

import typer

from .. import log
from ..errors import deg
from ..names import FIT_MODEL_CHOICES as MODEL_NAMES
from ..names import (OPTIMIZER_NAMES, OPTIMIZERS_BY_MODEL, RESIDUAL_NAMES, STEP2_NAMES,
                     SWEEP_GAIN_NAMES, metavar)
from ..outputs import declare
from . import require_files

#: The default model; only its poor fits try the other models for a hint (a model chosen
#: on purpose, e.g. the standard model for a comparison, is not second-guessed).
DEFAULT_MODEL = "goniochromatic"


def fit(
    measurement: Path = typer.Argument(..., metavar="MEASUREMENT.json", show_default=False,
                                      help="A gonio.measurement file (gonio ingest)."),
    output: Path = typer.Option(..., "--output", "-o", metavar="MATERIAL.json",
                                help="The gonio.material file to write."),
    model: str = typer.Option(DEFAULT_MODEL, "--model", "-m", metavar=metavar(MODEL_NAMES),
                              help="The model (docs/fit.md); auto: every model, the best "
                                   "on held-out angles of incidence."),
    refine: bool = typer.Option(True, "--refine/--no-refine",
                                help="Fit alpha, rho, c jointly after seed 000's two steps."),
    step2: str = typer.Option("mirror", "--step2", metavar=metavar(STEP2_NAMES),
                              help="Configurations of the paper's step 2: mirror (eq. 7) or all."),
    exclude_theta_i: List[float] = typer.Option(
        [], "--exclude-theta-i-deg", "--exclude-theta-i", metavar="DEG",
        help="Leave out an angle of incidence (deg); repeatable."),
    exclude_theta_o: List[float] = typer.Option(
        [], "--exclude-theta-o-deg", "--exclude-theta-o", metavar="DEG",
        help="Leave out a detector angle (deg, signed); repeatable."),
    weights: Optional[Path] = typer.Option(
        None, "--weights", metavar="WEIGHTS.csv",
        help="Weights by configuration: CSV theta_i_deg,theta_o_deg,weight (unlisted: 1; "
             "0 leaves one out)."),
    residuals: str = typer.Option(
        "compressive", "--residuals", metavar=metavar(RESIDUAL_NAMES),
        help="compressive (peak and tail alike, default), log (multiplicative noise) or "
             "linear."),
    sweep_gain: str = typer.Option(
        "auto", "--sweep-gain", metavar=metavar(SWEEP_GAIN_NAMES),
        help="One gain per angle of incidence, fitted with the model (separately "
             "calibrated lamps); auto: for a multi-angle instrument's file (docs/fit.md)."),
    std_weights: bool = typer.Option(True, "--std-weights/--no-std-weights",
                                     help="Weight by brdf_std of the repeats when present."),
    optimizer: Optional[str] = typer.Option(
        None, "--optimizer", metavar=metavar(OPTIMIZER_NAMES), show_default=False,
        help="Default: the model's first. " + "; ".join(
            f"{m}: {', '.join(v)}" for m, v in OPTIMIZERS_BY_MODEL.items()) + "."),
    alpha: Optional[float] = typer.Option(None, "--alpha", metavar="ALPHA",
                                          help="Fix the roughness instead of fitting it."),
    max_error: Optional[float] = typer.Option(
        None, "--max-error", metavar="DE00",
        help="Largest acceptable mean CIEDE2000 of the model against the data; a fit above "
             "it (or otherwise poor) exits 3 and writes nothing."),
    plot: Optional[Path] = typer.Option(None, "--plot", metavar="FIT.png",
                                        help="Also draw seed 000 Figure 4 for this fit (PNG)."),
    jobs: Optional[int] = typer.Option(
        None, "--jobs", "-j", metavar="N",
        help="Processes that fit --model auto's candidates at once [default: one per "
             "core]; the result does not depend on it."),
    on_failure: str = typer.Option(
        "error", "--on-failure", metavar="error|write",
        help="error: exit 2 and write nothing; write: write the material with status failed."),
) -> None:
    """Fit a reflectance model to a measurement and judge it (seed 000 eqs. 1-7; seed 004
    eqs. 9-14).

    Prints the model, its colour error against the data (mean and worst CIEDE2000, D65,
    10 degree observer), the worst configuration, a verdict: good, poor or failed
    (thresholds in docs/fit.md), which is also the material's status, and the fitted
    roughness with its 95 % interval.

    \b
    Example:
      gonio fit red.measurement.json -o red.material.json --exclude-theta-i-deg 70 --plot red.png
      gonio fit wrap.measurement.json -o wrap.material.json --model auto
    """
    from ..fit import run as stage  # lazy: gonio --help skips the fit core (bench_startup.py)
    require_files([measurement], schema="gonio.measurement")
    options = stage.RunOptions(  # checked here, before any file is read
        model=model, refine=refine, step2=step2, exclude_theta_i_deg=list(exclude_theta_i),
        exclude_theta_o_deg=list(exclude_theta_o), weights=weights, residuals=residuals,
        sweep_gain=sweep_gain, std_weights=std_weights, optimizer=optimizer, alpha=alpha,
        max_error=max_error, jobs=jobs, on_failure=on_failure)
    declare({"-o": output, "--plot": plot}, [measurement, weights])
    require_files([weights] if weights is not None else [], missing_fix="check the path")
    result = stage.run(measurement, options)
    for line in warning_lines(output, result):
        log.warn(line)
    stage.write(result, output, plot=plot)
    for line in report_lines(output, result, stage.better_model_hint):
        log.info(line)


def warning_lines(output: Path, result) -> list[str]:
    """The warnings of a fit kept with ``--on-failure write`` and of its data."""
    failed = ([f"{output}: written with status failed: {result.model_fit.result.message}"]
              if result.failed else [])
    return failed + result.warnings


def report_lines(output: Path, result, hint) -> Iterator[str]:
    """What ``gonio fit`` says of a fit, line by line: each method's figures, ``auto``'s
    candidates, the verdict, and for a poor fit of the default model whether another does
    better (``hint(result)``, which fits them all: last, after the others are shown)."""
    yield summary_line(output, result.model_fit)
    if result.auto is not None:
        yield auto_line(result.auto)
    yield verdict_line(output, result.model_fit, result.judgement,
                       result.material.fit.get("intervals"))
    if result.verdict == "poor" and result.options.model == DEFAULT_MODEL:
        note = hint(result)
        if note:
            yield note


def summary_line(output: Path, result) -> str:
    """One line per method: α (if any), errors and time, so a user sees what each bought;
    a method that failed says so in words."""
    parts = []
    for name, r in result.reports.items():
        if not r.params or not r.success or not r.errors:
            parts.append(f"{name}: failed ({r.message})")
            continue
        a = f"alpha={r.params['alpha']:.4g} " if "alpha" in r.params else ""
        spread = r.extra.get("alpha_std_percent_of_mean")
        spread = f"(per-theta_i spread {spread:.1f}%) " if spread is not None else ""
        parts.append(f"{name}: {a}{spread}log-RMSE={r.errors['log_rmse']:.4f} "
                     f"rel-RMSE={r.errors['relative_rmse_percent']:.2f}% "
                     f"{1e3 * r.time_s:.1f} ms")
    return f"{output}: {result.model}: " + "; ".join(parts)


def verdict_line(output: Path, result, judgement: dict, intervals: dict | None = None) -> str:
    """The verdict, one line, led by what decides it: the colour error (CIEDE2000 of
    R = π f, mean and worst with its configuration), the mirror peaks, what ``good`` means
    (the thresholds; 1 CIEDE2000 is about a just-noticeable difference), the verdict and
    its reasons, then the scalar parameters with their 95 % intervals (``intervals``, the
    material's ``fit.intervals``) and the notes. The relative RMSE, which the dark readings
    dominate, stays in the material (``fit.methods``), off this line."""
    # lazy: gonio --help skips numpy and the fit core (bench_startup.py)
    from ..fit.verdict import parameters_text
    t = judgement.get("thresholds", {})
    mean_max = t.get("mean_delta_e", 0.7)
    worst_max = max(t.get("worst_delta_e", 1.5), mean_max)
    text = [f"{output}: {result.model}:"]
    decided = []
    if "delta_e2000_mean" in judgement:
        wc = judgement["worst_colour_configuration"]
        text.append(f" colour error CIEDE2000 mean {judgement['delta_e2000_mean']:.2f}, worst "
                    f"{judgement['delta_e2000_worst']:.2f} at theta_i {deg(wc['theta_i_deg'])}, "
                    f"theta_o {deg(wc['theta_o_deg'])}"
                    + (f", phi_o {deg(wc['phi_o_deg'])}" if "phi_o_deg" in wc else ""))
        decided.append(f"mean <= {mean_max:g}, worst <= {worst_max:g}")
    ratios = judgement.get("mirror_peak_y_ratio")
    if ratios:
        v = list(ratios.values())
        text.append(f"; mirror peak x{min(v):.2f}-{max(v):.2f} of the data's")
        decided.append(f"peaks x{t.get('peak_ratio_min', 0.75):.2f}-"
                       f"{t.get('peak_ratio_max', 4 / 3):.2f}")
    if decided:
        text.append(f"; good if {', '.join(decided)} (CIEDE2000 1 ~ just noticeable)")
    why = f" ({'; '.join(judgement['reasons'])})" if judgement["reasons"] else ""
    text.append(f": {judgement['verdict']}{why}")
    shown = parameters_text(result.params, intervals) if result.result.success else ""
    if shown:
        text.append(f"; {shown}")
    text.extend(f"; {n}" for n in judgement.get("notes", ()))
    return "".join(text)


def auto_line(auto: dict) -> str:
    """The candidates of --model auto by held-out colour error (those that could not win
    are not held out, and show their error on all the data)."""
    parts = []
    for c in sorted(auto["candidates"], key=lambda c: (c["held_out_delta_e2000_mean"] is None,
                                                       c["held_out_delta_e2000_mean"] or 0)):
        v, own = c["held_out_delta_e2000_mean"], c.get("delta_e2000_mean")
        parts.append(f"{c['model']} {v:.2f}" if v is not None else
                     f"{c['model']} not held out (all the data: {own:.2f})"
                     if c.get("not_held_out") and own is not None else f"{c['model']} failed")
    return f"auto: held-out CIEDE2000 mean: {', '.join(parts)}; chose {auto['chosen']}"


EXAMPLE = ("gonio fit red.measurement.json -o red.material.json --exclude-theta-i-deg 70 "
           "--plot red.png")


SHORT_HELP = "Fit a reflectance model to a measurement and judge it (seeds 000 and 004)."


def register(app: typer.Typer) -> None:
    app.command("fit", short_help=SHORT_HELP)(fit)
