"""Warnings and progress for the CLI, silent with ``--quiet``.

Cores never print (STYLE 1): they call :func:`warn` (collected and shown by the shell on
stderr) and wrap long loops in :func:`progress`, which draws a bar on stderr only when
the step is long enough to need one and the user did not ask for quiet.
"""

from __future__ import annotations

import contextlib
import sys
import time
from typing import Iterable, Iterator, TypeVar

T = TypeVar("T")

_state: dict = {"quiet": False, "collect": None}

#: A progress bar appears only for loops expected to run longer than this (s).
PROGRESS_MIN_S = 2.0


def set_quiet(quiet: bool) -> None:
    """Silence warnings and progress bars (``gonio --quiet``)."""
    _state["quiet"] = bool(quiet)


def is_quiet() -> bool:
    return _state["quiet"] or _state["collect"] is not None


@contextlib.contextmanager
def collecting(into: list[str]) -> Iterator[list[str]]:
    """Inside the block, warnings are appended to ``into`` (without ``gonio: warning:``)
    instead of printed, and information and progress are not shown: how a batch job
    (:mod:`gonio_cli.batch.jobs`) takes a stage's warnings as values."""
    before = _state["collect"]
    _state["collect"] = into
    try:
        yield into
    finally:
        _state["collect"] = before


def warn(message: str) -> None:
    """One-line warning on stderr: ``gonio: warning: …`` (unless quiet)."""
    text = " ".join(message.split())
    if _state["collect"] is not None:
        _state["collect"].append(text)
    elif not _state["quiet"]:
        print(f"gonio: warning: {text}", file=sys.stderr)


def info(message: str) -> None:
    """One-line information on stderr (unless quiet); stdout is kept for data."""
    if not is_quiet():
        print(message, file=sys.stderr)


def progress(items: Iterable[T], description: str, total: int | None = None,
             expected_s: float | None = None) -> Iterator[T]:
    """Iterate ``items`` with a rich progress bar on stderr when worth showing.

    The bar is drawn if not quiet, stderr is a terminal and either ``expected_s`` exceeds
    :data:`PROGRESS_MIN_S` or (when unknown) the loop is still running after that time.
    Otherwise (``--quiet``, output redirected to a file or a pipe, as in ``make``) nothing
    is printed and the command's one summary line at the end is all there is.
    """
    if is_quiet() or not sys.stderr.isatty() or (
            expected_s is not None and expected_s < PROGRESS_MIN_S):
        yield from items
        return
    from rich.console import Console
    from rich.progress import Progress

    if total is None:
        try:
            total = len(items)  # type: ignore[arg-type]
        except TypeError:
            total = None
    start = time.perf_counter()
    # on stderr, like every message: stdout is kept for data (--summary, reports)
    with Progress(console=Console(file=sys.stderr), transient=True, disable=False,
                  redirect_stdout=False, redirect_stderr=False) as bar:
        task = None
        for done, item in enumerate(items):
            if task is None and (expected_s is not None
                                 or time.perf_counter() - start > PROGRESS_MIN_S):
                task = bar.add_task(description, total=total, completed=done)
            yield item
            if task is not None:
                bar.advance(task)


#: Warning categories that speak to a developer (a library's API is changing), never to
#: a user: silenced. Every other Python warning becomes a gonio warning line.
DEVELOPER_WARNINGS = (DeprecationWarning, PendingDeprecationWarning, FutureWarning)


@contextlib.contextmanager
def python_warnings(subject: str | None = None) -> Iterator[None]:
    """Python warnings inside the block (numpy's RuntimeWarning, scipy's OptimizeWarning,
    colour-science's ColourWarning …) become one ``gonio: warning: SUBJECT: …`` line each,
    never Python's two-line ``file.py:12: RuntimeWarning: …`` with a source line.

    ``subject`` is the file the command works on (the CLI passes its first input file); a
    warning repeated with the same text is shown once. Developer warnings
    (:data:`DEVELOPER_WARNINGS`) are silenced. ``--quiet`` silences them all, as every
    warning.
    """
    import warnings

    seen: set[str] = set()

    def show(message, category, filename, lineno, file=None, line=None):  # noqa: ARG001
        text = " ".join(str(message).split())
        if text in seen:
            return
        seen.add(text)
        parts = filename.replace("\\", "/").split("/")
        package = parts[parts.index("site-packages") + 1] if "site-packages" in parts else (
            "gonio" if "gonio_cli" in parts else parts[-1])
        origin = package.removesuffix(".py")
        where = f"{subject}: " if subject else ""
        warn(f"{where}{text} ({category.__name__} from {origin})")

    with warnings.catch_warnings():  # the filters in force (-W, a test's) still apply
        for category in DEVELOPER_WARNINGS:
            warnings.simplefilter("ignore", category)
        warnings.showwarning = show
        yield


@contextlib.contextmanager
def timer() -> Iterator[dict]:
    """``with timer() as t: ...`` then ``t["time_s"]`` is the wall time in seconds."""
    t = {"time_s": 0.0}
    start = time.perf_counter()
    try:
        yield t
    finally:
        t["time_s"] = time.perf_counter() - start
