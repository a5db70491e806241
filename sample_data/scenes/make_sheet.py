"""Make ``sample_data/scenes/sheet.obj``: a bent sheet of paper for the print scene.

A cylinder section (axis along +y) of radius RADIUS, bulging towards +z (the camera of
``print.toml``): x = R sin φ, z = R (cos φ − 1), y ∈ [−1, 1], with φ ∈ [−Φ, Φ] and
Φ = 1 / R so the arc is 2 long, as wide as it is high (the print is square). Texture
coordinates follow OpenGL (docs/conventions.md: v = 0 is the bottom row of the image): u = (φ + Φ)
/ 2Φ left to right, v = (y + 1) / 2 bottom to top. Normals are the cylinder's
(sin φ, 0, cos φ). SEGMENTS_X × SEGMENTS_Y quads, two counter-clockwise triangles each
(front towards +z).

Run: ``python sample_data/scenes/make_sheet.py [OUT.obj]``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

RADIUS = 1.6
SEGMENTS_X, SEGMENTS_Y = 48, 8


def sheet(radius: float = RADIUS, nx: int = SEGMENTS_X, ny: int = SEGMENTS_Y) -> str:
    half = 1.0 / radius
    phi = np.linspace(-half, half, nx + 1)
    y = np.linspace(-1.0, 1.0, ny + 1)
    P, Y = np.meshgrid(phi, y)                                  # rows: y, columns: φ
    v = np.stack([radius * np.sin(P), Y, radius * (np.cos(P) - 1.0)], -1).reshape(-1, 3)
    n = np.stack([np.sin(P), np.zeros_like(P), np.cos(P)], -1).reshape(-1, 3)
    uv = np.stack([(P + half) / (2 * half), (Y + 1.0) / 2.0], -1).reshape(-1, 2)
    idx = np.arange(v.shape[0]).reshape(ny + 1, nx + 1) + 1     # OBJ is 1-based
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]
    faces = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3),
                            np.stack([a, d, c], -1).reshape(-1, 3)])
    lines = ["# bent sheet for print.toml, written by make_sheet.py"]
    lines += [f"v {x:.6f} {yy:.6f} {z:.6f}" for x, yy, z in v]
    lines += [f"vt {s:.6f} {t:.6f}" for s, t in uv]
    lines += [f"vn {x:.6f} {yy:.6f} {z:.6f}" for x, yy, z in n]
    lines += ["f " + " ".join(f"{i}/{i}/{i}" for i in f) for f in faces]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).with_name("sheet.obj")
    out.write_text(sheet())
    print(out)
