"""Shading: GBuffer + surfaces + lights (+ environment) → CIE XYZ per pixel (stage 5).

Direct light (point and directional) is summed per pixel as docs/conventions.md writes it,

    L_o(λ) = Σ_lights f(ωi, ωo, λ) · E · S(λ) · cos θi,    XYZ = Σλ L_o cmf / Σλ ȳ,

with E the irradiance at normal incidence (directional: ``irradiance``; point: I / d²)
and S the light's spectrum (Σ S ȳ / Σ ȳ = 1). Shadows enter as a visibility V in [0, 1]
per sample and light (:mod:`.shadow`, computed by the pipeline before this stage):
E cos θi becomes V E cos θi in every term a light feeds — each material path, the inks
and substrate of a print, and the sparkles. Without a visibility (``visibility=None``,
or None for a light) every light reaches every pixel whose normal faces it. The
environment's diffuse light is multiplied by its own visibility (``env_visibility``,
:mod:`.occlusion`).

Two spectral paths (``spectral=``):

``"exact"``
    f (..., n_λ) from the model, times S, summed against the colour-matching functions:
    41 multiply-adds per pixel, light and channel.
``"table"`` (default)
    The models are written so the wavelength sum leaves the pixel loop:

    * goniochromatic (seed 000 eq. 5): f = D(θh)/4 · ρ(λ) exp(c(λ) x) with
      x = 1 − cos((θi+θo)/2) (eq. 6), so per light spectrum S
      XYZ = D/4 · E cos θi · T(x),  T(x) = Σλ ρ exp(c x) S cmf / Σ ȳ,
      a (n_x, 3) table over x ∈ [0, 1] built once per ink and light spectrum and read by
      linear interpolation. Its size is chosen by the error it gives: doubled from
      :data:`TABLE_MIN_SIZE` until the largest relative error at the midpoints between
      entries (where linear interpolation is worst) is below :data:`TABLE_REL_TOL`
      (measured: the demo inks stop at 257 (blue), 513 (green) and 1025 (red, c ≤ 5.6)
      entries, ≤ 24 kB each; against the exact sum on a 512² sphere under two lights,
      largest relative XYZ difference 1e-5, CIEDE2000 ≤ 2e-4).
    * torrance-sparrow (seed 000 eq. 2 with Schlick's F): F = f0 + (1 − f0) m,
      m = (1 − cos θd)⁵, is linear in f0, so XYZ = geo · E cos θi · (X(f0 S) + m X((1−f0) S))
      with geo = G D / (4 cos θi cos θo): exact, two XYZ vectors per light.
    * cook-torrance (seed 004 eq. 11): separable the same way when the Beckmann slope m(λ)
      is the same at every wavelength; otherwise (as the demo paint, whose m varies by
      ~1 %) it takes the exact path.
    * anything else (the measured reference, :mod:`.measured`): exact path.

A printed pixel (seed 000 "Printing application") mixes the three inks by their filtered
coverage over the substrate: f = Σ_k cov_k f_k + (1 − Σ_k cov_k) f_substrate; an ink is
evaluated only where its coverage is > 0, and not at all for an object where it is 0
everywhere (counted in ``stats.counts["shade"]["inks_skipped"]``). The substrate is black
(None) or a dim normalised Phong term (seed 000 Figure 8, ref. 27):

    f_substrate(λ) = spectrum(λ) · (kd / π + ks (n + 2) / (2π) max(0, R_L·V)^n)

with R_L the mirror direction of the light and n the ``shininess``.

Sparkles (seed 004 §6.1, eq. 17; :mod:`gonio_cli.sparkle`): an object with a sparkle
texture gets an added lobe per light, only at the samples whose texel has a bit set,

    f_sparkle(λ) = C_s(λ) · f_mirror · (cos(α − θh))^e,    α = arccos(N·H),

    L_o += f_sparkle · E · S(λ) · cos θi    (docs/conventions.md: a BRDF, times E cos θi).

Seed 004 adds an intensity I_r = C_s (cos(α − θh))^e to the display colour; here it is a
BRDF-like lobe so that it follows the light's spectrum, irradiance and cos θi like the
paint. Its scale f_mirror is the ȳ-weighted mean of the object's own BRDF at the mirror
configuration at normal incidence (θi = θo = 0: the peak of the paint's highlight), so a
fully lit sparkle (α = θh) is about as bright as the mirror highlight.
C_s(λ) = Σc rgb_c B_c(λ) is ``sparkle_color`` as a reflectance through the Mallett–Yuksel
basis (docs/conventions.md, without the D65 factor: (1, 1, 1) is 1 at every λ). No environment
light on sparkles (a glint of the sky would need the texture in the lobe sums).

Glints (an object with ``glint_density``, :mod:`.glint_term`): per light, s (r − 1) times
the flake lobe of the paint, so a share s of the lobe is drawn as flakes (the sky's sun,
split off as a light, lights them too) and the mean over flake seeds is the smooth term.

Precision: the direct-light loop computes in the G-buffer's dtype (the pipeline: float32)
for the goniochromatic table kernel with α ≥ :data:`FLOAT32_MIN_ALPHA`, in float64 for
every other term (from the same float32 G-buffer rows), through reused scratch buffers
and component rows (3, n), and returns rows whose columns are contiguous.

Only what reaches the picture is computed: the pixels of each object, lit pixels per
light, inks with coverage, and no environment work without an environment
(:mod:`.environment`), no sparkle work without a sparkle texture.

The spectral kernels (the ``"table"`` forms above) and their registry are
:mod:`gonio_cli.render.kernels`; the direct term's block loop over pixels and lights
:mod:`gonio_cli.render.direct`; what covers an object :mod:`.surface`, the sparkle term
:mod:`.sparkle_term`, the glints :mod:`.glint_term`, an object's environment term
:func:`gonio_cli.render.env_model.surface_environment_xyz`. Here: :func:`shade_rows`,
which gives each object its terms and sums them.
"""


