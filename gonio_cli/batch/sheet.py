"""``OUTDIR/index.html``: a static contact sheet of a batch (no server, no external assets).

Every image the batch wrote is a thumbnail linked to the full image, grouped by material
and scene, with the material's fit verdict and colour errors (read from its
gonio.material file) and links to the material and its fit plot, each job's time and
status, and the turntable previews (animated PNGs, which browsers play in an ``<img>``).
Failed jobs are listed with their one-line errors. Links are relative, so the folder can
be copied or served as it is.

Thumbnails are shown at their own pixel size, never stretched: an image up to
:data:`NATIVE_MAX_PX` is its own thumbnail; a larger one gets a copy reduced by a whole
factor in ``OUTDIR/thumbs/``. Under every frame the sheet says what the eye would miss in
a thumbnail (:func:`frame_flags`): the share of its covered pixels clipped at white (any
channel at 255) above :data:`CLIP_WARN`, and a frame that is nearly black.
"""

from __future__ import annotations

import html
import json
import os
from typing import Any, Mapping, Sequence

from . import SHEET_NAME
from ..artifact import atomic_path
from ..folders import make_folder

#: Largest side (pixels) of an image shown as it is; a larger one is reduced by the smallest
#: whole factor that brings it to this size or below (the full image is a click away).
NATIVE_MAX_PX = 256

#: Share of a frame's covered pixels (not pure black) with a channel at 255 above which the
#: sheet says the frame clips: the batch's target is < 1 % (lower the material's exposure:
#: ``render = { exposure-stops = -1 }`` in its [[material]]).
CLIP_WARN = 0.01

#: A frame whose brightest 1 % of pixels have an encoded luma below this (0–1) is said to
#: be nearly black (5 % grey: what a thumbnail shows as black on a screen).
DARK_P99 = 0.05

_CSS = """
body{font:14px/1.4 system-ui,sans-serif;margin:1.5em;background:#fafafa;color:#222}
h1{font-size:1.4em}h2{margin-top:1.6em;border-bottom:1px solid #ccc}h3{font-size:1em}
.row{display:flex;flex-wrap:wrap;gap:10px;align-items:flex-start}
figure{margin:0;text-align:center;font-size:12px}
figure img{background:#000;display:block;margin:auto}
figure.preview img{outline:2px solid #48c}
figcaption .warn{color:#b00;font-weight:bold}
.good{color:#170}.poor{color:#a60}.failed,.blocked{color:#b00}
table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:2px 6px;text-align:left}
"""


def _e(text: Any) -> str:
    return html.escape(str(text), quote=True)


def _verdict(material_path: str | None) -> str:
    """The fit verdict line of a gonio.material file, or '' if there is none."""
    if not material_path:
        return ""
    try:
        with open(material_path, encoding="utf-8") as fh:
            doc = json.load(fh)
        v = doc["fit"]["verdict"]
        status = doc.get("status", v.get("verdict", "?"))
    except (OSError, ValueError, KeyError, TypeError):
        return ""
    parts = [f"<b class='{_e(status)}'>{_e(status)}</b>", _e(doc.get("model", ""))]
    for key, label in (("delta_e2000_mean", "ΔE00 mean"), ("delta_e2000_worst", "worst")):
        if isinstance(v.get(key), (int, float)):
            parts.append(f"{label} {v[key]:.2f}")
    if v.get("reasons"):
        parts.append(_e("; ".join(map(str, v["reasons"]))))
    gains = doc["fit"].get("sweep_gain")
    if isinstance(gains, dict) and isinstance(gains.get("gain"), list):
        alone = (v.get("brdf_alone") or {}).get("delta_e2000_mean")
        parts.append(_e("with light-source gains " + " ".join(
            f"x{g:.3f}" for g in gains["gain"] if isinstance(g, (int, float)))
            + (f" (the BRDF alone: {alone:.2f})" if isinstance(alone, (int, float)) else "")))
    return "fit: " + ", ".join(p for p in parts if p)


#: Folder of the thumbnails, inside the output folder.
THUMBS_DIR = "thumbs"


