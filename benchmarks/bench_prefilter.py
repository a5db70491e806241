"""Benchmark of ``gonio prefilter``: time for a 2048 × 1024 map, brute beside it, and error
against time per method and resolution.

    .venv/bin/python benchmarks/bench_prefilter.py [--quick] [--map SKY.hdr]

1. The target: a 2048 × 1024 map, 8 exponents from 1 to 1e4, ``auto`` (with its
   spot checks), under 5 s in total; then the same run with every texel weighed at its
   centre (no area integration of hot texels or narrow lobes), to show what the area
   integration costs.
2. ``brute`` beside ``auto`` on a 128 × 64 map (where brute is feasible): time and the
   relative error of ``auto`` against it (99th percentile and maximum over texels).
3. Error against time on a 512 × 256 map: ``ring`` with working maps 0–3 octaves finer
   than the output (0 = the output's own resolution), at the auto output resolution and
   one octave finer; the reference is ``ring`` on the full input, which (2.) shows equal
   to ``brute`` to float32 round-off.
4. What a renderer sees: bilinear lookup of the auto-sized maps at every input texel
   centre against the exact map at input resolution (512 × 256).

The map is the given HDR (default: Poly Haven's quarry_01 if present, whose sun is
~4e5 × the median sky) or else ``sample_data/sky.exr``, brought to 2048 × 1024 by repeating
texels. Smaller maps are made from it by area (gonio_cli.envmap.downsample).
"""

from __future__ import annotations

import contextlib
import sys
from pathlib import Path

from gonio_cli.__main__ import use_blas_threads

use_blas_threads()  # before numpy: kernels timed as in a gonio process

import numpy as np

from gonio_cli import envmap
from gonio_cli import prefilter as pf

import process
from gonio_cli.imageio import read_image
from gonio_cli.report import sweeps
from gonio_cli.report.sweeps import prefilter_errors as errors, timed

ROOT = Path(__file__).resolve().parent.parent
#: The bundled sky by default; a real one with --map (e.g. a 1024 × 512 Poly Haven sky with
#: a sun 4e5 × the sky, as the figures in docs/prefilter.md were measured on).
DEFAULT_MAPS = [ROOT / "sample_data/sky.exr"]
TARGET_S = 5.0


