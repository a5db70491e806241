"""The Mitsuba export judged as the fitted targets are: the plugin just written, loaded in
Mitsuba's ``scalar_rgb`` variant from the export folder, evaluated at the measurement's
configurations (or the in-plane grid) and compared with the material
(:func:`gonio_cli.export.judge.report`): one line on stderr and ``report.json`` in the
folder, so a user sees what each target loses, Mitsuba included.

The plugin evaluates the material's own model (a port of its equations to Dr.Jit, in
single precision), so what it loses is round-off and the RGB reduction of the spectrum,
which is the same one the judge makes: a CIEDE2000 well under 0.1 says the port is
whole; anything more is a bug in the port. Without Mitsuba installed (the optional
``gonio[mitsuba]``) the folder is written and the report is left out, with a warning.
"""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path
from typing import Any, Callable

import numpy as np

from .. import log
from ..artifact import write_artifact
from ..geometry import Cosines
from .judge import REPORT_SCHEMA, REPORT_VERSION, report

#: The variant the report is made in: RGB (the judge compares linear sRGB) and scalar
#: (no LLVM needed; a few hundred configurations take well under a second).
VARIANT = "scalar_rgb"
#: The report's name inside the export folder.
REPORT_NAME = "report.json"


def directions(cos: Cosines) -> tuple[np.ndarray, np.ndarray]:
    """ωi and ωo (N, 3) with the cosines ``cos`` (the BRDFs are isotropic, so any such
    pair): ωi in the xz plane, ωo at the azimuth where ωi·ωo = cos 2θd = 2 cos²θd − 1."""
    ci, co = (np.clip(np.asarray(c, float).ravel(), -1.0, 1.0)
              for c in (cos.cos_theta_i, cos.cos_theta_o))
    si, so = np.sqrt(1.0 - ci * ci), np.sqrt(1.0 - co * co)
    dot = 2.0 * np.asarray(cos.cos_theta_d, float).ravel() ** 2 - 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        cos_phi = np.where(si * so > 1e-12, (dot - ci * co) / (si * so), 1.0)
    cos_phi = np.clip(cos_phi, -1.0, 1.0)
    sin_phi = np.sqrt(1.0 - cos_phi * cos_phi)
    wi = np.stack([si, np.zeros_like(si), ci], axis=-1)
    wo = np.stack([so * cos_phi, so * sin_phi, co], axis=-1)
    return wi, wo


def plugin_rgb(folder: Path) -> Callable[[Cosines], np.ndarray] | None:
    """f (N, 3) in linear sRGB of the plugin in ``folder`` at cosines, through Mitsuba's
    own ``eval`` (which holds the cosine of ωo, divided out here); None without Mitsuba."""
    if importlib.util.find_spec("mitsuba") is None:
        return None
    import mitsuba as mi  # lazy: the optional gonio[mitsuba], only for this report

    mi.set_variant(VARIANT)
    spec = importlib.util.spec_from_file_location("gonio_bsdf", folder / "gonio_bsdf.py")
    plugin = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(plugin)
    plugin.register()
    bsdf = mi.load_dict({"type": "gonio", "params": str(folder / "bsdf_params.json")})
    ctx = mi.BSDFContext()

    def rgb(cos: Cosines) -> np.ndarray:
        wi, wo = directions(cos)
        out = np.zeros((len(wi), 3))
        si = mi.SurfaceInteraction3f()
        si.sh_frame = mi.Frame3f(mi.Vector3f(0.0, 0.0, 1.0))
        for k, (a, b) in enumerate(zip(wi, wo)):
            if a[2] <= 0.0 or b[2] <= 0.0:
                continue
            si.wi = mi.Vector3f(*a)
            value = bsdf.eval(ctx, si, mi.Vector3f(*b))
            out[k] = [float(value[c]) / b[2] for c in range(3)]
        return out
    return rgb


def judge_mitsuba(material, material_path, folder) -> tuple[Path | None, dict[str, Any] | None]:
    """Write ``folder/report.json`` for the plugin in ``folder``; (its path, its payload),
    or (None, None) with a warning when Mitsuba is not installed."""
    folder = Path(folder).resolve()
    rgb = plugin_rgb(folder)
    if rgb is None:
        log.warn(f"{folder}: not judged: Mitsuba is not installed (pip install "
                 "'gonio[mitsuba]'); the plugin is written")
        return None, None
    rep = report("mitsuba", material, material_path, rgb)
    if not all(math.isfinite(rep[k]) for k in ("delta_e2000_mean", "delta_e2000_worst")):
        raise ValueError("the Mitsuba plugin gave a non-finite colour (a bug in the port)")
    payload = {**rep, "file": folder.name, "variant": VARIANT}
    path = folder / REPORT_NAME
    write_artifact(path, REPORT_SCHEMA, REPORT_VERSION, payload, inputs=[material_path],
                   parameters={"target": "mitsuba"})
    return path, payload