from __future__ import annotations

import time
from typing import Any, Sequence

import numpy as np

from ..errors import InputError
from ..names import SPECTRAL_PATHS, pick
from . import GBuffer, Light, Stats
from .direct import Pixels, direct_xyz, rows_buffer
from .env_model import surface_environment_xyz
from .glint_term import glint_xyz
from .kernels import Kernel, make_kernel, substrate_kernel, work_dtype, xyz_weights
from .sparkle_term import sparkle_xyz
from .surface import Surface, check_surface


def shade(gbuffer: GBuffer, surfaces: Sequence[Surface], lights: Sequence[Light],
          wavelength_nm, environment=None, spectral: str = "table",
          stats: Stats | None = None, visibility=None, env_visibility=None) -> np.ndarray:
    """XYZ of every pixel of the GBuffer as an (H, W, 3) float64 image (background 0):
    :func:`shade_rows` (its parameters), placed into the image."""
    rows = shade_rows(gbuffer, surfaces, lights, wavelength_nm, environment, spectral, stats,
                      visibility=visibility, env_visibility=env_visibility)
    h, w = gbuffer.object_id.shape
    if gbuffer.pixels is None:
        return rows.reshape(h, w, 3)
    image = np.zeros((h * w, 3))
    image[gbuffer.pixels] = rows
    return image.reshape(h, w, 3)


