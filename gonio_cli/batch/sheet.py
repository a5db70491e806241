"""``OUTDIR/index.html``: a static contact sheet of a batch (no server, no external assets).

Every image the batch wrote is a thumbnail linked to the full image, grouped by material
and scene, with the material's fit verdict and colour errors (read from its
gonio.material file), each job's time and status, and the turntable previews (animated
PNGs, which browsers play in an ``<img>``). Failed jobs are listed with their one-line
errors. Links are relative, so the folder can be copied or served as it is; images
larger than twice the thumbnail width get a small copy in ``OUTDIR/thumbs/``.
"""

from __future__ import annotations

import html
import json
import os
from typing import Any, Mapping, Sequence

from . import SHEET_NAME

#: Thumbnail width in CSS pixels (the full image is a click away).
THUMB_PX = 128

_CSS = """
body{font:14px/1.4 system-ui,sans-serif;margin:1.5em;background:#fafafa;color:#222}
h1{font-size:1.4em}h2{margin-top:1.6em;border-bottom:1px solid #ccc}h3{font-size:1em}
.row{display:flex;flex-wrap:wrap;gap:10px;align-items:flex-start}
figure{margin:0;text-align:center;font-size:12px}
figure img{width:%dpx;height:auto;image-rendering:auto;background:#000;display:block}
figure.preview img{outline:2px solid #48c}
.good{color:#170}.poor{color:#a60}.failed,.blocked{color:#b00}
table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:2px 6px;text-align:left}
""" % THUMB_PX


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


def thumbnail(outdir: str, image: str) -> str:
    """A small copy of ``image`` for the sheet (``OUTDIR/thumbs/…``, remade when older
    than the image), or the image itself if it is small already or animated (a
    turntable preview plays as it is)."""
    from PIL import Image

    with Image.open(image) as im:
        if max(im.size) <= 2 * THUMB_PX or getattr(im, "n_frames", 1) > 1:
            return image
        thumb = os.path.join(outdir, THUMBS_DIR, os.path.relpath(image, outdir))
        if os.path.isfile(thumb) and os.path.getmtime(thumb) >= os.path.getmtime(image):
            return thumb
        small = im.convert("RGB")
        small.thumbnail((2 * THUMB_PX, 2 * THUMB_PX))  # sharp on 2x displays
    from ..artifact import atomic_path, make_folder

    make_folder(os.path.dirname(thumb))
    with atomic_path(thumb) as tmp:
        small.save(tmp, format="PNG")
    return thumb


def _figure(outdir: str, rec: Mapping[str, Any], caption: str, preview: bool = False) -> str:
    if not rec.get("outputs") or not os.path.isfile(rec["outputs"][0]["path"]):
        return (f"<figure><div class='{_e(rec['status'])}' style='width:{THUMB_PX}px'>"
                f"{_e(rec['status'])}</div><figcaption>{_e(caption)}</figcaption></figure>")
    image = rec["outputs"][0]["path"]

    def rel(path: str) -> str:
        return _e(os.path.relpath(path, outdir).replace(os.sep, "/"))

    cls = " class='preview'" if preview else ""
    return (f"<figure{cls}><a href='{rel(image)}'><img src='{rel(thumbnail(outdir, image))}' "
            f"alt='{_e(rec['key'])}' class='thumb'></a><figcaption>{_e(caption)}"
            "</figcaption></figure>")


def write_sheet(outdir: str | os.PathLike, records: Sequence[Mapping[str, Any]], *,
                title: str = "gonio batch") -> str:
    """Write ``OUTDIR/index.html`` for a batch's records (plan order); return its path."""
    from ..artifact import atomic_path

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
            "Click a thumbnail for the full image; turntable previews have a blue frame."
            "</p>"]
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
        if line:
            body.append(f"<p>{line}</p>")
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
                                                    else "") + f"{t}, {r['status']}"))
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
