"""Halftone speed against tone error, per method (4096² in < 2 s with error
diffusion).

Prints a Markdown table: for each method the core time on the synthetic print test image
(:func:`gonio_cli.halftone.testimage.print_test_image`, decoded from sRGB and gamut-scaled
once, outside the timing), best of ``--repeats`` runs, next to its tone error (RMSE of
the σ = 2 px blurred mask against the blurred target) and the worst coverage error per
ink. The numba compile time of the error-diffusion kernel is measured apart, before the
first timed call; the blue-noise mask is generated (or read from the cache) before its
timed calls too. ``--quick`` runs a 512² image once.

    .venv/bin/python benchmarks/bench_halftone.py [--quick] [--size N] [--repeats N]
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from gonio_cli.halftone import METHODS, halftone, ink_coverage, prepare, tone_error
from gonio_cli.halftone import diffusion, screens
from gonio_cli.halftone.testimage import print_test_image

#: The target for error diffusion at 4096² (s).
TARGET_S = 2.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="512², one run per method")
    parser.add_argument("--size", type=int, default=None, help="image side in pixels")
    parser.add_argument("--repeats", type=int, default=None, help="timed runs per method")
    args = parser.parse_args()
    size = args.size or (512 if args.quick else 4096)
    repeats = args.repeats or (1 if args.quick else 3)

    t = time.perf_counter()
    prepared = prepare(print_test_image(size, size), is_float=False)
    prepare_s = time.perf_counter() - t
    compile_s = diffusion.compile_kernel()
    t = time.perf_counter()
    _, mask_source = screens.blue_noise_ranks(METHODS["blue-noise"].parameters["mask_size"].default)
    mask_s = time.perf_counter() - t

    print(f"## gonio halftone: {size} × {size} print test image "
          f"({platform.processor() or platform.machine()}, best of {repeats})\n")
    print("| method | kind | time (s) | Mpx/s | tone RMSE (σ = 2 px) | worst coverage error |")
    print("|---|---|---:|---:|---:|---:|")
    target = prepared.coverage.reshape(-1, 3).mean(axis=0, dtype=np.float64)
    for name, method in METHODS.items():
        times = []
        for _ in range(repeats):
            result = halftone(prepared.coverage, name)
            times.append(result.time_s)
        best = min(times)
        rmse, _ = tone_error(result.labels, prepared.coverage)
        worst = float(np.abs(ink_coverage(result.labels) - target).max())
        flag = ""
        if method.kind == "error diffusion" and size >= 4096:
            flag = " ✓" if best < TARGET_S else f" ✗ (target {TARGET_S:g} s)"
        print(f"| {name} | {method.kind} | {best:.3f}{flag} | {size * size / best / 1e6:.1f} "
              f"| {rmse:.4f} | {100 * worst:.3f} % |")
    print(f"\nnumba compile of the error-diffusion kernel (once per process, import "
          f"included): {compile_s:.2f} s; blue-noise mask: {mask_s:.2f} s ({mask_source}); "
          f"drawing, decoding and gamut-mapping the test image: {prepare_s:.2f} s (not in the times above).")


if __name__ == "__main__":
    main()