def shade_rows(gbuffer: GBuffer, surfaces: Sequence[Surface], lights: Sequence[Light],
               wavelength_nm, environment=None, spectral: str = "table",
               stats: Stats | None = None, dtype=np.float64,
               observer: np.ndarray | None = None, visibility=None,
               env_visibility=None) -> np.ndarray:
    """XYZ of every pixel of the GBuffer (docs/conventions.md: XYZ = Σλ L cmf / Σλ ȳ).

    Parameters
    ----------
    gbuffer : :class:`~gonio_cli.render.GBuffer` (H, W); ``object_id`` indexes ``surfaces``.
    surfaces : one :class:`Surface` per scene object.
    lights : point and directional :class:`~gonio_cli.render.Light`.
    wavelength_nm : (n_λ,) the working grid of the materials and light spectra.
    environment : :class:`gonio_cli.render.environment.Environment` or None; the surfaces
        then need ``lobes`` (seed 001 eqs. 7-9).
    spectral : "table" (fast forms, module docstring) or "exact" (41-wavelength sum).
    stats : :class:`~gonio_cli.render.Stats` to fill: ``time_s["shade"]``,
        ``time_s["shade.environment"]`` and ``counts["shade"]``.

    dtype : of the result (the pipeline: float32; the arithmetic of a block is float64
        or the G-buffer's dtype).
    observer : (n_λ, C) the channels' spectral weights, default cmf / Σ ȳ (XYZ, C = 3);
        columns of the identity give the radiance at C wavelengths (:func:`xyz_weights`).
    visibility : None (no shadows) or one entry per light: None (unshadowed) or (rows,)
        the fraction of the light that reaches each row's sample, in [0, 1]
        (:func:`gonio_cli.render.shadow.shadow_visibility`).
    env_visibility : None (no occlusion of the environment) or (rows,) the share of each
        row's diffuse environment irradiance the scene lets through, in [0, 1]
        (:func:`gonio_cli.render.occlusion.occlusion_visibility`), applied to the
        environment light of diffuse lobes.

    Returns
    -------
    (rows, 3) XYZ, one row per row of the G-buffer's attributes (compact: covered samples;
    dense: every pixel, background 0), in radiance units (a white f = 1/π under E = π
    shows Y = 1). Only covered rows are shaded.
    """
    start = time.perf_counter()
    pick(SPECTRAL_PATHS, spectral, "spectral path")
    sh = _Shading(np.asarray(wavelength_nm, dtype=float), spectral, observer)
    out = rows_buffer(gbuffer.rows, dtype, sh.channels)
    obj = gbuffer.row_object_id()
    flat = _flat_rows(gbuffer, lights, visibility, env_visibility)
    if obj.size and obj.max() >= len(surfaces):
        raise InputError(f"the GBuffer names object {int(obj.max())} but the scene has "
                         f"{len(surfaces)} surfaces")
    for k, surface in enumerate(surfaces):
        check_surface(surface, k, sh.wl)
        index = np.flatnonzero(obj == k)
        if index.size == 0:
            continue
        sh.counts["pixels"] += int(index.size)
        px = Pixels(flat, None if index.size == obj.size else index, index.size)
        whole = px.flat_index is None                     # the object covers every row
        obj_xyz = out if whole else rows_buffer(index.size, dtype, sh.channels)
        _object_xyz(sh, obj_xyz, surface, k, gbuffer, index, px, flat, lights, environment)
        if not whole:
            out[index] = obj_xyz                              # objects never share a pixel
    if stats is not None:
        stats.time_s["shade"] = time.perf_counter() - start
        if environment is not None:
            stats.time_s["shade.environment"] = sh.time_s["environment"]
        if "sparkle_pixels" in sh.counts:
            stats.time_s["shade.sparkle"] = sh.time_s["sparkle"]
        if "glint_samples" in sh.counts:
            stats.time_s["shade.glint"] = sh.time_s["glint"]
        stats.counts["shade"] = sh.counts
    return out


