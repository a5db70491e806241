"""What every section of ``gonio report`` returns (:class:`Section`), what the sections run
on (:class:`Ink`, :class:`Inputs`), and the text they share: Markdown tables, run times and
the bundled sample files they read."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from ..samples import sample_data_dir


def format_seconds(t: float) -> str:
    """A run time for the report: three significant digits with its unit, never "0.0"
    (below a millisecond the timer's resolution and the noise of a busy machine make more
    digits meaningless: "<1 ms")."""
    if t < 1e-3:
        return "<1 ms"
    return f"{1e3 * t:.3g} ms" if t < 1.0 else f"{t:.3g} s"


def sample_file(*parts: str) -> Path:
    """A file of the bundled sample data (:func:`gonio_cli.samples.sample_data_dir`)."""
    return sample_data_dir().joinpath(*parts)


@dataclass
class Section:
    """One section's result: ``numbers`` (JSON-able), ``markdown`` (tables and text, which
    refer to the plots by file name), ``plots`` file name → ``fn(path)`` that draws it."""

    name: str
    title: str
    numbers: dict[str, Any]
    markdown: str
    plots: dict[str, Callable[[Path], None]] = field(default_factory=dict)
    time_s: float = 0.0


@dataclass
class Ink:
    """A measured material: its measurement and the fitted models (model → Material)."""

    name: str
    measurement: Any
    materials: dict[str, Any]


@dataclass
class Inputs:
    """What the report runs on: inks (measurement + fits) and materials for the sheets."""

    inks: list[Ink]
    sheets: list[tuple[str, Any]]
    sources: list[str]


def md_table(header: list[str], rows: list[list[str]]) -> str:
    align = ["---" if i == 0 or not any(_numeric(r[i]) for r in rows) else "---:"
             for i in range(len(header))]
    return "\n".join(["| " + " | ".join(header) + " |", "|" + "|".join(align) + "|"]
                     + ["| " + " | ".join(r) + " |" for r in rows])


def _numeric(text: str) -> bool:
    try:
        float(text.replace("×", "").split()[0])
        return True
    except (ValueError, IndexError):
        return False
