"""The bundled sample data and how the demo reads it.

The sample data is ``sample_data/`` of a gonio source checkout (it is not inside the
package): :func:`sample_data_dir` finds it, from ``$GONIO_SAMPLE_DATA`` or beside the
package (a clone, an editable install), and otherwise says what to do. Its ``inks.toml``
holds, once, how the demo ingests and fits the sample inks (:func:`demo_inks`,
:func:`demo_fit_options`); ``gonio report``, ``tests/test_fit.py`` and
``pipelines/rgbink.mk`` (``python -m gonio_cli.samples ingest-args INK``) read it here.
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .errors import InputError

#: Environment variable naming a ``sample_data`` folder (for an installed gonio).
SAMPLE_DATA_ENV = "GONIO_SAMPLE_DATA"
#: The file that says how the demo reads the sample inks (and marks the folder).
INKS_FILE = "inks.toml"
#: ``gonio fit`` flags of the ``[fit]`` keys (the ``ingest`` keys are ``--key-with-dashes``).
FIT_FLAGS = {"exclude_theta_i_deg": "--exclude-theta-i-deg"}


def sample_data_dir() -> Path:
    """The ``sample_data`` folder: ``$GONIO_SAMPLE_DATA``, else the checkout beside the
    package; an :class:`~gonio_cli.errors.InputError` saying how to get it otherwise."""
    given = os.environ.get(SAMPLE_DATA_ENV)
    if given:
        folder = Path(given)
        if not (folder / INKS_FILE).is_file():
            raise InputError(f"${SAMPLE_DATA_ENV} has no {INKS_FILE}", path=folder,
                             fix="point it at the sample_data folder of a gonio checkout")
        return folder
    folder = Path(__file__).resolve().parent.parent / "sample_data"
    if (folder / INKS_FILE).is_file():
        return folder
    raise InputError("the sample data is not installed with the gonio package (it is "
                     "sample_data/ of the source)",
                     fix=f"set {SAMPLE_DATA_ENV} to the sample_data folder of a gonio "
                         "checkout, or give your own files")


@dataclass(frozen=True)
class DemoInk:
    """One sample ink as the demo reads it: ``files`` (absolute) and ``ingest`` options."""

    name: str
    files: tuple[Path, ...]
    ingest: dict[str, Any] = field(default_factory=dict)


def _inks_doc(folder: Path | None = None) -> tuple[Path, dict[str, Any]]:
    import tomllib

    folder = sample_data_dir() if folder is None else Path(folder)
    with open(folder / INKS_FILE, "rb") as fh:
        return folder, tomllib.load(fh)


def demo_inks(folder: Path | None = None) -> list[DemoInk]:
    """The sample inks in the order of ``inks.toml`` (red, green, blue)."""
    folder, doc = _inks_doc(folder)
    return [DemoInk(name, tuple(folder / f for f in spec["files"]),
                    {k: v for k, v in spec.items() if k != "files"})
            for name, spec in doc["ink"].items()]


def demo_fit_options(folder: Path | None = None) -> dict[str, Any]:
    """The demo's fit options (``FitOptions``/``prepare`` keywords): the excluded rows."""
    return dict(_inks_doc(folder)[1].get("fit", {}))


def _flags(options: dict[str, Any], names: dict[str, str] | None = None) -> list[str]:
    out = []
    for key, value in options.items():
        flag = (names or {}).get(key, "--" + key.replace("_", "-"))
        for v in value if isinstance(value, list) else [value]:
            out += [flag, f"{v:g}" if isinstance(v, float) else str(v)]
    return out


def main(argv: list[str] | None = None) -> int:
    """``python -m gonio_cli.samples ingest-args INK`` / ``fit-args``: the demo's options
    as command-line flags (for pipelines/rgbink.mk)."""
    args = sys.argv[1:] if argv is None else argv
    if args[:1] == ["fit-args"] and len(args) == 1:
        print(" ".join(_flags(demo_fit_options(), FIT_FLAGS)))
        return 0
    if args[:1] == ["ingest-args"] and len(args) == 2:
        inks = {i.name: i for i in demo_inks()}
        if args[1] in inks:
            print(" ".join(_flags(inks[args[1]].ingest)))
            return 0
        print(f"gonio_cli.samples: no ink {args[1]!r} in {INKS_FILE} "
              f"(it has {', '.join(inks)})", file=sys.stderr)
        return 2
    print("usage: python -m gonio_cli.samples ingest-args INK | fit-args", file=sys.stderr)
    return 2


if __name__ == "__main__":
    raise SystemExit(main())