class _Shading:
    """What :func:`shade_rows` shares across objects: the grid ``wl``, the ``spectral``
    path, the channels' ``observer``, the light weights and kernels made once per light
    spectrum and material, the counts of ``stats.counts["shade"]`` and the sub-stages'
    times."""

    def __init__(self, wl: np.ndarray, spectral: str, observer: np.ndarray | None):
        self.wl, self.spectral, self.observer = wl, spectral, observer
        self.channels = 3 if observer is None else np.shape(observer)[1]
        self.counts: dict[str, Any] = {"spectral": spectral, "pixels": 0,
                                       "lit_pixel_lights": 0, "ink_pixels": {},
                                       "inks_skipped": 0, "table_sizes": [],
                                       "environment_pixels": 0}
        self.time_s = {"environment": 0.0, "sparkle": 0.0, "glint": 0.0}
        self._weights: dict[bytes, np.ndarray] = {}
        self._kernels: dict[tuple[int, bytes], Kernel] = {}

    def light_weights(self, light: Light) -> np.ndarray:
        """The (n_λ, C) weights of the light's spectrum (:func:`xyz_weights`), once each."""
        s = np.asarray(light.spectrum, dtype=float)
        if s.shape != self.wl.shape:
            raise InputError(f"light {light.name or ''} has {s.size} spectral samples, the "
                             f"render {self.wl.size}", fix="resample the spectrum onto the grid")
        key = s.tobytes()
        if key not in self._weights:
            self._weights[key] = xyz_weights(s, self.wl, self.observer)
        return self._weights[key]

    def kernel_of(self, material, light: Light, substrate: bool = False) -> Kernel:
        """The spectral kernel of ``material`` under ``light``, once per pair."""
        key = (id(material), np.asarray(light.spectrum, dtype=float).tobytes())
        if key not in self._kernels:
            weights = self.light_weights(light)
            self._kernels[key] = (substrate_kernel(material, weights) if substrate
                                  else make_kernel(material, weights, self.spectral))
            size = getattr(self._kernels[key], "table_size", None)
            if size is not None:
                self.counts["table_sizes"].append(int(size))
        return self._kernels[key]


def _flat_rows(gbuffer: GBuffer, lights: Sequence[Light], visibility,
               env_visibility) -> dict[str, np.ndarray | None]:
    """The G-buffer's attributes as rows (position, normal, view), with each shadowing
    light's visibility (``visibility{i}``) and the environment's (``env_visibility``)."""
    flat = {"position": (None if gbuffer.position is None
                         else gbuffer.position.reshape(-1, 3)),
            "normal": gbuffer.normal.reshape(-1, 3), "view": gbuffer.view.reshape(-1, 3)}
    if visibility is not None:
        if len(visibility) != len(lights):
            raise InputError(f"{len(visibility)} visibilities for {len(lights)} lights")
        for li, vis in enumerate(visibility):          # per light, (rows,) or None
            if vis is not None:
                flat[f"visibility{li}"] = np.asarray(vis).reshape(-1)
    if env_visibility is not None:
        flat["env_visibility"] = np.asarray(env_visibility).reshape(-1)
    if flat["position"] is None and any(L.kind == "point" for L in lights):
        raise InputError("point lights need the G-buffer's positions",
                         fix="rasterize with position=True")
    return flat