def thumbnail(outdir: str, image: str) -> tuple[str, int, int]:
    """The image the sheet shows for ``image`` and its size in pixels (width, height): the
    image itself when its larger side is at most :data:`NATIVE_MAX_PX` or it is animated (a
    turntable preview plays as it is), else a copy reduced by a whole factor
    (``OUTDIR/thumbs/…``, remade when older than the image)."""
    from PIL import Image

    with Image.open(image) as im:
        w, h = im.size
        factor = -(-max(w, h) // NATIVE_MAX_PX)                 # ceil
        if factor <= 1 or getattr(im, "n_frames", 1) > 1:
            return image, w, h
        size = (max(1, w // factor), max(1, h // factor))
        thumb = os.path.join(outdir, THUMBS_DIR, os.path.relpath(image, outdir))
        if os.path.isfile(thumb) and os.path.getmtime(thumb) >= os.path.getmtime(image):
            return thumb, *size
        small = im.convert("RGB").reduce(factor)
    make_folder(os.path.dirname(thumb))
    with atomic_path(thumb) as tmp:
        small.save(tmp, format="PNG")
    return thumb, small.width, small.height


def frame_flags(image: str) -> list[str]:
    """What a thumbnail hides in a rendered frame (an 8-bit PNG): the share of its covered
    pixels (not pure black) clipped at white, when above :data:`CLIP_WARN`, and "nearly
    black" when its brightest 1 % lies below :data:`DARK_P99` of white in encoded luma
    (Rec. 709 weights on the stored values). An unreadable image says so."""
    import numpy as np
    from PIL import Image

    try:
        with Image.open(image) as im:
            rgb = np.asarray(im.convert("RGB"), dtype=np.float32) / 255.0
    except (OSError, ValueError):
        return ["unreadable image"]
    flags = []
    # rgb.max(axis=-1), channel by channel: numpy's reduction over a 3-long last axis
    # takes ~6 ms on a 384² frame, this ~0.3 ms (a frame's flags are made per job)
    peak = np.maximum(np.maximum(rgb[..., 0], rgb[..., 1]), rgb[..., 2])
    covered = peak > 0
    clipped = np.count_nonzero((peak >= 1.0) & covered)
    share = clipped / max(int(np.count_nonzero(covered)), 1)
    if share > CLIP_WARN:
        flags.append(f"{share:.0%} clipped")
    luma = rgb @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)
    if np.percentile(luma, 99) < DARK_P99:
        flags.append("nearly black")
    return flags


def image_entry(outdir: str, image: str, flags: bool = True) -> dict[str, Any]:
    """What the sheet shows for ``image``: its ``path``, the image ``shown`` (a thumbnail,
    :func:`thumbnail`), its ``width`` and ``height`` (px) and, if ``flags``, a frame's
    :func:`frame_flags`. A worker makes it as its job ends (the record's ``image``), so
    the driver does not open every image again at the end of a batch."""
    shown, w, h = thumbnail(outdir, image)
    return {"path": image, "shown": shown, "width": w, "height": h,
            "flags": frame_flags(image) if flags else []}


def _figure(outdir: str, rec: Mapping[str, Any], caption: str, preview: bool = False,
            links: str = "") -> str:
    if not rec.get("outputs") or not os.path.isfile(rec["outputs"][0]["path"]):
        return (f"<figure><div class='{_e(rec['status'])}' style='width:96px'>"
                f"{_e(rec['status'])}</div><figcaption>{_e(caption)}</figcaption></figure>")
    image = rec["outputs"][0]["path"]
    entry = rec.get("image")
    if not (isinstance(entry, dict) and entry.get("path") == image
            and os.path.isfile(str(entry.get("shown")))):
        entry = image_entry(outdir, image, not preview)
    shown, w, h = entry["shown"], entry["width"], entry["height"]
    flags = "" if preview else "".join(f"<br><span class='warn'>{_e(f)}</span>"
                                       for f in entry.get("flags", []))
    cls = " class='preview'" if preview else ""
    return (f"<figure{cls}><a href='{_rel(outdir, image)}'><img src='{_rel(outdir, shown)}' "
            f"width='{w}' height='{h}' alt='{_e(rec['key'])}' class='thumb'></a>"
            f"<figcaption>{_e(caption)}{flags}{links}</figcaption></figure>")


def _rel(outdir: str, path: str) -> str:
    return _e(os.path.relpath(path, outdir).replace(os.sep, "/"))


def _material_links(outdir: str, fit: Mapping[str, Any] | None) -> tuple[str, str]:
    """(line, caption links) to a fitted material and its fit plot (the fit job's outputs:
    the material file, then the plot where the plan asked for one)."""
    paths = [o["path"] for o in (fit or {}).get("outputs", []) if os.path.isfile(o["path"])]
    json_files = [p for p in paths if p.endswith(".json")]
    plots = [p for p in paths if p.lower().endswith(".png")]
    links = ([f"<a href='{_rel(outdir, json_files[0])}'>material</a>"] if json_files else []) \
        + ([f"<a href='{_rel(outdir, plots[0])}'>fit plot</a>"] if plots else [])
    if not links:
        return "", ""
    return " · ".join(links), "<br>" + " · ".join(links)


def write_sheet(outdir: str | os.PathLike, records: Sequence[Mapping[str, Any]], *,
                title: str = "gonio batch") -> str:
    """Write ``OUTDIR/index.html`` for a batch's records (plan order); return its path."""
    outdir = os.fspath(outdir)
    by_material: dict[str, dict[str, list]] = {}
    fits: dict[str, Mapping[str, Any]] = {}
    other: list[Mapping[str, Any]] = []
    for r in records:
        labels = r.get("labels", {})
        name, role = labels.get("material"), labels.get("role")
        if name:
            by_material.setdefault(name, {})
        if name and role == "fit":
            fits[name] = r
        if name and role in ("frame", "preview", "render"):
            by_material.setdefault(name, {}).setdefault(labels.get("scene", ""), []).append(r)
        elif not name and any(o["path"].lower().endswith(".png") for o in r.get("outputs", [])):
            other.append(r)
    failed = [r for r in records if r["status"] not in ("ok", "skipped")]
    n_img = sum(1 for r in records for o in r.get("outputs", [])
                if o["path"].lower().endswith(".png"))
    body = [f"<h1>{_e(title)}</h1>",
            f"<p>{len(records)} jobs, {n_img} images, {len(failed)} failed. "
            "Thumbnails at their own pixel size; click one for the full image. Turntable "
            f"previews have a blue frame; a frame with more than {CLIP_WARN:.0%} of its "
            "pixels clipped, or nearly black, says so in red.</p>"]
    if failed:
        body.append("<h2>Failed jobs</h2><table><tr><th>job</th><th>status</th>"
                    "<th>error</th></tr>")
        body += [f"<tr><td>{_e(r['key'])}</td><td class='{_e(r['status'])}'>{_e(r['status'])}"
                 f"</td><td>{_e(r.get('error') or '')}</td></tr>" for r in failed]
        body.append("</table>")
    for name, scenes in by_material.items():
        fit = fits.get(name)
        material = fit["outputs"][0]["path"] if fit and fit.get("outputs") else None
        body.append(f"<h2 id='{_e(name)}'>{_e(name)}</h2>")
        line = _verdict(material)
        if fit is not None:
            line += (f" ({fit['status']}, {fit.get('time_s', 0):.2f} s)" if line else
                     f"fit: <span class='{_e(fit['status'])}'>{_e(fit['status'])}</span> "
                     f"{_e(fit.get('error') or '')}")
        links, caption_links = _material_links(outdir, fit)
        if line or links:
            body.append(f"<p>{line}{' — ' if line and links else ''}{links}</p>")
        for scene, recs in scenes.items():
            body.append(f"<h3>{_e(scene)}</h3><div class='row'>")
            for r in recs:
                labels = r.get("labels", {})
                t = f"{r.get('time_s', 0):.2f} s"
                if labels.get("role") == "preview":
                    body.append(_figure(outdir, r, f"turntable, {labels.get('frames')} "
                                                   "frames", preview=True))
                else:
                    frame = labels.get("frame")
                    body.append(_figure(outdir, r, (f"frame {frame}, " if frame is not None
                                                    else "") + f"{t}, {r['status']}",
                                        links=caption_links))
            body.append("</div>")
    if other:
        body.append("<h2>Other images</h2><div class='row'>")
        body += [_figure(outdir, r, f"{r['key']}, {r.get('time_s', 0):.2f} s") for r in other]
        body.append("</div>")
    page = ("<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
            f"<title>{_e(title)}</title><style>{_CSS}</style></head><body>\n"
            + "\n".join(body) + "\n</body></html>\n")
    path = os.path.join(outdir, SHEET_NAME)
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8") as fh:
        fh.write(page)
    return path
