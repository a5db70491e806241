"""The CSV layer of ``gonio ingest``: delimited text → cells → spectra in one of the layouts.

:func:`read_table` splits a file into a :class:`Table` (``,`` / ``;`` / tab delimiters
tried in :data:`DELIMITERS` order, a decimal comma with ``;``, a UTF-8 BOM, ``#``
comments, preamble lines before the header of instrument exports, row-numbered errors);
:data:`LABEL_COLUMNS` are set aside and :func:`~gonio_cli.csvlayouts.select_sample` picks one sample of a file
that holds several; the layouts (long, wide, multi-angle) that turn a table into
:class:`Spectra` are :mod:`gonio_cli.csvlayouts` (:func:`~gonio_cli.csvlayouts.read_spectra`),
built on this module's table, cell and wavelength checks. :func:`read_columns` and
:func:`read_spectrum` are the readers of every small CSV (sample sets, lights, white
standards). Pure numpy, no heavy import (``gonio ingest`` stays light);
:mod:`gonio_cli.ingest` converts, merges and resamples what these read.
"""

from __future__ import annotations

import csv
import itertools
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from .errors import InputError, binary_kind
from .schemas import MAX_MAGNITUDE
from .spectra import WAVELENGTH_TOL_NM

# ------------------------------------------------------------------------- constants --

#: Two configurations whose angles agree to this many decimals (1e-6°) are the same
#: configuration (repeats); CSV exports print angles with at most a few decimals, so
#: anything closer is float noise, and goniometers are repeatable to ~0.01° at best.
ANGLE_DECIMALS = 6

#: Wavelengths agreeing to this many decimals (1e-6 nm) are one sample, matching
#: :data:`gonio_cli.spectra.WAVELENGTH_TOL_NM` (float noise in CSV headers).
WAVELENGTH_DECIMALS = 6


#: Angles in degrees are refused as radians when every |angle| of a file is at most π/2
#: and they are not all equal: a real degree sweep spans more than 1.57°.
RADIAN_LIMIT = math.pi / 2


#: The header is searched for among the first this many lines with content (preamble
#: lines of instrument exports: job, standard, instrument, illuminant …, a few to a few
#: dozen); a file whose header is not among them gets the first line's error.
HEADER_SEARCH_LINES = 100

#: An error listing the samples of a file names at most this many (then "… N more").
MAX_LISTED_SAMPLES = 10

#: Header names of the angle columns (degrees) and of the multi-angle geometry label.
THETA_I = "theta_i_deg"
THETA_O = "theta_o_deg"
#: The optional detector azimuth column of every layout (docs/conventions.md).
PHI_O = "phi_o_deg"
GEOMETRY = "geometry"
WAVELENGTH = "wavelength_nm"
VALUE = "value"

#: Delimiters tried on the header line, in this order (the first one present wins).
DELIMITERS = ("\t", ";", ",")
#: Their names in messages and in a read's ``info``.
DELIMITER_NAMES = {"\t": "tab", ";": "semicolon", ",": "comma"}

#: Label columns of instrument exports, set aside by name (normalised by
#: :func:`label_kind`: lower case, runs of space, ``_``, ``-``, ``.`` as one space) with
#: what they hold. ``sample`` columns name the sample: a file with several values in one
#: holds several samples (``--sample`` picks one); the first of them in this order that a
#: file has is its sample column. ``note`` columns (dates, operators, comments) are
#: recorded in the summary and otherwise ignored; any other unknown column is an error.
LABEL_COLUMNS: dict[str, str] = {
    **dict.fromkeys(("sample", "sample name", "name", "specimen", "sample id", "id"),
                    "sample"),
    **dict.fromkeys(("date", "time", "date/time", "date time", "datetime", "timestamp",
                     "comment", "comments", "note", "notes", "operator", "user",
                     "standard", "job", "batch", "instrument"), "note"),
}

_LAYOUT_HELP = ("expected theta_i_deg,theta_o_deg,wavelength_nm,value (long), "
                "theta_i_deg,theta_o_deg,<wavelength_nm>,... (wide) or "
                "geometry,<wavelength_nm>,... (multi-angle)")


# ------------------------------------------------------------------------ data types --

