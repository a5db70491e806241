"""The demo pictures of the README and the docs pages (``docs/images/``) are the demo's own
outputs: copy them (``make readme-images``) or check that they have not drifted from what
the code now makes (``make readme-check``, run by CI after ``make demo``).

    .venv/bin/python tests/readme_images.py --check [--out out]
    .venv/bin/python tests/readme_images.py --write [--out out]

:data:`IMAGES` is the one list of which demo output each of those images is (the README
shows the first two; ``tests/test_docs.py`` checks that each is shown on some page). A
check compares the pixels: an image drifts when its size differs or its mean absolute
difference exceeds :data:`MEAN_TOLERANCE` levels of 255 (the renders are deterministic:
0 on this machine; a fit plot redrawn by another matplotlib moves a few anti-aliased edge
pixels, far below one level on average). Plots of measured run time (:data:`TIMINGS`)
differ between any two runs, so only their size is checked.
"""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: Image (docs/images/) → the demo output it shows (relative to the output folder).
IMAGES = {
    "render_paint_sky.png": "render/paint_sky.png",
    "demo_green_fit.png": "rgbink/green.fit.png",
    "render_figure5.png": "render/figure5.png",
    "render_print_D65.png": "render/print-D65.png",
    "render_print_A.png": "render/print-A.png",
    "render_print_A_unadapted.png": "render/print-A-unadapted.png",
    "render_paint_env.png": "render/paint_env.png",
    "render_paint_sparkle.png": "render/paint_sparkle.png",
    "report_fit.png": "report/fit.png",
    "report_table1_spheres.png": "report/table1_spheres.png",
    "report_sheet_green.png": "report/sheet-02-green.png",
}

#: Images whose content is a measured run time (checked for size only).
TIMINGS = {"report_fit.png"}

#: Largest mean absolute difference (levels of 255) of an image that has not drifted.
MEAN_TOLERANCE = 1.0


def drift(image: Path, source: Path, timing: bool) -> str | None:
    """Why ``image`` is not what ``source`` is (None if it is)."""
    import numpy as np
    from PIL import Image

    if not source.is_file():
        return f"{source} is missing: run make demo first"
    if not image.is_file():
        return f"{image} is missing"
    with Image.open(image) as a, Image.open(source) as b:
        if a.size != b.size:
            return f"{image} is {a.size[0]} x {a.size[1]}, the demo makes {b.size[0]} x {b.size[1]}"
        if timing:
            return None
        diff = np.abs(np.asarray(a.convert("RGB"), float) - np.asarray(b.convert("RGB"), float))
    if diff.mean() > MEAN_TOLERANCE:
        return (f"{image} differs from {source} by {diff.mean():.2f} levels on average "
                f"(tolerance {MEAN_TOLERANCE})")
    return None


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=ROOT / "out", help="the demo's output folder")
    mode = p.add_mutually_exclusive_group(required=True)
    mode.add_argument("--check", action="store_true")
    mode.add_argument("--write", action="store_true")
    a = p.parse_args()
    docs = ROOT / "docs" / "images"
    problems = []
    for name, source in IMAGES.items():
        if a.write:
            shutil.copyfile(a.out / source, docs / name)
            continue
        why = drift(docs / name, a.out / source, name in TIMINGS)
        if why:
            problems.append(why)
    for why in problems:
        print(f"readme-check: {why}; make readme-images copies the demo's images",
              file=sys.stderr)
    if a.check and not problems:
        print(f"readme-check: the docs' {len(IMAGES)} demo images are what the demo makes")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
