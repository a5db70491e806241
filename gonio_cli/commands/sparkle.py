"""``gonio sparkle``: the thin shell over :mod:`gonio_cli.sparkle` (seed 004 §6)."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from ..names import SPARKLE_RULE_NAMES as RULE_NAMES
from ..names import metavar
from ..numbers import NumberList

#: ``--theta-i-deg``: the photos' angles of incidence, in the photos' order.
THETA_I_DEG = NumberList("--theta-i-deg", "10,20,30", unit="deg")


def sparkle(
    photos: List[Path] = typer.Argument(..., metavar="PHOTO", show_default=False,
                                        help="Photographs of the sample, camera along the "
                                             "normal, one per angle of incidence, same size."),
    output: Path = typer.Option(..., "--output", "-o", metavar="SPARKLE.png",
                                help="The packed 8-bit sparkle texture (eq. 16)."),
    theta_i: str = typer.Option("10,20,30,40,50,60,70", "--theta-i-deg", "--theta-i",
                                metavar="DEG,...",
                                help="Angle of incidence of each photo, in the photos' "
                                     "order (degrees; at most 8)."),
    rule: str = typer.Option("mad", "--rule", metavar=metavar(RULE_NAMES),
                             help=f"Segmentation of the brightest pixels: one of "
                                  f"{', '.join(RULE_NAMES)}."),
    parameter: Optional[float] = typer.Option(None, "--parameter", metavar="X",
                                    help="mad: k of median + k·1.4826·MAD (default 5); "
                                         "percentile: p, the brightest p % (default 1)."),
) -> None:
    """Build the sparkle texture of seed 004 §6 from photographs (eqs. 15–16).

    Bit k of each pixel is set where the photo with the k-th largest angle of incidence
    is bright: θi = 70 − 10k, θh = θi / 2 for the seed's angles.

    \b
    Example:
      gonio sparkle sample_data/sparkle/photo_ti*.png -o sparkle.png
    """
    from .. import log
    from .. import sparkle as core
    from ..artifact import image_metadata
    from ..errors import InputError
    from ..imageio import read_image, write_png
    from . import require_files

    require_files(photos, what="image file")  # first: a pattern that matched nothing is 1 photo
    core.get_rule(rule)
    if output.suffix.lower() != ".png":
        raise InputError("the sparkle texture must be a PNG", path=output, fix="name it *.png")
    angles = THETA_I_DEG.parse(theta_i)
    from ..outputs import declare
    declare({"-o": output}, photos)
    if len(photos) > core.N_BITS:
        raise InputError(f"{len(photos)} photos; a sparkle texture holds at most "
                         f"{core.N_BITS} (one bit each, eq. 16)")
    if len(angles) != len(photos):
        raise InputError(f"{len(photos)} photos but {len(angles)} angles in --theta-i-deg "
                         f"{theta_i}", fix="give one angle per photo, in the same order")
    core.bit_order(angles)
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
        result = core.build_texture([im.pixels for im in images], angles, rule, parameter)
    meta = image_metadata(
        core.TEXTURE_SCHEMA, core.TEXTURE_VERSION, inputs=photos,
        theta_i_deg=result.theta_i_deg,
        theta_h_deg=core.theta_h_deg(result.theta_i_deg).tolist(),
        bit_order="bit k = k-th largest theta_i (seed 004 eq. 16)",
        rule=result.rule, parameter=result.parameter, thresholds=result.thresholds,
        fraction_set=result.fraction, color=result.color, time_s=round(t["time_s"], 6))
    write_png(output, result.texture, metadata=meta)
    per_bit = " ".join(f"{a:g}°:{100 * f:.1f}%" for a, f in
                       zip(result.theta_i_deg, result.fraction))
    log.info(f"{output}: {result.texture.shape[1]}x{result.texture.shape[0]} "
             f"{100 * float((result.texture > 0).mean()):.1f}% sparkle pixels; set per θi "
             f"{per_bit} (rule {result.rule}, {result.parameter:g})")


EXAMPLE = "gonio sparkle sample_data/sparkle/photo_ti*.png -o sparkle.png"


SHORT_HELP = "Pack photographs of a metallic paint into a sparkle texture."


def register(app: typer.Typer) -> None:
    app.command("sparkle", short_help=SHORT_HELP)(sparkle)