@dataclass
class Table:
    """A delimited text file split into cells, comments and blank rows removed.

    Attributes
    ----------
    path : str
    header : list of str, the column names (stripped; trailing empty names removed).
    header_line : int, 1-based line number of the header.
    cells : (n_rows, n_cols) str array.
    lines : (n_rows,) int, 1-based line number of each data row.
    delimiter : str; decimal_comma : bool.
    comment_lines, empty_rows : int, lines skipped.
    preamble_lines : int, lines with content before the header (instrument exports).
    """

    path: str
    header: list[str]
    header_line: int
    cells: np.ndarray
    lines: np.ndarray
    delimiter: str
    decimal_comma: bool
    comment_lines: int
    empty_rows: int
    preamble_lines: int = 0

    def index(self, name: str) -> int:
        """Position of a column by its (lower-case) name."""
        return [h.lower() for h in self.header].index(name)


@dataclass
class Spectra:
    """Spectra of one file (or of merged files) on one wavelength grid.

    Attributes
    ----------
    path : str, the file (``"a.csv, b.csv"`` after merging).
    layout : str, a key of :data:`gonio_cli.csvlayouts.LAYOUTS`.
    wavelength_nm : (n_λ,) float, strictly increasing.
    theta_i_deg, theta_o_deg : (n,) float, degrees, signed as in docs/conventions.md.
    values : (n, n_λ) float, in the units of the file's quantity.
    lines : (n, n_λ) int, 1-based line of each value in its file (for messages).
    columns : (n_λ,) list of str, the column each wavelength was read from.
    info : dict, what was read (delimiter, rows, skipped lines, dropped wavelengths).
    phi_o_deg : (n,) float, the detector's azimuth (degrees, canonical with θo:
        :func:`gonio_cli.geometry.canonical_azimuth`), or None: every row in plane.
    """

    path: str
    layout: str
    wavelength_nm: np.ndarray
    theta_i_deg: np.ndarray
    theta_o_deg: np.ndarray
    values: np.ndarray
    lines: np.ndarray
    columns: list[str]
    info: dict[str, Any] = field(default_factory=dict)
    phi_o_deg: np.ndarray | None = None


@dataclass(frozen=True)
class Layout:
    """A CSV layout: the columns it needs besides the wavelengths, and its reader."""

    name: str
    columns: tuple[str, ...]
    wide: bool  # one column per wavelength (header cells that are numbers)
    example: str
    read: Callable[[Table], Spectra]


# ------------------------------------------------------------------------- reading --

def _read_lines(path: str) -> list[str]:
    """The file's text lines (UTF-8, BOM stripped); refuse a missing or binary file."""
    try:
        data = Path(path).read_bytes()
    except FileNotFoundError:
        raise InputError("no such file", path=path, fix="check the path") from None
    except IsADirectoryError:
        raise InputError("is a folder, not a CSV file", path=path,
                         fix=f"name the CSV files inside it, e.g. {path}/*.csv") from None
    except OSError as exc:
        raise InputError(f"cannot read it ({exc.strerror or exc})", path=path) from None
    kind = binary_kind(data[:16])
    if kind is not None:
        raise InputError(f"not a CSV file ({kind})", path=path,
                         fix="pass the spectra as CSV text (from a spreadsheet: save it as "
                             "CSV UTF-8); the layouts are in docs/ingest.md")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"is not UTF-8 text (byte 0x{data[exc.start]:02x})", path=path,
                         row=data[:exc.start].count(b"\n") + 1,
                         fix="export the CSV as UTF-8") from None
    return text.splitlines()


def _delimiter(header: str, path: str, line: int) -> str:
    for d in DELIMITERS:
        if d in header:
            return d
    raise InputError(f"cannot find a delimiter in the header {header.strip()!r}", path=path,
                     row=line, fix="separate columns with ',', ';' or tab; " + _LAYOUT_HELP)


def label_kind(name: str) -> str | None:
    """``"sample"`` or ``"note"`` for a label column of :data:`LABEL_COLUMNS`, else None.

    >>> label_kind("Date/Time"), label_kind("Sample_ID"), label_kind("380")
    ('note', 'sample', None)
    """
    return LABEL_COLUMNS.get(label_key(name))


def label_key(name: str) -> str:
    """A header name as :data:`LABEL_COLUMNS` spells it (``Sample_ID`` → ``sample id``)."""
    return re.sub(r"[\s_.-]+", " ", name.strip().lower()).strip()


