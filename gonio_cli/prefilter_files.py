"""``gonio prefilter`` as a library call, and its files: a lat-long HDR map in, the
prefiltered maps and ``index.json`` out, around the pure-array core
:mod:`gonio_cli.prefilter`.

:func:`run` reads the map (:func:`read_envmap`, which checks its texels), splits the sun off
if asked (:func:`split_sun`), checks the memory and prefilters it for every exponent (or
the chain of exponents the map's sharpness calls for); :func:`write` writes every map
(``prefiltered_E<E>.exr``, :func:`map_name`) and ``index.json``
(:class:`gonio_cli.schemas.PrefilterIndex`) through a temporary folder beside OUTDIR, moved
into it when the command succeeds, ``index.json`` last (the outputs' transaction,
:mod:`gonio_cli.outputs`). The shell :mod:`gonio_cli.commands.prefilter` parses the
options, declares the output folder and calls these.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from . import log, memory
from .artifact import image_metadata
from .envmap import chain_exponents
from .envsun import find_sun_region, split_sun as split_off_sun
from .errors import InputError
from .imageio import read_image, write_exr
from .outputs import folder_output
from .prefilter import PrefilterResult, memory_estimate, prefilter
from .prefilter.inputs import validate_exponents, validate_map
from .prefilter.methods import check_method
from .schemas import PrefilterIndex, write_prefilter_index

#: Digits of a non-integer exponent in its file name (``prefiltered_E12p5.exr``).
NAME_DIGITS = 6


def map_name(exponent: float) -> str:
    """File name of the map of exponent E: ``prefiltered_E64.exr``, ``prefiltered_E12p5.exr``."""
    if float(exponent).is_integer():
        tag = str(int(exponent))
    else:
        tag = np.format_float_positional(exponent, precision=NAME_DIGITS, unique=True,
                                         trim="-").replace(".", "p")
    return f"prefiltered_E{tag}.exr"


def read_envmap(envmap_path: Path, fix_invalid: bool = False):
    """The map's (H, W, 3) linear RGB and the number of texels replaced (``fix_invalid``:
    :func:`gonio_cli.prefilter.inputs.validate_map`); an 8-bit image is an InputError."""
    image = read_image(envmap_path)
    if not image.is_float:
        raise InputError(f"is a {image.format} image, not HDR", path=envmap_path,
                         fix="pass a linear EXR or HDR (RGBE) map")
    pixels = image.pixels
    if pixels.shape[2] == 4:  # RGBA: the alpha of an environment map is not light
        pixels = pixels[:, :, :3]
    return validate_map(pixels, fix_invalid=fix_invalid, path=envmap_path)


def sun_entry(sun) -> dict:
    """``index.json``'s ``sun`` of a :class:`gonio_cli.envsun.Sun` (units in the names)."""
    return {"direction": [float(x) for x in sun.direction],
            "irradiance_rgb": [float(x) for x in sun.irradiance_rgb],
            "angular_diameter_deg": float(sun.angular_diameter_deg),
            "solid_angle_sr": float(sun.solid_angle_sr), "texels": int(sun.texels),
            "flux_share": float(sun.flux_share), "fill_share": float(sun.fill_share)}


def split_sun(pixels: np.ndarray, envmap_path) -> tuple[np.ndarray, dict] | None:
    """(residual, index.json's sun entry) of :func:`gonio_cli.envsun.split_sun`, said on
    stderr; None, with a warning that says why, when the map has no sun."""
    residual, found = split_off_sun(pixels)
    if found is None:
        log.warn(f"{envmap_path}: no sun split off ({find_sun_region(pixels).reason}); "
                 "the map is prefiltered whole and casts no shadow")
        return None
    log.info(f"{envmap_path}: sun at theta {found.theta_deg:.1f} deg, phi "
             f"{found.phi_deg:.1f} deg, {found.angular_diameter_deg:.2f} deg across, "
             f"{found.flux_share:.0%} of the map's light, split off as a light")
    return residual.astype(np.float32), sun_entry(found)


# ------------------------------------------------------------------- the stage --

@dataclass(frozen=True)
class PrefilterOptions:
    """The options of ``gonio prefilter`` besides the exponents (their help is the
    shell's). ``chain``: the exponents 1, 2, 4, … up to the map's own sharpness
    (:func:`gonio_cli.envmap.chain_exponents`) instead of a list; ``lobes``: the
    ``gonio.lobes`` file a list was read from (recorded as an input)."""

    chain: bool = False
    sun: bool = False
    method: str = "auto"
    resolution: int | None = None
    fix_invalid: bool = False
    check: bool = True
    lobes: Path | None = None


