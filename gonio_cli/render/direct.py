"""The direct-light term of the shading (:mod:`gonio_cli.render.shade`, docs/conventions.md):
one term of f (a material, an ink or the substrate) under point and directional lights,

    XYZ = Σ_lights f(ωi, ωo) · V E S cos θi,

per pixel, in blocks of :data:`BLOCK` pixels whose temporaries are reused scratch
buffers (:class:`~gonio_cli.render.kernels.Scratch`), with the spectral kernels of
:mod:`gonio_cli.render.kernels`. Here: where a light is (:func:`incident`), the pixels of
one object (:class:`Pixels`) and the block loop (:func:`direct_xyz`)."""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ..errors import InputError
from ..geometry import Cosines, cosines_from_dots_into
from . import Light
from .kernels import Kernel, Scratch

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


class Pixels:
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

    def take(self, sel: np.ndarray) -> "Pixels":
        return Pixels(self.flat, self.flat_index, self.size, sel)


def direct_xyz(material, is_substrate: bool, tp: Pixels, lights: Sequence[Light],
            kernel_of, counts: dict, acc: np.ndarray | None = None,
            dtype=np.float64, channels: int = 3) -> np.ndarray:
    """XYZ (n, 3) of one term of f (a material, an ink or the substrate) under the lights,
    added to ``acc`` (a new array if None: the (3, n) rows of :func:`rows_buffer`).

    Computed in ``dtype`` (:func:`work_dtype`) from the G-buffer's normal, view (and
    position) as (3, m) component rows, in blocks of :data:`BLOCK` pixels whose
    temporaries are :class:`Scratch` buffers reused by every block, so they stay in the
    CPU cache. Kernels with ``accumulate`` add into ``acc`` in place.
    """
    dtype = np.dtype(dtype)
    if acc is None:
        acc = rows_buffer(tp.size, dtype, channels)
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


def rows_buffer(n: int, dtype, channels: int = 3) -> np.ndarray:
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
