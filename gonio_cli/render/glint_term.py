"""The glint term of the shading (docs/render.md, "Glints"; :mod:`gonio_cli.glint`).

An object with ``glint_density`` has a share s of its flake lobe — the Beckmann lobe of a
``cook-torrance`` material (seed 004 eqs. 9–12) — drawn as flakes: per light,

    L_o += s · (r − 1) · f_lobe · V E S(λ) cos θi,
    f_lobe(λ) = ks(λ) F(θd; f0(λ)) D(θh; m(λ)) G / (π cos θi cos θo)    (seed 004 eq. 11),

with r = D_glint / D from :func:`gonio_cli.glint.glint_ratio` (1 where the smooth lobe is
kept). The smooth render already holds f_lobe, so the object shows (1 − s) f_lobe + s r
f_lobe: where no flake glints, the lobe is dimmed by s; where one does, it is r times as
bright, in the lobe's own colour (ks F: the paint's flake spectrum). The environment's sun
(``gonio prefilter --sun``) is a light here; the rest of the sky lights the flakes by
their mean (the smooth lobe of the environment term), which is what the flakes average
to.

f_lobe's XYZ per light spectrum is read from two tables over cos θh (Schlick's F is
linear in f0): T0 = Σλ ks f0 D S cmf / Σ ȳ and T1 = Σλ ks (1 − f0) D S cmf / Σ ȳ, so
XYZ = G / (π cos θi cos θo) (T0 + (1 − cos θd)⁵ T1), exact but for the linear
interpolation between :data:`TABLE_SIZE` entries (relative error ≤ 1e-4 for m ≥ 0.05,
tests/test_glint.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..brdf import COS_EPS, beckmann_d, vgroove_g
from ..errors import InputError
from ..geometry import Cosines
from ..glint import GlintLayer, MAX_STRETCH, MIN_GLINTS, check_layer, cone_area, glint_ratio
from ..spectra import luminance
from .direct import incident
from .mesh import rotation_matrix

#: Entries of the lobe tables over cos θh ∈ [0, 1].
TABLE_SIZE = 4097
#: The models whose flake lobe the glints draw (STYLE 3): model → its lobe's parameters.
GLINT_MODELS = {"cook-torrance": ("ks", "m", "f0")}


@dataclass
class GlintView:
    """What the glints need of the camera: ``eye`` (3,), unit ``forward`` (3,) and
    ``pixel_angle`` = 2 tan(fov / 2) / (rows of the supersampled image), so a sample at
    depth z along ``forward`` is Δ = z · pixel_angle from its neighbours."""

    eye: np.ndarray
    forward: np.ndarray
    pixel_angle: float

    def spacing(self, position: np.ndarray) -> np.ndarray:
        """Δ (n,) at world positions (n, 3)."""
        z = (np.asarray(position, float) - self.eye) @ self.forward
        return np.maximum(z, 0.0) * self.pixel_angle


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot products of (n, 3) with (n, 3) or (3,): (n,)."""
    if b.ndim == 1:
        return a[:, 0] * b[0] + a[:, 1] * b[1] + a[:, 2] * b[2]
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def flake_lobe(material, where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ks, m, f0), each (n_λ,), of a material whose model has a flake lobe."""
    model = getattr(material, "model", None)
    if model not in GLINT_MODELS:
        raise InputError(f"{where}: glints draw the flake lobe of a "
                         f"{' or '.join(GLINT_MODELS)} material, not of a {model or 'measured'} "
                         "one", fix="fit the paint with --model cook-torrance, or drop "
                                    "glint_density")
    return tuple(np.asarray(material.params[k], float).reshape(-1) for k in GLINT_MODELS[model])


def flake_slope(material, wavelength_nm, where: str) -> float:
    """The flakes' Beckmann m: the ȳ-weighted mean of the lobe's m(λ)."""
    _, m, _ = flake_lobe(material, where)
    return float(luminance(m, wavelength_nm))


def lobe_tables(material, weights: np.ndarray, where: str) -> np.ndarray:
    """(2, TABLE_SIZE, C): T0 and T1 (module docstring) for light weights S cmf / Σ ȳ
    (n_λ, C), over cos θh = linspace(0, 1)."""
    ks, m, f0 = flake_lobe(material, where)
    ch = np.linspace(0.0, 1.0, TABLE_SIZE)
    d = beckmann_d(np.maximum(ch, COS_EPS), m)                   # (TABLE_SIZE, n_λ)
    return np.stack([(d * (ks * f0)) @ weights, (d * (ks * (1.0 - f0))) @ weights])


def lobe_xyz(tables: np.ndarray, cos: Cosines) -> np.ndarray:
    """f_lobe's XYZ (n, C) per unit E cos θi, from :func:`lobe_tables`."""
    ci, co = cos.cos_theta_i, cos.cos_theta_o
    x = np.clip(cos.cos_theta_h, 0.0, 1.0) * (TABLE_SIZE - 1)
    j = np.minimum(x.astype(np.intp), TABLE_SIZE - 2)
    t = (x - j)[:, None]
    t0 = tables[0, j] * (1 - t) + tables[0, j + 1] * t
    t1 = tables[1, j] * (1 - t) + tables[1, j + 1] * t
    schlick = ((1.0 - np.clip(cos.cos_theta_d, 0.0, 1.0)) ** 5)[:, None]
    geo = vgroove_g(cos) / (np.pi * np.maximum(ci, COS_EPS) * np.maximum(co, COS_EPS))
    return geo[:, None] * (t0 + schlick * t1)


