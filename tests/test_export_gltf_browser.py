"""``gonio export --to gltf`` opens in a real browser viewer.

The demo's clear-coated paint (sample_data/coat_paint.csv, fitted and exported as
tests/test_export_gltf.py does) is loaded by three.js's GLTFLoader in headless Chromium
(tests/js/view_gltf.html, served on 127.0.0.1; three is pinned in tests/js and installed
by ``make js-tools``), rendered under three's neutral RoomEnvironment, and screenshotted.
The page reports "loaded" or the loader's error; the screenshot must show the preview
sphere where the camera puts it, in the hue of the exported ``baseColorFactor``.
Skipped with the reason where Chromium or three is missing.
"""

from __future__ import annotations

import colorsys
import subprocess
import threading
from contextlib import contextmanager
from functools import partial
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import unquote, urlsplit

import numpy as np
import pytest
from browser import chromium, headless_flags
from test_export_gltf import export_demo_coat

from gonio_cli.spectra import srgb_encode

JS = Path(__file__).resolve().parent / "js"
PAGE = "view_gltf.html"
SIZE = 400                                     # the page's canvas, px
BACKGROUND = np.array([128, 128, 128])         # the page's background, #808080
#: the unit sphere 4.5 from a 30° camera: its disc's radius over the half-frame
DISC = np.tan(np.arcsin(1.0 / 4.5)) / np.tan(np.radians(15.0))
#: a pixel is the object's when a channel differs from the background by more than this
OFF_BACKGROUND = 12


def _three() -> None:
    if not (JS / "node_modules" / "three" / "build" / "three.module.js").is_file():
        pytest.skip("three.js is not installed: run make js-tools (npm ci in tests/js; "
                    "make test does it where npm is found)")


class _Viewer(SimpleHTTPRequestHandler):
    """tests/js as the site root, ``/model.glb`` the file under test; ``/status?TEXT``
    records the page's outcome."""

    def __init__(self, *args, glb: Path, statuses: list, **kw):
        self.glb, self.statuses = glb, statuses
        super().__init__(*args, directory=str(JS), **kw)

    def translate_path(self, path):
        if urlsplit(path).path == "/model.glb":
            return str(self.glb)
        return super().translate_path(path)

    def do_GET(self):
        url = urlsplit(self.path)
        if url.path != "/status":
            return super().do_GET()
        self.statuses.append(unquote(url.query))
        self.send_response(204)
        self.end_headers()

    def log_message(self, *args):
        pass


@contextmanager
def _serving(glb: Path):
    """(the viewer's URL, the statuses the page reports) while a loopback server runs."""
    statuses: list[str] = []
    server = ThreadingHTTPServer(("127.0.0.1", 0),
                                 partial(_Viewer, glb=glb, statuses=statuses))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/{PAGE}", statuses
    finally:
        server.shutdown()
        server.server_close()
        thread.join(timeout=10)


def view(glb: Path, tmp_path: Path) -> tuple[list[str], np.ndarray]:
    """Open ``glb`` in the three.js viewer in headless Chromium: (the page's statuses, its
    screenshot as (SIZE, SIZE, 3) uint8, also saved as tmp_path/view.png)."""
    from PIL import Image

    browser = chromium()
    _three()
    shot = tmp_path / "view.png"
    # WebGL without a GPU: ANGLE on SwiftShader (--use-gl=swiftshader gives no context)
    flags = [*headless_flags(tmp_path / "profile"), "--use-angle=swiftshader",
             "--enable-unsafe-swiftshader", f"--window-size={SIZE},{SIZE}",
             "--hide-scrollbars", f"--screenshot={shot}"]
    with _serving(glb) as (url, statuses):
        run = subprocess.run([browser, *flags, url], capture_output=True, text=True,
                             timeout=120)
    assert shot.is_file(), run.stderr[-600:]
    return statuses, np.asarray(Image.open(shot).convert("RGB"))[:SIZE, :SIZE]


def figures(img: np.ndarray) -> dict:
    """What the screenshot shows: the object's fraction of the frame, its centroid (px),
    whether the centre 40 × 40 is all object, and the hue (°) and saturation of its mean
    colour."""
    mask = np.abs(img.astype(int) - BACKGROUND).max(axis=-1) > OFF_BACKGROUND
    ys, xs = np.nonzero(mask)
    c = SIZE // 2
    mean = img[mask].mean(axis=0) / 255.0 if mask.any() else np.full(3, 0.5)
    hue, _, sat = colorsys.rgb_to_hls(*mean)
    return {"coverage": float(mask.mean()),
            "centroid": (float(xs.mean()), float(ys.mean())) if mask.any() else (-1.0, -1.0),
            "centre_is_object": bool(mask[c - 20:c + 20, c - 20:c + 20].all()),
            "hue": 360.0 * hue, "saturation": sat, "mean_rgb": mean}


def hue_of(linear_rgb) -> float:
    """The hue (°) of a linear sRGB colour as displayed (sRGB-encoded)."""
    return 360.0 * colorsys.rgb_to_hls(*srgb_encode(np.asarray(linear_rgb, float)))[0]


def test_exported_glb_renders_in_three_js(tmp_path):
    chromium()
    _three()
    report = export_demo_coat(tmp_path, "gltf", ".glb")
    statuses, img = view(tmp_path / "coat.glb", tmp_path)
    assert statuses == ["loaded"], statuses
    got = figures(img)
    # the disc of the unit sphere, π (DISC/2)² of the frame (0.568; 0.567 on 2026-12),
    # centred where the camera looks
    assert got["coverage"] == pytest.approx(np.pi * DISC ** 2 / 4, rel=0.05), got
    assert np.allclose(got["centroid"], SIZE / 2, atol=4), got
    assert got["centre_is_object"], got
    # lit by a neutral environment the sphere keeps the hue of its baseColorFactor
    want = hue_of(report["gltf"]["base_color"])
    assert abs((got["hue"] - want + 180.0) % 360.0 - 180.0) < 30.0, (want, got)
    assert got["saturation"] > 0.25, got


def test_a_broken_glb_is_reported_not_shown(tmp_path):
    """The check above can fail: a truncated file is the loader's error, and nothing but
    the background is drawn."""
    from gonio_cli.export.gltf import glb_bytes
    from gonio_cli.export.gltf_brdf import GltfMaterial

    chromium()
    _three()
    glb = tmp_path / "bad.glb"
    glb.write_bytes(glb_bytes(GltfMaterial(base_color=(0.6, 0.2, 0.1), metallic=0.0,
                                           roughness=0.5))[:-64])
    statuses, img = view(glb, tmp_path)
    assert len(statuses) == 1 and statuses[0].startswith("error: "), statuses
    assert figures(img)["coverage"] < 0.01
