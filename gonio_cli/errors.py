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
