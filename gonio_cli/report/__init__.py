"""``gonio report``: error against run time for every setting a user chooses, seed 000
Table 1 reproduced, and material sheets.

:func:`run_report` runs the chosen sections of :data:`~gonio_cli.report.sections.SECTIONS`
in this process and returns a :class:`Report` (numbers, Markdown, plot makers); the
renderer reads materials from files, so it is given a scratch ``workdir`` for them.
:func:`write_report`, the stage's one call from the shell (:mod:`gonio_cli.commands.report`),
runs it in a temporary folder and writes ``report.md``, ``report.json`` and the PNGs into
the folder the shell stages.
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable

from ..artifact import atomic_path, make_document, write_json
from ..errors import InputError
from ..names import REPORT_SECTION_NAMES as SECTION_NAMES
from .inputs import default_inputs, inputs_from_files, write_scratch
from .section import format_seconds
from .sections import SECTIONS

SCHEMA = "gonio.report"
SCHEMA_VERSION = 1


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
    start = time.perf_counter()
    paths = [Path(p) for p in paths]
    names = list(sections)
    inputs = inputs_from_files(paths) if paths else default_inputs()
    if any(n in ("render", "table1") for n in names):
        if not inputs.inks:
            raise InputError("render and table1 need a measurement (*.measurement.json)",
                             fix="give one, or leave those out with --sections")
        write_scratch(inputs, Path(workdir))
    loop = progress(names) if progress is not None else names
    done = []
    for name in loop:
        t = time.perf_counter()
        section = SECTIONS[name](inputs, Path(workdir), quick)
        section.time_s = time.perf_counter() - t
        done.append(section)
    return Report(done, inputs.sources, quick, time.perf_counter() - start,
                  {"sections": names, "quick": quick})


def write_report(folder: Path, sections: Iterable[str], *, paths: Iterable[Path] = (),
                 quick: bool = False, start: float | None = None,
                 progress: Callable | None = None) -> Report:
    """Run ``sections`` (:func:`run_report`, in a scratch folder of its own) and write the
    report into ``folder``: one PNG per plot, ``report.json`` (schema ``gonio.report``) and
    ``report.md``, last. ``start``: the ``time.perf_counter()`` the run's time counts from
    (default: now). Returns the :class:`Report`."""
    start = time.perf_counter() if start is None else start
    names, paths = list(sections), list(paths)
    with tempfile.TemporaryDirectory(prefix="gonio-report-") as work:
        result = run_report(names, Path(work), paths=paths, quick=quick, progress=progress)
        for section in result.sections:
            for name, draw in section.plots.items():
                with atomic_path(folder / name) as tmp:
                    draw(tmp)
    result.time_s = time.perf_counter() - start
    doc = make_document(SCHEMA, SCHEMA_VERSION, result.payload(), inputs=paths,
                        parameters={"sections": names, "quick": quick}, time_s=result.time_s)
    write_json(folder / "report.json", doc)
    with atomic_path(folder / "report.md") as tmp:  # last
        tmp.write_text(result.markdown(), encoding="utf-8")
    return result
