"""Input formats besides CSV (:data:`FORMATS`), routed by file suffix to their own module."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

# ------------------------------------------------------------- other input formats --

@dataclass(frozen=True)
class InputFormat:
    """An input format besides CSV, routed by file suffix to its own module.

    The module (imported on first use, so a CSV run never loads it) has the three
    functions the CSV path has here: ``resolve_parameters(paths, **options)``,
    ``ingest(paths, **options)`` and ``file_lines(info)`` (its ``--summary`` lines).
    """

    name: str
    suffix: str
    module: str

    def load(self):
        import importlib

        return importlib.import_module(self.module)


#: Input formats besides CSV by name; :func:`input_format` picks one by file suffix.
FORMATS = {"rgl-bsdf": InputFormat("rgl-bsdf", ".bsdf", "gonio_cli.ingest.rgl")}


def input_format(paths: Sequence[str | os.PathLike]) -> InputFormat | None:
    """The :data:`FORMATS` entry of the first input with its suffix (any case), or None
    for CSV input."""
    for p in paths:
        suffix = Path(p).suffix.lower()
        for fmt in FORMATS.values():
            if suffix == fmt.suffix:
                return fmt
    return None
