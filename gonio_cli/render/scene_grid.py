"""The working spectral grid of a render (:func:`choose_grid`): the scene's, or the
materials' common range at its step when they do not cover it (one warning), or an error
when they share none."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..spectra import WAVELENGTH_TOL_NM, covers, grid_spec
from .scene_types import SceneObject


def _wavelength_range(path: Path) -> tuple[float, float] | None:
    """(min, max) of a material's or measurement's ``wavelength_nm``, or None if the file
    cannot be read so (the full read of the pipeline then names the problem)."""
    try:
        w = np.asarray(json.loads(path.read_text(encoding="utf-8"))["wavelength_nm"],
                       dtype=float)
    except (OSError, ValueError, KeyError, TypeError, IndexError):
        return None
    if w.ndim != 1 or w.size == 0 or not np.all(np.isfinite(w)):
        return None
    return float(w.min()), float(w.max())


def spectral_ranges(objects: list[SceneObject]) -> list[tuple[str, float, float]]:
    """(file name, min nm, max nm) of every material, ink and measured reference of the
    scene's objects, each file once (only ``wavelength_nm`` is looked at here)."""
    seen: dict[Path, tuple[str, float, float] | None] = {}
    for o in objects:
        for p in (o.material, o.measured, *(o.inks or [])):
            if p is not None and p not in seen:
                r = _wavelength_range(p)
                seen[p] = None if r is None else (p.name, *r)
    return [r for r in seen.values() if r is not None]


#: What to do with materials that share no spectral range.
REFIT_FIX = "re-ingest and refit them on one grid (gonio ingest --grid-nm)"


def choose_grid(grid_nm: np.ndarray, ranges, where: str = "") -> tuple[np.ndarray, str | None]:
    """The working grid of a scene whose materials span ``ranges``.

    Parameters
    ----------
    grid_nm : (n_λ,) the scene's grid (``[output] grid_nm`` or its default), evenly spaced.
    ranges : [(name, min nm, max nm)] of the materials (:func:`spectral_ranges`).
    where : the scene file as the user named it, for the messages.

    Returns
    -------
    (grid, note) : ``grid_nm`` itself and None when every material covers it (each is
    then resampled onto it); otherwise the samples of ``grid_nm`` inside every material's
    range (its step, a subset of its samples), and the one-line warning that says so.

    Raises
    ------
    InputError : the materials share less than one step of the grid.
    """
    g = np.asarray(grid_nm, dtype=float)
    short = [r for r in ranges if not covers([r[1], r[2]], g)]
    if not short:
        return g, None
    spans = ", ".join(f"{name} {a:g}-{b:g} nm" for name, a, b in ranges)
    lo, hi = max(r[1] for r in ranges), min(r[2] for r in ranges)
    if hi < lo:
        raise InputError(f"the materials share no range ({spans})", path=where or None,
                         fix=REFIT_FIX)
    step = float(g[1] - g[0])
    tol = WAVELENGTH_TOL_NM / step
    # the scene grid's samples inside [lo, hi]: never beyond the scene's own range
    k0 = max(0, math.ceil((lo - g[0]) / step - tol))
    k1 = min(g.size - 1, math.floor((hi - g[0]) / step + tol))
    if k1 <= k0:
        raise InputError(f"the materials' common range {lo:g}-{hi:g} nm holds less than one "
                         f"{step:g} nm step of the scene's grid {g[0]:g}-{g[-1]:g} nm "
                         f"({spans})", path=where or None, fix=REFIT_FIX)
    chosen = g[0] + step * np.arange(k0, k1 + 1)
    named = ", ".join(f"{name} {a:g}-{b:g} nm" for name, a, b in short[:3]) + (
        ", ..." if len(short) > 3 else "")
    note = (f"{where + ': ' if where else ''}not every material covers the scene's grid "
            f"{g[0]:g}-{g[-1]:g} nm ({named}): rendering on their common range "
            f"{grid_spec(chosen)} nm (choose another with --grid-nm)")
    return chosen, note
