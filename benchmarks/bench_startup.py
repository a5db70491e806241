"""Start-up of ``gonio``: what every run pays before its stage starts, and what the lazy
imports of the command shells save.

Every ``gonio`` run imports :mod:`gonio_cli.cli` and, through it, every command shell of
:mod:`gonio_cli.commands` (to register the commands). The shells import their stage's
core (numpy, scipy, the stage's modules) inside the command function, with a ``# lazy:``
comment citing this benchmark, so that ``gonio --version``, ``gonio --help`` and one
stage do not load the other stages' cores.

Part 1, whole processes (``python -m gonio_cli …``, as a user runs them, bytecode
cached): ``--version``, ``--help`` and the help of three stages, best of ``--repeats``.

Part 2, imports (``python -c "import …"``), best of ``--repeats``: the CLI alone, then the
CLI with each stage core (the extra time is what that core's lazy import saves every run
of another command), and the CLI with every core at once (what the lazy imports save a
``gonio --version`` or ``gonio --help``: the shells' imports made eager).

    .venv/bin/python benchmarks/bench_startup.py [--repeats N]
"""

from __future__ import annotations

import argparse
import sys

import process

#: Whole processes timed in part 1 (arguments of ``python -m gonio_cli``).
COMMANDS = (("--version",), ("--help",), ("fit", "--help"), ("render", "--help"),
            ("ingest", "--help"))

#: The core each command shell imports lazily, by command (what the shell would load at
#: start-up if its imports were at the top).
CORES = {
    "ingest": "gonio_cli.ingest",
    "fit": "gonio_cli.fit",
    "eval": "gonio_cli.evaluate",
    "lobes": "gonio_cli.lobes",
    "prefilter": "gonio_cli.prefilter",
    "render": "gonio_cli.render.pipeline",
    "sparkle": "gonio_cli.sparkle",
    "halftone": "gonio_cli.halftone",
    "export": "gonio_cli.export",
    "report": "gonio_cli.report",
    "batch": "gonio_cli.batch.engine",
}

#: Target: ``gonio --version`` and ``gonio --help`` within this of the bare CLI import
#: (nothing of a core loaded at start-up).
TARGET_VERSION_MS = 400.0


def best_ms(argv: list[str], repeats: int) -> float:
    """Best wall time (ms) of ``repeats`` runs of one process (:func:`process.run_with_cpu`)."""
    return 1e3 * min(process.run_with_cpu(argv)["wall_s"] for _ in range(repeats))


def imports_ms(modules: list[str], repeats: int) -> float:
    """Best wall time (ms) of a Python process that imports ``modules``."""
    return best_ms([sys.executable, "-c", "import " + ", ".join(modules)], repeats)


def process_table(repeats: int) -> float:
    print(f"## Whole processes: python -m gonio_cli … (best of {repeats}; load "
          f"{process.load_average()})\n")
    print("| command | wall (ms) |")
    print("|---|---:|")
    version_ms = 0.0
    for args in COMMANDS:
        ms = best_ms([sys.executable, "-m", "gonio_cli", *args], repeats)
        version_ms = ms if args == ("--version",) else version_ms
        print(f"| gonio {' '.join(args)} | {ms:.0f} |")
    print()
    return version_ms


def import_table(repeats: int) -> None:
    python_ms = best_ms([sys.executable, "-c", "pass"], repeats)
    cli_ms = imports_ms(["gonio_cli.cli"], repeats)
    print(f"## Imports (best of {repeats}): what each shell's lazy import saves\n")
    print(f"Python alone: {python_ms:.0f} ms; `import gonio_cli.cli` (every command "
          f"shell, no core): {cli_ms:.0f} ms.\n")
    print("| command | its core | import with the CLI (ms) | saved by the lazy import (ms) |")
    print("|---|---|---:|---:|")
    for command, core in CORES.items():
        ms = imports_ms(["gonio_cli.cli", core], repeats)
        print(f"| {command} | {core} | {ms:.0f} | {ms - cli_ms:.0f} |")
    every_ms = imports_ms(["gonio_cli.cli", *CORES.values()], repeats)
    print(f"| every command | all of them | {every_ms:.0f} | {every_ms - cli_ms:.0f} |\n")
    print(f"Eager imports in the shells would add {every_ms - cli_ms:.0f} ms to every "
          f"gonio run (--version and --help included).\n")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="runs per figure (best)")
    args = parser.parse_args(argv)
    version_ms = process_table(args.repeats)
    import_table(args.repeats)
    ok = version_ms <= TARGET_VERSION_MS
    print(f"gonio --version: {version_ms:.0f} ms, target ≤ {TARGET_VERSION_MS:.0f} ms: "
          f"{'met' if ok else 'NOT met'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
