"""The sections of ``gonio report``: each runs its sweep in this process and returns a
:class:`Section` (numbers, Markdown tables and plot makers). Pure: reads inputs, writes
nothing but the scratch scenes and materials the renderer reads, into the caller's
``workdir`` (a temporary folder of the shell).

Here the shared types and helpers and the fit, lobes, prefilter and render sections;
seed 000's Table 1 is :mod:`.table1`, the colour sheets :mod:`.sheets`, and the registry
of all of them in report order :data:`SECTIONS` (below, after the imports of those two).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..names import SPECTRAL_PATHS
from . import format_seconds, sweeps


def sample_file(*parts: str) -> Path:
    """A file of the bundled sample data (:func:`gonio_cli.samples.sample_data_dir`)."""
    from ..samples import sample_data_dir

    return sample_data_dir().joinpath(*parts)

#: Seed 000 Table 1 (RTX 4080 laptop GPU, 512 × 512): the paper's numbers, pasted and
#: labelled as such in the report. Render time per frame in µs, shared by the three inks.
PAPER_TABLE1 = {
    "goniochromatic": {"red": (0.1182, 0.7557), "green": (0.1163, 0.7159),
                       "blue": (0.0792, 0.8034), "frame_us": 107.0},
    "torrance-sparrow": {"red": (0.1495, 0.6096), "green": (0.1444, 0.5978),
                         "blue": (0.1020, 0.7329), "frame_us": 116.0},
}
MODEL_LABEL = {"goniochromatic": "ours (eq. 5)", "torrance-sparrow": "standard (TS)"}


@dataclass
class Section:
    """One section's result: ``numbers`` (JSON-able), ``markdown`` (tables and text, which
    refer to the plots by file name), ``plots`` file name → ``fn(path)`` that draws it."""

    name: str
    title: str
    numbers: dict[str, Any]
    markdown: str
    plots: dict[str, Callable[[Path], None]] = field(default_factory=dict)
    time_s: float = 0.0


@dataclass
class Ink:
    """A measured material: its measurement and the fitted models (model → Material)."""

    name: str
    measurement: Any
    materials: dict[str, Any]


@dataclass
class Inputs:
    """What the report runs on: inks (measurement + fits) and materials for the sheets."""

    inks: list[Ink]
    sheets: list[tuple[str, Any]]
    sources: list[str]


def md_table(header: list[str], rows: list[list[str]]) -> str:
    align = ["---" if i == 0 or not any(_numeric(r[i]) for r in rows) else "---:"
             for i in range(len(header))]
    return "\n".join(["| " + " | ".join(header) + " |", "|" + "|".join(align) + "|"]
                     + ["| " + " | ".join(r) + " |" for r in rows])


def _numeric(text: str) -> bool:
    try:
        float(text.replace("×", "").split()[0])
        return True
    except (ValueError, IndexError):
        return False


#: Errors below this are drawn at it on log axes (an exact method's 0 or 1e-16 would
#: stretch the axis over decades of nothing) and marked as such in the legend.
ERROR_FLOOR = 1e-9


def scatter(path: Path, series: dict[str, tuple[list[float], list[float]]], xlabel: str,
             ylabel: str, title: str, logx=True, logy=True,
             point_labels: dict[str, list[str]] | None = None,
             floor: float | None = None) -> None:
    """An error-against-time scatter plot (one marker style per series), PNG.

    ``point_labels``: per series, a text written beside each point (e.g. the ink).
    ``floor``: y values below it are drawn at it with a hollow marker, and the legend
    says "≤ floor (exact)".
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=110)
    markers = "osD^v<>ph*"
    floored_any = False
    for k, (label, (x, y)) in enumerate(series.items()):
        x, y = np.asarray(x, float), np.asarray(y, float)
        floored = np.zeros(y.shape, bool) if floor is None else y < floor
        if floor is not None:
            y = np.maximum(y, floor)
        ok = np.isfinite(x) & np.isfinite(y) & (x > 0) & ((y > 0) | (not logy))
        marker = markers[k % len(markers)]
        (line,) = ax.plot(x[ok & ~floored], y[ok & ~floored], marker, label=label, alpha=0.8)
        if np.any(ok & floored):
            floored_any = True
            ax.plot(x[ok & floored], y[ok & floored], marker, mfc="none",
                    color=line.get_color(), alpha=0.9)
        for xi, yi, text in zip(x[ok], y[ok],
                                np.asarray((point_labels or {}).get(label, []), object)[ok]
                                if (point_labels or {}).get(label) else []):
            ax.annotate(text, (xi, yi), textcoords="offset points", xytext=(4, 3), fontsize=7)
    if floored_any:
        ax.plot([], [], "o", mfc="none", color="0.3", label=f"hollow: ≤{floor:g} (exact), "
                                                            f"drawn at {floor:g}")
    if logx:
        ax.set_xscale("log")
    if logy:
        ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


