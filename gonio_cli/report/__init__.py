"""``gonio report``: error against run time for every setting a user chooses, seed 000
Table 1 reproduced, and material sheets.

Pure core (STYLE 1): :func:`run_report` runs the chosen sections of
:data:`~gonio_cli.report.sections.SECTIONS` in this process and returns a
:class:`Report` (numbers, Markdown, plot makers); the shell (:mod:`gonio_cli.commands.report`)
writes ``report.md``, ``report.json`` and the PNGs. The renderer reads materials from
files, so the core is given a scratch ``workdir`` for them (the shell's temporary folder).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable

from ..errors import InputError

SCHEMA = "gonio.report"
SCHEMA_VERSION = 1
#: Section names in report order (the registry lives in :mod:`.sections`, imported lazily).
from ..names import REPORT_SECTION_NAMES as SECTION_NAMES  # noqa: E402


def format_seconds(t: float) -> str:
    """A run time for the report: three significant digits with its unit, never "0.0"
    (below a millisecond the timer's resolution and the noise of a busy machine make more
    digits meaningless: "<1 ms")."""
    if t < 1e-3:
        return "<1 ms"
    return f"{1e3 * t:.3g} ms" if t < 1.0 else f"{t:.3g} s"


def parse_sections(spec: str | None) -> list[str]:
    """``"fit,table1"`` → ["fit", "table1"] in report order; None or "" → all. An unknown
    name is an :class:`InputError` that lists the valid ones."""
    if not spec:
        return list(SECTION_NAMES)
    names = [s.strip() for s in spec.split(",") if s.strip()]
    bad = [s for s in names if s not in SECTION_NAMES]
    if bad or not names:
        raise InputError(f"--sections {spec!r}: unknown section {', '.join(map(repr, bad))}"
                         if bad else f"--sections {spec!r} names no section",
                         fix=f"use a comma-separated list of {', '.join(SECTION_NAMES)}")
    return [s for s in SECTION_NAMES if s in names]


@dataclass
class Report:
    sections: list  # of sections.Section
    inputs: list[str]
    quick: bool
    time_s: float = 0.0
    parameters: dict[str, Any] = field(default_factory=dict)

    def payload(self) -> dict[str, Any]:
        return {"quick": self.quick,
                "sections": {s.name: {"title": s.title, "time_s": s.time_s,
                                      "plots": sorted(s.plots), **s.numbers}
                             for s in self.sections}}

    def markdown(self) -> str:
        head = ["# gonio report", "",
                f"{'Quick' if self.quick else 'Full'} run, {format_seconds(self.time_s)} in "
                "total; every number was measured in the run that wrote this file (only the paper's "
                "Table 1 figures are pasted, and labelled). Inputs: "
                + (", ".join(f"`{p}`" for p in self.inputs) or "synthetic data") + ".", "",
                "| section | time |", "|---|---:|"]
        head += [f"| [{s.title}](#{s.name}) | {format_seconds(s.time_s)} |"
                 for s in self.sections]
        body = [f'\n<a id="{s.name}"></a>\n\n## {s.title}\n\n{s.markdown}'
                for s in self.sections]
        return "\n".join(head) + "\n" + "\n".join(body) + "\n"


def run_report(sections: Iterable[str], workdir: Path, *, paths: Iterable[Path] = (),
               quick: bool = False, progress=None) -> Report:
    """Run ``sections`` (names of :data:`SECTION_NAMES`) on the given measurement and
    material files, or on the bundled sample inks when none are given.

    ``workdir``: an existing scratch folder for the files the renderer reads.
    ``progress``: wraps the section loop (e.g. :func:`gonio_cli.log.progress`).
    """
    from . import sections as S

    start = time.perf_counter()
    paths = [Path(p) for p in paths]
    names = list(sections)
    inputs = S.inputs_from_files(paths) if paths else S.default_inputs()
    if any(n in ("render", "table1") for n in names):
        if not inputs.inks:
            raise InputError("render and table1 need a measurement (*.measurement.json)",
                             fix="give one, or leave those out with --sections")
        S.write_scratch(inputs, Path(workdir))
    loop = progress(names) if progress is not None else names
    done = []
    for name in loop:
        t = time.perf_counter()
        section = S.SECTIONS[name](inputs, Path(workdir), quick)
        section.time_s = time.perf_counter() - t
        done.append(section)
    return Report(done, inputs.sources, quick, time.perf_counter() - start,
                  {"sections": names, "quick": quick})
