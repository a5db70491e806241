"""``gonio fit``: the thin shell over :mod:`gonio_cli.fit`."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from ..names import FIT_MODEL_CHOICES as MODEL_NAMES
from ..names import (OPTIMIZER_NAMES, OPTIMIZERS_BY_MODEL, RESIDUAL_NAMES, STEP2_NAMES,
                     SWEEP_GAIN_NAMES, metavar)

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

    Prints the model, its relative RMSE, its colour error against the data (mean and
    worst CIEDE2000, D65, 10 degree observer), the worst configuration and a verdict:
    good, poor or failed (thresholds in docs/fit.md), which is also the material's status.

    \b
    Example:
      gonio fit red.measurement.json -o red.material.json --exclude-theta-i-deg 70 --plot red.png
      gonio fit wrap.measurement.json -o wrap.material.json --model auto
    """
    from .. import log
    from ..errors import FitError, InputError, PoorFitError
    from ..fit import check_options, judge, to_material
    from ..fit import fit as run_fit
    from ..fit import fit_auto
    from ..fit import gains as sweep_gains
    from ..fit.common import prepare
    from ..fit.results import FitOptions
    from ..names import pick
    from ..schemas import read_measurement, write_material
    from . import require_files

    require_files([measurement], schema="gonio.measurement")
    pick(("error", "write"), on_failure, "--on-failure")
    check_options(model, optimizer)
    pick(SWEEP_GAIN_NAMES, sweep_gain, "--sweep-gain")
    if jobs is not None and jobs < 1:
        raise InputError(f"--jobs {jobs} is not a number of processes", fix="give N >= 1")
    if max_error is not None and not (max_error > 0 and max_error < 1e3):
        raise InputError(f"--max-error {max_error:g} is not a CIEDE2000 limit",
                         fix="give a number in (0, 1000), e.g. 1.0")
    from ..outputs import declare
    declare({"-o": output, "--plot": plot}, [measurement, weights])
    m = read_measurement(measurement)
    w = read_weights(weights, m) if weights is not None else None
    options = FitOptions(refine=refine, step2=step2, optimizer=optimizer, alpha=alpha)
    extra = {}
    with log.timer() as t:
        data = prepare(m, residuals=residuals, exclude_theta_i_deg=exclude_theta_i,
                       exclude_theta_o_deg=exclude_theta_o, weights=w,
                       use_std=std_weights, path=measurement)
        why = sweep_gains.wanted(sweep_gain, m, data, path=measurement)
        gains = None
        if model == "auto":
            from ..machine import cpu_count

            n_jobs = jobs if jobs is not None else cpu_count()
            if why:
                result, candidates, gains = sweep_gains.fit_auto_with_gains(
                    data, options, lambda d: _named(fit_auto, measurement)(d, options,
                                                                          jobs=n_jobs),
                    _named(run_fit, measurement), why)
            else:
                result, candidates = _named(fit_auto, measurement)(data, options,
                                                                   jobs=n_jobs)
            from ..fit.auto import criterion

            judged = criterion(data) + (
                f"; on the data divided by light-source gains first fitted with "
                f"{sweep_gains.REFERENCE_MODEL}" if gains is not None else "")
            extra["auto"] = {"criterion": judged, "chosen": result.model,
                             "candidates": [c.to_dict() for c in candidates]}
        elif why:
            result, gains = sweep_gains.fit_with_gains(data, model, options,
                                                       _named(run_fit, measurement), why)
        else:
            result = _named(run_fit, measurement)(data, model, options)
        if gains is not None:
            extra["sweep_gain"] = gains.to_dict()
        judgement = judge(data, result, max_error, gains)
    final = result.result
    if not final.success:
        if on_failure == "error":
            raise FitError(f"{measurement}: the {result.model} fit cannot be trusted: "
                           f"{final.message}", fix="see --on-failure write to keep it anyway")
        log.warn(f"{output}: written with status failed: {final.message}")
    elif judgement["verdict"] == "poor" and max_error is not None:
        raise PoorFitError(f"{measurement}: the {result.model} fit is poor: "
                           f"{'; '.join(judgement['reasons'])}; nothing written",
                           fix="try --model auto, or raise --max-error")
    if data.excluded.get("non_positive_values") and residuals == "log":
        log.warn(f"{measurement}: {data.excluded['non_positive_values']} non-positive values "
                 "left out of the log-residual fit")
    material = to_material(result, judgement, extra)
    parameters = {"model": model, "refine": refine, "step2": step2,
                  "exclude_theta_i_deg": list(exclude_theta_i),
                  "exclude_theta_o_deg": list(exclude_theta_o),
                  "weights": str(weights) if weights is not None else None,
                  "residuals": residuals, "sweep_gain": sweep_gain,
                  "std_weights": std_weights, "optimizer": optimizer,
                  "alpha": alpha, "max_error": max_error, "on_failure": on_failure}
    inputs = [measurement] + ([weights] if weights is not None else [])
    write_material(output, material, inputs=inputs, parameters=parameters,
                   time_s=t["time_s"])
    if plot is not None:
        from ..fit.plot import plot_fit

        plot_fit(plot, m, material, title=f"{Path(measurement).name}: {result.model}",
                 excluded_theta_i_deg=exclude_theta_i, gains=gains)
    log.info(summary_line(output, result))
    if model == "auto":
        log.info(auto_line(extra["auto"]))
    log.info(verdict_line(output, result, judgement))
    if judgement["verdict"] == "poor" and model == DEFAULT_MODEL:
        # the product's own model: say whether another one does better (fits them all)
        hint = better_model_hint(data, result, judgement, options, gains)
        if hint:
            log.info(hint)


