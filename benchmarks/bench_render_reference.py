"""gonio's environment light against Mitsuba 3's path tracer: error beside time.

    .venv/bin/python benchmarks/bench_render_reference.py [--size 512] [--spp 256]
        [--envmap SKY.hdr] [--out out] [--bsdf X_rgb.bsdf]
        [--cases lambert,glossy,coat,carpaint,rgl] [--methods model,lobes] [--keep DIR]

The scene of ``sample_data/scenes/paint_env.toml`` (a unit sphere, eye (0, 0.6, 4), fov
32°) under a sky (``--envmap``: EXR or HDR lat-long; default the shipped Poly Haven 1k
``quarry_01``, sample_data/envmaps/), lit by the environment alone, for each case:

* ``lambert`` — a Lambertian paint (Cook–Torrance, ks = 0; the test's material): what
  the diffuse map alone must get right;
* ``glossy`` — a grey metal, Torrance–Sparrow α = 0.05: the horizon's reflection;
* ``coat`` — the demo's clear-coated paint (``OUT/carpaint/coat.material.json``: a fit of
  ``sample_data/coat_paint.csv``, coat α ≈ 0.02);
* ``carpaint`` — the demo's car paint (``OUT/carpaint/paint.material.json``, ``make demo``);
* ``rgl`` — an RGL ``.bsdf`` (``--bsdf``): gonio's chain (``gonio ingest`` in plane,
  ``gonio fit --model auto``) against Mitsuba's ``measured`` plugin on the file itself.

gonio runs each method of ``--methods`` as whole commands, each timed as a process (wall
time, peak memory: benchmarks/process.py), against the same Mitsuba render: ``model`` (the
default: ``gonio prefilter --chain --sun``, ``gonio render`` with ``method = "model"``, the
material's own lobes) and ``lobes`` (seed 001's chain: ``gonio lobes basis --samples
hemisphere``, ``gonio lobes fit --samples hemisphere --solver nnls``, ``gonio prefilter
--lobes``, ``gonio render`` with ``method = "lobes"``).
Mitsuba renders in this process (``gonio_cli.export.mitsuba_reference.render_mitsuba``,
two passes of spp/2 for its noise figure): its render time and variant. Printed per case:
mean / p95 CIEDE2000 (interior pixels, one white: Mitsuba's 99th percentile of Y), the
noise floor (the mean CIEDE2000 Mitsuba's own noise makes), the luminance ratio and the
sharp-feature (horizon) rows; side-by-side PNGs (gonio | Mitsuba | CIEDE2000 × 10 → white),
Mitsuba's XYZ EXR and ``reference.json`` in ``--keep`` (default a temporary folder, removed).
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))

import process  # noqa: E402  (whole-process wall time and memory)

from gonio_cli.export import mitsuba_reference as mr  # noqa: E402
from gonio_cli.export import reference_compare as rc  # noqa: E402

#: A real sky with a hard horizon and a sun: Poly Haven's quarry_01 at 1k (CC0).
DEFAULT_ENVMAP = ROOT / "sample_data/envmaps/quarry_01_1k.hdr"
SCENE = ROOT / "sample_data/scenes/paint_env.toml"


def glossy_material(path: Path) -> Path:
    """A glossy grey metal (Torrance–Sparrow, GGX α = 0.05, F0 = 0.6): the sky's horizon
    shows sharply in its reflection, the feature whose row is compared."""
    from gonio_cli.schemas import Material, write_material
    from gonio_cli.spectra import parse_grid

    g = parse_grid()
    write_material(path, Material("torrance-sparrow", g, {"alpha": 0.05,
                                                          "f0": np.full(g.size, 0.6)}))
    return path


def lambert_material(path: Path) -> Path:
    """The test's Lambertian paint (f = kd/π exactly, a yellow-orange kd)."""
    from gonio_cli.schemas import Material, write_material
    from gonio_cli.spectra import parse_grid

    g = parse_grid()
    kd = 0.15 + 0.6 / (1.0 + np.exp(-(g - 560.0) / 30.0))
    write_material(path, Material("cook-torrance", g, {
        "kd": kd, "ks": np.zeros(g.size), "m": np.full(g.size, 0.3),
        "f0": np.full(g.size, 0.04)}))
    return path


