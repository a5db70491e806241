"""The fit stage as one library call: a measurement and :class:`RunOptions` in, a
:class:`FitResult` out (what ``gonio fit`` writes and prints).

:func:`run` decides everything ``gonio fit`` decides: the data prepared (exclusions,
weights, residuals), the light-source gains (:mod:`.gains`), one model or ``--model
auto``'s choice (:mod:`.auto`), the verdict (:func:`gonio_cli.fit.judge`) and the failure
policy (``on_failure``, ``max_error``). It writes nothing and prints nothing: it returns
values and raises :class:`~gonio_cli.errors.GonioError`. :func:`write` writes the material
(and seed 000 Figure 4); :func:`better_model_hint` is the note a poor default fit gets.
``gonio fit``, ``gonio report`` (its in-memory fits) and plain Python call the same
:func:`run`, so a material has the same status and verdict whichever made it::

    from gonio_cli.fit.run import RunOptions, run
    result = run("red.measurement.json", RunOptions(exclude_theta_i_deg=[70.0]))
    result.verdict, result.material.params["alpha"]
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .. import log
from ..errors import FitError, GonioError, InputError, PoorFitError
from ..machine import cpu_count
from ..names import SWEEP_GAIN_NAMES, pick
from ..schemas import Material, Measurement, read_measurement, write_material
from . import FITTERS, check_options, fit, fit_auto, judge, to_material
from . import gains as sweep_gains
from . import uncertainty
from .auto import criterion
from .common import FitData, prepare
from .plot import plot_fit
from .results import FitOptions, ModelFit
from .weights import read_weights

#: ``on_failure``: what a fit that cannot be trusted does (``--on-failure``).
ON_FAILURE = ("error", "write")


@dataclass
class RunOptions:
    """Everything ``gonio fit`` is told besides its files (its flags, same names and
    defaults; docs/fit.md).

    model : a key of :data:`gonio_cli.fit.FITTERS` or ``"auto"``
    refine, step2, optimizer, alpha : the fitter's :class:`~.results.FitOptions`
    exclude_theta_i_deg, exclude_theta_o_deg : angles left out (deg)
    weights : a CSV theta_i_deg,theta_o_deg,weight (:mod:`.weights`), or None
    residuals : "compressive", "log" or "linear" (:func:`~.common.prepare`)
    sweep_gain : "auto", "on" or "off" (:mod:`.gains`)
    std_weights : weight by the repeats' brdf_std when present
    max_error : the largest acceptable mean CIEDE2000; a poor fit then raises
    jobs : processes for ``auto``'s candidates (None: one per core)
    on_failure : "error" (a failed fit raises) or "write" (it is returned, status failed)
    """

    model: str = "goniochromatic"
    refine: bool = True
    step2: str = "mirror"
    exclude_theta_i_deg: list[float] = field(default_factory=list)
    exclude_theta_o_deg: list[float] = field(default_factory=list)
    weights: str | os.PathLike | None = None
    residuals: str = "compressive"
    sweep_gain: str = "auto"
    std_weights: bool = True
    optimizer: str | None = None
    alpha: float | None = None
    max_error: float | None = None
    jobs: int | None = None
    on_failure: str = "error"

    def __post_init__(self):
        self.check()

    def check(self) -> None:
        """Refuse a value no fit can take, before any file is read (the CLI's errors);
        run on construction and again by :func:`run`."""
        pick(ON_FAILURE, self.on_failure, "--on-failure")
        check_options(self.model, self.optimizer)
        pick(SWEEP_GAIN_NAMES, self.sweep_gain, "--sweep-gain")
        if self.jobs is not None and self.jobs < 1:
            raise InputError(f"--jobs {self.jobs} is not a number of processes",
                             fix="give N >= 1")
        if self.max_error is not None and not (self.max_error > 0 and self.max_error < 1e3):
            raise InputError(f"--max-error {self.max_error:g} is not a CIEDE2000 limit",
                             fix="give a number in (0, 1000), e.g. 1.0")

    def fit_options(self) -> FitOptions:
        return FitOptions(refine=self.refine, step2=self.step2, optimizer=self.optimizer,
                          alpha=self.alpha)

    def parameters(self) -> dict[str, Any]:
        """The material's ``parameters``: every option as given."""
        return {"model": self.model, "refine": self.refine, "step2": self.step2,
                "exclude_theta_i_deg": list(self.exclude_theta_i_deg),
                "exclude_theta_o_deg": list(self.exclude_theta_o_deg),
                "weights": str(self.weights) if self.weights is not None else None,
                "residuals": self.residuals, "sweep_gain": self.sweep_gain,
                "std_weights": self.std_weights, "optimizer": self.optimizer,
                "alpha": self.alpha, "max_error": self.max_error,
                "on_failure": self.on_failure}


@dataclass
class FitResult:
    """What one fit learnt and decided.

    ``model_fit`` is the chosen model's fit (its reports), ``judgement`` the verdict
    (:func:`gonio_cli.fit.judge`), ``material`` the artifact's content (status = verdict);
    ``gains`` the light-source gains (or None), ``auto`` the ``--model auto`` record (or
    None); ``warnings`` lines for the console; ``time_s`` the fit's wall time.
    """

    options: RunOptions
    measurement: Measurement
    path: Path | None
    data: FitData
    model_fit: ModelFit
    judgement: dict[str, Any]
    material: Material
    gains: sweep_gains.SweepGains | None = None
    auto: dict[str, Any] | None = None
    time_s: float = 0.0
    warnings: list[str] = field(default_factory=list)

    @property
    def verdict(self) -> str:
        return self.judgement["verdict"]

    @property
    def failed(self) -> bool:
        """The final method did not succeed (returned only with ``on_failure="write"``)."""
        return not self.model_fit.result.success


def run(measurement: Measurement | str | os.PathLike, options: RunOptions | None = None,
        *, path: str | os.PathLike | None = None) -> FitResult:
    """Fit a measurement (a :class:`~gonio_cli.schemas.Measurement` or the path of a
    ``gonio.measurement`` file) as ``gonio fit`` does (module doc).

    ``path`` names an in-memory measurement in errors (a path given as ``measurement``
    names itself).

    Raises
    ------
    InputError
        Bad options or weights, exclusions that leave nothing.
    FitError
        No fit could be made, or (``on_failure="error"``) the fit failed.
    PoorFitError
        The verdict is poor and ``max_error`` was given.
    """
    options = options or RunOptions()
    options.check()
    if not isinstance(measurement, Measurement):
        path = Path(measurement)
        measurement = read_measurement(path)
    path = Path(path) if path is not None else None
    w = read_weights(options.weights, measurement) if options.weights is not None else None
    with log.timer() as t:
        try:
            data = prepare(measurement, residuals=options.residuals,
                           exclude_theta_i_deg=options.exclude_theta_i_deg,
                           exclude_theta_o_deg=options.exclude_theta_o_deg, weights=w,
                           use_std=options.std_weights, path=path)
            why = sweep_gains.wanted(options.sweep_gain, measurement, data, path=path)
            model_fit, gains, auto = _fit(data, options, why)
            judgement = judge(data, model_fit, options.max_error, gains)
            intervals = fit_intervals(data, model_fit, gains)
        except GonioError as exc:       # about the data (no usable readings …): name them
            if path is not None and exc.path is None and not exc.message.startswith("--"):
                exc.path = str(path)
            raise
    _apply_failure_policy(model_fit, judgement, options, path)
    extra = {"auto": auto} if auto is not None else {}
    if gains is not None:
        extra["sweep_gain"] = gains.to_dict()
    extra["intervals"] = intervals
    result = FitResult(options, measurement, path, data, model_fit, judgement,
                       to_material(model_fit, judgement, extra), gains, auto, t["time_s"])
    if data.excluded.get("non_positive_values") and options.residuals == "log":
        result.warnings.append(f"{_name(path)}: {data.excluded['non_positive_values']} "
                               "non-positive values left out of the log-residual fit")
    return result


def fit_intervals(data: FitData, model_fit: ModelFit, gains=None) -> dict[str, Any]:
    """The material's ``fit.intervals`` (:func:`.uncertainty.estimate`, 95 %), with the
    time it took; a failed fit has none (``available`` False)."""
    if not model_fit.result.success:
        return {"level": uncertainty.LEVEL, "method": uncertainty.METHOD, "available": False,
                "why": "the fit failed"}
    with log.timer() as t:
        out = uncertainty.estimate(data, model_fit.model, model_fit.params, gains,
                                   model_fit.result.extra.get("smoothness"))
    out["time_s"] = t["time_s"]
    return out


def _fit(data: FitData, options: RunOptions, why: str | None):
    """(the chosen model's fit, the gains or None, the ``auto`` record or None)."""
    fit_options = options.fit_options()
    if options.model != "auto":
        if why:
            return (*sweep_gains.fit_with_gains(data, options.model, fit_options, fit, why),
                    None)
        return fit(data, options.model, fit_options), None, None
    jobs = options.jobs if options.jobs is not None else cpu_count()
    gains = None
    if why:
        model_fit, candidates, gains = sweep_gains.fit_auto_with_gains(
            data, fit_options, lambda d: fit_auto(d, fit_options, jobs=jobs), fit, why)
    else:
        model_fit, candidates = fit_auto(data, fit_options, jobs=jobs)
    judged = criterion(data) + (
        f"; on the data divided by light-source gains first fitted with "
        f"{sweep_gains.REFERENCE_MODEL}" if gains is not None else "")
    auto = {"criterion": judged, "chosen": model_fit.model,
            "candidates": [c.to_dict() for c in candidates]}
    return model_fit, gains, auto


def _name(path: Path | None) -> str:
    return str(path) if path is not None else "the measurement"


def _apply_failure_policy(model_fit: ModelFit, judgement: dict[str, Any],
                          options: RunOptions, path: Path | None) -> None:
    """``on_failure="error"``: a failed fit raises; ``max_error`` given: a poor one does."""
    final = model_fit.result
    if not final.success:
        if options.on_failure == "error":
            raise FitError(f"{_name(path)}: the {model_fit.model} fit cannot be trusted: "
                           f"{final.message}", fix="see --on-failure write to keep it anyway")
    elif judgement["verdict"] == "poor" and options.max_error is not None:
        raise PoorFitError(f"{_name(path)}: the {model_fit.model} fit is poor: "
                           f"{'; '.join(judgement['reasons'])}; nothing written",
                           fix="try --model auto, or raise --max-error")


def write(result: FitResult, output: str | os.PathLike, *,
          plot: str | os.PathLike | None = None) -> None:
    """Write the material (``gonio.material``, its inputs the measurement file and the
    weights) and, with ``plot``, seed 000 Figure 4 of the fit (PNG)."""
    options = result.options
    inputs = ([result.path] if result.path is not None else []) + (
        [options.weights] if options.weights is not None else [])
    write_material(output, result.material, inputs=inputs, parameters=options.parameters(),
                   time_s=result.time_s)
    if plot is not None:
        name = result.path.name if result.path is not None else "measurement"
        plot_fit(plot, result.measurement, result.material,
                 title=f"{name}: {result.model_fit.model}",
                 excluded_theta_i_deg=options.exclude_theta_i_deg, gains=result.gains)


def better_model_hint(result: FitResult) -> str | None:
    """For a poor fit: the other models' in-sample colour error, if one does better
    (with the fit's light-source gains, each on the data divided by them)."""
    judgement, model_fit, gains, data = (result.judgement, result.model_fit, result.gains,
                                         result.data)
    if "delta_e2000_mean" not in judgement:
        return None
    best = (judgement["delta_e2000_mean"], model_fit.model)
    seen = data if gains is None else sweep_gains.scaled(
        data, gains.per_configuration(data.theta_i_deg))
    for name in FITTERS:
        if name == model_fit.model:
            continue
        try:
            other = fit(seen, name, result.options.fit_options())
        except GonioError:
            continue
        j = judge(data, other, gains=gains)
        if other.result.success and np.isfinite(j.get("delta_e2000_mean", np.inf)) \
                and j["delta_e2000_mean"] < best[0]:
            best = (j["delta_e2000_mean"], name)
    if best[1] == model_fit.model:
        return None
    return (f"gonio: note: --model {best[1]} fits these data better (CIEDE2000 mean "
            f"{best[0]:.2f} in sample); --model auto chooses by held-out error")
