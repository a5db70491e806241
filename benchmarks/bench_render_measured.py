"""The measured reference of seed 000 Figure 5, old against new interpolation, in one run.

    .venv/bin/python benchmarks/bench_render_measured.py [--out out] [--repeats 3]

Renders ``sample_data/scenes/figure5.toml`` (480², ssaa 2, the demo's inks: ``make demo``)
twice as users run it, its measured objects with ``interpolation = "four-nearest"`` (the
piecewise-linear four nearest neighbours) and ``"smooth"`` (the thin-plate spline in
(θh, σ), gonio_cli/render/measured_smooth.py), and prints per interpolation:

* the whole ``gonio render`` as a process (best wall time of ``--repeats``, after one
  untimed run, and its peak memory), and from the run report the ``materials`` stage
  (reading and, for ``smooth``, fitting the three splines) and the ``shade`` stage (all
  nine spheres; the six fitted ones cost the same in both runs);
* per ink, the crease ratio of the measured sphere (gonio_cli/render/crease.py: the
  largest spike of |Δ²L*| along a row over its running median, away from the lights'
  terminators; below 3 is no crease) and, for comparison, of the fitted eq. 5 sphere;
* per ink, the mean CIEDE2000 of the measured sphere against the fitted eq. 5 and
  Torrance–Sparrow spheres of its row (pixel by pixel, same position on the sphere);
* the shaded samples outside the measured range (``measured_outside_samples``).
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))

import process  # noqa: E402  (whole-process wall time and memory)

from gonio_cli.imageio import read_image  # noqa: E402
from gonio_cli.render.crease import away_from_terminators, crease_ratio, lightness  # noqa: E402
from gonio_cli.spectra import delta_e_2000, srgb_white_xyz, xyz_to_lab  # noqa: E402

SCENE = ROOT / "sample_data/scenes/figure5.toml"
INKS = ("red", "green", "blue")
#: Figure 5's grid: sphere centres (x of the columns measured, eq. 5, Torrance–Sparrow;
#: y of the rows red, green, blue), the camera's distance and field of view (figure5.toml).
COLUMNS_X = (-2.4, 0.0, 2.4)
ROWS_Y = (2.4, 0.0, -2.4)
CAMERA_DISTANCE = 40.0
FOV_DEG = 10.6
#: The lights of figure5.toml (towards the light).
LIGHTS = np.array([[-1.0, 1.0, 1.2], [1.0, 0.3, -0.6]])
#: Squared radius of the sphere masks: inside the silhouette by ~1 % (its antialiased ring).
MASK_R2 = 0.98


def scene_with(interpolation: str, out: Path, path: Path) -> Path:
    """figure5.toml with ``${out}`` set and every measured object's interpolation."""
    text = SCENE.read_text().replace('out = "../../out"', f'out = "{out.resolve()}"')
    text = re.sub(r'(measured = "[^"]*"\n)', rf'\1interpolation = "{interpolation}"\n', text)
    path.write_text(text)
    return path


def sphere_geometry(width: int, col: int, row: int):
    """(mask (H, W), normals (H, W, 3)) of the sphere of Figure 5's column and row, seen
    along −z (the camera is 40 units away: orthographic to within 3 %)."""
    scale = width / 2 / (CAMERA_DISTANCE * np.tan(np.radians(FOV_DEG / 2)))
    c = (np.arange(width) + 0.5 - width / 2) / scale
    x, y = np.meshgrid(c - COLUMNS_X[col], -c - ROWS_Y[row])
    mask = x * x + y * y < MASK_R2
    n = np.stack([x, y, np.sqrt(np.clip(1.0 - x * x - y * y, 0.0, 1.0))], axis=-1)
    return mask, n


def shift(image: np.ndarray, width: int, col_from: int, col_to: int) -> np.ndarray:
    """``image`` moved so that column ``col_from``'s sphere lands on ``col_to``'s."""
    scale = width / 2 / (CAMERA_DISTANCE * np.tan(np.radians(FOV_DEG / 2)))
    return np.roll(image, int(round((COLUMNS_X[col_to] - COLUMNS_X[col_from]) * scale)), axis=1)