def _object_xyz(sh: _Shading, obj_xyz: np.ndarray, surface: Surface, k: int,
                gbuffer: GBuffer, index: np.ndarray, px: Pixels, flat: dict,
                lights: Sequence[Light], environment) -> None:
    """Add object ``k``'s light to its rows ``obj_xyz``: each term of f under the lights,
    weighted by its coverage, then its sparkles, glints and the environment."""
    terms, cov = _terms(sh.counts, surface, k, gbuffer, index, px)
    for material, is_substrate, weight, tp in terms:
        work = work_dtype(material, sh.spectral, gbuffer.normal.dtype, is_substrate)
        if weight is None and tp.sel is None:         # accumulate in place
            direct_xyz(material, is_substrate, tp, lights, sh.kernel_of, sh.counts, obj_xyz,
                       dtype=work, channels=sh.channels)
            continue
        acc = direct_xyz(material, is_substrate, tp, lights, sh.kernel_of, sh.counts,
                         dtype=work, channels=sh.channels)
        if weight is not None:
            acc *= weight[:, None]
        if tp.sel is None:
            obj_xyz += acc
        else:
            obj_xyz[tp.sel] += acc
    if surface.sparkle is not None:
        t0 = time.perf_counter()
        if "sparkle_pixels" not in sh.counts:
            sh.counts.update(sparkle_pixels=0, sparkle_lit_pixel_lights=0,
                             sparkle_minified_pixels=0)
        obj_xyz += sparkle_xyz(surface, k, gbuffer, index, flat, lights,
                               sh.light_weights, sh.wl, sh.counts, sh.channels)
        sh.time_s["sparkle"] += time.perf_counter() - t0
    if surface.glint is not None:
        t0 = time.perf_counter()
        if "glint_samples" not in sh.counts:
            sh.counts.update(glint_samples=0, glint_flakes=0, glint_glints=0)
        obj_xyz += glint_xyz(surface, f"object {k} ({surface.name})", index, flat,
                             lights, sh.light_weights, sh.wl, sh.counts, sh.channels)
        sh.time_s["glint"] += time.perf_counter() - t0
    if environment is not None:
        t0 = time.perf_counter()
        obj_xyz += _environment_term(environment, surface, k, px, cov, sh.wl, sh.observer)
        sh.counts["environment_pixels"] += int(index.size)
        sh.time_s["environment"] += time.perf_counter() - t0


def _terms(counts: dict, surface: Surface, k: int, gbuffer: GBuffer, index: np.ndarray,
           px: Pixels):
    """The terms of object ``k``'s f, each (material, is it the substrate, per-pixel
    weight or None, its :class:`~gonio_cli.render.direct.Pixels`), and the coverage of
    its inks ((n, 3), None unless printed): a printed object's inks where they cover
    (counted in ``counts``) and its substrate where bare, else its material."""
    if not surface.printed:
        return [(surface.material, False, None, px)], None
    if gbuffer.uv is None:
        raise InputError(f"object {k} is printed but the GBuffer has no uv",
                         fix="give the mesh texture coordinates")
    uv = gbuffer.uv.reshape(-1, 2)[index]
    fp = (np.zeros(index.size) if gbuffer.uv_footprint is None
          else gbuffer.uv_footprint.reshape(-1)[index])
    cov = np.clip(np.asarray(surface.coverage(uv, fp), dtype=float), 0.0, 1.0)
    terms: list[tuple[Any, bool, np.ndarray | None, Pixels]] = []
    for j, ink in enumerate(surface.inks):
        sel = cov[:, j] > 0
        n_sel = int(np.count_nonzero(sel))
        counts["ink_pixels"][f"{k}.{j}"] = n_sel
        if n_sel == 0:
            counts["inks_skipped"] += 1
            continue
        terms.append((ink, False, cov[sel, j], px.take(sel)))
    bare = np.clip(1.0 - cov.sum(axis=1), 0.0, 1.0)
    if surface.substrate is not None:
        sel = bare > 0
        if np.any(sel):
            terms.append((surface.substrate, True, bare[sel], px.take(sel)))
    return terms, cov


def _environment_term(environment, surface: Surface, k: int, px: Pixels,
                      cov: np.ndarray | None, wl: np.ndarray,
                      observer: np.ndarray | None = None) -> np.ndarray:
    """Environment light of one object's pixels (n, C) XYZ; printed: coverage-weighted
    (:func:`gonio_cli.render.env_model.surface_environment_xyz`)."""
    where = f"object {k}" + (f" ({surface.name})" if surface.name else "")
    vis = px.get("env_visibility") if "env_visibility" in px.flat else None
    return surface_environment_xyz(environment, surface, where, px.get("normal"),
                                   px.get("view"), cov, wl, observer, vis)
