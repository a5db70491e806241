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
:mod:`gonio_cli.render.kernels`, re-exported here; what covers an object is
:mod:`.surface`, the sparkle term :mod:`.sparkle_term`, an object's environment term
:func:`gonio_cli.render.env_model.surface_environment_xyz`. Here: the lights and the
direct term, the one per-pixel loop of :func:`shade_rows`.
"""

from __future__ import annotations

import time
from typing import Any, Sequence

import numpy as np

from ..errors import InputError
from ..geometry import Cosines, cosines_from_dots_into
from . import GBuffer, Light, Stats
from .surface import Surface, check_surface
# The spectral kernels and their registry (gonio_cli.render.kernels), importable from here.
from .kernels import (EXACT_BLOCK, FLOAT32_MIN_ALPHA, SINGLE_PRECISION, TABLE_KERNELS,
                      TABLE_MAX_SIZE, TABLE_MIN_SIZE, TABLE_REL_TOL, Directions, Kernel,
                      Scratch, TableLookup, goniochromatic_table, make_kernel,
                      substrate_kernel, table_lookup, work_dtype, xyz_weights)

#: The spectral paths of :func:`shade` (STYLE 3: a registry, named in errors).
from ..names import SPECTRAL_PATHS, pick  # noqa: E402  (the names, spelled once)

#: Pixels per block of the direct-light loop: its ~16 reused scratch arrays of 16 384
#: float32 (1 MB; 2 MB in float64) stay in a typical L2 cache, whole-image arrays (262k
#: pixels, 1 M at ssaa 2) do not, and a block's ~60 array operations amortise the ~1 µs
#: Python cost of each (measured on the 512² sphere: 8192 and 32 768 are ~10 % slower).
BLOCK = 16384

#: A point light closer than this (scene units) to a shaded point is treated as at this
#: distance, so E = I / d² stays finite on a surface that touches the light.
MIN_LIGHT_DISTANCE = 1e-6

# -------------------------------------------------------------------------------- lights --

def incident(light: Light, position: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """ωi towards the light and the irradiance at normal incidence E per pixel.

    Directional: ωi (3,) the unit ``direction`` (the same for every pixel) and
    E = ``irradiance`` (a scalar array); point: ωi (n, 3) and E = I / d² (n,)
    (docs/conventions.md), d floored at :data:`MIN_LIGHT_DISTANCE`. ``position``: (n, 3).
    """
    if light.kind == "directional":
        d = np.asarray(light.direction, dtype=float)
        norm = np.linalg.norm(d)
        if not (np.isfinite(norm) and norm > 0):
            raise InputError(f"light {light.name or ''} has direction {d.tolist()}, not a "
                             "non-zero vector")
        return d / norm, np.asarray(float(light.irradiance))
    if light.kind == "point":
        d = np.asarray(light.position, dtype=float) - position
        dist2 = np.maximum(np.einsum("ij,ij->i", d, d), MIN_LIGHT_DISTANCE ** 2)
        return d / np.sqrt(dist2)[:, None], float(light.intensity) / dist2
    raise InputError(f"light kind {light.kind!r} is unknown", fix="use directional or point")


# ------------------------------------------------------------- per-pixel forms in place --
#
# The direct-light loop evaluates per pixel and light seed 000 eq. 1 (the half-vector
# cosines from three dot products), eq. 6 (the argument of the goniochromatic exponent)
# and eq. 3 (GGX D). :mod:`gonio_cli.geometry` and :mod:`gonio_cli.brdf` hold them for the
# fits: float64 whatever comes in, fresh temporaries, log forms for α down to 1e-150. The
# ``*_into`` forms the loop uses are the same expressions in the dtype of their inputs
# (float32 on the render's G-buffer) written into reused buffers (``Scratch``, in
# :mod:`.kernels`) — measured 6× faster on a 512² frame — and tests/test_render_shade.py
# checks them against the shared functions.


# --------------------------------------------------------------------------------- shade --

class _Pixels:
    """Some pixels of one object: ``sel`` (n_obj,) bool or None (all of them).

    ``flat_index`` (n,) indexes the flattened GBuffer (None: the object covers the whole
    image, so its arrays are views). :meth:`get` gathers a whole array (cached, for the
    environment term); :meth:`block` gathers one block for the direct-light loop, so the
    gather itself runs in cache.
    """

    def __init__(self, flat: dict, index: np.ndarray | None, size: int,
                 sel: np.ndarray | None = None):
        self.flat, self.sel = flat, sel
        self.flat_index = index if sel is None else index[sel] if index is not None \
            else np.flatnonzero(sel)
        self.size = size if sel is None else int(np.count_nonzero(sel))
        self._cache: dict[str, np.ndarray] = {}

    def block(self, name: str, b: slice) -> np.ndarray:
        a = self.flat[name]
        return a[b] if self.flat_index is None else a[self.flat_index[b]]

    def block_rows(self, name: str, b: slice, dtype) -> np.ndarray:
        """One block of an attribute as (c, m) contiguous component rows in ``dtype``: a
        view when the G-buffer stores it so (compact rows from the rasterizer) and the
        object covers every row, else one gather or copy."""
        t = self.flat[name].T                                 # (c, rows)
        rows = t[:, b] if self.flat_index is None else t[:, self.flat_index[b]]
        return np.ascontiguousarray(rows, dtype=dtype)

    def get(self, name: str) -> np.ndarray:
        if name not in self._cache:
            self._cache[name] = self.block(name, slice(None))
        return self._cache[name]

    def take(self, sel: np.ndarray) -> "_Pixels":
        return _Pixels(self.flat, self.flat_index, self.size, sel)


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
    wl = np.asarray(wavelength_nm, dtype=float)
    channels = 3 if observer is None else np.shape(observer)[1]
    out = _rows_buffer(gbuffer.rows, dtype, channels)
    counts: dict[str, Any] = {"spectral": spectral, "pixels": 0, "lit_pixel_lights": 0,
                              "ink_pixels": {}, "inks_skipped": 0, "table_sizes": [],
                              "environment_pixels": 0}
    env_time = 0.0
    sparkle_time = 0.0
    glint_time = 0.0
    weights_of: dict[bytes, np.ndarray] = {}

    def light_weights(light: Light) -> np.ndarray:
        s = np.asarray(light.spectrum, dtype=float)
        if s.shape != wl.shape:
            raise InputError(f"light {light.name or ''} has {s.size} spectral samples, the "
                             f"render {wl.size}", fix="resample the spectrum onto the grid")
        key = s.tobytes()
        if key not in weights_of:
            weights_of[key] = xyz_weights(s, wl, observer)
        return weights_of[key]

    kernels: dict[tuple[int, bytes], Kernel] = {}

    def kernel_of(material, light: Light, substrate: bool = False) -> Kernel:
        key = (id(material), np.asarray(light.spectrum, dtype=float).tobytes())
        if key not in kernels:
            weights = light_weights(light)
            kernels[key] = (substrate_kernel(material, weights) if substrate
                            else make_kernel(material, weights, spectral))
            size = getattr(kernels[key], "table_size", None)
            if size is not None:
                counts["table_sizes"].append(int(size))
        return kernels[key]

    obj = gbuffer.row_object_id()
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
    n_objects = len(surfaces)
    if obj.size and obj.max() >= n_objects:
        raise InputError(f"the GBuffer names object {int(obj.max())} but the scene has "
                         f"{n_objects} surfaces")
    for k, surface in enumerate(surfaces):
        check_surface(surface, k, wl)
        index = np.flatnonzero(obj == k)
        if index.size == 0:
            continue
        counts["pixels"] += int(index.size)
        px = _Pixels(flat, None if index.size == obj.size else index, index.size)
        cov = None

        # (material, is it the substrate, per-pixel weight or None, its pixels) per term
        terms: list[tuple[Any, bool, np.ndarray | None, _Pixels]] = []
        if surface.printed:
            if gbuffer.uv is None:
                raise InputError(f"object {k} is printed but the GBuffer has no uv",
                                 fix="give the mesh texture coordinates")
            uv = gbuffer.uv.reshape(-1, 2)[index]
            fp = (np.zeros(index.size) if gbuffer.uv_footprint is None
                  else gbuffer.uv_footprint.reshape(-1)[index])
            cov = np.clip(np.asarray(surface.coverage(uv, fp), dtype=float), 0.0, 1.0)
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
        else:
            terms.append((surface.material, False, None, px))

        whole = px.flat_index is None                     # the object covers every row
        obj_xyz = out if whole else _rows_buffer(index.size, dtype, channels)
        for material, is_substrate, weight, tp in terms:
            work = work_dtype(material, spectral, gbuffer.normal.dtype, is_substrate)
            if weight is None and tp.sel is None:         # accumulate in place
                _direct(material, is_substrate, tp, lights, kernel_of, counts, obj_xyz,
                        dtype=work, channels=channels)
                continue
            acc = _direct(material, is_substrate, tp, lights, kernel_of, counts, dtype=work,
                          channels=channels)
            if weight is not None:
                acc *= weight[:, None]
            if tp.sel is None:
                obj_xyz += acc
            else:
                obj_xyz[tp.sel] += acc

        if surface.sparkle is not None:
            from .sparkle_term import sparkle_xyz

            t0 = time.perf_counter()
            if "sparkle_pixels" not in counts:
                counts.update(sparkle_pixels=0, sparkle_lit_pixel_lights=0,
                              sparkle_minified_pixels=0)
            obj_xyz += sparkle_xyz(surface, k, gbuffer, index, flat, lights,
                                   light_weights, wl, counts, channels)
            sparkle_time += time.perf_counter() - t0

        if surface.glint is not None:
            from .glint_term import glint_xyz

            t0 = time.perf_counter()
            if "glint_samples" not in counts:
                counts.update(glint_samples=0, glint_flakes=0, glint_glints=0)
            obj_xyz += glint_xyz(surface, f"object {k} ({surface.name})", index, flat,
                                 lights, light_weights, wl, counts, channels)
            glint_time += time.perf_counter() - t0

        if environment is not None:
            t0 = time.perf_counter()
            obj_xyz += _environment_term(environment, surface, k, px, cov, wl, observer)
            counts["environment_pixels"] += int(index.size)
            env_time += time.perf_counter() - t0
        if not whole:
            out[index] = obj_xyz                              # objects never share a pixel

    if stats is not None:
        stats.time_s["shade"] = time.perf_counter() - start
        if environment is not None:
            stats.time_s["shade.environment"] = env_time
        if "sparkle_pixels" in counts:
            stats.time_s["shade.sparkle"] = sparkle_time
        if "glint_samples" in counts:
            stats.time_s["shade.glint"] = glint_time
        stats.counts["shade"] = counts
    return out


def _direct(material, is_substrate: bool, tp: _Pixels, lights: Sequence[Light],
            kernel_of, counts: dict, acc: np.ndarray | None = None,
            dtype=np.float64, channels: int = 3) -> np.ndarray:
    """XYZ (n, 3) of one term of f (a material, an ink or the substrate) under the lights,
    added to ``acc`` (a new array if None: the (3, n) rows of :func:`_rows_buffer`).

    Computed in ``dtype`` (:func:`work_dtype`) from the G-buffer's normal, view (and
    position) as (3, m) component rows, in blocks of :data:`BLOCK` pixels whose
    temporaries are :class:`Scratch` buffers reused by every block, so they stay in the
    CPU cache. Kernels with ``accumulate`` add into ``acc`` in place.
    """
    dtype = np.dtype(dtype)
    if acc is None:
        acc = _rows_buffer(tp.size, dtype, channels)
    acc_t = acc.T                                             # (3, n): contiguous rows
    scratch = Scratch(dtype, min(BLOCK, tp.size))
    point = any(L.kind == "point" for L in lights)
    light_kernels: dict[int, Kernel] = {}     # per light, made at its first lit pixel
    for start in range(0, tp.size, BLOCK):
        b = slice(start, start + BLOCK)
        n_b, v_b = tp.block_rows("normal", b, dtype), tp.block_rows("view", b, dtype)
        m = n_b.shape[1]
        co_b = _dot_rows(n_b, v_b, scratch("dot_o", m), scratch)
        seen = np.greater(co_b, 0, out=scratch("seen", m))  # 1 where N·ωo > 0, else 0
        p_b = tp.block_rows("position", b, np.float64) if point else None
        for li, light in enumerate(lights):
            wi, e = incident(light, None if p_b is None else p_b.T)
            if wi.ndim == 1:                                  # directional: one ωi
                wi_b = wi.astype(dtype)
                cos_i = np.dot(wi_b, n_b, out=scratch("dot_i", m))
                cos_io = np.dot(wi_b, v_b, out=scratch("dot_io", m))
                e = dtype.type(e)
            else:                                             # point: ωi per pixel
                wi_b = np.ascontiguousarray(wi.T, dtype)
                cos_i = _dot_rows(n_b, wi_b, scratch("dot_i", m), scratch)
                cos_io = _dot_rows(v_b, wi_b, scratch("dot_io", m), scratch)
                e = e.astype(dtype)
            # E cos θi where lit (N·ωi > 0) and seen (N·ωo > 0), else 0 (fmax: NaN → 0)
            scale = np.fmax(cos_i, 0, out=scratch("scale", m))
            scale *= e
            scale *= seen
            if f"visibility{li}" in tp.flat:                  # shadows: V E cos θi
                scale *= tp.block(f"visibility{li}", b)
            lit = np.greater(scale, 0, out=scratch("lit", m, np.bool_))
            n_lit = int(np.count_nonzero(lit))
            counts["lit_pixel_lights"] += n_lit
            if n_lit == 0:
                continue
            kernel = light_kernels.get(li)
            if kernel is None:
                kernel = light_kernels[li] = kernel_of(material, light, is_substrate)
            cos = cosines_from_dots_into(cos_i, co_b, cos_io, scratch,
                                cos_d=getattr(kernel, "needs_cos_d", True))
            accumulate = getattr(kernel, "accumulate", None)
            if accumulate is not None:
                accumulate(cos, scale, acc_t[:, b], scratch)
                continue

            def directions(sel=None, wi=wi_b, n_b=n_b, v_b=v_b):
                w = np.broadcast_to(wi.T, n_b.T.shape) if wi.ndim == 2 else \
                    np.broadcast_to(wi, n_b.T.shape)
                if sel is None:
                    return w, v_b.T, n_b.T
                return w[sel], v_b.T[sel], n_b.T[sel]

            if kernel.cheap or n_lit == m:
                acc_t[:, b] += kernel(cos, scale, directions).T
            else:
                acc[b][lit] += kernel(Cosines(*(a[lit] for a in cos)), scale[lit],
                                      lambda lit=lit, d=directions: d(lit))
    return acc


def _rows_buffer(n: int, dtype, channels: int = 3) -> np.ndarray:
    """Zeros (n, channels) whose columns are contiguous: the transpose of a (channels, n)
    array, so per-channel accumulation runs on contiguous rows (``.T`` gives them back)."""
    return np.zeros((channels, n), dtype).T


def _dot_rows(a: np.ndarray, b: np.ndarray, out: np.ndarray, scratch) -> np.ndarray:
    """Σ_k a[k] b[k] of (3, m) component rows into ``out`` (m,)."""
    tmp = scratch("dot_tmp", a.shape[1])
    np.multiply(a[0], b[0], out=out)
    for k in (1, 2):
        np.multiply(a[k], b[k], out=tmp)
        out += tmp
    return out


def _environment_term(environment, surface: Surface, k: int, px: _Pixels,
                      cov: np.ndarray | None, wl: np.ndarray,
                      observer: np.ndarray | None = None) -> np.ndarray:
    """Environment light of one object's pixels (n, C) XYZ; printed: coverage-weighted
    (:func:`gonio_cli.render.env_model.surface_environment_xyz`)."""
    from .env_model import surface_environment_xyz

    where = f"object {k}" + (f" ({surface.name})" if surface.name else "")
    vis = px.get("env_visibility") if "env_visibility" in px.flat else None
    return surface_environment_xyz(environment, surface, where, px.get("normal"),
                                   px.get("view"), cov, wl, observer, vis)
