"""Run the shell examples of gonio's Markdown files, in order, as a user would paste them.

A *shell block* is a fenced block tagged ``sh``, ``bash`` or ``console``. In ``sh`` and
``bash`` blocks every line is a command (a line ending in ``\\`` continues on the next one;
blank lines and ``#`` comment lines are skipped). In ``console`` blocks only lines that
start with the prompt ``$ `` are commands; the other lines are their output. Blocks tagged
otherwise (``text`` for usage synopses and sample output, ``json``, ``toml``, ``make`` …)
are never run.

Two ways a command is not run:

* an HTML comment ``<!-- not run: REASON -->`` on the line right before the block's
  opening fence (blank lines between are allowed) skips the whole block; the reason is
  required and kept rare (an address that exists only on the author's cluster, say);
* a command whose first word is in :data:`SKIPPED_PROGRAMS` (``make``: CI runs
  ``make test`` and ``make demo`` itself, and a Makefile target inside a temporary copy
  would rebuild the project).

Commands run one at a time with ``bash -c``, with the current interpreter's folder (its
``gonio`` and ``python``) first on ``PATH``; a command may use what earlier commands wrote
into its working folder. The files of :data:`CHAIN` (the README's worked chain, then
``docs/tour.md``, which goes on from it) run in that order in one folder, as a user pastes
them on a fresh clone; every other page of ``docs/`` builds on what they wrote.

From the command line (in a scratch folder; a page outside :data:`CHAIN` gets the chain
run first, since its examples read what the chain wrote)::

    python tests/docs_runner.py README.md docs/tour.md docs/lobes.md
    python tests/docs_runner.py docs/lobes.md          # the same
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

#: The Markdown files (relative to the project) whose examples are one chain, run in this
#: order in one folder; every other page's examples run after them.
CHAIN = ("README.md", "docs/tour.md")

#: Fence languages whose lines are run.
SHELL_LANGUAGES = ("sh", "bash", "console")

#: Programs whose lines are never run, with the reason (shown in the skip list).
SKIPPED_PROGRAMS = {
    "make": "CI runs `make test` and `make demo` itself; a make target would rebuild the "
            "project inside the test",
}

#: Marker that skips the next block; the reason after the colon is required.
NOT_RUN = re.compile(r"^\s*<!--\s*not run:\s*(?P<reason>\S.*?)\s*-->\s*$")

#: The prompt of ``console`` blocks.
PROMPT = "$ "

#: One command may take this long before it counts as failed (seconds). The slowest
#: example (the quick report) takes well under a minute; this only stops a hang.
COMMAND_TIMEOUT_S = 600.0

_FENCE = re.compile(r"^(?P<indent>\s*)(?P<fence>`{3,}|~{3,})\s*(?P<info>[^`\s]*)")


@dataclass
class Command:
    """One command of a Markdown file: its text and where it starts (1-based line)."""

    text: str
    line: int
    skip_reason: str | None = None


@dataclass
class Block:
    """One fenced shell block."""

    language: str
    line: int                       # line of the opening fence
    commands: list[Command] = field(default_factory=list)
    skip_reason: str | None = None  # from <!-- not run: … -->


@dataclass
class Result:
    """A command that was run (or skipped) and what came of it."""

    command: Command
    returncode: int | None          # None: skipped
    stdout: str = ""
    stderr: str = ""
    time_s: float = 0.0

    @property
    def failed(self) -> bool:
        return self.returncode not in (None, 0)


def _commands(lines: list[tuple[int, str]], language: str) -> list[Command]:
    """Commands of one block's body lines ``(line number, text)``."""
    out: list[Command] = []
    pending: list[str] = []
    start = 0
    in_console_command = False
    for number, raw in lines:
        text = raw.rstrip()
        if language == "console" and not pending:
            in_console_command = text.startswith(PROMPT) or text == PROMPT.strip()
            if not in_console_command:
                continue                      # output of the previous command
            text = text[len(PROMPT):] if text.startswith(PROMPT) else ""
        if not pending:
            if not text.strip() or text.lstrip().startswith("#"):
                continue
            start = number
        if text.endswith("\\"):
            pending.append(text[:-1])
            continue
        pending.append(text)
        out.append(Command(" ".join(p.strip() for p in pending), start))
        pending = []
    if pending:
        out.append(Command(" ".join(p.strip() for p in pending), start))
    for c in out:
        program = c.text.split()[0] if c.text.split() else ""
        if program in SKIPPED_PROGRAMS:
            c.skip_reason = f"{program}: {SKIPPED_PROGRAMS[program]}"
    return out


