"""``gonio sparkle``: the thin shell over :func:`gonio_cli.sparkle_files.make_texture`
(seed 004 §6)."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from ..names import SPARKLE_RULE_NAMES as RULE_NAMES
from ..names import metavar
from . import require_files


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
    require_files(photos, what="image file")  # first: a pattern that matched nothing is 1 photo
    # lazy: gonio --help and the other commands do not load sparkle_files (benchmarks/bench_startup.py)
    from ..sparkle_files import make_texture

    make_texture(photos, output, theta_i, rule, parameter)


EXAMPLE = "gonio sparkle sample_data/sparkle/photo_ti*.png -o sparkle.png"


SHORT_HELP = "Pack photographs of a metallic paint into a sparkle texture."


def register(app: typer.Typer) -> None:
    app.command("sparkle", short_help=SHORT_HELP)(sparkle)
