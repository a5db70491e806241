"""Synthetic sparkle photographs of a metallic paint (seed 004 §6, Figure 4), with truth.

Random mirror flakes (discs of radius 0.8–1.6 px) lie in a 128 × 128 crop. Each flake's
normal is tilted in the plane of incidence by θf from the mean normal. Most flakes are
tilted near one of the seed's half angles θh = θi / 2 ∈ {5, …, 35}° (eq. 15) with a
little spread (normal, σ = 0.7°); the rest are tilted by 40–60°, beyond what any photo
lights. The camera looks along the normal and the light comes from θi ∈ {10, …, 70}°: a
flake reflects into the camera with brightness exp(−(θf − θi/2)² / (2 σ_lamp²)),
σ_lamp = 1° (the lamp's angular size), over a dim, noisy background. Photos are 8-bit
grey PNGs, values as stored (linear).

Truth: a flake is *lit* in photo k when |θf − θh_k| ≤ :data:`LIT_DEG` (there it is ≥ 0.1
of full brightness, far above the background noise, and in every other photo ≤ 0.015).
The packed truth texture (eq. 16, bit k ↔ θi = 70 − 10k) is :func:`truth_texture`.

    python sample_data/make_sparkle_photos.py [OUT_DIR]      (default sample_data/sparkle)

Deterministic (seeded): rerunning reproduces every file byte for byte.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

SIZE = 128
THETA_I_DEG = (10, 20, 30, 40, 50, 60, 70)
N_FLAKES = 700
#: Fraction of flakes tilted beyond every photo (never lit).
UNLIT_FRACTION = 0.2
SPREAD_DEG = 0.7
LAMP_SIGMA_DEG = 1.0
#: A flake counts as lit in a photo within this of its θh (3 spreads).
LIT_DEG = 2.1
BACKGROUND = 0.06
NOISE = 0.01
FLAKE_PEAK = 0.9
SEED = 4004


def make_flakes(rng: np.random.Generator) -> list[dict]:
    flakes = []
    theta_h = 0.5 * np.asarray(THETA_I_DEG, float)
    for _ in range(N_FLAKES):
        x, y = rng.uniform(0, SIZE, 2)
        r = rng.uniform(0.8, 1.6)
        if rng.random() < UNLIT_FRACTION:
            tilt = rng.uniform(40.0, 60.0)
        else:
            tilt = float(np.clip(rng.choice(theta_h) + rng.normal(0, SPREAD_DEG),
                                 theta_h[0] - LIT_DEG, theta_h[-1] + LIT_DEG))
        flakes.append({"x": round(float(x), 4), "y": round(float(y), 4),
                       "radius": round(float(r), 4), "tilt_deg": round(float(tilt), 4)})
    return flakes


def _footprint(f: dict) -> tuple[np.ndarray, np.ndarray]:
    """Pixels (rows, cols) whose centre lies in the flake's disc."""
    r = f["radius"]
    rows, cols = np.mgrid[int(f["y"] - r) - 1:int(f["y"] + r) + 2,
                          int(f["x"] - r) - 1:int(f["x"] + r) + 2]
    inside = ((cols + 0.5 - f["x"]) ** 2 + (rows + 0.5 - f["y"]) ** 2 <= r * r) \
        & (rows >= 0) & (rows < SIZE) & (cols >= 0) & (cols < SIZE)
    return rows[inside], cols[inside]


def truth_texture(flakes: list[dict]) -> np.ndarray:
    """(SIZE, SIZE) uint8: bit k set where a flake lit at θi = 70 − 10k covers the pixel."""
    t = np.zeros((SIZE, SIZE), np.uint8)
    for f in flakes:
        rows, cols = _footprint(f)
        for k, ti in enumerate(sorted(THETA_I_DEG, reverse=True)):
            if abs(f["tilt_deg"] - ti / 2) <= LIT_DEG:
                t[rows, cols] |= np.uint8(1 << k)
    return t


def photos(flakes: list[dict], rng: np.random.Generator) -> dict[int, np.ndarray]:
    """θi → (SIZE, SIZE) float in [0, 1], 8-bit quantised."""
    out = {}
    for ti in THETA_I_DEG:
        img = np.full((SIZE, SIZE), BACKGROUND) + rng.normal(0, NOISE, (SIZE, SIZE))
        for f in flakes:
            b = np.exp(-0.5 * ((f["tilt_deg"] - ti / 2) / LAMP_SIGMA_DEG) ** 2)
            if b > 1e-6:
                rows, cols = _footprint(f)
                img[rows, cols] += FLAKE_PEAK * b
        out[ti] = np.round(np.clip(img, 0, 1) * 255) / 255
    return out


def main(out_dir: str | Path = Path(__file__).resolve().parent / "sparkle") -> None:
    from gonio_cli.imageio import write_png

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(SEED)
    flakes = make_flakes(rng)
    for ti, img in photos(flakes, rng).items():
        write_png(out / f"photo_ti{ti:02d}.png", img,
                  {"schema": "gonio.sparkle-photo", "theta_i_deg": ti,
                   "source": "sample_data/make_sparkle_photos.py"})
    (out / "flakes.json").write_text(json.dumps(
        {"size_px": SIZE, "theta_i_deg": list(THETA_I_DEG), "lit_deg": LIT_DEG,
         "flakes": flakes}, separators=(",", ":")) + "\n")


if __name__ == "__main__":
    main(*sys.argv[1:])
