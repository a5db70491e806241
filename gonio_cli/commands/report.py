"""``gonio report``: the thin shell over :mod:`gonio_cli.report`.

Writes ``REPORT_DIR/report.md``, ``report.json`` (schema ``gonio.report`` v1) and one PNG
per plot. Atomic as a whole: everything is written into a temporary folder beside
``REPORT_DIR`` and moved into place at the end; a failed run leaves ``REPORT_DIR`` as it
was.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import List, Optional

import typer

from .. import log
from ..errors import InputError
from ..names import REPORT_SECTION_NAMES as SECTION_NAMES
from ..outputs import declare, folder_output


def report(
    inputs: Optional[List[Path]] = typer.Argument(
        None, metavar="FILE.json", show_default=False,
        help="gonio.measurement files (Table 1, paired with NAME.material.json and "
             "NAME.torrance-sparrow.material.json when given, else fitted in memory) and "
             "gonio.material files (sheets). None: the bundled sample inks."),
    output: Path = typer.Option(..., "--output", "-o", metavar="REPORT_DIR",
                                help="Folder for report.md, report.json and the plots "
                                     "(replaced as a whole)."),
    quick: bool = typer.Option(False, "--quick",
                               help="Small sizes and one repeat: under a minute."),
    sections: Optional[str] = typer.Option(
        None, "--sections", metavar="LIST",
        help=f"Comma-separated subset of {','.join(SECTION_NAMES)} (default: all)."),
) -> None:
    """Error against run time for every stage's settings, seed 000 Table 1 beside the
    paper's numbers, and material sheets, as Markdown with PNG plots.

    \b
    Example:
      gonio report --quick -o report/
      gonio report out/rgbink/*.measurement.json out/rgbink/*.material.json -o report/
    """
    from .. import report as stage  # lazy: gonio --help skips the report core (bench_startup.py)
    start = time.perf_counter()
    names = stage.parse_sections(sections)  # before anything is written
    paths = list(inputs or [])
    for p in paths:
        if not p.is_file():
            raise InputError("no such file", path=p, fix="give gonio.measurement or "
                                                          "gonio.material JSON files")
    if output.exists() and not output.is_dir():
        raise InputError(f"-o {output} is a file", fix="name a folder")
    declare({"-o": output}, paths, replaced=["-o"])
    # REPORT_DIR is staged whole and replaces the old one when the command succeeds
    with folder_output(output) as folder:
        result = stage.write_report(folder, names, paths=paths, quick=quick, start=start,
                                    progress=lambda it: log.progress(it, "report sections",
                                                                     expected_s=10.0))
    log.info(f"{output / 'report.md'}: {len(result.sections)} sections "
             f"({', '.join(names)}), {result.time_s:.1f} s")


EXAMPLE = "gonio report --quick -o report/"


def register(app: typer.Typer) -> None:
    app.command("report")(report)
