"""The CSV layer of ``gonio ingest``: delimited text → cells → spectra in one of the layouts.

:func:`read_table` splits a file into a :class:`Table` (``,`` / ``;`` / tab delimiters
tried in :data:`DELIMITERS` order, a decimal comma with ``;``, a UTF-8 BOM, ``#``
comments, preamble lines before the header of instrument exports, row-numbered errors);
:data:`LABEL_COLUMNS` are set aside and :func:`select_sample` picks one sample of a file
that holds several; :data:`LAYOUTS` (long, wide, multi-angle, detected from the header)
turn a table into :class:`Spectra` (:func:`read_spectra`). :func:`read_columns` and
:func:`read_spectrum` are the readers of every small CSV (sample sets, lights, white
standards). Pure numpy, no heavy import (``gonio ingest`` stays light). Re-exported by
:mod:`gonio_cli.ingest`, which converts, merges and resamples what this reads.

Why one module: the readers, the checks of cells, angles and wavelengths and the three
layouts share the :class:`Table` and its row-numbered errors; split further, each part
would import the others' private checks.
"""

from __future__ import annotations

import csv
import itertools
import math
import os
import re
from dataclasses import dataclass, field, replace
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
GEOMETRY = "geometry"
WAVELENGTH = "wavelength_nm"
VALUE = "value"

#: Delimiters tried on the header line, in this order (the first one present wins).
DELIMITERS = ("\t", ";", ",")
_DELIMITER_NAMES = {"\t": "tab", ";": "semicolon", ",": "comma"}

#: ASTM E2194 aspecular label: ``45as15`` = light at 45°, detector 15° from the specular
#: direction towards the light (θo = 45 − 15 = 30°); a degree sign is tolerated.
_ASPECULAR = re.compile(r"^\s*(\d+(?:\.\d*)?)\s*°?\s*as\s*([+-]?\d+(?:\.\d*)?)\s*°?\s*$",
                        re.IGNORECASE)

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
    layout : str, a key of :data:`LAYOUTS`.
    wavelength_nm : (n_λ,) float, strictly increasing.
    theta_i_deg, theta_o_deg : (n,) float, degrees, signed as in docs/conventions.md.
    values : (n, n_λ) float, in the units of the file's quantity.
    lines : (n, n_λ) int, 1-based line of each value in its file (for messages).
    columns : (n_λ,) list of str, the column each wavelength was read from.
    info : dict, what was read (delimiter, rows, skipped lines, dropped wavelengths).
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
    return LABEL_COLUMNS.get(_label_key(name))


def _label_key(name: str) -> str:
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


def is_layout_header(names: Sequence[str]) -> bool:
    """Whether header cells ``names`` (lower case) hold every column of the layout they
    select (:func:`detect_layout`), label columns and empty cells aside."""
    columns = [n for n in names if n and label_kind(n) is None]
    return all(c in columns for c in detect_layout(columns).columns)


#: Every column name of a layout (a header with a mistake still has some).
_KNOWN_NAMES = frozenset((THETA_I, THETA_O, WAVELENGTH, VALUE, GEOMETRY))


def _header_index(content: Sequence[tuple[int, str]]) -> int | None:
    """Position in ``content`` of the header: the first line that is a layout's header
    (:func:`is_layout_header`), so preamble lines before it are skipped. If none is, the
    first line naming a known column (a header with a mistake, reported by the layout
    checks), else None."""
    fallback = None
    for k, (_, text) in enumerate(content[:HEADER_SEARCH_LINES]):
        names = _header_names(text)
        if names is None:
            continue
        if is_layout_header(names):
            return k
        if fallback is None and any(n in _KNOWN_NAMES or label_kind(n) for n in names):
            fallback = k
    return fallback


