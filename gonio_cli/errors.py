"""The one error type of gonio (STYLE 8).

Every core function raises a :class:`GonioError` subclass for anything the user can fix.
The CLI catches it once (:func:`gonio_cli.cli.main`), prints ``gonio: error: <message>`` on
one line of stderr and exits with status 2; no traceback reaches the user.

A message names the place (file, row or column or field), the value and the fix, e.g.::

    spectra.csv:42: theta_i_deg=95 is outside [0, 90); fix the angle or drop the row
"""

from __future__ import annotations

import os

#: Exit status for every error the user can fix (bad input, bad options, untrustworthy fit).
EXIT_USAGE = 2

#: Exit status of a fit that ran but is poor against a limit the user set
#: (``gonio fit --max-error``): not bad input, a result below the bar; nothing written.
EXIT_POOR_FIT = 3

#: Exit status of a run stopped by Ctrl-C: 128 + SIGINT (2), what a shell reports for a
#: process the signal ended, so ``make`` and shell loops stop too.
EXIT_INTERRUPTED = 130

#: Exit status of a run stopped by SIGTERM (``kill``, a CI timeout): 128 + SIGTERM (15).
EXIT_TERMINATED = 143


class Terminated(BaseException):
    """SIGTERM, raised in the main thread by :func:`gonio_cli.cli.run`'s handler so that
    every ``with`` block unwinds as for Ctrl-C: temporary folders are removed and staged
    outputs dropped. A ``BaseException``, like ``KeyboardInterrupt``, so that no
    ``except Exception`` swallows it."""


class GonioError(Exception):
    """Base class of all errors gonio reports to a user.

    Parameters
    ----------
    message : str
        What is wrong, with the offending value.
    path : str or os.PathLike, optional
        The file the error is in; printed first.
    row : int, optional
        1-based line number in ``path`` (as an editor shows it).
    column : str, optional
        Column or field name (``theta_i_deg``, ``[camera].fov_deg``).
    fix : str, optional
        What the user can do about it.
    """

    #: The process's exit status when this error ends a command.
    exit_code = EXIT_USAGE

    def __init__(self, message: str, *, path=None, row: int | None = None,
                 column: str | None = None, fix: str | None = None):
        self.message = message
        self.path = os.fspath(path) if path is not None else None
        self.row = row
        self.column = column
        self.fix = fix
        super().__init__(self.format())

    def format(self) -> str:
        """The one-line message: ``path:row: column: message; fix``."""
        where = ""
        if self.path is not None:
            where = self.path
            if self.row is not None:
                where += f":{self.row}"
            where += ": "
        elif self.row is not None:
            where = f"row {self.row}: "
        col = f"column {self.column}: " if self.column else ""
        text = f"{where}{col}{self.message}"
        if self.fix:
            text += f"; {self.fix}"
        return " ".join(text.split())  # one line, always


class InputError(GonioError):
    """Input data or options that cannot be used as given."""


class ArtifactError(GonioError):
    """An artifact file that is missing, unreadable, of another schema or an unknown version."""


class FitError(GonioError):
    """A fit that cannot be trusted (no signal, too few configurations, non-finite result)."""


class PoorFitError(FitError):
    """A fit that ran but misses the user's limit (``--max-error``): exit status 3."""

    exit_code = EXIT_POOR_FIT


class NumericError(GonioError, ValueError):
    """A number outside the range the maths survives (docs/conventions.md, "Numeric
    ranges"), or a result that overflowed: refused before anything is written. Also a
    :class:`ValueError`, what ``json.dumps`` raises for NaN, so callers that caught that
    still do."""


class WriteError(GonioError, OSError):
    """An output that cannot be written: its folder is missing, not writable, not a
    folder, or the disk is full. Also an :class:`OSError`, so code that treats a write as
    optional (the on-disk cache) still catches it."""


class MemoryLimitError(InputError):
    """Work whose estimated memory exceeds what the machine has (:mod:`gonio_cli.memory`),
    refused before it starts."""


class OutputError(GonioError):
    """Outputs refused before any work: two outputs (or an output and an input) that are
    the same file, or an output that exists and is not a writable regular file."""


# ------------------------------------------------------- naming the real cause --

#: Leading bytes of binary files users hand to gonio by mistake → what the file is.
#: (File format signatures: PNG spec §5.2, JFIF, OpenEXR, PKWARE APPNOTE, ISO 32000,
#: RFC 1952, TIFF 6.0, Microsoft Compound File.)
FILE_SIGNATURES = {
    b"\x89PNG\r\n\x1a\n": "PNG image",
    b"\xff\xd8\xff": "JPEG image",
    b"\x76\x2f\x31\x01": "OpenEXR image",
    b"II*\x00": "TIFF image",
    b"MM\x00*": "TIFF image",
    b"PK\x03\x04": "ZIP archive, e.g. an Excel .xlsx workbook",
    b"%PDF-": "PDF document",
    b"\x1f\x8b": "gzip-compressed file",
    b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1": "legacy Office file, e.g. an Excel .xls workbook",
    b"#?RADIANCE": "Radiance HDR image",
    b"#?RGBE": "Radiance HDR image",
}


def binary_kind(head: bytes) -> str | None:
    """What a file is, from its first bytes, if it is one of :data:`FILE_SIGNATURES`."""
    return next((kind for magic, kind in FILE_SIGNATURES.items() if head.startswith(magic)),
                None)


def num(value) -> str:
    """A number as a message shows it: ``nan``, ``0.5``, ``95``, ``1e-20``.

    numpy scalars print as their value (``str``), never as their ``repr``
    (``np.float64(nan)``); integral floats drop their ``.0``. Anything else is ``str``.
    """
    if isinstance(value, bool) or type(value).__name__ in ("bool", "bool_"):
        return str(bool(value))
    if type(value).__module__ == "numpy" and hasattr(value, "dtype"):
        text = str(value)  # np.float64 is also a float, whose repr names the type
    elif isinstance(value, float):
        text = repr(value)
    else:
        return str(value)
    return text[:-2] if text.endswith(".0") else text


def deg(value) -> str:
    """An angle in degrees as a message shows it, to 0.01°: ``70``, ``1.06``, ``-7.5``.

    The canonical spelling of a configuration out of the plane is exact trigonometry
    (θo 70.0032°, φo 1.06416° for 1° around a mirror at 70°): a reader wants the angle,
    not the round-off."""
    text = f"{round(float(value), 2):g}"
    return "0" if text == "-0" else text