def _named(fit, measurement: Path):
    """``fit`` whose errors about the data (no usable readings …) name the measurement."""
    from ..errors import GonioError

    def run(*args, **kwargs):
        try:
            return fit(*args, **kwargs)
        except GonioError as exc:
            if exc.path is None and not exc.message.startswith("--"):
                exc.path = str(measurement)
            raise
    return run


def read_weights(path: Path, m) -> "np.ndarray":
    """Per-configuration weights (N,) from a CSV theta_i_deg,theta_o_deg,weight; 1 for the
    configurations it does not list. Every row must name a measured configuration. Split
    by ingest's one CSV reader (delimiters, BOM, comments, line numbers)."""
    import numpy as np

    from ..errors import InputError
    from ..csvio import read_table
    from ..schemas import MAX_MAGNITUDE
    from . import require_files

    require_files([path], missing_fix="check the path")
    table = read_table(path)
    if table.header != ["theta_i_deg", "theta_o_deg", "weight"]:
        raise InputError(f"header is {','.join(table.header) or 'missing'}", path=path,
                         row=table.header_line,
                         fix="the header must be theta_i_deg,theta_o_deg,weight")
    w = np.ones(m.theta_i_deg.shape)
    for row, line in zip(table.cells, table.lines):
        try:
            ti, to, wt = (float(c) for c in row)
        except ValueError:
            raise InputError(f"expected three numbers, got {','.join(row)}", path=path,
                             row=int(line), fix="theta_i_deg,theta_o_deg,weight per line"
                             ) from None
        if not (0 <= wt <= MAX_MAGNITUDE):                    # also NaN
            raise InputError(f"weight {wt:g} is not a finite number in [0, "
                             f"{MAX_MAGNITUDE:g}]", path=path,
                             row=int(line), column="weight")
        hit = (np.abs(m.theta_i_deg - ti) < 1e-6) & (np.abs(m.theta_o_deg - to) < 1e-6)
        if not hit.any():
            raise InputError(f"no measured configuration has theta_i_deg={ti:g}, "
                             f"theta_o_deg={to:g}", path=path, row=int(line),
                             fix="list only configurations of the measurement")
        w[hit] = wt
    return w


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