# -------------------------------------------------------------------------------- inputs --

def default_inputs(exclude_theta_i_deg=None) -> Inputs:
    """The bundled sample inks as the demo ingests them (sample_data/inks.toml, read by
    pipelines/rgbink.mk too), fitted in memory with both models (seed 000 leaves out the
    70° row: the file's ``[fit]``, unless ``exclude_theta_i_deg`` is given)."""
    from ..ingest import ingest
    from ..samples import demo_fit_options, demo_inks

    if exclude_theta_i_deg is None:
        exclude_theta_i_deg = tuple(demo_fit_options().get("exclude_theta_i_deg", ()))
    inks, sources = [], []
    for ink in demo_inks():
        sources += [str(p) for p in ink.files]
        m = ingest(list(ink.files), **ink.ingest)
        inks.append(Ink(ink.name, m, fit_models(m, exclude_theta_i_deg)))
    return Inputs(inks, [(f"{i.name} ({MODEL_LABEL[k]})", mat) for i in inks
                         for k, mat in i.materials.items()], sources)


def fit_models(m, exclude_theta_i_deg=(70.0,)) -> dict:
    """Goniochromatic and Torrance–Sparrow fits of a measurement, in memory."""
    from ..fit import fit, to_material
    from ..fit.common import prepare
    from ..fit.results import FitOptions

    data = prepare(m, exclude_theta_i_deg=list(exclude_theta_i_deg))
    return {model: to_material(fit(data, model, FitOptions()))
            for model in ("goniochromatic", "torrance-sparrow")}


def inputs_from_files(paths: list[Path]) -> Inputs:
    """Measurements (``*.measurement.json``) and materials (``gonio.material`` files).

    A measurement ``NAME.measurement.json`` pairs with ``NAME.material.json`` and
    ``NAME.torrance-sparrow.material.json`` among the given files (fitted in memory when
    not given) and goes into Table 1; every material gets a sheet.
    """
    from ..errors import GonioError, InputError
    from ..schemas import read_material, read_measurement

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
            try:
                fits = fit_models(m)
            except GonioError as exc:  # about this measurement's data: name it
                if exc.path is None:
                    exc.path = str(next(p for p in paths
                                        if p.name == f"{name}.measurement.json"))
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
    from ..schemas import write_material, write_measurement

    folder = workdir / "rgbink"
    folder.mkdir(parents=True, exist_ok=True)
    for ink in inputs.inks:
        write_measurement(folder / f"{ink.name}.measurement.json", ink.measurement)
        write_material(folder / f"{ink.name}.material.json", ink.materials["goniochromatic"])
        write_material(folder / f"{ink.name}.torrance-sparrow.material.json",
                       ink.materials["torrance-sparrow"])
    return workdir


# ----------------------------------------------------------------------------------- fit --

def fit_section(inputs: Inputs, workdir: Path, quick: bool) -> Section:
    from ..fit.sweep import comparison_sweep, format_comparison, format_rows, \
        goniochromatic_sweep

    rows = goniochromatic_sweep(alphas=(0.19,) if quick else (0.03, 0.19, 0.5),
                                inks=("red",) if quick else ("red", "green", "blue"),
                                repeats=1 if quick else 5)
    comp = comparison_sweep(repeats=1 if quick else 5)
    numbers = {"goniochromatic": [r.__dict__ for r in rows], "comparison": comp}

    def plot(path):
        series: dict[str, tuple[list, list]] = {}
        for r in rows:
            x, y = series.setdefault(f"{r.method} / {r.optimizer}", ([], []))
            x.append(r.time_ms)
            y.append(max(r.alpha_error_percent, 1e-4))
        scatter(path, series, "fit time (ms, median)", "α error vs truth (%)",
                 "fit: parameter error against run time (synthetic eq. 5 data, 2% noise)")

    md = ("Synthetic measurements from eq. 5 with known α, ρ, c (2 % log-normal noise, "
          "seed 000's geometry); each method × optimiser fitted in this run.\n\n"
          + format_rows(rows) + "\n\nComparison models on data made from themselves:\n\n"
          + format_comparison(comp) + "\n\n![fit](fit.png)")
    return Section("fit", "Fit: method × optimiser", numbers, md, {"fit.png": plot})


# --------------------------------------------------------------------------------- lobes --

