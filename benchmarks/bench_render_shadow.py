"""Benchmark of shadows in ``gonio render``: the stage, the frame, the whole command.

    .venv/bin/python benchmarks/bench_render_shadow.py [--quick] [--out OUT]

Scene (the issue's target): 512 × 512, ssaa 1, a 20 448-triangle sphere resting on a floor
(``builtin:plane`` scaled 5), both a goniochromatic-coat material (seed 000 eq. 5 + a
Lambertian term + a GGX clear coat; synthetic), under the demo's prefiltered sky
(``OUT/sky``, with the paint's lobe weights ``OUT/lobes/paint.lobes.json``; ``OUT``
defaults to the demo's ``out/``, and without it the environment is left out and said so)
and one directional D65 sun with ``shadow = true`` (the default) or ``false``.

1. The frame in a warm process, shadows on and off: the median per stage of N renders
   (N = 9, 3 with ``--quick``), and the shadow stage's counts. Target: frame ≤ 80 ms
   with the shadow.
2. The shadow kernel alone (:func:`gonio_cli.render.shadow.shadow_visibility` on the
   frame's G-buffer), split into its parts: the maps (rasterization + bounds) and the
   lookups (the one-texel test, the filter at the edges); the median of N.
3. Whole ``gonio render`` processes (wall time, peak RSS), shadows on and off: best of 3
   (1 with ``--quick``). Target: ≤ 1 s.
4. The accuracy figures the tests assert (tests/test_render_shadow.py, its scenes and
   analytic truth), printed: per size (128² as in the tests, and 512²) the largest V in
   the analytic umbra, the distance (px) of the rendered V = ½ outline from the analytic
   one (mean, max), and the 10° sun's penumbra against the disc integral.

The tests check the shadows; this prints their figures and the timings.
"""

from __future__ import annotations

import argparse
import functools
import statistics
import sys
import tempfile
import textwrap
import time
from pathlib import Path

from gonio_cli.__main__ import use_blas_threads

use_blas_threads()  # before numpy: kernels timed as in a gonio process

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))

import process  # noqa: E402  (whole-process wall time and memory)

SIZE = 512
TARGETS = {"frame_s": 0.080, "whole_s": 1.0}


def coat_material(path: Path) -> None:
    """A synthetic goniochromatic-coat material (a red colour-shifting layer under a
    clear coat) on the default grid."""
    from gonio_cli.schemas import Material, write_material
    from gonio_cli.spectra import parse_grid

    wl = parse_grid()
    rho = 0.02 + 0.25 * np.exp(-0.5 * ((wl - 620.0) / 35.0) ** 2)
    c = 0.3 + 5.0 / (1.0 + np.exp((wl - 580.0) / 20.0))
    write_material(path, Material("goniochromatic-coat", wl, {
        "alpha": 0.18, "rho": rho, "c": c, "rho_d": 0.3 * rho, "alpha_coat": 0.05,
        "k_coat": 1.0, "f0_coat": 0.04}))


def write_scene(folder: Path, out: Path | None, shadow: bool) -> Path:
    """The benchmark scene (module docstring); the environment only if ``out`` has it."""
    coat_material(folder / "coat.json")
    env, lobes = "", ""
    if out is not None:
        env = f'\n[environment]\nprefiltered = "{out / "sky" / "index.json"}"\n'
        lobes = f'lobes = "{out / "lobes" / "paint.lobes.json"}"'
    text = textwrap.dedent(f"""
        [camera]
        eye = [0.0, 3.0, 5.5]
        target = [0.0, 0.6, 0.0]
        fov_deg = 40.0
        width = {SIZE}
        height = {SIZE}

        [[object]]
        name = "sphere"
        mesh = "builtin:sphere"
        material = "coat.json"
        translate = [0.0, 1.0, 0.0]
        {lobes}

        [[object]]
        name = "floor"
        mesh = "builtin:plane"
        material = "coat.json"
        rotate_deg = [-90.0, 0.0, 0.0]
        scale = 5.0
        {lobes}

        [[light]]
        name = "sun"
        type = "directional"
        direction = [1.0, 1.6, 0.6]
        irradiance = 3.0
        shadow = {str(shadow).lower()}

        [output]
        ssaa = 1
        exposure = -2.0
        tonemap = "filmic"
        """) + env
    path = folder / f"shadow_{'on' if shadow else 'off'}.toml"
    path.write_text(text)
    return path


