"""Shading speed: the tabulated spectral path against the exact 41-wavelength sum
("the tabulated spectral sum about 6 ms per light", "the naive 41-wavelength sum
75 ms").

A synthetic GBuffer of a sphere built analytically (orthographic view from +z, radius
√2·1.01 so all 512 × 512 pixels are covered), two directional D65 lights (no shadows), the
three materials of seed 000 Figure 5: goniochromatic inks (table), their Torrance–Sparrow
counterpart (separable, exact) and a Cook–Torrance paint; the measured reference takes the
exact path only. For each: the best of ``--repeats`` calls of :func:`shade` per path, the
time per light, and the difference between the paths (largest relative XYZ difference
and CIEDE2000, mean and max, over pixels brighter than 1e-3 of the peak). ``--quick``:
256², 2 repeats. Uses ``out/rgbink`` and ``out/carpaint`` if ``make demo`` has run,
synthetic inks otherwise.

    .venv/bin/python benchmarks/bench_render_shade.py [--quick] [--size N] [--repeats N]
"""

from __future__ import annotations

import argparse
import os
import platform
import time

from gonio_cli.__main__ import use_blas_threads

use_blas_threads()  # before numpy: kernels timed as in a gonio process

import numpy as np

from gonio_cli.render import GBuffer, Light, Stats
from gonio_cli.render.shade import shade
from gonio_cli.render.surface import Surface
from gonio_cli.schemas import Material, read_material
from gonio_cli.spectra import illuminant, parse_grid

#: The demo's prefiltered sky and lobe weights (``make demo``), for the environment line.
ENV_INDEX, ENV_LOBES = "out/sky/index.json", "out/lobes/red.lobes.json"

#: The target for the tabulated path, per light, at 512 × 512 (s).
TARGET_PER_LIGHT_S = 0.006


def full_sphere_gbuffer(n: int) -> GBuffer:
    """Orthographic view from +z of a sphere of radius √2·1.01: every pixel covered."""
    radius = np.sqrt(2.0) * 1.01
    c = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    x, y = np.meshgrid(c, -c)
    z = np.sqrt(radius ** 2 - x * x - y * y)
    p = np.stack([x, y, z], -1)
    view = np.zeros_like(p)
    view[..., 2] = 1.0
    return GBuffer(np.zeros((n, n), dtype=int), p, p / radius, view)


def materials(wl):
    paths = {"red (goniochromatic)": "out/rgbink/red.material.json",
             "green (goniochromatic)": "out/rgbink/green.material.json",
             "blue (goniochromatic)": "out/rgbink/blue.material.json",
             "red (torrance-sparrow)": "out/rgbink/red.torrance-sparrow.material.json",
             "paint (cook-torrance)": "out/carpaint/paint.material.json"}
    if all(os.path.exists(p) for p in paths.values()):
        return {k: read_material(p) for k, p in paths.items()}
    out = {}
    for name, peak in (("red", 620.0), ("green", 530.0), ("blue", 450.0)):
        rho = 0.05 + 0.6 * np.exp(-0.5 * ((wl - peak) / 40.0) ** 2)
        c = 0.5 + 5.0 * np.exp(-0.5 * ((wl - peak + 60.0) / 50.0) ** 2)
        out[f"{name} (goniochromatic, synthetic)"] = Material(
            "goniochromatic", wl, {"alpha": 0.19, "rho": rho, "c": c})
    return out


def best_of(repeats, fn):
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t)
    return min(times), result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="256², 2 repeats")
    parser.add_argument("--size", type=int, default=None, help="image side in pixels")
    parser.add_argument("--repeats", type=int, default=None, help="timed calls per path")
    args = parser.parse_args()
    size = args.size or (256 if args.quick else 512)
    repeats = args.repeats or (2 if args.quick else 7)

    import colour  # imported before timing (1.5 s)

    wl = parse_grid()
    s = illuminant("D65", wl)
    lights = [Light("directional", s, direction=np.array([1.0, 1.0, 1.0]) / np.sqrt(3.0),
                    irradiance=3.0),
              Light("directional", s, direction=np.array([-1.0, 0.2, 0.5]), irradiance=1.0)]
    g = full_sphere_gbuffer(size)
    print(f"## gonio render: shading, {size} × {size} covered pixels, {len(lights)} "
          f"directional lights ({platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} CPUs, best of {repeats})\n")
    print("| material | path | table size | time (ms) | per light (ms) | max rel. XYZ diff | "
          "mean ΔE00 | max ΔE00 |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for name, m in materials(wl).items():
        surf = [Surface(material=m)]
        stats = Stats()
        t_table, table = best_of(repeats, lambda: shade(g, surf, lights, wl, spectral="table",
                                                        stats=stats))
        t_exact, exact = best_of(repeats, lambda: shade(g, surf, lights, wl, spectral="exact"))
        bright = exact[..., 1] > 1e-3 * exact[..., 1].max()
        rel = np.max(np.abs(table[bright] - exact[bright]) / np.maximum(exact[bright], 1e-300))
        white = exact[bright, 1].max()
        de = colour.delta_E(colour.XYZ_to_Lab(table[bright] / white),
                            colour.XYZ_to_Lab(exact[bright] / white), method="CIE 2000")
        sizes = stats.counts["shade"]["table_sizes"]
        for path, t in (("table", t_table), ("exact", t_exact)):
            print(f"| {name} | {path} | {sizes[0] if sizes and path == 'table' else '—'} | "
                  f"{t * 1e3:.1f} | {t * 1e3 / len(lights):.1f} | "
                  + (f"{rel:.1e} | {de.mean():.1e} | {de.max():.1e} |" if path == "table"
                     else "— | — | — |"))
    print(f"\nTarget: tabulated path ≤ {TARGET_PER_LIGHT_S * 1e3:.0f} ms per light "
          "(target), on an idle machine.")
    if os.path.exists(ENV_INDEX) and os.path.exists(ENV_LOBES):
        from gonio_cli.render.environment import load_environment
        from gonio_cli.schemas import read_lobes

        env = load_environment(ENV_INDEX)
        lobes = read_lobes(ENV_LOBES)
        surf = [Surface(material=read_material("out/rgbink/red.material.json"), lobes=lobes)]
        shade(g, surf, [], wl, environment=env)                # reads the maps once
        t_env, _ = best_of(repeats, lambda: shade(g, surf, [], wl, environment=env))
        print(f"\nEnvironment light ({ENV_INDEX}, {ENV_LOBES}: {lobes.exponents.size} lobes, "
              f"{lobes.view_angle_deg.size} view angles, {lobes.channel_kind} weights): "
              f"{t_env * 1e3:.0f} ms for {size} × {size} pixels.")


if __name__ == "__main__":
    main()
