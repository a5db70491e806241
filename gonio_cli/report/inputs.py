"""What ``gonio report`` runs on (:class:`~.section.Inputs`): the bundled sample inks
ingested and fitted in memory, or the measurement and material files given; and the scratch
files the renderer reads. The in-memory fits are :func:`gonio_cli.fit.run.run`'s, as
``gonio fit`` makes them."""

from __future__ import annotations

from pathlib import Path

from ..errors import GonioError, InputError
from ..fit.run import RunOptions, run
from ..ingest import ingest
from ..samples import demo_fit_options, demo_inks
from ..schemas import read_material, read_measurement, write_material, write_measurement
from .section import Ink, Inputs

#: The models of seed 000 Table 1 fitted for each ink, and their labels in the report.
MODEL_LABEL = {"goniochromatic": "ours (eq. 5)", "torrance-sparrow": "standard (TS)"}


def default_inputs(exclude_theta_i_deg=None) -> Inputs:
    """The bundled sample inks as the demo ingests them (sample_data/inks.toml, read by
    pipelines/rgbink.mk too), fitted in memory with both models (seed 000 leaves out the
    70° row: the file's ``[fit]``, unless ``exclude_theta_i_deg`` is given)."""
    if exclude_theta_i_deg is None:
        exclude_theta_i_deg = tuple(demo_fit_options().get("exclude_theta_i_deg", ()))
    inks, sources = [], []
    for ink in demo_inks():
        sources += [str(p) for p in ink.files]
        m = ingest(list(ink.files), **ink.ingest)
        inks.append(Ink(ink.name, m, fit_models(m, exclude_theta_i_deg)))
    return Inputs(inks, [(f"{i.name} ({MODEL_LABEL[k]})", mat) for i in inks
                         for k, mat in i.materials.items()], sources)


def fit_models(m, exclude_theta_i_deg=(70.0,), path=None) -> dict:
    """Goniochromatic and Torrance–Sparrow fits of a measurement, in memory, each made as
    ``gonio fit M --model MODEL --exclude-theta-i-deg ... --on-failure write`` makes it
    (:func:`gonio_cli.fit.run.run`: the same data preparation, gains, verdict and status).
    ``path`` names the measurement in errors."""
    exclude = list(exclude_theta_i_deg)
    return {model: run(m, RunOptions(model=model, exclude_theta_i_deg=exclude,
                                     on_failure="write"), path=path).material
            for model in MODEL_LABEL}


def inputs_from_files(paths: list[Path]) -> Inputs:
    """Measurements (``*.measurement.json``) and materials (``gonio.material`` files).

    A measurement ``NAME.measurement.json`` pairs with ``NAME.material.json`` and
    ``NAME.torrance-sparrow.material.json`` among the given files (fitted in memory when
    not given) and goes into Table 1; every material gets a sheet.
    """
    measurements, materials = {}, {}
    for p in paths:
        if not Path(p).is_file():
            raise InputError("no such file", path=p, fix="give measurement or material files")
        if p.name.endswith(".measurement.json"):
            measurements[p.name[: -len(".measurement.json")]] = read_measurement(p)
        else:
            materials[p.name[: -len(".json")] if p.name.endswith(".json") else p.name] = \
                read_material(p)
    inks = []
    for name, m in measurements.items():
        fits = {}
        gc, ts = materials.get(f"{name}.material"), materials.get(
            f"{name}.torrance-sparrow.material")
        if gc is None or ts is None:
            source = next(p for p in paths if p.name == f"{name}.measurement.json")
            try:
                fits = fit_models(m, path=source)
            except GonioError as exc:  # about this measurement's data: name it
                if exc.path is None:
                    exc.path = str(source)
                raise
        inks.append(Ink(name, m, {"goniochromatic": gc or fits["goniochromatic"],
                                  "torrance-sparrow": ts or fits["torrance-sparrow"]}))
    sheets = [(name.removesuffix(".material"), mat) for name, mat in materials.items()]
    if not sheets:
        sheets = [(f"{i.name} ({MODEL_LABEL[k]})", mat) for i in inks
                  for k, mat in i.materials.items()]
    return Inputs(inks, sheets, [str(p) for p in paths])


def write_scratch(inputs: Inputs, workdir: Path) -> Path:
    """The inks' measurements and materials as files the renderer reads:
    ``workdir/rgbink/NAME.measurement.json`` etc., as the demo lays them out."""
    folder = workdir / "rgbink"
    folder.mkdir(parents=True, exist_ok=True)
    for ink in inputs.inks:
        write_measurement(folder / f"{ink.name}.measurement.json", ink.measurement)
        write_material(folder / f"{ink.name}.material.json", ink.materials["goniochromatic"])
        write_material(folder / f"{ink.name}.torrance-sparrow.material.json",
                       ink.materials["torrance-sparrow"])
    return workdir