def _header_names(text: str) -> list[str] | None:
    """A line's cells as lower-case header names (None if it has no delimiter)."""
    delim = next((d for d in DELIMITERS if d in text), None)
    if delim is None:
        return None
    cells = next(csv.reader([text], delimiter=delim, skipinitialspace=True), [])
    return [c.strip().lower().replace(",", ".") if delim == ";" else c.strip().lower()
            for c in cells]


#: Every column name of a layout (a header with a mistake still has some).
_KNOWN_NAMES = frozenset((THETA_I, THETA_O, PHI_O, WAVELENGTH, VALUE, GEOMETRY))


def _header_index(content: Sequence[tuple[int, str]],
                  is_header: Callable[[list[str]], bool]) -> int | None:
    """Position in ``content`` of the header: the first line whose cells pass
    ``is_header`` (a layout's header: :func:`gonio_cli.csvlayouts.is_layout_header`), so
    preamble lines before it are skipped. If none does, the first line naming a known
    column (a header with a mistake, reported by the layout checks), else None."""
    fallback = None
    for k, (_, text) in enumerate(content[:HEADER_SEARCH_LINES]):
        names = _header_names(text)
        if names is None:
            continue
        if is_header(names):
            return k
        if fallback is None and any(n in _KNOWN_NAMES or label_kind(n) for n in names):
            fallback = k
    return fallback


def read_table(path: str | os.PathLike, *,
               is_header: Callable[[list[str]], bool] | None = None,
               allow_empty: bool = False) -> Table:
    """Split a delimited file into a :class:`Table`.

    The delimiter is the first of tab, ``;``, ``,`` found in the header line; with ``;``
    a decimal comma is accepted (``0,25`` → 0.25; label columns keep their text). A UTF-8
    BOM, lines starting with ``#`` and rows with no content (blank, or only delimiters)
    are skipped. Every data row must have as many cells as the header.

    The header is the first line with content, or with ``is_header`` the first whose
    cells pass it (the header of one of the layouts, :func:`_header_index`); the lines
    before it are a preamble (``QC JOB:,Job …`` of an instrument export), counted and skipped.
    A header without data rows is an error, or with ``allow_empty`` a table of no rows.
    """
    path = os.fspath(path)
    raw = _read_lines(path)
    lead = list(map(str.lstrip, raw))  # (one C loop per step: 15 000-line files)
    comments = sum(1 for t in lead if t[:1] == "#")
    content = [(n, s) for n, s, t in zip(itertools.count(1), raw, lead) if t and t[0] != "#"]
    if not content:
        raise InputError("empty file (no header and no data rows)", path=path,
                         fix="export the measurement again; " + _LAYOUT_HELP)
    preamble = _header_index(content, is_header) if is_header is not None else 0
    if preamble is None:
        if any(d in content[0][1] for d in DELIMITERS):
            n = min(len(content), HEADER_SEARCH_LINES)
            raise InputError(f"has no header: none of its first {n} lines with content "
                             "names the columns of a layout", path=path, row=content[0][0],
                             fix="add the header line; " + _LAYOUT_HELP)
        preamble = 0  # no delimiter either: that error, on the first line
    content = content[preamble:]
    header_line, header_text = content[0]
    delim = _delimiter(header_text, path, header_line)
    decimal_comma = delim == ";"
    texts = [s for _, s in content]
    names = next(csv.reader(texts[:1], delimiter=delim, skipinitialspace=True))
    labels = [k for k, h in enumerate(names) if label_kind(h)]
    if decimal_comma and not labels:
        texts = [s.replace(",", ".") for s in texts]
    plain = None if decimal_comma and labels else _plain_rows(texts, delim)
    if plain is not None:
        return _plain_table(path, plain, [n for n, _ in content], delim, decimal_comma,
                            comments, preamble, allow_empty)
    rows = [[c.strip() for c in r]
            for r in csv.reader(texts, delimiter=delim, skipinitialspace=True)]
    if decimal_comma and labels:  # decimal commas in the numbers, not in the labels
        keep = set(labels)
        rows = [[c if k in keep else c.replace(",", ".") for k, c in enumerate(r)]
                for r in rows]
    header, data = rows[0], rows[1:]
    while header and not header[-1]:  # a trailing delimiter, common in exports
        header.pop()
    width = len(header)
    lines = [n for n, _ in content[1:]]
    keep = [any(r) for r in data]
    empty = keep.count(False)
    data = [r for r, k in zip(data, keep) if k]
    lines = [n for n, k in zip(lines, keep) if k]
    if not data and not allow_empty:
        raise InputError("has a header but no data rows", path=path, row=header_line,
                         fix="export the measurement again")
    for r, n in zip(data, lines):
        # Extra cells are tolerated only when empty (trailing delimiters).
        if len(r) < width or any(r[width:]):
            raise InputError(f"has {len(r)} cells, the header has {width}", path=path, row=n,
                             fix="every row needs one cell per column"
                             + ("; with decimal commas, separate columns with ';'"
                                if delim == "," else ""))
    cells = np.array([r[:width] for r in data], dtype=str).reshape(len(data), width)
    return Table(path, header, header_line, cells, np.asarray(lines, dtype=int), delim,
                 decimal_comma, comments, empty, preamble)