def extract_blocks(markdown: str) -> list[Block]:
    """Every shell block of a Markdown text, in order, with its commands and skip marks."""
    lines = markdown.splitlines()
    blocks: list[Block] = []
    i = 0
    last_marker: tuple[int, str] | None = None   # (line index, reason) of a pending mark
    while i < len(lines):
        m = _FENCE.match(lines[i])
        if not m:
            marker = NOT_RUN.match(lines[i])
            if marker:
                last_marker = (i, marker.group("reason"))
            elif lines[i].strip():
                last_marker = None
            i += 1
            continue
        fence, language = m.group("fence"), m.group("info").lower()
        body: list[tuple[int, str]] = []
        j = i + 1
        while j < len(lines) and not lines[j].strip().startswith(fence):
            body.append((j + 1, lines[j]))
            j += 1
        if language in SHELL_LANGUAGES:
            block = Block(language, i + 1, _commands(body, language),
                          last_marker[1] if last_marker else None)
            if block.skip_reason:
                for c in block.commands:
                    c.skip_reason = c.skip_reason or f"not run: {block.skip_reason}"
            blocks.append(block)
        last_marker = None
        i = j + 1
    return blocks


def command_environment(cwd: Path) -> dict[str, str]:
    """The environment of every command: this interpreter's ``gonio`` first on PATH."""
    env = dict(os.environ)
    bindir = str(Path(sys.executable).parent)
    env["PATH"] = bindir + os.pathsep + env.get("PATH", "")
    env["PWD"] = str(cwd)            # bash keeps an inherited PWD; make $PWD the folder
    env.pop("VIRTUAL_ENV", None)
    env.setdefault("MPLBACKEND", "Agg")
    return env


def run_commands(commands: list[Command], cwd: Path, *,
                 stop_at_failure: bool = True) -> list[Result]:
    """Run the commands in order in ``cwd``; skipped ones get ``returncode`` None."""
    env = command_environment(cwd)
    results: list[Result] = []
    for c in commands:
        if c.skip_reason:
            results.append(Result(c, None))
            continue
        t0 = time.perf_counter()
        try:
            p = subprocess.run(["bash", "-c", c.text], cwd=cwd, env=env, capture_output=True,
                               text=True, timeout=COMMAND_TIMEOUT_S)
            code, out, err = p.returncode, p.stdout, p.stderr
        except subprocess.TimeoutExpired as e:
            code, out, err = -1, str(e.stdout or ""), f"timed out after {COMMAND_TIMEOUT_S} s"
        results.append(Result(c, code, out, err, time.perf_counter() - t0))
        if code != 0 and stop_at_failure:
            break
    return results


def run_markdown(path: Path, cwd: Path) -> list[Result]:
    """Run every shell command of the Markdown file ``path`` in order in ``cwd``."""
    commands = [c for b in extract_blocks(path.read_text(encoding="utf-8")) for c in b.commands]
    return run_commands(commands, cwd)


def failure_message(path: Path | str, results: list[Result]) -> str | None:
    """One paragraph naming the first failed command (file:line, exit status, stderr)."""
    for r in results:
        if r.failed:
            tail = (r.stderr.strip() or r.stdout.strip()).splitlines()[-5:]
            return (f"{path}:{r.command.line}: `{r.command.text}` exited with status "
                    f"{r.returncode}:\n    " + "\n    ".join(tail))
    return None


def prepare_workspace(root: Path, project: Path) -> Path:
    """A folder as a fresh clone's top level looks to the examples: a copy of sample_data.

    Copied, not linked: a few examples rerun the sample-data generators, which must not
    touch the project's own files.
    """
    root.mkdir(parents=True, exist_ok=True)
    shutil.copytree(project / "sample_data", root / "sample_data")
    return root


def with_chain(names: list[str]) -> list[str]:
    """``names`` in the order they run: the :data:`CHAIN` files first, as far as a named
    page needs them (all of them for a page outside the chain), then the others as given."""
    names = list(dict.fromkeys(names))
    chain = [n for n in CHAIN if n in names]
    if any(n not in CHAIN for n in names):
        chain = list(CHAIN)
    elif chain:
        chain = list(CHAIN[:CHAIN.index(chain[-1]) + 1])
    return chain + [n for n in names if n not in chain]


def main(argv: list[str]) -> int:
    """Run the files named (default README.md), after the chain they build on, one after
    another in one scratch folder."""
    project = Path(__file__).resolve().parents[1]
    status = 0
    with tempfile.TemporaryDirectory(prefix="gonio-docs-") as tmp:
        cwd = prepare_workspace(Path(tmp), project)
        for name in with_chain(argv or ["README.md"]):
            results = run_markdown(project / name, cwd)
            for r in results:
                state = (f"skipped ({r.command.skip_reason})" if r.returncode is None
                         else f"exit {r.returncode}, {r.time_s:.1f} s")
                print(f"{name}:{r.command.line}: {r.command.text}\n    {state}", flush=True)
            message = failure_message(name, results)
            if message:
                print(message, file=sys.stderr)
                status = 1
    return status


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
