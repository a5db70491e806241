"""A synthetic, resolution-independent print test image (sRGB-encoded, values in [0, 1]).

Four quadrants, each defined analytically so any size can be drawn (the sample image at
256², the benchmark at 4096²):

- top left: a colour wheel, hue by angle, saturation by radius, full value, on black;
- top right: four horizontal ramps 0 → 1: red, green, blue and grey;
- bottom left: a skin-tone patch with a soft vertical shading, on a mid grey;
- bottom right: a smooth two-dimensional blend r = x, g = y, b = 1 − x.
"""

from __future__ import annotations

import numpy as np

#: sRGB-encoded skin tone (a light-medium complexion, as in colour checkers' "light skin").
SKIN_SRGB = (0.76, 0.59, 0.51)

#: Mid grey of the skin-tone quadrant's background (sRGB-encoded).
MID_GREY_SRGB = 0.5

#: Radius of the colour wheel as a fraction of its quadrant's side.
WHEEL_RADIUS = 0.45


def _hsv_to_rgb(h: np.ndarray, s: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Hue h in [0, 1), saturation, value → RGB (..., 3) (the standard hexcone model):
    channel n is v − v s clip(min(k, 4 − k), 0, 1), k = (n + 6h) mod 6, n = 5, 3, 1."""
    out = np.empty(h.shape + (3,), dtype=np.float32)
    for ch, n in enumerate((5.0, 3.0, 1.0)):
        k = (n + 6.0 * h) % 6.0
        out[..., ch] = v - v * s * np.clip(np.minimum(k, 4.0 - k), 0.0, 1.0)
    return out


def print_test_image(height: int = 256, width: int = 256) -> np.ndarray:
    """The test image, (height, width, 3) float32 sRGB-encoded in [0, 1], deterministic."""
    u = ((np.arange(width) + 0.5) / width).astype(np.float32)    # 0 … 1 across
    v = ((np.arange(height) + 0.5) / height).astype(np.float32)  # 0 … 1 down
    img = np.empty((height, width, 3), dtype=np.float32)
    left, top = u < 0.5, v < 0.5
    ul, ur, vt, vb = u[left], u[~left], v[top], v[~top]
    # colour wheel (top left)
    qu, qv = ul[None, :] * 2 - 0.5, vt[:, None] * 2 - 0.5          # −0.5 … 0.5
    r = np.hypot(qu, qv) / WHEEL_RADIUS
    hue = (np.arctan2(qv, qu) / (2 * np.pi)) % 1.0
    wheel = _hsv_to_rgb(hue, np.clip(r, 0, 1), np.ones_like(r))
    img[np.ix_(top, left)] = wheel * (r <= 1)[..., None]
    # ramps (top right): red, green, blue, grey bands
    ramp = (ur - 0.5) * 2
    band = np.clip((vt * 8).astype(int), 0, 3)
    ramps = np.zeros((vt.size, ur.size, 3), dtype=np.float32)
    for k in range(3):
        ramps[band == k, :, k] = ramp
    ramps[band == 3] = ramp[:, None]
    img[np.ix_(top, ~left)] = ramps
    # skin patch (bottom left)
    pu, pv = ul[None, :] * 2 - 0.5, (vb[:, None] - 0.5) * 2 - 0.5
    inside = (np.abs(pu) < 0.35) & (np.abs(pv) < 0.35)
    shade = 1.0 - 0.4 * (pv + 0.35)
    skin = np.where(inside[..., None], np.float32(SKIN_SRGB) * shade[..., None],
                    np.float32(MID_GREY_SRGB))
    img[np.ix_(~top, left)] = skin
    # 2-D blend (bottom right)
    bu, bv = np.broadcast_arrays((ur[None, :] - 0.5) * 2, (vb[:, None] - 0.5) * 2)
    img[np.ix_(~top, ~left)] = np.stack([bu, bv, 1 - bu], axis=-1)
    return np.clip(img, 0.0, 1.0)