#: Characters that make the csv module's reading of a line differ from splitting it at
#: the delimiter (quoting; line ends and NUL, which it treats specially).
_CSV_SPECIAL = ('"', "\r", "\n", "\0")


def _plain_rows(texts: list[str], delim: str) -> tuple[list[str], np.ndarray] | None:
    """The header cells and the data cells (n_rows, n_cells) of ``texts`` (header line
    first), each stripped, split in one go: what :func:`read_table`'s ``csv.reader`` with
    ``skipinitialspace`` and ``strip`` gives, for the usual file where no cell is quoted
    and every line has the header's number of cells. None for any other file (the csv
    module reads it, and reports a row that is short)."""
    joined = "".join(texts)
    if len(texts) < 2 or any(c in joined for c in _CSV_SPECIAL):
        return None
    n = texts[0].count(delim)
    if any(s.count(delim) != n for s in texts):
        return None
    header = [c.strip() for c in texts[0].split(delim)]
    flat = [c.strip() for c in delim.join(texts[1:]).split(delim)]
    return header, np.array(flat, dtype=str).reshape(len(texts) - 1, n + 1)


def _plain_table(path: str, plain: tuple[list[str], np.ndarray], lines: list[int],
                 delim: str, decimal_comma: bool, comments: int, preamble: int,
                 allow_empty: bool = False) -> Table:
    """:func:`read_table`'s checks and :class:`Table` for the cells of :func:`_plain_rows`
    (``lines``: the 1-based line of the header and of each row), vectorised."""
    header, data = plain
    while header and not header[-1]:  # a trailing delimiter, common in exports
        header.pop()
    width = len(header)
    keep = (data != "").any(axis=1)
    rows = np.asarray(lines[1:], dtype=int)[keep]
    data = data[keep]
    if not len(data) and not allow_empty:
        raise InputError("has a header but no data rows", path=path, row=lines[0],
                         fix="export the measurement again")
    extra = np.flatnonzero((data[:, width:] != "").any(axis=1))
    if extra.size:  # extra cells are tolerated only when empty (trailing delimiters)
        raise InputError(f"has {data.shape[1]} cells, the header has {width}", path=path,
                         row=int(rows[extra[0]]),
                         fix="every row needs one cell per column"
                         + ("; with decimal commas, separate columns with ';'"
                            if delim == "," else ""))
    cells = np.ascontiguousarray(data[:, :width])
    return Table(path, header, lines[0], cells, rows, delim, decimal_comma, comments,
                 int(keep.size - np.count_nonzero(keep)), preamble)


def float_cells(table: Table, cols: Sequence[int]) -> np.ndarray:
    """Cells of the given columns as finite floats, (n_rows, len(cols)); else InputError."""
    sub = table.cells[:, list(cols)]
    try:
        out = sub.astype(float)
    except ValueError:
        out = None
    if out is None:
        for r, c in np.ndindex(sub.shape):
            try:
                float(sub[r, c])
            except ValueError:
                cell = str(sub[r, c])
                what = f"cell {cell!r} is not a number" if cell else "cell is empty"
                raise InputError(what, path=table.path, row=int(table.lines[r]),
                                 column=table.header[cols[c]],
                                 fix="write plain numbers, '.' or (with ';') ',' as decimal "
                                     "mark") from None
        raise InputError("holds a cell numpy cannot read as a number", path=table.path)
    bad = ~(np.abs(out) <= MAX_MAGNITUDE)              # NaN, inf, or beyond any unit error
    if bad.any():
        r, c = np.argwhere(bad)[0]
        what = ("is not finite (NaN or inf)" if not np.isfinite(out[r, c]) else
                f"is beyond ±{MAX_MAGNITUDE:g} (docs/conventions.md, Numeric ranges)")
        raise InputError(f"value {sub[r, c]} {what}", path=table.path,
                         row=int(table.lines[r]), column=table.header[cols[c]],
                         fix="remove the row or measure the configuration again")
    return out


