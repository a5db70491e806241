"""Which command makes each artifact: the fix of a file that is missing or is not the
artifact a command reads (``make a material from it with `gonio fit red.measurement.json
-o red.material.json```).

Standard library only: the typer shells name the command that makes a missing input
before any core is loaded (:func:`gonio_cli.commands.require_files`), and
:func:`gonio_cli.artifact.read_artifact` names it for a file of the wrong kind.
"""

from __future__ import annotations

import os
from pathlib import Path


#: What each artifact is called in a message, the command that makes it (``{src}`` its
#: input, ``{out}`` its output) and that input's and output's names when not known.
MAKERS = {
    "gonio.measurement": ("a measurement", "gonio ingest {src} -o {out}", "INPUT.csv",
                          "measurement.json"),
    "gonio.material": ("a material", "gonio fit {src} -o {out}", "MEASUREMENT.json",
                       "material.json"),
    "gonio.lobe_basis": ("a lobe basis", "gonio lobes basis {src} -o {out}", "MATERIAL.json",
                         "basis.json"),
    "gonio.lobes": ("lobe weights", "gonio lobes fit {src} --basis BASIS.json -o {out}",
                    "MATERIAL.json", "lobes.json"),
    "gonio.prefilter": ("a prefiltered environment", "gonio prefilter ENV.exr --lobes {src} "
                        "-o {out}", "LOBES.json", "FOLDER"),
}

#: The schema each maker reads (``gonio fit`` reads a measurement …): a file of that
#: schema given where the made one is expected is the input of the command to run.
MADE_FROM = {"gonio.material": "gonio.measurement", "gonio.lobe_basis": "gonio.material",
              "gonio.lobes": "gonio.material", "gonio.prefilter": "gonio.lobes"}


def make_fix(schema: str, path=None, found: str | None = None, *,
             missing: bool = False) -> str:
    """The fix of a file that is not the ``schema`` artifact a command reads: the command
    that makes one. The user's ``path`` is that command's input where it is what the
    command reads (``found``: its schema; a ``.csv`` or ``.bsdf`` for ``gonio ingest``),
    e.g. ``make a material from it with `gonio fit red.measurement.json -o
    red.material.json```; a ``missing`` file is the command's output."""
    if schema not in MAKERS:
        return "pass the file this command reads"
    what, command, src, out = MAKERS[schema]
    name = os.fspath(path) if path is not None else ""
    stem = Path(name).name.split(".")[0]
    if stem and out != "FOLDER":
        out = f"{stem}.{out}"
    if missing:
        return f"check the path, or make it with `{command.format(src=src, out=name)}`"
    if (found is not None and found == MADE_FROM.get(schema)) or \
            (schema == "gonio.measurement" and name.lower().endswith((".csv", ".bsdf"))):
        return f"make {what} from it with `{command.format(src=name, out=out)}`"
    return f"make {what} with `{command.format(src=src, out=out)}`"


def artifact_name(schema: str) -> str:
    """``schema`` as a message names it (``a material``), else the schema itself."""
    return MAKERS[schema][0] if schema in MAKERS else f"a {schema} file"