def figures(exr: Path) -> dict:
    """Crease ratios and CIEDE2000 of the measured column (module docstring)."""
    xyz = read_image(exr).pixels[..., :3].astype(float)
    width = xyz.shape[1]
    lstar = lightness(xyz, 1.0)
    lab = xyz_to_lab(xyz, srgb_white_xyz())
    lights = LIGHTS / np.linalg.norm(LIGHTS, axis=1, keepdims=True)
    out = {}
    for r, ink in enumerate(INKS):
        crease = []
        for col in (0, 1):
            mask, n = sphere_geometry(width, col, r)
            crease.append(crease_ratio(lstar, mask, away_from_terminators(n, lights)))
        mask, _ = sphere_geometry(width, 0, r)
        de = [float(delta_e_2000(lab[mask], shift(lab, width, c, 0)[mask]).mean())
              for c in (1, 2)]
        out[ink] = {"crease_measured": crease[0], "crease_eq5": crease[1],
                    "de_eq5": de[0], "de_ts": de[1]}
    return out


def run(interpolation: str, out: Path, work: Path, repeats: int) -> dict:
    scene = scene_with(interpolation, out, work / f"{interpolation}.toml")
    png, exr, rep = (work / f"{interpolation}.{e}" for e in ("png", "exr", "json"))
    args = [process.gonio_command(), "-q", "render", str(scene), "-o", str(png), "--exr",
            str(exr), "--exr-space", "xyz", "--adapt", "none", "--report", str(rep)]
    process.run_measured(args)
    runs = [process.run_measured(args) for _ in range(repeats)]
    wall, peak, _ = min(runs, key=lambda r: r[0])
    report = json.loads(rep.read_text())
    stages = {s["stage"]: s["time_s"] for s in report["stages"]}
    return {"wall_s": wall, "peak_mb": peak, "materials_s": stages.get("materials", 0.0),
            "shade_s": stages.get("shade", 0.0),
            "outside": report["counts"].get("measured_outside_samples"),
            "figures": figures(exr)}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=ROOT / "out", help="the demo's outputs")
    p.add_argument("--repeats", type=int, default=3)
    a = p.parse_args()
    if not (a.out / "rgbink/red.measurement.json").is_file():
        raise SystemExit(f"{a.out}/rgbink is missing: run make demo first")
    work = Path(tempfile.mkdtemp(prefix="gonio-measured-"))
    results = {i: run(i, a.out, work, a.repeats) for i in ("four-nearest", "smooth")}
    print(f"# Figure 5, 480², ssaa 2; load {process.load_average()}; images in {work}")
    print(f"| interpolation | whole command (best of {a.repeats}) | peak MB | materials | "
          "shade (9 spheres) | samples outside the measured range |")
    print("|---|---:|---:|---:|---:|---:|")
    for name, r in results.items():
        print(f"| {name} | {r['wall_s']:.2f} s | {r['peak_mb']:.0f} | "
              f"{r['materials_s'] * 1e3:.0f} ms | {r['shade_s'] * 1e3:.0f} ms | "
              f"{'—' if r['outside'] is None else r['outside']} |")
    print("\n| interpolation | ink | crease ratio measured (eq. 5 sphere) | CIEDE2000 vs "
          "eq. 5 | CIEDE2000 vs Torrance–Sparrow |")
    print("|---|---|---:|---:|---:|")
    for name, r in results.items():
        for ink, f in r["figures"].items():
            print(f"| {name} | {ink} | {f['crease_measured']:.2f} ({f['crease_eq5']:.2f}) | "
                  f"{f['de_eq5']:.2f} | {f['de_ts']:.2f} |")
        means = [np.mean([f[k] for f in r["figures"].values()]) for k in ("de_eq5", "de_ts")]
        print(f"| {name} | mean | | {means[0]:.2f} | {means[1]:.2f} |")


if __name__ == "__main__":
    main()
