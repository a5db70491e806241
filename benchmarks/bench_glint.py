"""Glints as users render them: the sample car paint under the sample sky with its sun.

    .venv/bin/python benchmarks/bench_glint.py [--out out] [--repeats 3] [--jitters 64]

The scene of issue 27: a unit sphere of the demo's paint (``OUT/carpaint/paint.material.json``,
``make demo``: seed 004's Cook–Torrance fit) at 512², ssaa 1, lit by the sample sky
(``sample_data/sky.exr``) prefiltered as a chain with its sun split off as a light
(``gonio prefilter --chain --sun``) and by nothing else; with glints as in
``sample_data/scenes/paint_sparkle.toml`` and without.

Printed: the whole ``gonio render`` as a process (best wall time of ``--repeats`` after a
warm-up, peak memory), the frame and ``shade.glint`` from its run report, with and without
glints; then the figures of issue 27's "done when", each from geometry computed here (the
analytic sphere), not from the renderer:

* **contrast**: sparkles are pixels ≥ :data:`SPARKLE_RATIO` × the render without glints
  and the brightest of their 3 × 3 neighbours; isolated ones have no other sparkle within
  :data:`ISOLATION_PX`; contrast = a sparkle's Y over the median Y of the ring of
  :data:`RING_PX` around it in the same render (the paint around it);
* **sun side**: the share of sparkles whose sphere normal faces the sky's sun (n·ω_sun > 0);
* **persistence**: the camera orbits the target by 0.5° about the vertical; a sparkle
  persists when the sphere point under it, projected into the moved camera, has a sparkle
  within :data:`MATCH_PX` px;
* **mean of jittered renders**: ``--jitters`` renders with glint_seed 1 … N (other flakes
  of the same statistics), their mean against the render without glints: the relative
  difference of the sphere's total Y, and per 32 × 32 px block where glints are drawn
  (median and p95 of |relative difference|, and its mean: seed noise shrinks as
  1/√N, a bias does not).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))

import process  # noqa: E402  (whole-process wall time and memory)

#: A pixel is a sparkle candidate at this ratio to the render without glints.
SPARKLE_RATIO = 3.0
#: An isolated sparkle has no other candidate within this many pixels (Chebyshev).
ISOLATION_PX = 4
#: The ring (Chebyshev radius) whose median Y is "the paint around it".
RING_PX = 4
#: A reprojected sparkle is matched by one within this many pixels in the moved camera.
MATCH_PX = 1.5
#: The glints of the demo (sample_data/scenes/paint_sparkle.toml).
GLINTS = {"glint_density": 2e5, "glint_share": 0.5, "glint_angle_deg": 1.0}
SKY = ROOT / "sample_data/sky.exr"
EYE = np.array([0.0, 0.6, 4.0])


def scene_doc(paint: Path, index: Path, eye=EYE, glints: dict | None = None,
              size: int = 512) -> dict:
    """The scene as a TOML document (dict): the paint sphere under the sky, no lights."""
    obj = {"name": "paint", "mesh": "builtin:sphere", "material": str(paint)}
    obj.update(glints or {})
    return {"camera": {"eye": list(map(float, eye)), "target": [0.0, 0.0, 0.0],
                       "up": [0.0, 1.0, 0.0], "fov_deg": 32.0, "width": size,
                       "height": size},
            "object": [obj], "environment": {"prefiltered": str(index)},
            "output": {"exposure": -4.0, "tonemap": "neutral", "ssaa": 1}}


def write_scene(doc: dict, path: Path) -> Path:
    """A scene document as a TOML file (the few types used here)."""
    def value(v):
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, list):
            return "[" + ", ".join(value(x) for x in v) + "]"
        return repr(v)

    lines = []
    for table in ("camera", "environment", "output"):
        lines += [f"[{table}]"] + [f"{k} = {value(v)}" for k, v in doc[table].items()]
    for obj in doc["object"]:
        lines += ["[[object]]"] + [f"{k} = {value(v)}" for k, v in obj.items()]
    path.write_text("\n".join(lines) + "\n")
    return path


def render_y(doc: dict, work: Path, name: str) -> np.ndarray:
    """Y (H, W) of a scene document rendered in this process."""
    from gonio_cli.render.pipeline import render_scene
    from gonio_cli.render.scene import load_scene

    return render_scene(load_scene(write_scene(doc, work / f"{name}.toml"))).xyz[..., 1]


def timed(doc: dict, work: Path, name: str, repeats: int) -> dict:
    """Best of ``repeats`` whole ``gonio render`` processes (after an untimed warm-up)."""
    scene = write_scene(doc, work / f"{name}.toml")
    report = work / f"{name}.json"
    args = [sys.executable, "-m", "gonio_cli", "-q", "render", str(scene), "-o",
            str(work / f"{name}.png"), "--report", str(report)]
    process.run_measured(args)
    best = None
    for _ in range(repeats):
        wall, peak, _ = process.run_measured(args)
        rep = json.loads(report.read_text())
        sub = {s["stage"]: s["time_s"] for s in rep["substages"]}
        run = {"wall_s": wall, "peak_mb": peak, "frame_s": rep["frame_time_s"],
               "glint_s": sub.get("shade.glint", 0.0),
               "counts": {k: v for k, v in rep["counts"]["shade"].items() if "glint" in k}}
        best = run if best is None or run["frame_s"] < best["frame_s"] else best
    return best


def sphere_points(eye, size: int, rows, cols) -> np.ndarray:
    """The unit sphere's points (n, 3) under pixel centres (rows, cols) of the camera at
    ``eye`` looking at the origin (NaN where the ray misses)."""
    from gonio_cli.render import Camera
    from gonio_cli.render.raster import pixel_rays

    cam = Camera(np.asarray(eye, float), np.zeros(3), np.array([0.0, 1.0, 0.0]), 32.0, size,
                 size)
    d = pixel_rays(cam)[rows, cols]
    e = np.asarray(eye, float)
    b = d @ e
    disc = b * b - (e @ e - 1.0)
    t = -b - np.sqrt(np.where(disc >= 0, disc, np.nan))
    return e + t[:, None] * d


def project(eye, size: int, x: np.ndarray) -> np.ndarray:
    """Pixel coordinates (n, 2) (row, col of the pixel whose centre is nearest) of points
    x (n, 3), the inverse of :func:`gonio_cli.render.raster.pixel_rays`."""
    from gonio_cli.render import Camera
    from gonio_cli.render.raster import camera_basis, focal_px

    cam = Camera(np.asarray(eye, float), np.zeros(3), np.array([0.0, 1.0, 0.0]), 32.0, size,
                 size)
    e, r, u, f = camera_basis(cam)
    k = focal_px(cam, 1)
    rel = x - e
    z = rel @ f
    return np.stack([size / 2 - k * (rel @ u) / z, size / 2 + k * (rel @ r) / z], 1) - 0.5


def sparkles(y: np.ndarray, y0: np.ndarray) -> np.ndarray:
    """(n, 2) rows, cols of sparkles: ≥ SPARKLE_RATIO × y0 and a 3 × 3 maximum."""
    from scipy.ndimage import maximum_filter

    cand = (y >= SPARKLE_RATIO * y0) & (y0 > 0)
    peak = cand & (y >= maximum_filter(y, size=3))
    return np.argwhere(peak)


def contrast(y: np.ndarray, y0: np.ndarray, peaks: np.ndarray) -> np.ndarray:
    """Contrast of each isolated sparkle (module docstring)."""
    cand = (y >= SPARKLE_RATIO * y0) & (y0 > 0)
    out = []
    r = RING_PX
    for i, j in peaks:
        if i < r or j < r or i + r >= y.shape[0] or j + r >= y.shape[1]:
            continue
        win = cand[i - ISOLATION_PX:i + ISOLATION_PX + 1, j - ISOLATION_PX:j + ISOLATION_PX + 1]
        near = cand[i - 1:i + 2, j - 1:j + 2].sum()
        if win.sum() > near:
            continue
        block = y[i - r:i + r + 1, j - r:j + r + 1].copy()
        block[1:-1, 1:-1] = np.nan
        ring = block[np.isfinite(block)]
        if ring.size and np.median(ring) > 0:
            out.append(y[i, j] / np.median(ring))
    return np.asarray(out)


def orbit(eye, deg: float) -> np.ndarray:
    """``eye`` turned by ``deg`` about the vertical axis through the origin."""
    t = np.radians(deg)
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]) @ np.asarray(eye, float)


def figures(paint: Path, index: Path, sun: np.ndarray, work: Path, jitters: int,
            size: int) -> None:
    """The done-when figures (module docstring), printed."""
    y0 = render_y(scene_doc(paint, index, size=size), work, "smooth")
    y = render_y(scene_doc(paint, index, glints=GLINTS, size=size), work, "glints")
    peaks = sparkles(y, y0)
    c = contrast(y, y0, peaks)
    x = sphere_points(EYE, size, peaks[:, 0], peaks[:, 1])
    sun_side = float(np.mean(x @ sun > 0)) if len(x) else float("nan")
    print(f"sparkles: {len(peaks)}; isolated {c.size}: contrast median {np.median(c):.1f}, "
          f"p10 {np.percentile(c, 10):.1f}, share >= 20: {np.mean(c >= 20):.2f}")
    print(f"sun side (n . sun > 0): {sun_side:.3f} of sparkles")
    eye2 = orbit(EYE, 0.5)
    doc2 = scene_doc(paint, index, eye=eye2, glints=GLINTS, size=size)
    y2 = render_y(doc2, work, "moved")
    y20 = render_y(scene_doc(paint, index, eye=eye2, size=size), work, "moved_smooth")
    peaks2 = sparkles(y2, y20)
    ok = np.isfinite(x[:, 0])
    moved = project(eye2, size, x[ok])
    d = np.abs(moved[:, None, :] - peaks2[None, :, :]).max(axis=2) if len(peaks2) else None
    kept = float(np.mean(d.min(axis=1) <= MATCH_PX)) if d is not None else 0.0
    print(f"persistence after a 0.5 deg orbit: {kept:.3f} of {ok.sum()} sparkles "
          f"({len(peaks2)} in the moved view)")
    b = 32
    blocks = lambda a: a[:size // b * b, :size // b * b].reshape(   # noqa: E731
        size // b, b, size // b, b).sum(axis=(1, 3))
    sums = np.zeros((size // b, size // b))
    for seed in range(1, jitters + 1):
        sums += blocks(render_y(scene_doc(paint, index, glints={**GLINTS, "glint_seed": seed},
                                          size=size), work, "jitter"))
    y0b = blocks(y0)
    rel = sums.sum() / jitters / y0b.sum() - 1.0
    drawn = (np.abs(sums / jitters - y0b) > 1e-9 * y0b.max()) & (y0b > 0)   # glints there
    brel = sums[drawn] / jitters / y0b[drawn] - 1.0
    print(f"mean of {jitters} jittered renders vs no glints: total {100 * rel:+.2f} %; the "
          f"{drawn.sum()} {b}x{b} blocks with glints: |rel| median "
          f"{100 * np.median(np.abs(brel)):.2f} %, p95 {100 * np.percentile(np.abs(brel), 95):.2f}"
          f" %, mean {100 * brel.mean():+.2f} %")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=ROOT / "out", help="the demo's outputs")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--jitters", type=int, default=64)
    p.add_argument("--size", type=int, default=512)
    a = p.parse_args()
    paint = (a.out / "carpaint/paint.material.json").resolve()
    if not paint.is_file():
        raise SystemExit(f"{paint}: run make demo first (or give --out)")
    os.chdir(ROOT)                      # gonio_cli of this tree, as `python -m` finds it
    from gonio_cli.export.mitsuba_reference import run_gonio_process

    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        run_gonio_process(["prefilter", SKY, "--chain", "--sun", "-o", work / "sky"])
        index = work / "sky/index.json"
        sun = np.asarray(json.loads(index.read_text())["sun"]["direction"], float)
        print(f"# glints, paint sphere {a.size}^2 ssaa 1 under {SKY.name} with its sun; "
              f"load {process.load_average()}")
        rows = {name: timed(scene_doc(paint, index, glints=g, size=a.size), work, name,
                            a.repeats)
                for name, g in (("no glints", None), ("glints", GLINTS))}
        for name, r in rows.items():
            print(f"{name:10s} process {r['wall_s']:.2f} s, {r['peak_mb']:.0f} MB; frame "
                  f"{1000 * r['frame_s']:.0f} ms, shade.glint {1000 * r['glint_s']:.0f} ms "
                  f"{r['counts'] or ''}")
        g, s0 = rows["glints"], rows["no glints"]
        print(f"glints cost: frame {1000 * (g['frame_s'] - s0['frame_s']):+.0f} ms, process "
              f"{1000 * (g['wall_s'] - s0['wall_s']):+.0f} ms")
        figures(paint, index, sun, work, a.jitters, a.size)


if __name__ == "__main__":
    main()