class Timed:
    """Runs gonio commands as processes and keeps (command, wall s, peak MB) of each."""

    def __init__(self):
        self.rows: list[tuple[str, float, float]] = []

    def __call__(self, args) -> None:
        wall, peak, _ = process.run_measured([process.gonio_command(), "-q",
                                              *map(str, args)])
        self.rows.append((" ".join(map(str, args[:2 if args[0] == "lobes" else 1])), wall,
                          peak))


def scene_for(material: Path, envmap: Path, size: int, bsdf=None) -> mr.ReferenceScene:
    """paint_env.toml's camera (at ``size``²) and sphere with ``material`` (and ``bsdf``
    for Mitsuba), lit by ``envmap`` alone."""
    from gonio_cli.render import Camera
    from gonio_cli.render.scene import read_scene_toml

    cam = read_scene_toml(SCENE)["camera"]
    camera = Camera(*(np.asarray(cam[k], float) for k in ("eye", "target", "up")),
                    float(cam["fov_deg"]), size, size)
    return mr.ReferenceScene(camera, material, envmap, bsdf=bsdf)


def gonio_render(method: str, ref: mr.ReferenceScene, work: Path, timed: Timed,
                 n_lobes: int) -> Path:
    """gonio's whole chain for one ``method`` (module docstring); the render's XYZ EXR."""
    folder = work / f"gonio-{method}"
    if method == "lobes":
        lobes, env = mr.gonio_environment(ref, folder, n_lobes=n_lobes, run=timed)
        return mr.render_gonio(ref, folder, {**env, "method": "lobes"}, lobes=lobes,
                               run=timed)
    folder.mkdir(parents=True, exist_ok=True)
    timed(["prefilter", ref.envmap, "--chain", "--sun", "-o", folder / "chain"])
    return mr.render_gonio(ref, folder, {"prefiltered": (folder / "chain/index.json")
                                         .resolve(), "method": "model"}, run=timed)


def run_case(name: str, ref: mr.ReferenceScene, work: Path, spp: int, methods, n_lobes: int,
             colour: str, timed_before=()) -> list[dict]:
    """Mitsuba's render of one case and gonio's by each method, compared."""
    from gonio_cli.imageio import write_exr

    start = time.perf_counter()
    mitsuba = mr.render_mitsuba(ref, work / "mitsuba", spp=spp, colour=colour)
    mitsuba_wall = time.perf_counter() - start
    write_exr(work / "mitsuba.exr", mitsuba.xyz.astype(np.float32), {"exr_space": "xyz"})
    out = []
    for method in methods:
        timed = Timed()
        timed.rows += list(timed_before)
        exr = gonio_render(method, ref, work, timed, n_lobes)
        c = rc.compare(exr, mitsuba)
        rc.side_by_side(c, exr, mitsuba, work / f"{name}-{method}.png")
        out.append({"case": name, "method": method, **c.summary(),
                    "gonio_commands": timed.rows,
                    "mitsuba": {"variant": mitsuba.variant, "spp": mitsuba.spp,
                                "render_s": mitsuba.time_s, "wall_s": mitsuba_wall}})
    return out


def rgl_material(bsdf: Path, work: Path, timed: Timed) -> Path:
    """gonio ingest (in plane, the default angles) and gonio fit --model auto."""
    work.mkdir(parents=True, exist_ok=True)
    timed(["ingest", bsdf, "-o", work / "rgl.measurement.json"])
    timed(["fit", work / "rgl.measurement.json", "--model", "auto", "-o",
           work / "rgl.material.json"])
    return work / "rgl.material.json"


