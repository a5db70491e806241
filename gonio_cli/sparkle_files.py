"""The files of ``gonio sparkle``: photographs in, the packed sparkle texture (a PNG with
its metadata) out, around the pure-array core :mod:`gonio_cli.sparkle` (seed 004 §6,
eqs. 15–16). :func:`make_texture` is the stage as a library call: the typer shell
(:mod:`gonio_cli.commands.sparkle`) parses the options and calls it."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Sequence

from . import log
from .artifact import image_metadata
from .errors import InputError
from .imageio import read_image, write_png
from .numbers import NumberList
from .outputs import declare
from .sparkle import (N_BITS, TEXTURE_SCHEMA, TEXTURE_VERSION, TextureResult, bit_order,
                      build_texture, get_rule, theta_h_deg)


#: ``--theta-i-deg``: the photos' angles of incidence, in the photos' order.
THETA_I_DEG = NumberList("--theta-i-deg", "10,20,30", unit="deg")


def make_texture(photos: Sequence[str | os.PathLike], output: str | os.PathLike,
                 theta_i_deg: Sequence[float] | str, rule: str = "mad",
                 parameter: float | None = None) -> TextureResult:
    """Build the sparkle texture from ``photos`` and write it to ``output`` (a PNG).

    Parameters
    ----------
    photos : the photographs, one per angle of incidence, the same size (at most
        :data:`~gonio_cli.sparkle.N_BITS`).
    output : the texture's PNG (8 bits, eq. 16), with the angles of its bits, the rule and
        its thresholds in its metadata (``gonio.sparkle-texture``).
    theta_i_deg : each photo's angle of incidence in degrees, in the photos' order, or
        their text ``"10,20,30"`` (``--theta-i-deg``).
    rule, parameter : the segmentation (:data:`gonio_cli.sparkle.SEGMENTATION_RULES`).

    Returns
    -------
    The :class:`~gonio_cli.sparkle.TextureResult` written.

    Raises
    ------
    InputError : one line naming the option or the photo.
    """
    output = Path(output)
    get_rule(rule)
    if output.suffix.lower() != ".png":
        raise InputError("the sparkle texture must be a PNG", path=output, fix="name it *.png")
    angles = THETA_I_DEG.parse(theta_i_deg) if isinstance(theta_i_deg, str) else list(theta_i_deg)
    declare({"-o": output}, photos)
    if len(photos) > N_BITS:
        raise InputError(f"{len(photos)} photos; a sparkle texture holds at most "
                         f"{N_BITS} (one bit each, eq. 16)")
    if len(angles) != len(photos):
        raise InputError(f"{len(photos)} photos but {len(angles)} angles in --theta-i-deg "
                         f"{theta_i_deg}", fix="give one angle per photo, in the same order")
    bit_order(angles)
    images = [read_image(p) for p in log.progress(photos, "reading photos",
                                                   total=len(photos))]
    sizes = {(im.pixels.shape[1], im.pixels.shape[0]) for im in images}
    if len(sizes) != 1:
        first = images[0].pixels.shape
        other = next(im for im in images if im.pixels.shape[:2] != first[:2])
        raise InputError(f"is {other.pixels.shape[1]}x{other.pixels.shape[0]} px, the first "
                         f"photo {first[1]}x{first[0]}", path=other.path,
                         fix="crop all photos to the same area")
    with log.timer() as t:
        result = build_texture([im.pixels for im in images], angles, rule, parameter)
    meta = image_metadata(
        TEXTURE_SCHEMA, TEXTURE_VERSION, inputs=photos,
        theta_i_deg=result.theta_i_deg,
        theta_h_deg=theta_h_deg(result.theta_i_deg).tolist(),
        bit_order="bit k = k-th largest theta_i (seed 004 eq. 16)",
        rule=result.rule, parameter=result.parameter, thresholds=result.thresholds,
        fraction_set=result.fraction, color=result.color, time_s=round(t["time_s"], 6))
    write_png(output, result.texture, metadata=meta)
    per_bit = " ".join(f"{a:g}°:{100 * f:.1f}%" for a, f in
                       zip(result.theta_i_deg, result.fraction))
    log.info(f"{output}: {result.texture.shape[1]}x{result.texture.shape[0]} "
             f"{100 * float((result.texture > 0).mean()):.1f}% sparkle pixels; set per θi "
             f"{per_bit} (rule {result.rule}, {result.parameter:g})")
    return result