def light_cone(layer, light) -> tuple[float, float]:
    """The mirror cone (r_in, r_out) in slope units (:func:`gonio_cli.glint.cone_profile`):
    the light's disc in h (radius ρ_s: a quarter of its angular diameter, 0 for a point
    light) seen through the flake's spread (radius ρ_f, ``angle_rad``): flat to |ρ_s − ρ_f|,
    falling to 0 at ρ_s + ρ_f (a linear stand-in for the discs' convolution, with its
    area). A perfect flake (ρ_f = 0) sees the disc itself: F · L_source inside it."""
    src = np.radians(light.angular_diameter_deg) / 4.0 if light.kind == "directional" else 0.0
    rho_s, rho_f = float(np.tan(src)), float(np.tan(layer.angle_rad))
    return abs(rho_s - rho_f), rho_s + rho_f


def glint_xyz(surface, where: str, rows: np.ndarray, flat: dict, lights, light_weights,
              wl: np.ndarray, counts: dict, channels: int = 3) -> np.ndarray:
    """XYZ (n, C) the glints add to one object's rows (module docstring)."""
    layer, view = surface.glint, surface.glint_view
    out = np.zeros((rows.size, channels))
    if flat["position"] is None:
        raise InputError(f"{where} has glints but the G-buffer has no positions",
                         fix="rasterize with position=True")
    whole = rows.size == flat["normal"].shape[0]         # the object covers every row
    p, n, v = (flat[key] if whole else flat[key][rows] for key in ("position", "normal",
                                                                    "view"))
    spacing = _dot(p - view.eye.astype(p.dtype), view.forward) * view.pixel_angle
    cos_o = _dot(n, v)
    # the most flakes a sample's filter can hold (|n_a| ≤ 1, foreshortening capped) times
    # p22(0) π: with γ², the expected glints at θh = 0, the most any sample can have
    reach = float(layer.density * np.max(spacing, initial=0.0) ** 2 * MAX_STRETCH
                  / layer.m ** 2)
    cones = [light_cone(layer, light) for light in lights]
    bin_width = 2.0 * max((c[1] for c in cones), default=0.0)
    for j, light in enumerate(lights):
        wi, e = incident(light, p)
        cos_i = _dot(n, wi)
        scale = np.where((cos_i > 0) & (cos_o > 0), cos_i * e, 0.0)
        if f"visibility{j}" in flat:                              # shadows: V E cos θi
            scale = scale * flat[f"visibility{j}"][rows]
        if cones[j][1] == 0.0:
            continue
        # a bound of the expected glints, reach γ² exp(−tan²θh / m²) ≥ MIN_GLINTS, as
        # cos²θh ≥ 1 / (1 + tan²_max): only those samples are drawn (glint_ratio tests
        # each exactly)
        tan2_max = layer.m ** 2 * np.log(max(reach * cone_area(cones[j]) / np.pi / MIN_GLINTS,
                                             1.0))
        h = wi + v                                                 # not normalised
        hn2 = np.square(_dot(n, h))                  # h·n > 0 where lit (ωi·n, ωo·n > 0)
        lit = np.flatnonzero((scale > 0) & (hn2 * (1.0 + tan2_max) >= _dot(h, h)))
        if lit.size == 0:
            continue
        h = h[lit].astype(np.float64)
        h /= np.sqrt(_dot(h, h))[:, None]
        wi = np.broadcast_to(wi, p.shape)
        r, c = glint_ratio(p[lit].astype(np.float64), n[lit].astype(np.float64),
                           v[lit].astype(np.float64), h, spacing[lit].astype(np.float64),
                           layer, cones[j], bin_width)
        for key, value in c.items():
            counts[f"glint_{key}"] += value
        moved = np.flatnonzero(r != 1.0)
        if moved.size == 0:
            continue
        sel = lit[moved]
        cos = Cosines(*(np.clip(np.asarray(c, np.float64), 0.0, 1.0) for c in (
            cos_i[sel], cos_o[sel], _dot(n[sel], h[moved]), _dot(wi[sel], h[moved]))))
        key = np.asarray(light.spectrum, float).tobytes()
        if key not in surface.glint_cache:
            surface.glint_cache[key] = lobe_tables(surface.material, light_weights(light),
                                                   where)
        xyz = lobe_xyz(surface.glint_cache[key], cos)
        out[sel] += (layer.share * (r[moved] - 1.0) * scale[sel])[:, None] * xyz
    return out


def glint_surface(surface, o, scene, where: str) -> None:
    """Give ``surface`` the glint layer of scene object ``o`` (``glint_density`` …) and the
    view of ``scene``'s camera at its supersampling; nothing when ``o`` has no glints."""
    if o.glint_density is None:
        return
    layer = GlintLayer(o.glint_density, o.glint_share, float(np.radians(o.glint_angle_deg)),
                       flake_slope(surface.material, scene.grid_nm, where), o.glint_seed,
                       rotation_matrix(o.rotate_deg), np.asarray(o.translate, float))
    check_layer(layer, where)
    cam = scene.camera
    forward = np.asarray(cam.target, float) - np.asarray(cam.eye, float)
    rows = cam.height * scene.output.ssaa
    surface.glint = layer
    surface.glint_view = GlintView(np.asarray(cam.eye, float), forward / np.linalg.norm(forward),
                                   2.0 * np.tan(np.radians(cam.fov_deg) / 2.0) / rows)
