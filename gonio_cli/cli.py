"""The ``gonio`` command: one typer app, one subcommand per stage.

The shell is thin (STYLE 1): each subcommand in :mod:`gonio_cli.commands` parses options,
reads files, calls its stage's numpy core and writes files. Errors are converted once,
here (STYLE 8): a :class:`~gonio_cli.errors.GonioError` becomes one line
``gonio: error: …`` on stderr and exit status 2, never a traceback; Ctrl-C becomes one
line saying what was (or was not) written and exit status 130; ``gonio`` alone prints
the help and exits 0.
"""

from __future__ import annotations

import contextlib
import copy
import os
import signal
import sys
import threading
from typing import Optional, Sequence

import typer

from . import __version__, log, outputs
from .commands import STAGES, Group, apply_help_style, as_typed_in, remember_argv
from .errors import EXIT_INTERRUPTED, EXIT_TERMINATED, EXIT_USAGE, GonioError, Terminated

#: Stage shells in pipeline order; each module has ``register(app)`` and ``EXAMPLE``.
#: ``eval`` (the model at a measurement's configurations) follows ``fit``.
COMMAND_MODULES = (STAGES if "eval" in STAGES else
                   STAGES[:STAGES.index("fit") + 1] + ("eval",)
                   + STAGES[STAGES.index("fit") + 1:])


def _modules():
    import importlib

    return [importlib.import_module(f"{__package__}.commands.{name}")
            for name in COMMAND_MODULES]


def _epilog() -> str:
    examples = [f"  {m.EXAMPLE}" for m in _modules() if getattr(m, "EXAMPLE", "")]
    return ("\b\nExamples (one per stage):\n" + "\n".join(examples) + "\n\n"
            "Every command writes self-describing artifacts atomically; bad input gets one "
            "line on stderr naming the file, the row or field and the fix, and exit status 2.")


EPILOG = _epilog()

app = typer.Typer(
    name="gonio",
    help="Goniometer spectra to fitted goniochromatic BRDFs and rendered images.",
    epilog=EPILOG,
    add_completion=False,
    cls=Group,
    pretty_exceptions_enable=False,
    no_args_is_help=True,
    rich_markup_mode=None,
    context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100},
)


def _version(value: bool) -> None:
    if value:
        typer.echo(f"gonio {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: Optional[bool] = typer.Option(None, "--version", callback=_version,
                                           is_eager=True, help="Print the version and exit."),
    quiet: bool = typer.Option(False, "--quiet", "-q",
                               help="No warnings, progress bars or summaries on stderr."),
) -> None:
    log.set_quiet(quiet)


def _register() -> None:
    """Attach every stage's command (imports are cheap: cores load on first use)."""
    for module in _modules():
        module.register(app)
    apply_help_style(app)


_register()


def run(argv: Sequence[str] | None = None) -> int:
    """Run the CLI and return its exit status instead of exiting (used by tests)."""
    log.set_quiet(False)
    _forget_written()
    apply_help_style(app)  # commands registered since import (tests) get the same help
    args = list(argv) if argv is not None else sys.argv[1:]
    remember_argv(args)  # messages name an option as typed (commands.as_typed_in)
    try:
        # every output is staged and moved into place only when the command succeeds;
        # Python warnings become gonio warning lines naming the input
        with _sigterm_unwinds(), outputs.transaction() as tx, \
                log.python_warnings(_subject(args)):
            code = _app_for(args)(args=args, prog_name="gonio", standalone_mode=False)
            code = code if isinstance(code, int) else 0
            if code == 0:
                tx.commit()
        # typer turns Ctrl-C inside a command into exit status 130 without a word
        return _interrupted() if code == EXIT_INTERRUPTED else code
    except GonioError as exc:  # options named as the user typed them
        print(f"gonio: error: {as_typed_in(exc.format())}", file=sys.stderr)
        return exc.exit_code
    except SystemExit as exc:
        code = exc.code
        return code if isinstance(code, int) else (0 if code is None else 1)
    except KeyboardInterrupt:
        return _interrupted()
    except Terminated:
        return _interrupted("terminated", EXIT_TERMINATED)
    except OSError as exc:
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"gonio: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return EXIT_USAGE
    except Exception as exc:
        if _is_no_args_help(exc):  # 'gonio' or 'gonio lobes' alone: the help, status 0
            print(exc.format_message())
            return 0
        if _is_usage_error(exc):  # typer/click: bad option, missing argument, unknown command
            print(f"gonio: error: {exc.format_message()} (see 'gonio "
                  f"{_command(args)}--help')", file=sys.stderr)
            return int(exc.exit_code)
        if type(exc).__name__ == "Abort":  # end of input at a prompt
            print("gonio: aborted; nothing was written", file=sys.stderr)
            return EXIT_INTERRUPTED
        # a bug: one line, unless the user asks for the traceback
        if os.environ.get("GONIO_DEBUG"):
            raise
        print(f"gonio: internal error: {exc.__class__.__name__}: {exc} "
              "(a bug; rerun with GONIO_DEBUG=1 for the traceback and report it)",
              file=sys.stderr)
        return 1