def header_wavelength(text: str) -> float | None:
    """A header cell as a wavelength in nm, or None if it is a name."""
    try:
        value = float(text)
    except ValueError:
        return None
    return value if math.isfinite(value) else None


def check_wavelengths(wl: np.ndarray, names: Sequence[str], path: str, line,
                       column: str | None = None) -> None:
    """Wavelengths (nm) must be positive, strictly increasing and unique.

    ``line``: the header's line (wavelengths in the header, ``names`` their cells), or
    (n,) the line of each wavelength (a column of them, named ``column``)."""
    def where(k: int) -> dict:
        row = line if np.ndim(line) == 0 else int(line[k])
        return {"path": path, "row": row, "column": column or names[k]}

    if wl.size and wl[0] <= 0:
        raise InputError(f"wavelength {names[0]} nm is not positive", **where(0),
                         fix="wavelengths are in nm, e.g. 380")
    step = np.diff(wl)
    bad = np.flatnonzero(step <= WAVELENGTH_TOL_NM)
    if bad.size:
        k = int(bad[0]) + 1
        what = "repeats" if abs(step[k - 1]) <= WAVELENGTH_TOL_NM else "decreases"
        raise InputError(f"wavelength {names[k]} nm {what} (after {names[k - 1]} nm)",
                         **where(k),
                         fix="wavelengths must be strictly increasing and unique")



def read_columns(path: str | os.PathLike, columns: Sequence[str], what: str, *,
                 allow_empty: bool = False) -> tuple[np.ndarray, Table]:
    """Read a small CSV whose header is exactly ``columns`` (any case, any order refused).

    The one reader of gonio's auxiliary CSV files (a white standard, a dark, a light's
    spectrum, a sample set): the delimiters, decimal commas, BOM, ``#`` comments and blank
    rows of :func:`read_table`, every cell a finite number (:func:`float_cells`), and every
    error an :class:`InputError` naming the file, the line and the column. ``what`` names
    the file in messages (``"the white standard spectrum"``). Returns the values
    (n_rows, len(columns)) and the :class:`Table` (its ``lines`` give each row's line);
    ``allow_empty`` accepts a header without rows (then n_rows = 0).
    """
    table = read_table(path, allow_empty=allow_empty)
    if [h.lower() for h in table.header] != [c.lower() for c in columns]:
        raise InputError(f"{what} has columns {','.join(table.header)}",
                         path=table.path, row=table.header_line,
                         fix=f"its header is {','.join(columns)}")
    return float_cells(table, range(len(columns))), table


def read_spectrum(path: str | os.PathLike, role: str) -> tuple[np.ndarray, np.ndarray, Table]:
    """Read a single spectrum CSV with columns ``wavelength_nm,value``.

    ``role`` names it in messages (``"white standard"``, ``"dark"``, ``"light"``). Returns
    the wavelengths (n,) nm, positive and strictly increasing (an error names the row that
    is not), the values (n,) and the :class:`Table`. Read by :func:`read_columns`, so a
    file ``gonio ingest`` accepts as a white standard is accepted as a light by
    ``gonio render`` too.
    """
    values, table = read_columns(path, (WAVELENGTH, VALUE), f"the {role} spectrum")
    wl, v = values.T
    check_wavelengths(wl, [f"{w:g}" for w in wl], table.path, table.lines,
                       column=table.header[0])
    return wl, v, table


def grid_text(wl: np.ndarray) -> str:
    """``"380–780 nm step 10 (41 samples)"`` for messages and the summary."""
    steps = np.diff(wl)
    if steps.size and np.allclose(steps, steps[0], atol=WAVELENGTH_TOL_NM):
        step = f" step {steps[0]:g}"
    else:
        step = " non-uniform" if steps.size else ""
    return f"{wl[0]:g}-{wl[-1]:g} nm{step} ({wl.size} samples)"
