"""Regenerate the halftone sample image and the README's pixel-scale crop.

``print_image.png`` (256 × 256, 8-bit sRGB) is :func:`gonio_cli.halftone.testimage.
print_test_image`: a colour wheel, R/G/B/grey ramps, a skin-tone patch and a 2-D colour
blend, drawn analytically, so it is reproduced byte for byte::

    python sample_data/make_print_image.py                 # sample_data/print_image.png
    python sample_data/make_print_image.py --out DIR       # elsewhere
    python sample_data/make_print_image.py --crop docs/images/halftone_crop.png

``--crop`` also halftones it (Floyd–Steinberg, the default of ``gonio halftone``) and
writes a 64 × 64 crop where the four quadrants meet, the source on the left and the mask
on the right, each enlarged 6× with nearest-neighbour so every printed dot is visible.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from gonio_cli.halftone import halftone, prepare
from gonio_cli.halftone.testimage import print_test_image
from gonio_cli.imageio import write_png

SIZE_PX = 256

#: Crop (row, col, size) in the sample image where four quadrants meet: the colour wheel's rim
#: on black, the dark ends of the ramps, the grey and the blend (bare substrate shows).
CROP = (96, 96, 64)

#: Nearest-neighbour enlargement of the crop, and the gap between the two panels (px).
ZOOM = 6
GAP_PX = 8


def crop_figure(encoded: np.ndarray) -> np.ndarray:
    """Source crop | halftone crop, both enlarged :data:`ZOOM`× (H, W, 3) uint8."""
    result = halftone(prepare(encoded, is_float=False).coverage, "floyd-steinberg")
    r, c, n = CROP
    source = np.round(encoded[r:r + n, c:c + n] * 255).astype(np.uint8)
    mask = result.mask()[r:r + n, c:c + n]
    big = [np.repeat(np.repeat(a, ZOOM, axis=0), ZOOM, axis=1) for a in (source, mask)]
    gap = np.full((n * ZOOM, GAP_PX, 3), 255, dtype=np.uint8)
    return np.concatenate([big[0], gap, big[1]], axis=1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).parent)
    parser.add_argument("--crop", type=Path, default=None)
    args = parser.parse_args()
    encoded = print_test_image(SIZE_PX, SIZE_PX)
    quantised = np.round(encoded * 255).astype(np.uint8)
    write_png(args.out / "print_image.png", quantised)
    if args.crop is not None:
        write_png(args.crop, crop_figure(quantised.astype(np.float32) / 255))


if __name__ == "__main__":
    main()
