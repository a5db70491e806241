"""Environment light as users run it: the clear-coated paint under a real sky, error beside time.

    .venv/bin/python benchmarks/bench_render_env.py [--out out] [--repeats 3] [--spp 64]

The scene of issue 26's target: a sphere of the demo's clear-coated paint
(``OUT/carpaint/coat.material.json``, ``make demo``; coat α ≈ 0.02) at 512², lit by the
shipped real sky (Poly Haven ``quarry_01`` at 1k) prefiltered as a chain with its sun split
off as a directional light (``gonio prefilter --chain --sun``), ``[environment] method =
"model"``; beside it the same render by seed 001's lobes (``method = "lobes"``, the
4-lobe chain of ``bench_render_reference.py``), the tool the user had before.

Printed per method and ssaa: the whole ``gonio render`` as a process (best wall time of
``--repeats`` and its peak memory), the frame (rasterize + shade + resolve + tone map, from
the run report) and the environment's share of it (``shade.environment``), and the error:
mean / p95 CIEDE2000 against Mitsuba 3's path tracer on the same scene at 128²
(``--spp``; docs/reference.md has the 512² figures). The first render of a material
computes its lobe tables (``environment.lobes``) and caches them on disk; the timed runs
are the later ones, as on a user's machine.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))

import process  # noqa: E402  (whole-process wall time and memory)

from bench_render_reference import scene_for  # noqa: E402
from gonio_cli.export import mitsuba_reference as mr  # noqa: E402
from gonio_cli.export import reference_compare as rc  # noqa: E402

SKY = ROOT / "sample_data/envmaps/quarry_01_1k.hdr"


def environments(ref: mr.ReferenceScene, work: Path) -> dict[str, tuple[dict, Path | None]]:
    """Each method's [environment] table (and lobes file), made once, untimed."""
    run = mr.run_gonio_process
    run(["prefilter", SKY, "--chain", "--sun", "-o", work / "chain"])
    lobes, env = mr.gonio_environment(ref, work / "lobes", n_lobes=4)
    return {"model": ({"prefiltered": (work / "chain/index.json").resolve(),
                       "method": "model"}, None),
            "lobes": ({**env, "method": "lobes"}, lobes)}


def timed_render(ref: mr.ReferenceScene, work: Path, name: str, environment: dict, lobes,
                 repeats: int) -> dict:
    """Best of ``repeats`` whole ``gonio render`` processes (after one untimed warm-up)."""
    scene = mr.write_gonio_scene(ref, work / f"{name}.toml", environment, lobes=lobes)
    args = [process.gonio_command(), "-q", "render", str(scene), "-o", str(work / f"{name}.png"),
            "--report", str(work / f"{name}.json")]
    process.run_measured(args)
    runs = [process.run_measured(args) for _ in range(repeats)]
    wall, peak, _ = min(runs, key=lambda r: r[0])
    report = json.loads((work / f"{name}.json").read_text())
    sub = {s["stage"]: s["time_s"] for s in report["substages"]}
    return {"wall_s": wall, "peak_mb": peak, "frame_s": report["frame_time_s"],
            "environment_s": sub.get("shade.environment", 0.0)}


def error(ref: mr.ReferenceScene, work: Path, envs: dict, spp: int) -> dict[str, tuple]:
    """Mean and p95 CIEDE2000 of each method against Mitsuba at 128²."""
    small = replace(ref, camera=replace(ref.camera, width=128, height=128))
    mitsuba = mr.render_mitsuba(small, work / "mitsuba", spp=spp)
    out = {}
    for method, (environment, lobes) in envs.items():
        exr = mr.render_gonio(small, work / "small", environment, lobes=lobes, name=method)
        c = rc.compare(exr, mitsuba)
        out[method] = (c.mean_delta_e, c.p95_delta_e, c.noise_delta_e)
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=ROOT / "out", help="the demo's outputs")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--spp", type=int, default=64)
    a = p.parse_args()
    paint = a.out / "carpaint/coat.material.json"
    if not paint.is_file():
        raise SystemExit(f"{paint} is missing: run make demo first")
    work = Path(tempfile.mkdtemp(prefix="gonio-env-"))
    ref = scene_for(paint, SKY, 512)
    envs = environments(ref, work)
    errors = error(ref, work, envs, a.spp)
    print(f"# coat paint sphere, 512², quarry_01 1k; load {process.load_average()}")
    print("| method | ssaa | whole command (best of "
          f"{a.repeats}) | peak MB | frame | of it environment | CIEDE2000 vs Mitsuba at "
          "128² mean / p95 (its noise) |")
    print("|---|---:|---:|---:|---:|---:|---|")
    for method, (environment, lobes) in envs.items():
        for ssaa in (1, 2):
            r = timed_render(replace(ref, ssaa=ssaa), work, f"{method}-{ssaa}", environment,
                             lobes, a.repeats)
            m, p95, noise = errors[method]
            print(f"| {method} | {ssaa} | {r['wall_s']:.2f} s | {r['peak_mb']:.0f} | "
                  f"{r['frame_s'] * 1e3:.0f} ms | {r['environment_s'] * 1e3:.0f} ms | "
                  f"{m:.2f} / {p95:.2f} ({noise:.2f}) |")


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
