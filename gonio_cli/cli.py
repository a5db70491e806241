"""The ``gonio`` command: one typer app, one subcommand per stage.

The shell is thin (STYLE 1): each subcommand in :mod:`gonio_cli.commands` parses options,
reads files, calls its stage's numpy core and writes files. Errors are converted once,
here (STYLE 8): a :class:`~gonio_cli.errors.GonioError` becomes one line
``gonio: error: …`` on stderr and exit status 2, never a traceback.
"""

from __future__ import annotations

import os
import sys
from typing import Optional, Sequence

import typer

from . import __version__, log
from .errors import EXIT_USAGE, GonioError

#: Stage shells in pipeline order; each module has ``register(app)`` and ``EXAMPLE``.
COMMAND_MODULES = ("ingest", "fit", "lobes", "halftone", "prefilter", "sparkle", "render",
                   "report")


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


_register()


def run(argv: Sequence[str] | None = None) -> int:
    """Run the CLI and return its exit status instead of exiting (used by tests)."""
    log.set_quiet(False)
    args = list(argv) if argv is not None else sys.argv[1:]
    try:
        code = app(args=args, prog_name="gonio", standalone_mode=False)
        return code if isinstance(code, int) else 0
    except GonioError as exc:
        print(f"gonio: error: {exc.format()}", file=sys.stderr)
        return EXIT_USAGE
    except SystemExit as exc:
        code = exc.code
        return code if isinstance(code, int) else (0 if code is None else 1)
    except KeyboardInterrupt:
        print("gonio: interrupted; nothing was written", file=sys.stderr)
        return 130
    except OSError as exc:
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"gonio: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return EXIT_USAGE
    except Exception as exc:
        if _is_usage_error(exc):  # typer/click: bad option, missing argument, unknown command
            print(f"gonio: error: {exc.format_message()} (see 'gonio "
                  f"{_command(args)}--help')", file=sys.stderr)
            return int(exc.exit_code)
        if type(exc).__name__ == "Abort":
            print("gonio: aborted; nothing was written", file=sys.stderr)
            return 130
        # a bug: one line, unless the user asks for the traceback
        if os.environ.get("GONIO_DEBUG"):
            raise
        print(f"gonio: internal error: {exc.__class__.__name__}: {exc} "
              "(a bug; rerun with GONIO_DEBUG=1 for the traceback and report it)",
              file=sys.stderr)
        return 1


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