def lobes_section(inputs: Inputs, workdir: Path, quick: bool) -> Section:
    from .. import envmap
    from ..imageio import read_image

    res = sweeps.lobe_sweep(max_lobes=4 if quick else 8, repeats=3 if quick else 15)
    rows = res["rows"]
    sky = read_image(sample_file("sky.exr")).pixels[:, :, :3].astype(np.float64)
    sky = envmap.downsample(sky, max(1, sky.shape[0] // 64))
    ink = inputs.inks[0].materials.get("goniochromatic") if inputs.inks else None
    render = sweeps.lobe_render_times(res["basis"], ink, sky, size=96 if quick else 256) \
        if ink is not None else []
    res["render"] = render

    def plot(path):
        series: dict[str, tuple[list, list]] = {}
        for r in rows:
            x, y = series.setdefault(r["solver"], ([], []))
            x.append(r["time_ms"])
            y.append(r["rel_rms_worst"])
        scatter(path, series, "weight-fit time (ms, median)",
                 "relative RMS error (worst material)",
                 "lobes: approximation error against weight-fit time (1…N lobes)")

    md = (f"Basis search (seed 001 eq. 4, XYZ) over {len(res['materials'])} materials "
          f"({', '.join(res['materials'])}) took {format_seconds(res['basis_time_s'])}:\n\n"
          + md_table(["lobes", "eq. 4 error", "exponents"],
                      [[str(b["lobes"]), f"{b['eq4_error']:.4f}",
                        ", ".join(f"{e:.3g}" for e in b["exponents"])] for b in res["basis"]])
          + f"\n\nOne weight fit ({res['samples']} samples, dense set at 40° view, XYZ) per "
            "lobe count and solver:\n\n"
          + md_table(["lobes", "weights", "solver", "L1 (sum)", "rel. RMS (worst)",
                       "time ms"],
                      [[str(r["lobes"]), str(r["weights"]), r["solver"], f"{r['l1_sum']:.4g}",
                        f"{r['rel_rms_worst']:.4g}", f"{r['time_ms']:.3g}"] for r in rows])
          + ("\n\nEnvironment light per lobe count (seed 001 eqs. 7–9, what `gonio render` "
             f"runs): {inputs.inks[0].name if inputs.inks else ''} ink's eq. 5 weights fitted "
             "over the hemisphere, the bundled sky "
             f"prefiltered at the basis's exponents, the environment term over the "
             f"{render[0]['pixels']} pixels of a sphere:\n\n"
             + md_table(["lobes", "render ms (median)"],
                         [[str(r["lobes"]), f"{r['render_ms']:.3g}"] for r in render])
             if render else "")
          + "\n\n![lobes](lobes.png)")
    return Section("lobes", "Lobes: lobe count and weight solver", res, md,
                   {"lobes.png": plot})


# ----------------------------------------------------------------------------- prefilter --

def prefilter_section(inputs: Inputs, workdir: Path, quick: bool) -> Section:
    from .. import envmap
    from ..imageio import read_image

    sky = read_image(sample_file("sky.exr")).pixels[:, :, :3].astype(np.float64)
    h = sky.shape[0]
    small = envmap.downsample(sky, max(1, h // 64))
    mid = envmap.downsample(sky, max(1, h // (128 if quick else 256)))
    brute = sweeps.prefilter_brute_rows(small, [1.0, 10.0, 100.0] if quick else
                                        [1.0, 3.0, 10.0, 30.0, 100.0, 300.0, 1000.0])
    ring = [r for e in ([1.0, 100.0] if quick else [1.0, 10.0, 100.0, 1000.0])
            for r in sweeps.prefilter_ring_rows(mid, e)]

    def plot(path):
        series: dict[str, tuple[list, list]] = {}
        for r in brute:
            x, y = series.setdefault("ring (auto) vs brute", ([], []))
            x.append(r["ring_s"])
            y.append(r["p99_error"])
        for r in ring:
            x, y = series.setdefault(f"ring E={r['exponent']:g} vs full-res ring", ([], []))
            x.append(r["time_s"])
            y.append(r["p99_error"])
        scatter(path, series, "time (s)", "relative error, 99th percentile",
                 "prefilter: error against run time", floor=ERROR_FLOOR)

    md = (f"The bundled sky (`sample_data/sky.exr`), at {small.shape[1]}×{small.shape[0]} "
          "for brute force (the truth):\n\n"
          + md_table(["E", "output", "ring s", "brute s", "p99 error", "max error"],
                      [[f"{r['exponent']:.4g}", r["output"], f"{r['ring_s']:.3g}",
                        f"{r['brute_s']:.3g}", f"{r['p99_error']:.1e}", f"{r['max_error']:.1e}"]
                       for r in brute])
          + f"\n\nRing on {mid.shape[1]}×{mid.shape[0]} by output resolution and working map "
            "(reference: ring on the full input):\n\n"
          + md_table(["E", "output", "working map", "time s", "p99 error", "max error"],
                      [[f"{r['exponent']:.4g}", r["output"] + (" (auto)" if r["auto"] else ""),
                        r["working"], f"{r['time_s']:.3g}", f"{r['p99_error']:.1e}",
                        f"{r['max_error']:.1e}"] for r in ring])
          + "\n\n![prefilter](prefilter.png)")
    return Section("prefilter", "Prefilter: method and resolution per exponent",
                   {"brute": brute, "ring": ring}, md, {"prefilter.png": plot})


# -------------------------------------------------------------------------------- render --

def _sphere_scene(segments: int | None) -> tuple[Path, dict]:
    """spheres.toml as data with the sphere's tessellation set: (path, scene)."""
    from ..render.scene import read_scene_toml

    path = sample_file("scenes", "spheres.toml")
    doc = read_scene_toml(path)
    if segments is not None:
        sphere = next(o for o in doc["object"] if o.get("mesh") == "builtin:sphere")
        sphere["mesh"] = f"builtin:sphere?segments={segments}"
    return path, doc


def render_section(inputs: Inputs, workdir: Path, quick: bool) -> Section:
    size = 96 if quick else 256
    ink = inputs.inks[0].name
    variables = {"out": str(workdir), "material": ink}
    ref_settings = dict(spectral="exact", ssaa=4, segments=288)
    path, doc = _sphere_scene(288)
    ref, _, ref_t = sweeps.render_scene_file(path, variables, doc=doc, width=size,
                                             height=size, ssaa=4, spectral="exact")
    points = [dict(sweep=f"{sp}, ssaa 1-3", spectral=sp, ssaa=s, segments=None)
              for sp in SPECTRAL_PATHS for s in (1, 2, 3)]
    points += [dict(sweep="table, ssaa 2, segments 12-96", spectral="table", ssaa=2,
                    segments=n) for n in (12, 24, 48, 96)]
    rows = []
    for p in points:
        path, doc = _sphere_scene(p["segments"])
        sweeps.render_scene_file(path, variables, doc=doc, width=size, height=size,
                                 ssaa=p["ssaa"], spectral=p["spectral"])  # warm (first use)
        frame, stats, t = sweeps.render_scene_file(path, variables, doc=doc, width=size,
                                                   height=size, ssaa=p["ssaa"],
                                                   spectral=p["spectral"])
        covered = (frame.coverage > 0) | (ref.coverage > 0)
        de = sweeps.delta_e_2000(frame.xyz[covered], ref.xyz[covered])
        segments = p["segments"] or 144
        rows.append({**p, "segments": segments,
                     "triangles": 2 * segments * (segments // 2 - 1),
                     "de2000_mean": float(de.mean()), "de2000_p99": float(np.percentile(de, 99)),
                     "frame_ms": 1e3 * t, "shade_ms": 1e3 * stats.time_s.get("shade", 0.0)})

    def plot(path):
        series: dict[str, tuple[list, list]] = {}
        for r in rows:
            x, y = series.setdefault(r["sweep"], ([], []))
            x.append(r["frame_ms"])
            y.append(max(r["de2000_mean"], 1e-4))
        scatter(path, series, "frame time (ms)", "mean CIEDE2000 vs reference",
                 f"render: error against frame time ({size}×{size}, {ink} ink)")

    md = (f"The {ink} ink on `spheres.toml` at {size}×{size}; reference: exact spectral path, "
          f"ssaa 4, 288 segments ({format_seconds(ref_t)}). CIEDE2000 (Lab, D65 white at Y = 1) "
          "over pixels covered in either image; frame = rasterize + shade + downsample + tone "
          "map, second of two runs.\n\n"
          + md_table(["spectral", "ssaa", "segments", "triangles", "ΔE00 mean", "ΔE00 p99",
                       "frame ms", "shade ms"],
                      [[r["spectral"], str(r["ssaa"]), str(r["segments"]), str(r["triangles"]),
                        f"{r['de2000_mean']:.3f}", f"{r['de2000_p99']:.3f}",
                        f"{r['frame_ms']:.3g}", f"{r['shade_ms']:.3g}"] for r in rows])
          + "\n\n![render](render.png)")
    return Section("render", "Render: spectral path, supersampling, tessellation",
                   {"size_px": size, "reference": {**ref_settings, "frame_ms": 1e3 * ref_t},
                    "rows": rows}, md, {"render.png": plot})


from .sheets import sheets_section  # noqa: E402  (they build on the types above)
from .table1 import table1_section  # noqa: E402

#: Registry: section name → builder, in report order.
SECTIONS: dict[str, Callable[[Inputs, Path, bool], Section]] = {
    "fit": fit_section,
    "lobes": lobes_section,
    "prefilter": prefilter_section,
    "render": render_section,
    "table1": table1_section,
    "sheets": sheets_section,
}