def print_case(r: dict) -> None:
    print(f"\n## {r['case']}, gonio method {r['method']}: {r['pixels']} px")
    print(f"CIEDE2000 mean {r['mean_delta_e']:.2f}  p95 {r['p95_delta_e']:.2f}  "
          f"(Mitsuba's noise alone: {r['noise_delta_e']:.2f})  luminance ratio "
          f"{r['luminance_ratio']:.3f}")
    print(f"feature (column {r['feature_column']}): row gonio {r['feature_row_gonio']:.1f} / "
          f"Mitsuba {r['feature_row_mitsuba']:.1f}, offset {r['feature_offset_px']:+.1f} px; "
          f"step {r['feature_step_gonio']:.2f} / {r['feature_step_mitsuba']:.2f}"
          + ("" if r["feature_sharp"] else " (no sharp feature: the row means little)"))
    for cmd, wall, peak in r["gonio_commands"]:
        print(f"  gonio {cmd:<16} {wall:7.2f} s  {peak:6.0f} MB")
    m = r["mitsuba"]
    print(f"  Mitsuba {m['variant']}, {m['spp']} spp: render {m['render_s']:.1f} s "
          f"(with plugin export and scene loading {m['wall_s']:.1f} s)")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", type=int, default=512)
    p.add_argument("--spp", type=int, default=mr.DEFAULT_SPP)
    p.add_argument("--envmap", type=Path, default=DEFAULT_ENVMAP)
    p.add_argument("--out", type=Path, default=ROOT / "out", help="the demo's outputs")
    p.add_argument("--bsdf", type=Path, default=None, help="an RGL .bsdf for the rgl case")
    p.add_argument("--cases", default="lambert,glossy,coat,carpaint,rgl")
    p.add_argument("--methods", default="model,lobes",
                   help="gonio's environment methods to compare (model, lobes)")
    p.add_argument("--colour", choices=("spectral", "rgb"), default="spectral",
                   help="Mitsuba's variants (rgb for a sky whose sun is ~1 texel)")
    p.add_argument("--lobes", type=int, default=4,
                   help="lobe count of the basis (beyond 4 its error is flat here)")
    p.add_argument("--keep", type=Path, default=None, help="keep images and JSON here")
    a = p.parse_args()
    work = a.keep or Path(tempfile.mkdtemp(prefix="gonio-ref-"))
    work.mkdir(parents=True, exist_ok=True)
    print(f"# {a.size}² px, {a.envmap.name}, Mitsuba {a.spp} spp; load {process.load_average()}")
    results = []
    for case in a.cases.split(","):
        timed = Timed()
        folder = work / case
        folder.mkdir(parents=True, exist_ok=True)
        if case in ("lambert", "glossy"):
            make = lambert_material if case == "lambert" else glossy_material
            ref = scene_for(make(folder / f"{case}.material.json"), a.envmap, a.size)
        elif case in ("carpaint", "coat"):
            paint = a.out / f"carpaint/{'paint' if case == 'carpaint' else 'coat'}.material.json"
            if not paint.is_file():
                print(f"\n## {case}: skipped ({paint} missing: make demo)")
                continue
            ref = scene_for(paint, a.envmap, a.size)
        elif case == "rgl":
            if a.bsdf is None:
                print("\n## rgl: skipped (no --bsdf)")
                continue
            ref = scene_for(rgl_material(a.bsdf, folder, timed), a.envmap, a.size, a.bsdf)
        else:
            raise SystemExit(f"unknown case {case!r}: lambert, glossy, coat, carpaint or rgl")
        for r in run_case(case, ref, folder, a.spp, a.methods.split(","), a.lobes, a.colour,
                          timed.rows):
            results.append(r)
            print_case(r)
    (work / "reference.json").write_text(json.dumps(results, indent=1, default=float))
    print(f"\nimages and reference.json in {work}")
    if a.keep is None:
        shutil.rmtree(work)


if __name__ == "__main__":
    main()