def warm_frame(scene: Path, repeats: int) -> tuple[dict[str, float], dict]:
    """Median per-stage times (s) of ``repeats`` renders in this process (after one), and
    the last run's shadow counts."""
    from gonio_cli import log
    from gonio_cli.render import Stats
    from gonio_cli.render.frame import frame_time
    from gonio_cli.render.pipeline import render_scene
    from gonio_cli.render.scene import load_scene

    log.set_quiet(True)
    sc = load_scene(scene)
    render_scene(sc, Stats())
    runs, st = [], None
    for _ in range(repeats):
        st = Stats()
        render_scene(sc, st)
        runs.append(dict(st.time_s, frame=frame_time(st)))
    return ({k: statistics.median(r.get(k, 0.0) for r in runs) for k in runs[0]},
            st.counts.get("shadows", []))


def kernel_parts(scene: Path, repeats: int) -> dict[str, float]:
    """The shadow stage alone on the scene's G-buffer, with its parts timed: median
    seconds of ``repeats`` calls."""
    from gonio_cli.render import shadow, shadowmap
    from gonio_cli.render.budget import needs_positions
    from gonio_cli.render.load import load_meshes
    from gonio_cli.render.raster import rasterize
    from gonio_cli.render.scene import load_scene

    sc = load_scene(scene)
    meshes = load_meshes(sc)
    gb = rasterize(sc.camera, meshes, 1, uv=False, compact=True, dtype=np.float32,
                   position=needs_positions(sc), facet=True)
    parts: dict[str, float] = {}

    def timed(module, name, label):
        f = getattr(module, name)

        @functools.wraps(f)
        def g(*a, **k):
            t0 = time.perf_counter()
            try:
                return f(*a, **k)
            finally:
                parts[label] = parts.get(label, 0.0) + time.perf_counter() - t0
        return f, g

    patches = [(shadowmap, "render_maps", "maps: rasterization"),
               (shadowmap, "_make_view", "maps: bounds (dilation)"),
               (shadow, "_visibility", "lookup (one texel + filter)"),
               (shadow, "_filter", "lookup: filter at edges")]
    saved = []
    for module, name, label in patches:
        f, g = timed(module, name, label)
        saved.append((module, name, f))
        setattr(module, name, g)
    runs = []
    try:
        shadow.shadow_visibility(sc.lights, meshes, gb)            # warm
        for _ in range(repeats):
            parts.clear()
            t0 = time.perf_counter()
            shadow.shadow_visibility(sc.lights, meshes, gb)
            runs.append(dict(parts, total=time.perf_counter() - t0))
    finally:
        for module, name, f in saved:
            setattr(module, name, f)
    return {k: statistics.median(r.get(k, 0.0) for r in runs) for k in runs[0]}


def accuracy(size: int) -> str:
    """One row of section 4 at ``size``² (ssaa 1), from the tests' scenes and truth."""
    sys.path.insert(0, str(ROOT / "tests"))
    import test_render_shadow as t

    folder = Path(tempfile.mkdtemp(prefix="bench_shadow_acc."))
    n = t.GRID.size
    t.write_material(folder / "matte.json", t.Material("cook-torrance", t.GRID, {
        "kd": np.full(n, 0.5), "ks": np.zeros(n), "m": np.full(n, 0.3),
        "f0": np.full(n, 0.04)}))
    cells = []
    for kind, outline in (("directional", t.sphere_outline_directional),
                          ("point", t.sphere_outline_point)):
        v, scene = _visibility_at(t, folder, kind, size)
        floor = t.floor_pixels(scene)
        g = t.signed_px(scene, outline, np.zeros(3), np.array([0.0, 1.0, 0.0]))
        errs = t.crossing_errors(v, g, floor)
        cells.append(f"{np.nanmax(v[floor & (g < -t.EDGE_PX)]):.3f} | "
                     f"{errs.mean():.2f} / {errs.max():.2f}")
    return f"| {size}² | " + " | ".join(cells) + " |"


