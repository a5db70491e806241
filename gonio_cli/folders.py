"""The folders gonio writes into: making one, and the one-line error when one cannot take
a file.

Below both :mod:`gonio_cli.outputs` (the outputs' transaction stages files and folders in
them) and :mod:`gonio_cli.artifact` (atomic writes): standard library and
:mod:`gonio_cli.errors` only, so ``gonio --version``, which opens the transaction, stays
light.
"""

from __future__ import annotations

import errno
import os
from pathlib import Path

from .errors import WriteError


def folder_error(folder: str | os.PathLike, exc: OSError) -> WriteError:
    """The one-line error for an output folder that cannot take a file.

    Names the folder (never a temporary file's name) and what to do.
    """
    folder = os.fspath(folder) or "."
    if isinstance(exc, PermissionError):
        return WriteError(f"cannot write to folder {folder}: permission denied",
                          fix="choose another -o or fix the folder's permissions")
    if isinstance(exc, (NotADirectoryError, FileExistsError)):
        return WriteError(f"cannot write to folder {folder}: a file of that name (or of "
                          "one of its parents) is in the way",
                          fix="choose another -o or move that file")
    if isinstance(exc, FileNotFoundError):
        return WriteError(f"folder {folder} does not exist",
                          fix="create it (mkdir -p) or choose another -o")
    reason = exc.strerror or exc.__class__.__name__
    return WriteError(f"cannot write to folder {folder}: {reason}",
                      fix="choose another -o (another disk) or free some space"
                      if exc.errno == errno.ENOSPC else "choose another -o")


def make_folder(folder: str | os.PathLike) -> Path:
    """Create ``folder`` (and its parents) if needed; a failure is a :class:`WriteError`."""
    folder = Path(folder) if str(folder) else Path(".")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except PermissionError:
        parent = next((p for p in folder.parents if os.path.isdir(p)), Path("."))
        raise WriteError(f"cannot create folder {folder}: permission denied in {parent}",
                         fix="choose another -o or fix the permissions of "
                             f"{parent}") from None
    except OSError as exc:  # a file where a folder should be, a read-only disk, ...
        raise folder_error(folder, exc) from None
    return folder