def load_map(path: Path | None) -> tuple[np.ndarray, str]:
    """The map (given, or the bundled sky) repeated up to 2048 × 1024. A missing or bad
    file is a GonioError (one line from :func:`run`)."""
    path = path if path is not None else next(p for p in DEFAULT_MAPS if p.is_file())
    img = read_image(path).pixels[:, :, :3].astype(np.float64)
    rep = max(1, 1024 // img.shape[0])
    big = np.repeat(np.repeat(img, rep, axis=0), rep, axis=1)
    if big.shape[:2] != (1024, 2048):
        raise SystemExit(f"{path}: {img.shape[1]}x{img.shape[0]} does not scale to 2048x1024")
    return big, path.name


def table(header: list[str], rows: list[list[str]]) -> None:
    """Print a Markdown table (first column and numbers right-aligned)."""
    print("| " + " | ".join(header) + " |")
    print("|" + "|".join("---" if h in ("method", "output", "working map") else "---:"
                         for h in header) + "|")
    for row in rows:
        print("| " + " | ".join(row) + " |")


def target_run(big, exponents) -> None:
    results, total = timed(pf.prefilter, big, exponents)
    table(["E", "method", "output", "working map", "time (s)", "spot-check error (max)",
           "texels"],
          [[f"{r.exponent:.4g}", r.method, f"{r.width}×{r.height}",
            f"{r.working_shape[1]}×{r.working_shape[0]}", f"{r.time_s:.2f}",
            f"{r.error_estimate:.1e}", str(r.checked_texels)] for r in results])
    verdict = "meets" if total < TARGET_S else "MISSES"
    print(f"\nTotal {total:.2f} s for {len(results)} maps including spot checks "
          f"({verdict} the {TARGET_S:g} s target).")


@contextlib.contextmanager
def midpoint_only():
    """Every texel weighed at its centre (one quadrature node), as before hot texels and
    narrow lobes were integrated over texel areas: for the cost comparison only."""
    names = ("HOT_MIN_NODES", "HOT_NODES_PER_SIGMA", "KINK_NODES", "MIDPOINT_MAX_TEXEL_SIGMA")
    saved = [getattr(pf, n) for n in names]
    for n, v in zip(names, (1, 0.0, 0, np.inf)):
        setattr(pf, n, v)
    try:
        yield
    finally:
        for n, v in zip(names, saved):
            setattr(pf, n, v)


def area_cost(big, exponents) -> None:
    """The target run with and without the area integration (lower of two runs each)."""
    runs = {}
    for label in ("area", "midpoint", "area", "midpoint"):
        with midpoint_only() if label == "midpoint" else contextlib.nullcontext():
            results, total = timed(pf.prefilter, big, exponents)
        best = runs.get(label)
        if best is None or total < best[1]:
            runs[label] = (results, total)
    (area, t_area), (mid, t_mid) = runs["area"], runs["midpoint"]
    table(["E", "area-integrated (s)", "texel centres (s)"],
          [[f"{a.exponent:.4g}", f"{a.time_s:.2f}", f"{m.time_s:.2f}"]
           for a, m in zip(area, mid)])
    print(f"\nTotal {t_area:.2f} s with the area integration, {t_mid:.2f} s without "
          f"(spot checks included; lower of two runs each): it costs "
          f"{t_area - t_mid:.2f} s.")


def whole_process(big, exponents) -> None:
    """The same run as ``gonio prefilter`` as a process: wall time and peak memory."""
    import tempfile

    from gonio_cli.imageio import write_exr

    with tempfile.TemporaryDirectory(prefix="gonio-bench-prefilter-") as tmp:
        src = Path(tmp) / "sky.exr"
        write_exr(src, big.astype(np.float32), {})
        argv = [process.gonio_command(), "-q", "prefilter", str(src), "--exponents",
                ",".join(f"{e:.6g}" for e in exponents), "-o", str(Path(tmp) / "out")]
        wall, peak, _ = process.run_measured(argv)
    print(f"\nThe same as a whole `gonio prefilter` process (reading and writing the EXRs "
          f"included): {wall:.2f} s, peak memory {peak:.0f} MB.")


def brute_beside(small, exponents) -> None:
    table(["E", "output", "auto (s)", "brute (s)", "auto vs brute p99", "max"],
          [[f"{r['exponent']:.4g}", r["output"], f"{r['ring_s']:.3f}", f"{r['brute_s']:.2f}",
            f"{r['p99_error']:.1e}", f"{r['max_error']:.1e}"]
           for r in sweeps.prefilter_brute_rows(small, exponents)])


def error_time(mid, exponents) -> None:
    prepared = pf.ring.RingInputs(mid)
    table(["E", "output", "working map", "time (s)", "p99 error", "max error"],
          [[f"{r['exponent']:.4g}", r["output"] + (" (auto)" if r["auto"] else ""),
            r["working"], f"{r['time_s']:.3f}", f"{r['p99_error']:.1e}",
            f"{r['max_error']:.1e}"]
           for e in exponents for r in sweeps.prefilter_ring_rows(mid, e, prepared)])


def lookup_error(m, exponents) -> None:
    """Bilinear lookup (envmap.lookup, as a renderer reads the maps) of each auto-sized map
    at the input's texel centres, against the exact map at the input resolution."""
    h, w = m.shape[:2]
    prepared = pf.ring.RingInputs(m)
    rows = []
    for e in exponents:
        levels = pf.inputs.output_levels(h, w, e)
        out, _ = pf.ring.prefilter_ring(m, e, levels, prepared)
        exact, _ = pf.ring.prefilter_ring(m, e, 0, prepared, working_levels=99)
        p99, mx = errors(envmap.lookup(out, envmap.pixel_directions(h, w)), exact)
        rows.append([f"{e:.4g}", f"{w >> levels}×{h >> levels}",
                     f"{(h >> levels) * pf.inputs.lobe_sigma(e) / np.pi:.1f}", f"{p99:.1e}",
                     f"{mx:.1e}"])
    table(["E", "output", "texels per σ", "lookup p99 error", "max error"], rows)


def main(argv: list[str] | None = None) -> None:
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer exponents")
    parser.add_argument("--map", type=Path, metavar="SKY.exr|SKY.hdr",
                        help="a lat-long HDR map (default: sample_data/sky.exr)")
    args = parser.parse_args(argv)
    quick = args.quick
    big, name = load_map(args.map)
    exponents = list(np.geomspace(1.0, 1e4, 8))
    print(f"## gonio prefilter: {name} at 2048×1024, {len(exponents)} exponents 1…1e4\n")
    target_run(big, exponents)
    whole_process(big, exponents)
    print("\n## the cost of integrating hot texels and narrow lobes over texel areas\n")
    area_cost(big, exponents)
    small = envmap.downsample(big, 16)
    print("\n## brute beside auto (ring) on the same map at 128×64\n")
    brute_beside(small, [1.0, 10.0, 100.0, 1000.0] if quick else
                 [1.0, 3.0, 10.0, 30.0, 100.0, 300.0, 1000.0])
    print("\n## error against time: ring on 512×256, by working map and output resolution\n")
    error_time(envmap.downsample(big, 4), [1.0, 100.0] if quick else [1.0, 10.0, 100.0, 1000.0])
    print("\n## bilinear lookup of the auto-sized maps against the exact map, at 512×256\n")
    lookup_error(envmap.downsample(big, 4), [1.0, 10.0, 100.0] if quick else
                 [1.0, 3.0, 10.0, 30.0, 100.0, 300.0, 1000.0])


def run(argv: list[str] | None = None) -> int:
    """main() with gonio's error convention: a GonioError is one line and exit 2."""
    from gonio_cli.errors import EXIT_USAGE, GonioError

    try:
        main(argv)
    except GonioError as exc:
        print(f"{Path(sys.argv[0]).name}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    return 0


if __name__ == "__main__":
    sys.exit(run())