def _visibility_at(t, folder, kind, size):
    """The tests' ``visibility`` at another image size."""
    y, scene = t.render(folder, t.SPHERE_ON_FLOOR, t.light_toml(kind, True), size=size)
    y0, _ = t.render(folder, t.SPHERE_ON_FLOOR, t.light_toml(kind, False), size=size)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(y0 > 0, y / y0, np.nan), scene


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", type=Path, default=ROOT / "out",
                    help="the demo's output folder (sky and lobes), default out/")
    args = ap.parse_args()
    repeats = 3 if args.quick else 9
    out = args.out if (args.out / "sky" / "index.json").is_file() and (
        args.out / "lobes" / "paint.lobes.json").is_file() else None
    tmp = Path(tempfile.mkdtemp(prefix="bench_shadow."))
    on, off = write_scene(tmp, out, True), write_scene(tmp, out, False)
    print(f"# shadows: {SIZE}x{SIZE}, ssaa 1, sphere (20 448 triangles) on a floor, "
          f"goniochromatic-coat, one directional sun, "
          f"{'the demo sky (' + str(out) + ')' if out else 'NO environment (no demo out/)'}; "
          f"load average {process.load_average()}\n")

    print(f"## the frame in a warm process (median of {repeats}, ms)\n")
    f_on, counts = warm_frame(on, repeats)
    f_off, _ = warm_frame(off, repeats)
    print("| stage | shadow on | shadow off |")
    print("|---|---:|---:|")
    for k in ("rasterize", "shadows", "shade", "shade.environment", "downsample", "tonemap",
              "frame"):
        print(f"| {k} | {1e3 * f_on.get(k, 0):.1f} | {1e3 * f_off.get(k, 0):.1f} |")
    print(f"\nshadow counts: {counts}")
    print(f"\nTarget: frame ≤ {1e3 * TARGETS['frame_s']:.0f} ms with the shadow: "
          f"{1e3 * f_on['frame']:.0f} ms (without: {1e3 * f_off['frame']:.0f} ms).")

    print(f"\n## the shadow kernel alone (median of {repeats}, ms)\n")
    parts = kernel_parts(on, repeats)
    print("| part | ms |")
    print("|---|---:|")
    for k, v in parts.items():
        print(f"| {k} | {1e3 * v:.1f} |")

    print("\n## whole processes (best of {}; wall s, peak RSS MB)\n".format(
        1 if args.quick else 3))
    print("| render | wall (s) | peak RSS (MB) |")
    print("|---|---:|---:|")
    best = {}
    for label, scene in (("shadow on", on), ("shadow off", off)):
        cmd = [process.gonio_command(), "-q", "render", str(scene), "-o",
               str(tmp / "o.png")]
        runs = [process.run_measured(cmd) for _ in range(1 if args.quick else 3)]
        wall, rss, _ = min(runs)
        best[label] = wall
        print(f"| {label} | {wall:.2f} | {rss:.0f} |")
    print(f"\nTarget: whole command ≤ {TARGETS['whole_s']:.0f} s: "
          f"{best['shadow on']:.2f} s.")

    print("\n## accuracy (tests/test_render_shadow.py's scenes; V = rendered / unshadowed)\n")
    print("| image | sun: max V in umbra | sun: V = ½ outline off by (px, mean / max) "
          "| lamp: max V in umbra | lamp: outline off by (px) |")
    print("|---|---:|---:|---:|---:|")
    for size in (128,) if args.quick else (128, 512):
        print(accuracy(size))


if __name__ == "__main__":
    main()