#: Options of ``gonio`` itself that may come before a stage run with :func:`_app_for`
#: (``--help`` and ``--version`` there show the whole app).
_QUIET_FLAGS = ("-q", "--quiet")


def _app_for(args: Sequence[str]) -> typer.Typer:
    """The app with only the stage that ``args`` run (``gonio -q render …``), else all.

    typer turns every registered command into a click command, reading ~100 option
    signatures (~7 ms), before it runs one; ``gonio --help``, an unknown command and the
    usage-error hint (:func:`_command`) still see them all.
    """
    k = next((i for i, a in enumerate(args) if not a.startswith("-")), None)
    if k is None or any(a not in _QUIET_FLAGS for a in args[:k]):
        return app
    commands = [c for c in app.registered_commands if c.name == args[k]]
    groups = [g for g in app.registered_groups if g.name == args[k]]
    if len(commands) + len(groups) != 1:
        return app
    one = copy.copy(app)
    one.registered_commands, one.registered_groups = commands, groups
    return one


#: Options whose value is a file the command writes (never what a warning is about).
_OUTPUT_OPTIONS = frozenset({"-o", "--output", "--exr", "--report", "--plot",
                             "--gamut-warning"})


def _subject(args: Sequence[str]) -> str | None:
    """The first argument that is an existing input file: what a Python warning is about."""
    return next((a for before, a in zip([""] + list(args), args)
                 if not a.startswith("-") and before not in _OUTPUT_OPTIONS
                 and os.path.isfile(a)), None)


def _forget_written() -> None:
    """Start this run's record of written files."""
    outputs.forget_written()


def _outputs_written() -> list[str]:
    """Files this run moved into place that still exist, outside gonio's cache."""
    cache = sys.modules.get(f"{__package__}.cache")
    cache_dir = os.path.abspath(cache.cache_dir()) if cache is not None else None
    out = []
    for path in outputs.written_files():
        full = os.path.abspath(path)
        if os.path.exists(full) and not (cache_dir and full.startswith(cache_dir + os.sep)) \
                and os.fspath(path) not in out:
            out.append(os.fspath(path))
    return out


def _interrupted(how: str = "interrupted", code: int = EXIT_INTERRUPTED) -> int:
    """Ctrl-C (or SIGTERM, ``how="terminated"``): one line saying what was written
    (atomic writes leave nothing partial, temporary folders are gone)."""
    done = _outputs_written()
    if done:
        print(f"gonio: {how} after writing {', '.join(done)}; nothing else was "
              "written", file=sys.stderr)
    else:
        print(f"gonio: {how}; nothing was written", file=sys.stderr)
    return code


@contextlib.contextmanager
def _sigterm_unwinds():
    """While a command runs, SIGTERM raises :class:`~gonio_cli.errors.Terminated` in the
    main thread instead of ending the process at once, so that temporary folders (``gonio
    report``'s ``gonio-report-*``) and staged outputs are removed as for Ctrl-C. A second
    SIGTERM ends the process at once (the default); a forked child (``--model auto -j``)
    that inherits the handler dies as the default would. Off the main thread (where
    Python cannot set handlers) nothing changes; the previous handler is restored."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pid = os.getpid()

    def handler(signum, frame):
        signal.signal(signum, signal.SIG_DFL)
        if os.getpid() != pid:
            os.kill(os.getpid(), signum)
            return
        raise Terminated()

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _is_no_args_help(exc: Exception) -> bool:
    """click's "no arguments, so show the help" (an error with status 2 since click 8.2)."""
    return any(c.__name__ == "NoArgsIsHelpError" for c in type(exc).__mro__)


def _is_usage_error(exc: Exception) -> bool:
    """typer's (vendored) click usage errors, recognised by their interface so that the
    check does not depend on where a typer version keeps its click."""
    return callable(getattr(exc, "format_message", None)) and isinstance(
        getattr(exc, "exit_code", None), int)


def _command(args: Sequence[str]) -> str:
    """The subcommand named in ``args`` followed by a space, or ''."""
    names = set(typer.main.get_command(app).commands)  # type: ignore[attr-defined]
    return next((f"{a} " for a in args if a in names), "")


def main() -> None:
    """Console entry point (``gonio``)."""
    sys.exit(run())


if __name__ == "__main__":
    main()
