"""``gonio fit``: reflectance models fitted to a measurement (seed 000, seed 004).

The registry :data:`FITTERS` maps a model name (``--model``) to its fitter; each takes
:class:`~.common.FitData` and :class:`~.results.FitOptions` and returns a
:class:`~.results.ModelFit` with one :class:`~.results.FitReport` per method.

- ``goniochromatic`` (default): seed 000 eq. 5; :mod:`.goniochromatic`
- ``goniochromatic-diffuse``: eq. 5 plus a Lambertian ρ_d(λ); :mod:`.layered`
- ``goniochromatic-coat``: eq. 5, ρ_d(λ) and an achromatic GGX clear coat; :mod:`.layered`
- ``goniochromatic-backscatter``: the coat model with Hapke's opposition effect on ρ_d;
  :mod:`.layered`
- ``goniochromatic-undercoat``: eq. 5 and ρ_d under the clear coat, seen through it
  (refracted angles, Fresnel transmission); :mod:`.layered`
- ``goniochromatic-two-lobe``: eq. 5, ρ_d(λ) and a second GGX lobe with its own α_2 and
  colour ρ_2(λ); :mod:`.layered`
- ``torrance-sparrow``: seed 000 eq. 2 with GGX, Smith G, Schlick F0(λ); :mod:`.torrance_sparrow`
- ``cook-torrance``: seed 004 eqs. 9–12 per wavelength; :mod:`.cook_torrance`
- ``cook-torrance-2``, ``cook-torrance-3``: seed 004 eq. 11 with two or three Beckmann lobes
  (a clear coat and flake lobes), kd(λ), F0(λ); :mod:`.cook_torrance_lobes`
- ``sheen``: a fabric, ρ_d(λ), the Charlie sheen ρ_sheen(λ) (r) and an achromatic GGX lobe
  k_spec (α); :mod:`.sheen`
- ``tabulated-colour``: ρ_d(λ) and a GGX lobe (α) coloured by a table T(θh, θd, λ);
  :mod:`.tabulated_colour`

``auto`` (:data:`AUTO`) fits the candidates and keeps the best on held-out angles
(:mod:`.auto`); every fit is judged by :mod:`.verdict`. A multi-angle instrument's lamps
get one gain each, fitted with the model (:mod:`.gains`). The whole stage, as ``gonio fit``
runs it (data, gains, model, verdict, failure policy), is one call: :func:`.run.run`.
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

from ..brdf import MODELS, evaluate
from ..errors import FitError
from ..names import AUTO_MODEL, FIT_MODEL_CHOICES, OPTIMIZER_NAMES, pick
from ..schemas import Material
from . import (auto, cook_torrance, cook_torrance_lobes, goniochromatic, layered, sheen,
               tabulated_colour, torrance_sparrow)
from .alpha import choose_optimizer
from .common import FitData
from .gains import NOTE_RATIO
from .results import FitOptions, ModelFit
from .verdict import THRESHOLDS, fit_colour_errors, reciprocity, verdict

FITTERS: dict[str, Callable[[FitData, FitOptions], ModelFit]] = {
    "goniochromatic": goniochromatic.fit,
    "goniochromatic-diffuse": layered.fit_diffuse,
    "goniochromatic-coat": layered.fit_coat,
    "goniochromatic-backscatter": layered.fit_backscatter,
    "goniochromatic-undercoat": layered.fit_undercoat,
    "goniochromatic-two-lobe": layered.fit_two_lobe,
    "torrance-sparrow": torrance_sparrow.fit,
    "cook-torrance": cook_torrance.fit,
    "cook-torrance-2": cook_torrance_lobes.fit_2,
    "cook-torrance-3": cook_torrance_lobes.fit_3,
    "sheen": sheen.fit,
    "tabulated-colour": tabulated_colour.fit,
}

#: Each fitter's ``{--optimizer name: callable}``, the first its default; the names are
#: spelled once in :data:`gonio_cli.names.OPTIMIZERS_BY_MODEL` (a test checks the keys).
OPTIMIZERS_BY_MODEL: dict[str, dict[str, Callable]] = {
    "goniochromatic": goniochromatic.OPTIMIZERS,
    "goniochromatic-diffuse": layered.OPTIMIZERS,
    "goniochromatic-coat": layered.OPTIMIZERS,
    "goniochromatic-backscatter": layered.OPTIMIZERS,
    "goniochromatic-undercoat": layered.OPTIMIZERS,
    "goniochromatic-two-lobe": layered.OPTIMIZERS,
    "torrance-sparrow": torrance_sparrow.OPTIMIZERS,
    "cook-torrance": cook_torrance.OPTIMIZERS,
    "cook-torrance-2": cook_torrance_lobes.OPTIMIZERS,
    "cook-torrance-3": cook_torrance_lobes.OPTIMIZERS,
    "sheen": sheen.OPTIMIZERS,
    "tabulated-colour": tabulated_colour.OPTIMIZERS,
}

#: The ``--model`` value that chooses among :data:`FITTERS` by held-out error.
AUTO = AUTO_MODEL

#: Every ``--model`` value, for the CLI's help and errors.
MODEL_CHOICES = FIT_MODEL_CHOICES


def check_options(model: str, optimizer: str | None) -> None:
    """Refuse an unknown ``--model`` or an ``--optimizer`` that ``model`` does not take
    (before any file is read); ``auto`` takes any name, its candidates that lack it are
    skipped with a note."""
    pick(MODEL_CHOICES, model, "--model")
    if optimizer is None:
        return
    if model == AUTO:
        pick(OPTIMIZER_NAMES, optimizer, "--optimizer")
        return
    choose_optimizer(model, OPTIMIZERS_BY_MODEL[model], optimizer)


def fit(data: FitData, model: str = "goniochromatic",
        options: FitOptions | None = None) -> ModelFit:
    """Fit ``model`` (a key of :data:`FITTERS`) to prepared data."""
    if model not in FITTERS:
        pick(MODEL_CHOICES, model, "--model")
    result = FITTERS[model](data, options or FitOptions())
    _require_params(result)
    return result


def _require_params(result: ModelFit) -> None:
    """A fit whose final report lacks some of its model's parameters (a step that could not
    run) is refused here, with its own message, before anything evaluates it."""
    spec = MODELS.get(result.model)
    if spec is None:
        return
    missing = [k for k in spec.scalar_params + spec.spectral_params
               if k not in result.params]
    if missing:
        raise FitError(f"the {result.model} fit has no {', '.join(missing)}: "
                       f"{result.result.message or 'a step could not run'}",
                       fix="add configurations (more detector angles and angles of "
                           "incidence) or choose another --model")


def fit_auto(data: FitData, options: FitOptions | None = None, jobs: int = 1):
    """(best ModelFit, candidates) of ``--model auto`` (:func:`.auto.fit_auto`), its
    candidates fitted in ``jobs`` processes."""
    return auto.fit_auto(data, options or FitOptions(), fit, jobs=jobs)


def judge(data: FitData, result: ModelFit, max_mean_delta_e: float | None = None,
          gains=None) -> dict[str, Any]:
    """The verdict of a fit on its data (:mod:`.verdict`): a dict for the material with
    ``verdict``, ``reasons`` and the colour figures. With light-source ``gains``
    (:class:`.gains.SweepGains`) the model of the data is g(θi) f, judged so; the BRDF's
    own figures are kept beside (``brdf_alone``)."""
    f = evaluate(result.model, data.cos, result.params)
    y = data.y
    if gains is not None:
        g = gains.per_configuration(data.theta_i_deg)[:, None]
        alone = fit_colour_errors(data, f)
        f, y = f * g, data.y / g
    colour = fit_colour_errors(data, f)
    word, reasons = verdict(result.result.success, colour, max_mean_delta_e)
    out: dict[str, Any] = {"verdict": word, "reasons": reasons,
                           "thresholds": dict(THRESHOLDS, **(
                               {"mean_delta_e": max_mean_delta_e}
                               if max_mean_delta_e is not None else {}))}
    if colour is not None:
        out.update(colour.to_dict())
    notes = []
    if gains is not None:
        text = f"light-source gains {gains.text()} fitted with the model"
        if alone is not None:
            out["brdf_alone"] = {"delta_e2000_mean": alone.mean,
                                 "delta_e2000_worst": float(np.max(alone.delta_e))}
            text += (f" (the BRDF alone: CIEDE2000 mean {alone.mean:.2f}, worst "
                     f"{np.max(alone.delta_e):.2f})")
        if not gains.converged:
            text += (f"; the gains still moved after {gains.rounds} rounds (the model and "
                     f"the gains trade against each other: try --sweep-gain off)")
        if gains.ratio > NOTE_RATIO:
            text += (f"; the lamps differ by x{gains.ratio:.2f}: more than a calibration, "
                     f"did the sample move between sweeps?")
        notes.append(text)
    # what the data allow: a pair no reciprocal model can match both of explains a poor
    # fit (with gains: the data as the BRDF should reproduce them)
    gap = reciprocity(data.wavelength_nm, data.theta_i_deg, data.theta_o_deg, y,
                      data.phi_o_deg)
    if gap is not None:
        out["data_reciprocity"] = gap.to_dict()
        if word == "poor" and gap.delta_e - gap.uncertainty > THRESHOLDS["mean_delta_e"]:
            notes.append(gap.sentence())
    if notes:
        out["notes"] = notes
    return out


def to_material(result: ModelFit, judgement: dict[str, Any] | None = None,
                extra: dict[str, Any] | None = None) -> Material:
    """The material artifact's content: final parameters, the verdict (its status) and
    every method's report."""
    fit_info = {"final": result.final, "excluded": result.excluded,
                "methods": {k: r.to_dict() for k, r in result.reports.items()}}
    status = "good" if result.result.success else "failed"
    if judgement is not None:
        fit_info["verdict"] = judgement
        status = judgement["verdict"]
    fit_info.update(extra or {})
    return Material(result.model, result.wavelength_nm, dict(result.params), status, fit_info)
