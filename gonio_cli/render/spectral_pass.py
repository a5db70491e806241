"""The spectral image (``gonio render --spectral-exr``): a second shading pass over the
same G-buffer with one channel per wavelength (docs/render.md, "Spectral images")."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError
from ..spectra import rgb_spectral_basis
from .budget import bands_per_pass
from .resolve import resolve
from .scene_types import Scene
from .shade import shade_rows


def check_spectral_lobes(scene: Scene, surfaces: list) -> None:
    """A spectral image under an environment needs spectral lobe weights: weights fitted
    in XYZ channels have no spectrum (refused before rendering, naming the file)."""
    if scene.environment is None:
        return
    for o, s in zip(scene.objects, surfaces):
        lobes = s.lobes if isinstance(s.lobes, list) else [s.lobes]
        paths = o.lobes if isinstance(o.lobes, list) else [o.lobes]
        for path, lob in zip(paths, lobes):
            if lob is not None and lob.channel_kind != "spectral":
                raise InputError(f"[[object]] {o.index + 1} lobes = {Path(path).name}: "
                                 f"weights fitted in {lob.channel_kind} channels have no "
                                 "spectrum for --spectral-exr", path=scene.display,
                                 fix="fit them with gonio lobes fit --channels spectral "
                                     "(its default), or leave out --spectral-exr")


def spectral_radiance(gbuffer, surfaces: list, scene: Scene, lights: list, environment=None,
                      visibility=None, background: np.ndarray | None = None,
                      env_visibility=None) -> np.ndarray:
    """The spectral radiance image (H, W, n_λ) float32 on the working grid, under
    ``lights`` (the frame's: :func:`.env_scene.shading_lights`) with the frame's
    ``background`` (linear sRGB, :func:`.env_scene.background_rgb`) or None.

    The shading (:func:`gonio_cli.render.shade.shade_rows`) is linear in its channels'
    spectral weights, so with columns of the identity as the observer instead of
    cmf / Σ ȳ it returns L(λ) at those wavelengths: as few passes over the same G-buffer
    as memory allows (:func:`bands_per_pass`; one for the demo scenes), each
    box-filtered as the XYZ (:func:`resolve`). Every model keeps its spectral path
    (``--spectral``): the goniochromatic table then holds one column per wavelength (a
    per-band table, same tolerance), the others are exact per wavelength. Σλ L cmf / Σ ȳ
    of the result is the frame's XYZ to the tables' tolerance (1e-5 relative), with the
    same shadows (``visibility``, :func:`gonio_cli.render.shadow.shadow_visibility`) and
    occlusion of the environment (``env_visibility``, :mod:`.occlusion`).
    Background pixels hold the background's spectrum (docs/conventions.md's RGB →
    spectrum) times the uncovered fraction, as the colour image does.
    """
    wl = np.asarray(scene.grid_nm, dtype=float)
    n, ssaa, cam = wl.size, scene.output.ssaa, scene.camera
    out = np.empty((cam.height, cam.width, n), np.float32)
    identity = np.eye(n)
    step = bands_per_pass(gbuffer.rows, n)
    for start in range(0, n, step):
        rows = shade_rows(gbuffer, surfaces, lights, wl, environment=environment,
                          spectral=scene.output.spectral, dtype=np.float32,
                          observer=identity[:, start:start + step], visibility=visibility,
                          env_visibility=env_visibility)
        band, coverage = resolve(rows, gbuffer.pixels, gbuffer.object_id, ssaa, scene.display)
        del rows
        out[..., start:start + step] = band
    if background is not None:
        out += ((1.0 - coverage)[..., None]
                * (background @ rgb_spectral_basis(wl).T)).astype(np.float32)
    return out