def read_table(path: str | os.PathLike, *, find_header: bool = False,
               allow_empty: bool = False) -> Table:
    """Split a delimited file into a :class:`Table`.

    The delimiter is the first of tab, ``;``, ``,`` found in the header line; with ``;``
    a decimal comma is accepted (``0,25`` → 0.25; label columns keep their text). A UTF-8
    BOM, lines starting with ``#`` and rows with no content (blank, or only delimiters)
    are skipped. Every data row must have as many cells as the header.

    The header is the first line with content, or with ``find_header`` the first that is
    the header of one of the :data:`LAYOUTS` (:func:`_header_index`); the lines before it
    are a preamble (``QC JOB:,Job …`` of an instrument export), counted and skipped.
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
    preamble = _header_index(content) if find_header else 0
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


# ---------------------------------------------------------- labels and samples --

def split_labels(table: Table) -> tuple[Table, dict[str, np.ndarray]]:
    """Set aside the label columns (:data:`LABEL_COLUMNS`) of a table.

    Returns the table without them and ``{header name: (n_rows,) str}`` in file order
    (the first of two columns with one name).
    """
    labels: dict[str, np.ndarray] = {}
    keep = []
    for k, h in enumerate(table.header):
        if label_kind(h):
            labels.setdefault(h, table.cells[:, k])
        else:
            keep.append(k)
    if not labels:
        return table, labels
    return replace(table, header=[table.header[k] for k in keep],
                   cells=table.cells[:, keep]), labels


def _listing(names: Sequence[str]) -> str:
    """Sample names for a message, at most :data:`MAX_LISTED_SAMPLES` of them."""
    shown = [n if n else "(empty)" for n in names[:MAX_LISTED_SAMPLES]]
    more = len(names) - len(shown)
    return ", ".join(shown) + (f", ... ({more} more)" if more else "")


def select_sample(table: Table, labels: dict[str, np.ndarray],
                  sample: str | None) -> tuple[Table, dict[str, Any]]:
    """Keep the rows of one sample of a table with its labels set aside.

    The sample column is the first ``sample`` label of :data:`LABEL_COLUMNS` the file
    has. Several names in it are several samples: ``sample`` must then name one
    (exactly as written), and it must name one whenever it is given. Returns the table
    of its rows and what :attr:`Spectra.info` records: ``label_columns``,
    ``sample_column``, ``sample``, ``samples`` (every name, in file order) and
    ``rows_other_samples``.
    """
    order = list(LABEL_COLUMNS)
    columns = sorted((h for h in labels if label_kind(h) == "sample"),
                     key=lambda h: order.index(_label_key(h)))
    column = columns[0] if columns else None
    info: dict[str, Any] = {"label_columns": list(labels), "sample_column": column,
                            "sample": None, "samples": [], "rows_other_samples": 0}
    if column is None:
        if sample is not None:
            raise InputError(f"--sample {sample!r} is given, but the file has no column "
                             "naming samples", path=table.path, row=table.header_line,
                             fix="drop --sample, or name the samples in a column "
                                 "Name, Sample or ID")
        return table, info
    values = labels[column]
    names = list(dict.fromkeys(values.tolist()))
    info["samples"] = names
    if sample is None:
        if len(names) > 1:
            k = int(np.flatnonzero(values != names[0])[0])
            raise InputError(f"holds {len(names)} samples ({_listing(names)})",
                             path=table.path, row=int(table.lines[k]), column=column,
                             fix="pick one with --sample NAME")
        info["sample"] = names[0]
        return table, info
    if sample not in names:
        raise InputError(f"holds no sample {sample!r}, only {_listing(names)}",
                         path=table.path, row=table.header_line, column=column,
                         fix="pick one of those with --sample NAME, exactly as written")
    rows = values == sample
    info.update(sample=sample, rows_other_samples=int(np.count_nonzero(~rows)))
    return replace(table, cells=table.cells[rows], lines=table.lines[rows]), info


def _floats(table: Table, cols: Sequence[int]) -> np.ndarray:
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


def _wavelength_columns(table: Table) -> tuple[list[int], np.ndarray]:
    """Indices and values (nm) of the numeric header cells, checked increasing."""
    idx = [k for k, h in enumerate(table.header) if header_wavelength(h) is not None]
    wl = np.array([header_wavelength(table.header[k]) for k in idx], dtype=float)
    _check_wavelengths(wl, [table.header[k] for k in idx], table.path, table.header_line)
    return idx, wl


def _check_wavelengths(wl: np.ndarray, names: Sequence[str], path: str, line,
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


def _check_header(table: Table, layout: Layout) -> None:
    """Refuse unknown and missing columns (STYLE 7), naming them: an unknown one first, as
    a misspelt name (``Geometri``) is what leaves the right one missing."""
    names = [h.lower() for h in table.header]
    # a header with wavelength columns may be meant as either layout that has them
    example = (" or ".join(lay.example for lay in LAYOUTS.values() if lay.wide)
               if layout.wide else layout.example)
    allowed = set(layout.columns)
    for h in table.header:
        is_wl = layout.wide and header_wavelength(h) is not None
        if not is_wl and h.lower() not in allowed:
            raise InputError(f"unknown column {h!r} in the {layout.name} layout",
                             path=table.path, row=table.header_line, column=h or "(empty)",
                             fix=f"{example} (label columns such as Name, Sample, ID, "
                                 "Date/Time are set aside)")
    for name in layout.columns:
        if name not in names:
            raise InputError(f"missing column {name!r} for the {layout.name} layout",
                             path=table.path, row=table.header_line, fix=example)
    dup = [h for h in layout.columns if names.count(h) > 1]
    if dup:
        raise InputError(f"column {dup[0]!r} appears twice", path=table.path,
                         row=table.header_line, fix=layout.example)
    if layout.wide and not any(header_wavelength(h) is not None for h in table.header):
        raise InputError("has no wavelength columns", path=table.path, row=table.header_line,
                         fix=layout.example)


def _check_angles(theta_i, theta_o, lines, path, labels=None) -> None:
    """θi in [0, 90), θo in (−90, 90) (docs/conventions.md), and not radians. (n,) each.

    ``labels`` (n,) are the multi-angle geometry labels the angles came from, if any.
    """
    for theta, name, ok, rng in ((theta_i, THETA_I, (theta_i >= 0) & (theta_i < 90),
                                  "[0, 90)"),
                                 (theta_o, THETA_O, np.abs(theta_o) < 90, "(-90, 90)")):
        bad = np.flatnonzero(~ok)
        if bad.size:
            k = int(bad[0])
            source = f"{labels[k]} gives " if labels is not None else ""
            raise InputError(f"{source}{name}={theta[k]:g}, outside {rng}", path=path,
                             row=int(lines[k]),
                             column=GEOMETRY if labels is not None else name,
                             fix="angles are degrees, theta_i from the normal, theta_o "
                                 "signed (> 0 on the far side); fix or drop the row")
    both = np.concatenate([theta_i, theta_o])
    if np.max(np.abs(both)) <= RADIAN_LIMIT and np.ptp(both) > 0:
        raise InputError(f"every angle is within +-pi/2 (largest |angle| "
                         f"{np.max(np.abs(both)):.3g}): they look like radians",
                         path=path, column=GEOMETRY if labels is not None else
                         f"{THETA_I}, {THETA_O}",
                         fix="write angles in degrees (multiply by 180/pi)")


def rounded_keys(*cols: np.ndarray) -> np.ndarray:
    """(n, k) array of angle columns rounded to :data:`ANGLE_DECIMALS` (grouping keys)."""
    return np.round(np.stack(cols, axis=-1), ANGLE_DECIMALS) + 0.0  # + 0.0: −0 → 0


def _read_long(table: Table) -> Spectra:
    """Long layout: one row per (θi, θo, λ); repeats are later rows of the same triple."""
    cols = [table.index(n) for n in (THETA_I, THETA_O, WAVELENGTH, VALUE)]
    ti, to, wl, v = _floats(table, cols).T
    _check_angles(ti, to, table.lines, table.path)
    wl_r = np.round(wl, WAVELENGTH_DECIMALS)
    if wl_r.min() <= 0:
        k = int(np.argmin(wl_r))
        raise InputError(f"wavelength {wl[k]:g} nm is not positive", path=table.path,
                         row=int(table.lines[k]), column=WAVELENGTH,
                         fix="wavelengths are in nm, e.g. 380")
    w_u, j = np.unique(wl_r, return_inverse=True)
    cfg_u, c = np.unique(rounded_keys(ti, to), axis=0, return_inverse=True)
    j, c = j.reshape(-1), c.reshape(-1)
    n_wl = w_u.size
    rep = _occurrence(c * n_wl + j)
    spec_u, s = np.unique(c * (rep.max() + 1) + rep, return_inverse=True)
    s = s.reshape(-1)
    counts = np.bincount(s, minlength=spec_u.size)
    short = np.flatnonzero(counts != n_wl)
    if short.size:
        _incomplete_long(table, s, j, short[0], ti, to, rep, w_u)
    values = np.empty((spec_u.size, n_wl))
    lines = np.empty((spec_u.size, n_wl), dtype=int)
    values[s, j] = v
    lines[s, j] = table.lines
    cfg_of = c[np.unique(s, return_index=True)[1]]
    return Spectra(table.path, "long", w_u, cfg_u[cfg_of, 0], cfg_u[cfg_of, 1], values,
                   lines, [VALUE] * n_wl)


def _occurrence(key: np.ndarray) -> np.ndarray:
    """For each row (n,), how many earlier rows (in file order) have the same ``key``:
    the repeat index of a long-layout row, whose key is its (configuration, λ)."""
    n = key.size
    order = np.argsort(key, kind="stable")  # stable: file order within a key
    sorted_key = key[order]
    first = np.r_[True, sorted_key[1:] != sorted_key[:-1]]
    start = np.maximum.accumulate(np.where(first, np.arange(n), 0))
    out = np.empty(n, dtype=int)
    out[order] = np.arange(n) - start
    return out


def _incomplete_long(table, s, j, spec, ti, to, rep, w_u) -> None:
    """Name the first spectrum of a long file that lacks a wavelength, then raise."""
    rows = np.flatnonzero(s == spec)
    have = np.zeros(w_u.size, dtype=bool)
    have[j[rows]] = True
    k = rows[0]
    missing = w_u[~have]
    raise InputError(f"theta_i_deg={ti[k]:g}, theta_o_deg={to[k]:g} (repeat {rep[k] + 1}) "
                     f"has no value at {missing[0]:g} nm, which other rows have",
                     path=table.path, row=int(table.lines[k]), column=WAVELENGTH,
                     fix="every configuration (and every repeat of it) needs every "
                         "wavelength once")


def _wide_spectra(table: Table, layout: str, ti, to) -> Spectra:
    idx, wl = _wavelength_columns(table)
    values = _floats(table, idx)
    lines = np.broadcast_to(table.lines[:, None], values.shape).copy()
    return Spectra(table.path, layout, wl, ti, to, values, lines,
                   [table.header[k] for k in idx])


def _read_wide(table: Table) -> Spectra:
    """Wide layout: one row per measured spectrum, one column per wavelength (nm)."""
    ti, to = _floats(table, [table.index(THETA_I), table.index(THETA_O)]).T
    _check_angles(ti, to, table.lines, table.path)
    return _wide_spectra(table, "wide", ti, to)


def aspecular_angles(label: str) -> tuple[float, float] | None:
    """θi and θo (degrees) of an ASTM E2194 multi-angle label, or None if it is not one.

    ``"45as15"`` is light at 45° and the detector 15° from the specular direction towards
    the light, so θo = 45 − 15 = 30°; ``"45as-15"`` → 60°; ``"45as110"`` → −65°.

    >>> aspecular_angles("45as110")
    (45.0, -65.0)
    """
    m = _ASPECULAR.match(label)
    if m is None:
        return None
    theta_i = float(m.group(1))
    return theta_i, float(theta_o_of_aspecular(theta_i, float(m.group(2))))


def theta_o_of_aspecular(theta_i_deg, aspecular_deg):
    """θo = θi − a (degrees, docs/conventions.md): the detector ``aspecular_deg`` from the
    specular direction towards the light (ASTM E2194; CxF3's ``Aspecular``)."""
    return np.asarray(theta_i_deg, dtype=float) - np.asarray(aspecular_deg, dtype=float)


def aspecular_of_theta_o(theta_i_deg, theta_o_deg):
    """The aspecular angle a = θi − θo (degrees) of an in-plane configuration: the inverse
    of :func:`theta_o_of_aspecular`."""
    return np.asarray(theta_i_deg, dtype=float) - np.asarray(theta_o_deg, dtype=float)


def _read_multiangle(table: Table) -> Spectra:
    """Multi-angle layout: a ``geometry`` label (``45as15``) per row, wavelengths wide."""
    labels = [str(g) for g in table.cells[:, table.index(GEOMETRY)]]
    angles = [aspecular_angles(g) for g in labels]
    for g, a, n in zip(labels, angles, table.lines):
        if a is None:
            raise InputError(f"geometry {g!r} is not an aspecular label", path=table.path,
                             row=int(n), column=GEOMETRY,
                             fix="write <theta_i>as<aspecular angle>, e.g. 45as15 or 45as-15")
    ti, to = np.array(angles, dtype=float).reshape(-1, 2).T
    _check_angles(ti, to, table.lines, table.path, labels=labels)
    return _wide_spectra(table, "multi-angle", ti, to)


#: The CSV layouts, detected from the header by :func:`detect_layout` (STYLE 3).
LAYOUTS: dict[str, Layout] = {
    "long": Layout("long", (THETA_I, THETA_O, WAVELENGTH, VALUE), False,
                   "long layout header: theta_i_deg,theta_o_deg,wavelength_nm,value",
                   _read_long),
    "wide": Layout("wide", (THETA_I, THETA_O), True,
                   "wide layout header: theta_i_deg,theta_o_deg,380,390,...,780",
                   _read_wide),
    "multi-angle": Layout("multi-angle", (GEOMETRY,), True,
                          "multi-angle layout header: geometry,380,390,...,780",
                          _read_multiangle),
}


def detect_layout(header: Sequence[str]) -> Layout:
    """The :class:`Layout` of a header: wavelength columns → wide (or multi-angle with a
    ``geometry`` column), otherwise long."""
    names = [h.strip().lower() for h in header]
    if any(header_wavelength(h) is not None for h in names):
        return LAYOUTS["multi-angle" if GEOMETRY in names else "wide"]
    return LAYOUTS["long"]


def read_spectra(path: str | os.PathLike, sample: str | None = None) -> Spectra:
    """Read and check one goniometer CSV (any of :data:`LAYOUTS`).

    Preamble lines before the header are skipped (:func:`read_table`), label columns set
    aside (:func:`split_labels`) and, of a file holding several samples, the rows of
    ``sample`` kept (:func:`select_sample`).

    Returns
    -------
    Spectra
        One spectrum per data row (wide, multi-angle) or per (θi, θo, repeat) (long), on
        the file's own wavelengths, in the file's units; nothing converted or resampled.
    """
    table, labels = split_labels(read_table(path, find_header=True))
    layout = detect_layout(table.header)
    _check_header(table, layout)
    rows_read = int(table.lines.size)
    table, samples = select_sample(table, labels, sample)
    spectra = layout.read(table)
    spectra.info = {"path": table.path, "layout": layout.name,
                    "header_line": table.header_line,
                    "delimiter": _DELIMITER_NAMES[table.delimiter],
                    "decimal_comma": table.decimal_comma, "rows": rows_read,
                    "spectra": int(spectra.values.shape[0]),
                    "preamble_lines": table.preamble_lines,
                    "comment_lines": table.comment_lines, "empty_rows": table.empty_rows,
                    **samples,
                    "wavelength_nm": grid_text(spectra.wavelength_nm)}
    return spectra


def read_columns(path: str | os.PathLike, columns: Sequence[str], what: str, *,
                 allow_empty: bool = False) -> tuple[np.ndarray, Table]:
    """Read a small CSV whose header is exactly ``columns`` (any case, any order refused).

    The one reader of gonio's auxiliary CSV files (a white standard, a dark, a light's
    spectrum, a sample set): the delimiters, decimal commas, BOM, ``#`` comments and blank
    rows of :func:`read_table`, every cell a finite number (:func:`_floats`), and every
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
    return _floats(table, range(len(columns))), table


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
    _check_wavelengths(wl, [f"{w:g}" for w in wl], table.path, table.lines,
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
