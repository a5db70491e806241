"""The files of ``gonio prefilter``: the environment map it reads and the maps and
``index.json`` it writes, around the pure-array core :mod:`gonio_cli.prefilter`.

:func:`read_envmap` reads a lat-long HDR map (EXR or HDR) and checks its texels;
:func:`write_maps` writes every map (``prefiltered_E<E>.exr``, :func:`map_name`) and
``index.json`` (:class:`gonio_cli.schemas.PrefilterIndex`) through a temporary folder
beside OUTDIR, moved into it when the command succeeds, ``index.json`` last (the outputs'
transaction, :mod:`gonio_cli.outputs`).
"""

from __future__ import annotations

from pathlib import Path

#: Digits of a non-integer exponent in its file name (``prefiltered_E12p5.exr``).
NAME_DIGITS = 6


def map_name(exponent: float) -> str:
    """File name of the map of exponent E: ``prefiltered_E64.exr``, ``prefiltered_E12p5.exr``."""
    import numpy as np

    if float(exponent).is_integer():
        tag = str(int(exponent))
    else:
        tag = np.format_float_positional(exponent, precision=NAME_DIGITS, unique=True,
                                         trim="-").replace(".", "p")
    return f"prefiltered_E{tag}.exr"


def read_envmap(envmap_path: Path, fix_invalid: bool = False):
    """The map's (H, W, 3) linear RGB and the number of texels replaced (``fix_invalid``:
    :func:`gonio_cli.prefilter.validate_map`); an 8-bit image is an InputError."""
    from .errors import InputError
    from .imageio import read_image
    from .prefilter.inputs import validate_map

    image = read_image(envmap_path)
    if not image.is_float:
        raise InputError(f"is a {image.format} image, not HDR", path=envmap_path,
                         fix="pass a linear EXR or HDR (RGBE) map")
    pixels = image.pixels
    if pixels.shape[2] == 4:  # RGBA: the alpha of an environment map is not light
        pixels = pixels[:, :, :3]
    return validate_map(pixels, fix_invalid=fix_invalid, path=envmap_path)


def write_maps(output: Path, envmap_path: Path, lobes, shape, results, names, parameters,
               replaced: int, time_s: float, sun: dict | None = None) -> None:
    """Write the maps and index.json through a temporary folder beside OUTDIR; ``sun``:
    the sun split off the map (:func:`sun_entry`), or None."""
    from .artifact import image_metadata
    from .imageio import write_exr
    from .outputs import folder_output
    from .schemas import PrefilterIndex, write_prefilter_index

    # staged as a whole, moved into OUTDIR when the command succeeds, index.json last
    with folder_output(output, merge=True) as tmp:
        inputs = [envmap_path] + ([lobes] if lobes else [])
        base = image_metadata(PrefilterIndex.SCHEMA, PrefilterIndex.VERSION, inputs=inputs,
                              parameters=parameters)
        entries = []
        for r, name in zip(results, names):
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
                    "channels": int(shape[2]), "invalid_texels_replaced": int(replaced)},
            diffuse=names[0], maps=entries, sun=sun)
        # checked against the reader's definition before writing (gonio_cli.schemas)
        write_prefilter_index(tmp / "index.json", index, inputs=inputs,
                              parameters=parameters, time_s=time_s)


def sun_entry(sun) -> dict:
    """``index.json``'s ``sun`` of a :class:`gonio_cli.envsun.Sun` (units in the names)."""
    return {"direction": [float(x) for x in sun.direction],
            "irradiance_rgb": [float(x) for x in sun.irradiance_rgb],
            "angular_diameter_deg": float(sun.angular_diameter_deg),
            "solid_angle_sr": float(sun.solid_angle_sr), "texels": int(sun.texels),
            "flux_share": float(sun.flux_share), "fill_share": float(sun.fill_share)}