def verdict_line(output: Path, result, judgement: dict) -> str:
    """The verdict, one line that says what each figure is and which decides: the colour
    error (CIEDE2000 of R = π f; 1 is about a just-noticeable difference) against its
    thresholds, the mirror peaks against theirs, then the relative RMSE, which is shown
    but not judged (the dark readings dominate it), the verdict and its reasons."""
    r = result.result
    t = judgement.get("thresholds", {})
    mean_max = t.get("mean_delta_e", 0.7)
    worst_max = max(t.get("worst_delta_e", 1.5), mean_max)
    text = [f"{output}: {result.model}"]
    decided = []
    if "delta_e2000_mean" in judgement:
        wc = judgement["worst_colour_configuration"]
        text.append(f"CIEDE2000 mean {judgement['delta_e2000_mean']:.2f}, worst "
                    f"{judgement['delta_e2000_worst']:.2f} at theta_i {wc['theta_i_deg']:g}, "
                    f"theta_o {wc['theta_o_deg']:g} (colour error; 1 ~ just noticeable)")
        decided.append(f"mean <= {mean_max:g}, worst <= {worst_max:g}")
    ratios = judgement.get("mirror_peak_y_ratio")
    if ratios:
        v = list(ratios.values())
        text.append(f"mirror peak x{min(v):.2f}-{max(v):.2f} of the data's")
        decided.append(f"peaks x{t.get('peak_ratio_min', 0.75):.2f}-"
                       f"{t.get('peak_ratio_max', 4 / 3):.2f}")
    if r.errors:
        text.append(f"rel-RMSE {r.errors['relative_rmse_percent']:.1f}% (relative error "
                    "of each reading of f, largest where f is small: not judged)")
    rule = (f"; verdict by colour (good if {', '.join(decided)})" if decided else
            "; verdict")
    why = f" ({'; '.join(judgement['reasons'])})" if judgement["reasons"] else ""
    notes = "".join(f"; {n}" for n in judgement.get("notes", ()))
    return ", ".join(text) + f"{rule}: {judgement['verdict']}{why}{notes}"


def auto_line(auto: dict) -> str:
    """The candidates of --model auto by held-out colour error."""
    parts = []
    for c in sorted(auto["candidates"], key=lambda c: (c["held_out_delta_e2000_mean"] is None,
                                                       c["held_out_delta_e2000_mean"] or 0)):
        v = c["held_out_delta_e2000_mean"]
        parts.append(f"{c['model']} {v:.2f}" if v is not None else f"{c['model']} failed")
    return f"auto: held-out CIEDE2000 mean: {', '.join(parts)}; chose {auto['chosen']}"


def better_model_hint(data, result, judgement: dict, options, gains=None) -> str | None:
    """For a poor fit: the other models' in-sample colour error, if one does better
    (with the fit's light-source ``gains``, each on the data divided by them)."""
    import numpy as np

    from ..errors import GonioError
    from ..fit import FITTERS, judge
    from ..fit import fit as run_fit
    from ..fit.gains import scaled

    if "delta_e2000_mean" not in judgement:
        return None
    best = (judgement["delta_e2000_mean"], result.model)
    seen = data if gains is None else scaled(data, gains.per_configuration(data.theta_i_deg))
    for name in FITTERS:
        if name == result.model:
            continue
        try:
            other = run_fit(seen, name, options)
        except GonioError:
            continue
        j = judge(data, other, gains=gains)
        if other.result.success and np.isfinite(j.get("delta_e2000_mean", np.inf)) \
                and j["delta_e2000_mean"] < best[0]:
            best = (j["delta_e2000_mean"], name)
    if best[1] == result.model:
        return None
    return (f"gonio: note: --model {best[1]} fits these data better (CIEDE2000 mean "
            f"{best[0]:.2f} in sample); --model auto chooses by held-out error")


EXAMPLE = ("gonio fit red.measurement.json -o red.material.json --exclude-theta-i-deg 70 "
           "--plot red.png")


SHORT_HELP = "Fit a reflectance model to a measurement and judge it (seeds 000 and 004)."


def register(app: typer.Typer) -> None:
    app.command("fit", short_help=SHORT_HELP)(fit)
