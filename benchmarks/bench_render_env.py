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

Then the sun's shadow: the same sphere on a grey Lambertian floor (y = −1) under the sky,
seen from above, gonio (``--chain --sun``: the sun a shadowing light) against Mitsuba (the
whole map, the sun in it): where the floor lies in the sphere's geometric umbra (the ray
to the sun passes within 0.9 of the centre) and where it is sunlit (beyond 1.1), each
renderer's mean luminance, their ratio, and the umbra's share of the lit floor's; and the
time of gonio's occlusion of the sky (``[environment] occlusion``, on by default) in it.
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


def floor_masks(ref: mr.ReferenceScene, sun: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(umbra, lit) pixel masks of the floor y = ref.floor_y: camera rays that reach the
    floor without meeting the unit sphere, whose point's ray to ``sun`` passes within 0.9
    (umbra) or beyond 1.1 (lit) of the sphere's centre: geometry, not either render."""
    from gonio_cli.render.raster import pixel_rays

    d = pixel_rays(ref.camera).reshape(-1, 3)
    eye = np.asarray(ref.camera.eye, float)

    def miss(origin, direction, radius):
        b = direction @ -origin if origin.ndim == 1 else np.einsum("ij,ij->i", direction,
                                                                     -origin)
        c2 = (np.einsum("ij,ij->i", origin, origin) if origin.ndim == 2 else origin @ origin)
        return c2 - np.clip(b, 0, None) ** 2 > radius ** 2     # closest approach ahead

    t = (ref.floor_y - eye[1]) / d[:, 1]
    ok = (t > 0) & miss(eye, d, 1.0)
    p = eye + np.where(ok, t, 0)[:, None] * d
    s = np.broadcast_to(sun, p.shape)
    shape = (ref.camera.height, ref.camera.width)
    return ((ok & ~miss(p, s, 0.9)).reshape(shape), (ok & miss(p, s, 1.1)).reshape(shape))


def sun_shadow(paint: Path, work: Path, spp: int) -> None:
    """The sphere's shadow on the floor under the sky's sun, gonio against Mitsuba."""
    from gonio_cli.imageio import read_image
    from gonio_cli.render import Camera

    cam = Camera(np.array([2.0, 3.5, 5.0]), np.array([0.8, -1.0, -1.5]),
                 np.array([0.0, 1.0, 0.0]), 45.0, 256, 192)
    ref = mr.ReferenceScene(cam, paint, SKY, floor_y=-1.0)
    folder = work / "shadow"
    mr.run_gonio_process(["prefilter", SKY, "--chain", "--sun", "-o", folder / "chain"])
    index = json.loads((folder / "chain/index.json").read_text())
    exr = mr.render_gonio(ref, folder, {"prefiltered": (folder / "chain/index.json").resolve(),
                                        "method": "model"})
    mitsuba = mr.render_mitsuba(ref, folder / "mitsuba", spp=spp)
    umbra, lit = floor_masks(ref, np.asarray(index["sun"]["direction"], float))
    y_g = read_image(exr).pixels[..., 1].astype(float)
    y_m = mitsuba.xyz[..., 1]
    print(f"\n# the sun's shadow: sphere on a floor, 256 x 192, Mitsuba {mitsuba.spp} spp; "
          f"umbra {umbra.sum()} px, lit floor {lit.sum()} px")
    for name, y in (("gonio", y_g), ("Mitsuba", y_m)):
        print(f"{name:8s} umbra Y {y[umbra].mean():.4f}, lit floor Y {y[lit].mean():.4f}, "
              f"umbra / lit {y[umbra].mean() / y[lit].mean():.3f}")
    print(f"umbra Y gonio / Mitsuba {y_g[umbra].mean() / y_m[umbra].mean():.3f}; lit floor "
          f"{y_g[lit].mean() / y_m[lit].mean():.3f}")
    occlusion_cost(folder)


def occlusion_cost(folder: Path) -> None:
    """The occlusion of the sky by the sphere and the floor in that render: its stage's
    time (best of 3 warm ``gonio render`` processes' run reports) beside the frame's, and
    its counts."""
    scene = folder / "gonio.toml"
    args = [process.gonio_command(), "-q", "render", str(scene), "-o",
            str(folder / "timed.png"), "--report", str(folder / "timed.json")]
    process.run_measured(args)
    best = None
    for _ in range(3):
        process.run_measured(args)
        report = json.loads((folder / "timed.json").read_text())
        stages = {s["stage"]: s["time_s"] for s in report["stages"]}
        if best is None or stages.get("occlusion", 0.0) < best[0].get("occlusion", 0.0):
            best = (stages, report)
    stages, report = best
    counts = report["counts"].get("occlusion", {})
    print(f"occlusion {stages.get('occlusion', 0.0) * 1e3:.0f} ms of a frame of "
          f"{report['frame_time_s'] * 1e3:.0f} ms (shadows {stages.get('shadows', 0.0) * 1e3:.0f}"
          f" ms); {counts.get('directions')} directions, {counts.get('nodes')} nodes, "
          f"{counts.get('own_samples')} samples computed on their own")


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
    sun_shadow(paint, work, a.spp * 4)


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