@dataclass
class PrefilterRun:
    """What :func:`run` made: the maps (in increasing E) and their file names, the
    source's shape and texels replaced, the sun split off (``index.json``'s entry, or
    None), the artifact's inputs and parameters, and the time (s)."""

    results: list[PrefilterResult]
    names: list[str]
    shape: tuple[int, ...]
    replaced: int
    sun: dict | None
    inputs: list
    parameters: dict[str, Any]
    time_s: float

    def summary(self, output: Path) -> str:
        """The one line a run ends with; each map's size, method, error and time are in
        OUTDIR/index.json."""
        methods = "/".join(sorted({r.method for r in self.results}))
        exps = ", ".join(f"{r.exponent:g}" for r in self.results)
        worst = max(r.error_estimate for r in self.results)
        return (f"{output}: {len(self.results)} maps, E = {exps} ({methods}), spot-checked "
                f"error <= {worst:.2g}, {self.time_s:.2f} s (each map in "
                f"{output / 'index.json'})")


def check_options(options: PrefilterOptions) -> None:
    """Refuse a bad choice before anything is read or written."""
    check_method(options.method)


def run(envmap_path: str | os.PathLike, exponents: Sequence[float] | None = None,
        options: PrefilterOptions = PrefilterOptions()) -> PrefilterRun:
    """Prefilter an environment map for cosine lobes (seed 001 §5.1, eqs. 7-9).

    Parameters
    ----------
    envmap_path : path of a lat-long HDR map (EXR or HDR).
    exponents : the lobes' exponents (1 to 1e4; the diffuse map E = 1 is always made), or
        None with ``options.chain``.
    options : :class:`PrefilterOptions`.

    Raises
    ------
    GonioError
        A bad map, exponent or option, or a map too large for the memory.
    """
    check_options(options)
    if (exponents is None) != options.chain:
        raise InputError("give one of --chain, --exponents or --lobes",
                         fix="e.g. --chain (for any material) or --exponents 1,8,64")
    pixels, replaced = read_envmap(envmap_path, options.fix_invalid)
    sun_found = split_sun(pixels, envmap_path) if options.sun else None
    if sun_found is not None:
        pixels = sun_found[0]
    exps = chain_exponents(pixels.shape[0]) if options.chain else exponents
    exps = validate_exponents(exps, path=options.lobes)
    if replaced:
        log.warn(f"{envmap_path}: replaced {replaced} NaN, inf or negative texels "
                 "(negative → 0, NaN/inf → the mean of their row)")
    n_maps = len(set(exps) | {1.0})
    memory.check(memory_estimate(pixels.shape[0], pixels.shape[1], n_maps),
                 f"prefiltering a {pixels.shape[1]}x{pixels.shape[0]} map into {n_maps} maps",
                 path=envmap_path, fix="give a smaller map (or fewer --exponents)")
    start = time.perf_counter()
    results = prefilter(pixels, exps, method=options.method, resolution=options.resolution,
                        check=options.check, path=str(envmap_path))
    time_s = time.perf_counter() - start
    names = [map_name(r.exponent) for r in results]
    if len(set(names)) != len(names):
        raise InputError("two exponents round to the same file name",
                         fix="give exponents that differ in their first 6 digits")
    lobes = options.lobes
    parameters = {"exponents": exps, "lobes": str(lobes) if lobes else None,
                  "chain": options.chain, "sun": options.sun, "method": options.method,
                  "resolution": options.resolution, "fix_invalid": options.fix_invalid,
                  "check": options.check}
    return PrefilterRun(results, names, pixels.shape, replaced,
                        sun_found[1] if sun_found is not None else None,
                        [envmap_path] + ([lobes] if lobes else []), parameters, time_s)


def write(result: PrefilterRun, output: Path) -> None:
    """Write the maps and ``index.json`` of :func:`run` through a temporary folder beside
    the folder ``output``."""
    inputs, parameters, shape = result.inputs, result.parameters, result.shape
    # staged as a whole, moved into OUTDIR when the command succeeds, index.json last
    with folder_output(output, merge=True) as tmp:
        base = image_metadata(PrefilterIndex.SCHEMA, PrefilterIndex.VERSION, inputs=inputs,
                              parameters=parameters)
        entries = []
        for r, name in zip(result.results, result.names):
            meta = {**base, "exponent": r.exponent, "method": r.method,
                    "error_estimate": r.error_estimate, "time_s": r.time_s,
                    "layout": "lat-long, Mitsuba 3 envmap (docs/conventions.md)"}
            # uncompressed: a renderer reads every level of a chain on each run, and
            # float maps of a photographed sky barely deflate (a 1024x512 level: 6.15 MB
            # stored, 6.12 MB zipped; read in 6 ms instead of 40)
            write_exr(tmp / name, r.pixels, meta, compression="none")
            entries.append({"exponent": r.exponent, "path": name, "width": r.width,
                            "height": r.height, "method": r.method,
                            "error_estimate": r.error_estimate,
                            "checked_texels": r.checked_texels,
                            "working_width": r.working_shape[1],
                            "working_height": r.working_shape[0],
                            "time_s": r.time_s})
        index = PrefilterIndex(
            source={"width": int(shape[1]), "height": int(shape[0]),
                    "channels": int(shape[2]),
                    "invalid_texels_replaced": int(result.replaced)},
            diffuse=result.names[0], maps=entries, sun=result.sun)
        # checked against the reader's definition before writing (gonio_cli.schemas)
        write_prefilter_index(tmp / "index.json", index, inputs=inputs,
                              parameters=parameters, time_s=result.time_s)
