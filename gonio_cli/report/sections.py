"""The sections of ``gonio report``: each runs its sweep in this process and returns a
:class:`Section` (numbers, Markdown tables and plot makers). Pure: reads inputs, writes
nothing but the scratch scenes and materials the renderer reads, into the caller's
``workdir`` (a temporary folder of the shell).

Here the fit, lobes, prefilter and render sections and the registry of all of them in
report order, :data:`SECTIONS`; seed 000's Table 1 is :mod:`.table1`, the colour sheets
:mod:`.sheets`. What a section returns and runs on is :mod:`.section`, how the inputs are
read and fitted :mod:`.inputs`, the scatter plots :mod:`.scatter`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np

from .. import envmap
from ..fit.sweep import comparison_sweep, format_comparison, format_rows, goniochromatic_sweep
from ..imageio import read_image
from ..names import SPECTRAL_PATHS
from ..render.scene import read_scene_toml
from . import sweeps
from .scatter import ERROR_FLOOR, scatter
from .section import Inputs, Section, format_seconds, md_table, sample_file
from .sheets import sheets_section
from .table1 import table1_section


# ----------------------------------------------------------------------------------- fit --

def fit_section(inputs: Inputs, workdir: Path, quick: bool) -> Section:
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


#: Registry: section name → builder, in report order.
SECTIONS: dict[str, Callable[[Inputs, Path, bool], Section]] = {
    "fit": fit_section,
    "lobes": lobes_section,
    "prefilter": prefilter_section,
    "render": render_section,
    "table1": table1_section,
    "sheets": sheets_section,
}
