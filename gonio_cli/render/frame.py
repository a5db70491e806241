"""A rendered frame and the clock of its stages: :class:`Frame` (what
:func:`gonio_cli.render.pipeline.render_scene` returns and :mod:`.output` writes),
:class:`Stage` (a stage's wall time into :class:`~gonio_cli.render.Stats`) and the frame
time (:data:`FRAME_STAGES`, :func:`frame_time`). Below both the pipeline and the writers,
so neither imports the other."""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from . import Stats

#: Stages whose sum is the frame time (acceptance: rasterize, shadows, shade, tone map).
FRAME_STAGES = ("rasterize", "shadows", "occlusion", "shade", "downsample", "tonemap")


@dataclass
class Frame:
    """A rendered frame: ``linear`` (H, W, 3) float32 linear sRGB after the display's
    chromatic adaptation (``[output] adapt``: what the PNG shows; the colour EXR is
    :func:`.output.exr_pixels`, by default without adaptation),
    ``display`` (H, W, 3) uint8 sRGB-encoded after exposure and tone map (the PNG),
    ``xyz`` (H, W, 3) float64 CIE XYZ (box-filtered), ``coverage`` (H, W) the fraction of
    each pixel's samples that hit an object, ``out_of_gamut`` (H, W) bool the pixels whose
    colour lies outside sRGB (a negative linear channel, shown clipped to 0), ``spectra``
    (H, W, n_λ) float32 the spectral radiance on the working grid (box-filtered like
    ``xyz``, whose Σλ L cmf / Σ ȳ it is), only when asked for; ``background`` the linear
    sRGB behind the objects ((3,) or (H, W, 3),
    :func:`gonio_cli.render.env_scene.background_rgb`) or None."""

    linear: np.ndarray
    display: np.ndarray
    xyz_source: np.ndarray | Callable[[], np.ndarray] = field(repr=False)
    coverage: np.ndarray
    out_of_gamut: np.ndarray | None = None
    spectra: np.ndarray | None = None
    background: np.ndarray | None = None

    @functools.cached_property
    def xyz(self) -> np.ndarray:
        """(H, W, 3) float64 CIE XYZ; made on first use where
        :func:`gonio_cli.render.resolve.resolve` deferred it."""
        return self.xyz_source() if callable(self.xyz_source) else self.xyz_source


class Stage:
    """``with Stage(stats, "name"):`` adds the wall time to ``stats.time_s["name"]``."""

    def __init__(self, stats: Stats, name: str):
        self.stats, self.name = stats, name

    def __enter__(self):
        self.t0 = time.perf_counter()
        return self

    def __exit__(self, *exc):
        self.stats.time_s[self.name] = (self.stats.time_s.get(self.name, 0.0)
                                        + time.perf_counter() - self.t0)
        return False


def frame_time(stats: Stats) -> float:
    """The frame time (s): the sum of the :data:`FRAME_STAGES` that ran."""
    return float(sum(stats.time_s.get(k, 0.0) for k in FRAME_STAGES))
