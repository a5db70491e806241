"""Halftone speed against tone error: the core per method, and ``gonio halftone`` as a
whole process beside ImageMagick.

Part 1, the core: for each method the time on the synthetic print test image
(:func:`gonio_cli.halftone.testimage.print_test_image`, decoded from sRGB and gamut-scaled
once, outside the timing), best of ``--repeats`` runs, next to its tone error (RMSE of the
σ = 2 px blurred mask against the blurred target) and the worst coverage error per ink.

Part 2, whole processes on one PNG (``sample_data/print_image.png`` upscaled bilinearly to
``--size``², written to a temporary folder): wall time and peak memory (max RSS, from
``os.wait4``) of ``gonio halftone IN -o OUT`` (Floyd–Steinberg, defaults), first with an
empty ``NUMBA_CACHE_DIR`` (the kernel is compiled) and then again (it is loaded from the
cache), beside the kernel alone, beside ImageMagick's ``convert IN -dither FloydSteinberg
-remap PALETTE.png OUT`` with the four colours black, red, green, blue. Runs of the two
programs alternate so that both see the same machine load; the best of ``--repeats`` is
shown with the ratio. Both masks get the same tone error (against gonio's target
coverage: linear light, gamut-scaled). ``--quick`` runs a 512² image once.

    .venv/bin/python benchmarks/bench_halftone.py [--quick] [--size N] [--repeats N]
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from gonio_cli.__main__ import use_blas_threads

use_blas_threads()  # before numpy: kernels timed as in a gonio process

import numpy as np

from gonio_cli.halftone import (METHODS, PALETTE, halftone, ink_coverage, prepare,
                                tone_error)
from gonio_cli.halftone import diffusion, screens
from gonio_cli.halftone.testimage import print_test_image
from gonio_cli.imageio import read_image
import process

ROOT = Path(__file__).resolve().parent.parent
SAMPLE = ROOT / "sample_data" / "print_image.png"
GONIO = Path(sys.executable).with_name("gonio")

#: The target for error diffusion at 4096² (s), core only.
TARGET_S = 2.0

#: Targets for the whole process at 4096²: under a third of ImageMagick's wall time,
#: under 400 MB peak.
TARGET_RATIO = 1 / 3
TARGET_RSS_MB = 400.0


def core_table(size: int, repeats: int) -> None:
    t = time.perf_counter()
    prepared = prepare(print_test_image(size, size), is_float=False)
    prepare_s = time.perf_counter() - t
    compile_s = diffusion.compile_kernel()
    t = time.perf_counter()
    _, mask_source = screens.blue_noise_ranks(
        METHODS["blue-noise"].parameters["mask_size"].default)
    mask_s = time.perf_counter() - t

    print(f"## gonio halftone core: {size} × {size} print test image "
          f"({platform.processor() or platform.machine()}, best of {repeats})\n")
    print("| method | kind | time (s) | Mpx/s | tone RMSE (σ = 2 px) | worst coverage error |")
    print("|---|---|---:|---:|---:|---:|")
    target = prepared.coverage_mean
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
    print(f"\nkernel start-up: numba's import and load or compile, or the C build's import "
          f"(once per process; "
          f"{diffusion.kernel_status()}): {compile_s:.2f} s; blue-noise mask: {mask_s:.2f} s "
          f"({mask_source}); drawing, decoding and gamut-mapping the test image: "
          f"{prepare_s:.2f} s (not in the times above).")


def run_measured(argv: list[str], env: dict[str, str] | None = None) -> tuple[float, float]:
    """Wall time (s) and peak resident memory (MB) of one process (:mod:`process`)."""
    wall, peak, _ = process.run_measured(argv, env)
    return wall, peak


def imagemagick() -> tuple[str, str] | None:
    """(binary, version line) of the real ImageMagick, or None if absent."""
    binary = "/usr/bin/convert" if os.path.exists("/usr/bin/convert") else (
        shutil.which("magick") or shutil.which("convert"))
    if binary is None:
        return None
    try:
        out = subprocess.run([binary, "-version"], capture_output=True, text=True,
                             timeout=30).stdout
    except (OSError, subprocess.SubprocessError):
        return None
    line = out.splitlines()[0] if out else ""
    return (binary, line) if "ImageMagick" in line else None


def labels_of_rgb(path: Path) -> tuple[np.ndarray, int]:
    """Labels of an RGB mask file and the number of pixels that are none of the four
    colours (those count as bare substrate)."""
    rgb = read_image(path, keep_integers=True).pixels[:, :, :3]
    labels = np.zeros(rgb.shape[:2], dtype=np.uint8)
    matched = np.zeros(rgb.shape[:2], dtype=bool)
    for k, colour in enumerate(PALETTE):
        hit = np.all(rgb == colour, axis=2)
        labels[hit] = k
        matched |= hit
    return labels, int(rgb.shape[0] * rgb.shape[1] - np.count_nonzero(matched))


def whole_process(size: int, repeats: int) -> None:
    from PIL import Image as PILImage

    print(f"\n## whole processes: {size} × {size} PNG, Floyd–Steinberg "
          f"({os.cpu_count()} CPUs; load average before: "
          f"{' '.join(f'{x:.1f}' for x in os.getloadavg())})\n")
    with tempfile.TemporaryDirectory(prefix="gonio-bench-halftone-") as tmp:
        tmp = Path(tmp)
        src = tmp / "in.png"
        PILImage.open(SAMPLE).convert("RGB").resize((size, size), PILImage.BILINEAR).save(
            src, compress_level=1)
        PILImage.fromarray(PALETTE[None]).save(tmp / "palette.png")
        out = tmp / "gonio.png"
        env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp / "numba")}
        cmd = [str(GONIO), "--quiet", "halftone", str(src), "-o", str(out)]

        first_wall, first_rss = run_measured(cmd, env)
        magick = imagemagick()
        im_cmd = ([magick[0], str(src), "-dither", "FloydSteinberg", "-remap",
                   str(tmp / "palette.png"), str(tmp / "magick.png")] if magick else None)
        runs: dict[str, list[tuple[float, float]]] = {"gonio": [], "magick": []}
        for _ in range(repeats):
            runs["gonio"].append(run_measured(cmd, env))
            if im_cmd:
                runs["magick"].append(run_measured(im_cmd))

        img = read_image(src, keep_integers=True)
        prepared = prepare(img.pixels, is_float=False)
        kernel = halftone(prepared.coverage, "floyd-steinberg")
        gonio_labels, _ = labels_of_rgb(out)
        if not np.array_equal(gonio_labels, kernel.labels):
            raise SystemExit("gonio halftone's mask differs from the core's labels")
        gonio_rmse, _ = tone_error(gonio_labels, prepared.coverage)

        print("| run | wall (s) | peak RSS (MB) | tone RMSE (σ = 2 px) |")
        print("|---|---:|---:|---:|")
        print(f"| gonio halftone kernel alone (in-process, cache loaded) | {kernel.time_s:.3f} "
              f"| | {gonio_rmse:.4f} |")
        print(f"| gonio halftone, first call (a fresh NUMBA_CACHE_DIR, which the C build "
              f"does not use; Python may write its bytecode cache) "
              f"| {first_wall:.2f} | {first_rss:.0f} | {gonio_rmse:.4f} |")
        wall, rss = min(runs["gonio"])
        rss = max(r for _, r in runs["gonio"])
        rss_flag = "" if size < 4096 else (
            " ✓" if rss < TARGET_RSS_MB else f" ✗ (target {TARGET_RSS_MB:g})")
        print(f"| gonio halftone, later calls (best of {repeats}) "
              f"| {wall:.2f} | {rss:.0f}{rss_flag} | {gonio_rmse:.4f} |")
        if not im_cmd:
            print("| ImageMagick convert -dither FloydSteinberg -remap | skipped: not "
                  "installed | | |")
            return
        im_labels, foreign = labels_of_rgb(tmp / "magick.png")
        im_rmse, _ = tone_error(im_labels, prepared.coverage)
        im_wall = min(w for w, _ in runs["magick"])
        im_rss = max(r for _, r in runs["magick"])
        print(f"| ImageMagick convert -dither FloydSteinberg -remap (best of {repeats}) "
              f"| {im_wall:.2f} | {im_rss:.0f} | {im_rmse:.4f} |")
        ratio = wall / im_wall
        flag = "" if size < 4096 else (
            " ✓" if ratio < TARGET_RATIO else f" ✗ (target < {TARGET_RATIO:.2f})")
        print(f"\ngonio / ImageMagick wall time: {ratio:.2f}{flag}. ImageMagick: "
              f"{magick[0]}, {magick[1]}. Its remap dithers the sRGB-encoded values with "
              f"no gamut mapping, so its tone error against gonio's linear, gamut-scaled "
              f"target is large by construction"
              + (f"; {foreign} of its pixels are none of the four colours" if foreign else "")
              + ".")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="512², one run per method")
    parser.add_argument("--size", type=int, default=None, help="image side in pixels")
    parser.add_argument("--repeats", type=int, default=None, help="timed runs per method")
    args = parser.parse_args()
    size = args.size or (512 if args.quick else 4096)
    repeats = args.repeats or (1 if args.quick else 3)
    core_table(size, repeats)
    whole_process(size, repeats)


if __name__ == "__main__":
    main()
