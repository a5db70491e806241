"""The ingest stage: goniometer CSV spectra → one :class:`~gonio_cli.schemas.Measurement`.

Pure numpy core (STYLE 1): it never imports typer and never prints. Warnings go through
:func:`gonio_cli.log.warn`, and only once everything has been read and checked, so a run
that fails prints exactly one line (the error). Everything the user can fix raises
:class:`~gonio_cli.errors.InputError` naming the file, the line (1-based, as an editor
shows it), the column, the value and the fix.

Pipeline of :func:`ingest`, per input file and then for all of them:

1. :func:`read_spectra` reads a CSV in one of the :data:`LAYOUTS` (long, wide,
   multi-angle; detected from the header), with ``,`` / ``;`` / tab delimiters, a decimal
   comma when the delimiter is ``;``, a UTF-8 BOM and ``#`` comment lines; it checks every
   cell (numeric, finite), the angles (ranges, radians) and the wavelengths (increasing,
   unique). Instrument exports as a spreadsheet saves them are read too: preamble lines
   before the header (the header is the first line that is one of a layout's), label
   columns (:data:`LABEL_COLUMNS`: ``Name``, ``Date/Time`` …) set aside, and of a file
   that holds several samples the one ``--sample`` names.
2. The file's grid must cover the working grid (``--grid-nm``); wavelengths the
   resampling does not use are dropped (seed 000 trims its spectra to 380–780 nm).
3. ``--dark`` is subtracted (seed 004 §3), the values are multiplied by ``--scale``, then
   negative values are checked: beyond noise they are an error, small ones are clipped
   after averaging (step 6).
4. Files merge (they must share their grid) and the values are converted to BRDF in sr⁻¹
   by the quantity's rule (:data:`QUANTITIES`, seed 004 eqs. 5, 7, 8). A file whose values
   look like percent (:func:`check_percent`) is refused.
5. Repeated rows of one configuration are averaged, their sample standard deviation kept
   (seed 000 averages ten spectra per configuration).
6. Small negative means are clipped to 0 (counted), and everything is resampled onto
   the working grid (:func:`gonio_cli.spectra.resample`), with a warning if the grid
   differs.

Arrays: wavelength is the last axis (STYLE 6); ``values`` are (n_spectra, n_λ).
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

from . import log
from .errors import InputError, binary_kind
from .schemas import MAX_MAGNITUDE, Measurement
from .spectra import DEFAULT_GRID_NM, WAVELENGTH_TOL_NM, covers, parse_grid, resample, same_grid

# ------------------------------------------------------------------------- constants --

#: Two configurations whose angles agree to this many decimals (1e-6°) are the same
#: configuration (repeats); CSV exports print angles with at most a few decimals, so
#: anything closer is float noise, and goniometers are repeatable to ~0.01° at best.
ANGLE_DECIMALS = 6

#: Wavelengths agreeing to this many decimals (1e-6 nm) are one sample, matching
#: :data:`gonio_cli.spectra.WAVELENGTH_TOL_NM` (float noise in CSV headers).
WAVELENGTH_DECIMALS = 6

#: A negative value more negative than this fraction of the file's largest value is not
#: noise: a spectrometer with the 900:1 dynamic range of seed 004 §3 has a noise floor of
#: ~0.1 % of full scale; 1 % leaves a factor ~10 for dark drift between dark and sample.
#: Smaller negatives are noise around a zero signal and are clipped to 0 (counted).
NEGATIVE_NOISE_FRACTION = 0.01

#: Angles in degrees are refused as radians when every |angle| of a file is at most π/2
#: and they are not all equal: a real degree sweep spans more than 1.57°.
RADIAN_LIMIT = math.pi / 2

#: Reflectance of the white standard when ``--white-reflectance`` is not given: the 99 %
#: Spectralon of seed 000 ("Preparation and measurement"), docs/conventions.md.
DEFAULT_WHITE_REFLECTANCE = 0.99

#: A file whose median value is above this, in the quantity's :attr:`Quantity.level`, is
#: in percent (``--scale 0.01``), not fractions. A perfect white diffuser has reflectance
#: factor 1 at every geometry and matte samples stay below it (the MA-T12 green earth of
#: tests/fixtures/real: median 0.50); a glossy sample exceeds 1 only near the specular
#: direction, a few configurations of a goniometric sweep, so its median stays far lower
#: (the sample red ink: median BRDF 0.040 sr^-1, peak 7.2; an RGL colour-shifting wrap in
#: plane: median 0.018 sr^-1, peak 22). Percent data lands above 1.5 unless the sample
#: reflects under 1.5 % at most geometries (then it cannot be told from fractions). For
#: ``brdf`` the limit is 1.5 sr^-1, a reflectance factor of 4.7 at most configurations.
PERCENT_MEDIAN_LIMIT = 1.5

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


@dataclass(frozen=True)
class Quantity:
    """What an instrument reports, and its conversion to BRDF (sr⁻¹, no cos θi factor).

    ``convert(values, theta_o_deg=, white=, solid_angle_sr=)`` maps (n, n_λ) values to BRDF;
    ``options`` names the CLI options it needs (refused for the other quantities).
    ``level(values, brdf)`` is the (n, n_λ) figure :func:`check_percent` compares with
    :data:`PERCENT_MEDIAN_LIMIT` (``level_name`` says what it is in messages), and
    ``percent_fix`` the options that read percent values of this quantity.
    """

    name: str
    formula: str
    citation: str
    options: tuple[str, ...]
    convert: Callable[..., np.ndarray]
    level: Callable[[np.ndarray, np.ndarray], np.ndarray]
    level_name: str
    percent_fix: str


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


def _number(text: str) -> float | None:
    """A header cell as a wavelength in nm, or None if it is a name."""
    try:
        value = float(text)
    except ValueError:
        return None
    return value if math.isfinite(value) else None


def _wavelength_columns(table: Table) -> tuple[list[int], np.ndarray]:
    """Indices and values (nm) of the numeric header cells, checked increasing."""
    idx = [k for k, h in enumerate(table.header) if _number(h) is not None]
    wl = np.array([_number(table.header[k]) for k in idx], dtype=float)
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
        is_wl = layout.wide and _number(h) is not None
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
    if layout.wide and not any(_number(h) is not None for h in table.header):
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


def _rounded_keys(*cols: np.ndarray) -> np.ndarray:
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
    cfg_u, c = np.unique(_rounded_keys(ti, to), axis=0, return_inverse=True)
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
    theta_i, aspecular = float(m.group(1)), float(m.group(2))
    return theta_i, theta_i - aspecular


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
    if any(_number(h) is not None for h in names):
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
                    "wavelength_nm": _grid_text(spectra.wavelength_nm)}
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


# ------------------------------------------------------------------ grid handling --

def _grid_text(wl: np.ndarray) -> str:
    """``"380–780 nm step 10 (41 samples)"`` for messages and the summary."""
    steps = np.diff(wl)
    if steps.size and np.allclose(steps, steps[0], atol=WAVELENGTH_TOL_NM):
        step = f" step {steps[0]:g}"
    else:
        step = " non-uniform" if steps.size else ""
    return f"{wl[0]:g}-{wl[-1]:g} nm{step} ({wl.size} samples)"


def used_wavelengths(wavelength_nm: np.ndarray, grid_nm: np.ndarray) -> slice:
    """The input samples :func:`gonio_cli.spectra.resample` onto ``grid_nm`` can use.

    Resampling looks at most one grid step beyond the grid's ends (the hat average of finer
    input, and its check that a hat lies inside the input); linear interpolation uses the
    samples bracketing the ends. Keeping every sample within one step of the grid plus the
    first one at or beyond that step on each side leaves the resampled values unchanged
    for a uniform input grid; the rest is dropped (seed 000 trims its spectra to
    380–780 nm). ``wavelength_nm`` (n,) must cover ``grid_nm``.
    """
    w, g = np.asarray(wavelength_nm, float), np.asarray(grid_nm, float)
    step = float(np.min(np.diff(g)))
    below = np.flatnonzero(w <= g[0] - step + WAVELENGTH_TOL_NM)
    above = np.flatnonzero(w >= g[-1] + step - WAVELENGTH_TOL_NM)
    lo = int(below[-1]) if below.size else 0
    hi = int(above[0]) if above.size else w.size - 1
    return slice(lo, hi + 1)


def _require_cover(wl: np.ndarray, columns: Sequence[str], grid: np.ndarray, path: str,
                   line: int | None, what: str, fix: str) -> None:
    """Refuse wavelengths ``wl`` that do not span ``grid`` (no extrapolation), naming the
    column at the short end."""
    if covers(wl, grid):
        return
    short_end = 0 if wl[0] > grid[0] + WAVELENGTH_TOL_NM else -1
    raise InputError(f"wavelengths {wl[0]:g}-{wl[-1]:g} nm do not cover {what} "
                     f"{grid[0]:g}-{grid[-1]:g} nm", path=path, row=line,
                     column=columns[short_end], fix=fix)


def _wavelength_column_names(spectra: Spectra) -> tuple[list[str], int | None]:
    """Column names of the wavelengths and the header line, for messages."""
    if spectra.layout == "long":
        return [WAVELENGTH] * spectra.wavelength_nm.size, None
    return spectra.columns, spectra.info.get("header_line")


def crop(spectra: Spectra, grid: np.ndarray) -> Spectra:
    """Check that ``spectra`` cover ``grid`` and keep only the wavelengths it needs
    (:func:`used_wavelengths`); the number dropped goes to ``info``."""
    names, line = _wavelength_column_names(spectra)
    _require_cover(spectra.wavelength_nm, names, grid, spectra.path, line, "the working grid",
                   fix=f"measure over the whole grid or choose one inside the data, e.g. "
                       f"--grid-nm {_inner_grid(spectra.wavelength_nm)}")
    keep = used_wavelengths(spectra.wavelength_nm, grid)
    info = dict(spectra.info, wavelengths_dropped=int(spectra.wavelength_nm.size
                                                      - (keep.stop - keep.start)))
    return replace(spectra, wavelength_nm=spectra.wavelength_nm[keep],
                   values=spectra.values[:, keep], lines=spectra.lines[:, keep],
                   columns=spectra.columns[keep], info=info)


def _inner_grid(wl: np.ndarray) -> str:
    """A 10 nm ``--grid-nm`` inside the data's range (for a message's fix)."""
    lo, hi = math.ceil(wl[0] / 10) * 10, math.floor(wl[-1] / 10) * 10
    return f"{lo}:{hi}:10" if hi > lo else "START:STOP:STEP"


def _spectrum_on(wl_in, values_in, table: Table, wl: np.ndarray, role: str,
                 target: str) -> np.ndarray:
    """A single spectrum (white standard, dark) resampled onto the wavelengths ``wl``."""
    _require_cover(wl_in, [f"{w:g}" for w in wl_in], wl, table.path, None,
                   f"those of {target}",
                   fix=f"give the {role} spectrum over at least {wl[0]:g}-{wl[-1]:g} nm")
    return resample(wl_in, values_in, wl)


# ------------------------------------------------------------------ dark, negatives --

def subtract_dark(spectra: Spectra, dark: tuple[np.ndarray, np.ndarray, Table]) -> Spectra:
    """Subtract a dark/background spectrum from every row (seed 004 §3).

    ``dark`` is (wavelength_nm (m,), value (m,), table) from :func:`read_spectrum`, in the
    **same units as the file's value column** (the dark reading normalised exactly as the
    sample readings: for ratio-to-white divided by the white signal, for flux-ratio by the
    incident flux, for brdf already a BRDF offset). It is resampled onto the file's
    wavelengths, which it must cover.
    """
    wl, v, table = dark
    d = _spectrum_on(wl, v, table, spectra.wavelength_nm, "dark", spectra.path)
    return replace(spectra, values=spectra.values - d)


def check_negatives(spectra: Spectra) -> int:
    """Refuse values below −:data:`NEGATIVE_NOISE_FRACTION` × the file's peak; return how
    many small negatives (noise) remain (they are clipped after averaging)."""
    peak = max(float(spectra.values.max()), 0.0)
    limit = -NEGATIVE_NOISE_FRACTION * peak
    bad = spectra.values < limit
    if bad.any():
        r, c = np.unravel_index(np.argmin(np.where(bad, spectra.values, np.inf)),
                                spectra.values.shape)
        raise InputError(f"value {spectra.values[r, c]:.4g} at "
                         f"{spectra.wavelength_nm[c]:g} nm is negative beyond noise "
                         f"(below {NEGATIVE_NOISE_FRACTION:.0%} of the file's peak "
                         f"{peak:.4g})", path=spectra.path, row=int(spectra.lines[r, c]),
                         column=spectra.columns[c],
                         fix="check the dark subtraction, the sign and the quantity")
    return int(np.count_nonzero(spectra.values < 0))


# ---------------------------------------------------------------------- quantities --

def receptor_solid_angle(aperture_mm: float, distance_mm: float) -> float:
    """Solid angle (sr) of a circular receptor aperture, seed 004 eq. (7).

    Δω = π w² / (4 d²), ``aperture_mm`` the diameter w, ``distance_mm`` the distance d from
    the sample (small-aperture approximation; seed 004 uses w = 4 mm, d = 400 mm).

    >>> round(receptor_solid_angle(4.0, 400.0), 10)
    7.85398e-05
    """
    return math.pi * aperture_mm ** 2 / (4.0 * distance_mm ** 2)


def _from_brdf(values, **_):
    return values


def _from_reflectance_factor(values, **_):
    return values / np.pi


def _from_ratio_to_white(values, *, white, **_):
    return values * white / np.pi


def _from_flux_ratio(values, *, theta_o_deg, solid_angle_sr, **_):
    cos_theta_o = np.cos(np.radians(theta_o_deg))  # > 0: |θo| < 90° is checked on read
    return values / (cos_theta_o[:, None] * solid_angle_sr)


def _value_level(values, brdf):
    """The values themselves: fractions of a white diffuser's (or sr⁻¹), at most ~1 at
    most configurations of any real sample."""
    return values


def _reflectance_factor_level(values, brdf):
    """π f, the reflectance factor: flux ratios scale with the aperture, so their own
    size says nothing."""
    return np.pi * brdf


_PERCENT_FIX = "pass --scale 0.01 if they are percent"

#: Measured quantities and their conversion to BRDF in sr⁻¹ (STYLE 3).
QUANTITIES: dict[str, Quantity] = {
    "brdf": Quantity(
        "brdf", "f = value", "docs/conventions.md", (), _from_brdf, _value_level,
        "BRDF (sr^-1)", "pass --quantity reflectance-factor --scale 0.01 if they are "
        "reflectance factors in percent (as instruments export them), --scale 0.01 alone "
        "if a BRDF in percent"),
    "ratio-to-white": Quantity(
        "ratio-to-white", "f = ratio · R_white(λ) / π",
        "seed 004 eq. 8 with a Lambertian standard f_rs = R_white/π; seed 000 "
        "'Preparation and measurement'", ("white_reflectance",), _from_ratio_to_white,
        _value_level, "ratio to white", _PERCENT_FIX),
    "reflectance-factor": Quantity(
        "reflectance-factor", "f = R / π", "docs/conventions.md", (),
        _from_reflectance_factor, _value_level, "reflectance factor", _PERCENT_FIX),
    "flux-ratio": Quantity(
        "flux-ratio", "f = (ΔΦr/ΔΦi) / (cos θo · Δω), Δω = π w² / (4 d²)",
        "seed 004 eqs. 5 and 7", ("aperture_mm", "distance_mm"), _from_flux_ratio,
        _reflectance_factor_level, "reflectance factor pi*f", _PERCENT_FIX),
}

#: The quantity when ``--quantity`` is not given.
DEFAULT_QUANTITY = "brdf"

#: Layouts whose instruments export reflectance factors, not BRDFs: ingesting one
#: without ``--quantity`` warns (multi-angle spectrophotometers, ASTM E2194).
REFLECTANCE_FACTOR_LAYOUTS = ("multi-angle",)

_OPTION_FLAGS = {"white_reflectance": "--white-reflectance", "aperture_mm": "--aperture-mm",
                 "distance_mm": "--distance-mm"}


def resolve_parameters(paths: Sequence[str | os.PathLike], *, quantity: str | None = None,
                       white_reflectance: float | str | None = None,
                       aperture_mm: float | None = None, distance_mm: float | None = None,
                       dark: str | os.PathLike | None = None,
                       grid_nm: str | None = None, scale: float | None = None,
                       sample: str | None = None, theta_i_deg: str | None = None,
                       theta_o_deg: str | None = None) -> dict[str, Any]:
    """Check the options against each other and fill in defaults.

    Returns the effective parameters (recorded in the artifact): ``quantity`` (default
    :data:`DEFAULT_QUANTITY`), ``white_reflectance`` (a number, a CSV path, or None when
    not used), ``aperture_mm``, ``distance_mm``, ``dark`` (path or None), ``grid_nm``,
    ``scale`` (default 1) and ``sample`` (or None). An option the quantity does not use is
    an error (it would be silently ignored otherwise, STYLE 7).
    """
    where = os.fspath(paths[0]) if paths else None
    fmt = input_format(paths)
    if fmt is not None:
        return fmt.load().resolve_parameters(
            paths, theta_i_deg=theta_i_deg, theta_o_deg=theta_o_deg, grid_nm=grid_nm,
            quantity=quantity, white_reflectance=white_reflectance, aperture_mm=aperture_mm,
            distance_mm=distance_mm, dark=dark, scale=scale, sample=sample)
    for flag, value in (("--theta-i-deg", theta_i_deg), ("--theta-o-deg", theta_o_deg)):
        if value is not None:
            raise InputError(f"{flag} is for an RGL .bsdf input (its in-plane grid); a CSV "
                             "holds its own angles", path=where, fix=f"drop {flag}")
    quantity = DEFAULT_QUANTITY if quantity is None else quantity
    if quantity not in QUANTITIES:
        raise InputError(f"--quantity {quantity!r} is not known", path=where,
                         fix=f"use one of {', '.join(QUANTITIES)}")
    needs = QUANTITIES[quantity].options
    given = {"white_reflectance": white_reflectance, "aperture_mm": aperture_mm,
             "distance_mm": distance_mm}
    for name, value in given.items():
        if value is not None and name not in needs:
            users = [q for q, spec in QUANTITIES.items() if name in spec.options]
            raise InputError(f"{_OPTION_FLAGS[name]} is only used with --quantity "
                             f"{' or '.join(users)}, not {quantity}", path=where,
                             fix=f"drop {_OPTION_FLAGS[name]} or pass the right --quantity")
    if quantity == "ratio-to-white":
        white_reflectance = _white_option(white_reflectance, where)
    if quantity == "flux-ratio":
        _receptor_options(aperture_mm, distance_mm, where)
    grid = grid_nm if grid_nm is not None else DEFAULT_GRID_NM
    parse_grid(grid)  # refuse a bad --grid-nm before reading anything
    scale = 1.0 if scale is None else float(scale)
    if not (math.isfinite(scale) and 0 < scale <= MAX_MAGNITUDE):
        raise InputError(f"--scale {scale:g} is not a positive number up to "
                         f"{MAX_MAGNITUDE:g}", path=where,
                         fix="the factor the values are multiplied by, e.g. --scale 0.01 "
                             "for percent")
    if sample is not None and not str(sample).strip():
        raise InputError("--sample is empty", path=where,
                         fix="name the sample as the file's Name (or Sample, ID) column has it")
    return {"quantity": quantity, "white_reflectance": white_reflectance,
            "aperture_mm": aperture_mm, "distance_mm": distance_mm,
            "dark": os.fspath(dark) if dark is not None else None, "grid_nm": grid,
            "scale": scale, "sample": None if sample is None else str(sample).strip()}


def _white_option(value: float | str | None, where: str | None) -> float | str:
    """``--white-reflectance``: a number in (0, 1] (default 0.99) or a CSV path."""
    if value is None:
        return DEFAULT_WHITE_REFLECTANCE
    number = _number(str(value))
    if number is None:
        if not Path(str(value)).is_file():
            raise InputError(f"--white-reflectance {value!r} is neither a number nor a file",
                             path=where, fix="give the white standard's reflectance as a "
                             "fraction with a '.' (e.g. 0.99) or a CSV wavelength_nm,value")
        return os.fspath(value)
    if not 0 < number <= 1:
        raise InputError(f"--white-reflectance {number:g} is outside (0, 1]", path=where,
                         fix="the reflectance of the white standard as a fraction "
                             "(0.99 for 99 % Spectralon)")
    return number


#: Smallest aperture / distance of a flux-ratio receptor: below it Δω = π w²/(4 d²) is under
#: 1e-12 sr and a flux ratio divided by it overflows (a real receptor subtends ~1e-4 sr).
MIN_APERTURE_RATIO = 1e-6


def _receptor_options(aperture_mm, distance_mm, where) -> None:
    """flux-ratio needs the receptor's aperture and distance (seed 004 eq. 7)."""
    if aperture_mm is None or distance_mm is None:
        missing = [f for f, v in (("--aperture-mm", aperture_mm),
                                  ("--distance-mm", distance_mm)) if v is None]
        raise InputError(f"--quantity flux-ratio needs {' and '.join(missing)} (receptor "
                         "aperture diameter and its distance from the sample, seed 004 "
                         "eq. 7)", path=where,
                         fix="e.g. --aperture-mm 4 --distance-mm 400")
    if not (math.isfinite(aperture_mm) and math.isfinite(distance_mm)
            and MIN_APERTURE_RATIO * distance_mm <= aperture_mm < distance_mm
            and distance_mm <= MAX_MAGNITUDE):
        raise InputError(f"--aperture-mm {aperture_mm:g} and --distance-mm {distance_mm:g} "
                         f"need 0 < aperture < distance (seed 004 eq. 7 is for a small "
                         f"aperture), aperture >= {MIN_APERTURE_RATIO:g} × distance and "
                         f"distance <= {MAX_MAGNITUDE:g}",
                         path=where, fix="both in mm, e.g. 4 and 400")


def white_spectrum(white: float | str, wavelength_nm: np.ndarray, target: str) -> np.ndarray:
    """R_white (n_λ,) on ``wavelength_nm``: a constant, or a CSV spectrum resampled there.

    A CSV must hold fractions in (0, 1] and cover the wavelengths of ``target``.
    """
    if not isinstance(white, str):
        return np.full(wavelength_nm.shape, float(white))
    wl, v, table = read_spectrum(white, "white standard")
    bad = np.flatnonzero(~((v > 0) & (v <= 1)))
    if bad.size:
        k = int(bad[0])
        raise InputError(f"white reflectance {v[k]:g} at {wl[k]:g} nm is outside (0, 1]",
                         path=white, row=int(table.lines[k]), column=VALUE,
                         fix="a fraction (0.99, not 99 %)" if v[k] > 1
                         else "a white standard reflects; check the file")
    return _spectrum_on(wl, v, table, wavelength_nm, "white standard", target)


# ----------------------------------------------------------------- merge, repeats --

def merge(parts: Sequence[Spectra], grids: Sequence[np.ndarray]) -> Spectra:
    """Concatenate the spectra of several files; they must have read the same grid.

    ``grids`` are the files' wavelengths as read (before cropping), (n_λ,) each.
    """
    first = parts[0]
    for part, grid in zip(parts[1:], grids[1:]):
        if not same_grid(grid, grids[0]):
            names, line = _wavelength_column_names(part)
            raise InputError(f"its wavelengths ({_grid_text(grid)}) differ from those of "
                             f"{first.path} ({_grid_text(grids[0])}) from "
                             f"{_first_difference(grid, grids[0])} on", path=part.path,
                             row=line, column=names[0],
                             fix="ingest files from one instrument set-up together, or "
                                 "export them on the same wavelengths")
    if len(parts) == 1:
        return first
    return Spectra(", ".join(p.path for p in parts), "+".join(p.layout for p in parts),
                   first.wavelength_nm,
                   np.concatenate([p.theta_i_deg for p in parts]),
                   np.concatenate([p.theta_o_deg for p in parts]),
                   np.concatenate([p.values for p in parts]),
                   np.concatenate([p.lines for p in parts]), first.columns)


def _first_difference(a: np.ndarray, b: np.ndarray) -> str:
    """The first wavelength where grids ``a`` and ``b`` differ, as text."""
    n = min(a.size, b.size)
    diff = np.flatnonzero(np.abs(a[:n] - b[:n]) > WAVELENGTH_TOL_NM)
    k = int(diff[0]) if diff.size else n
    return f"{a[k]:g} nm" if k < a.size else f"{b[k]:g} nm (missing)"


def average_repeats(theta_i_deg, theta_o_deg, values):
    """Average the rows of each configuration and keep their sample standard deviation.

    Parameters
    ----------
    theta_i_deg, theta_o_deg : (n,) float, degrees; rows agreeing to
        :data:`ANGLE_DECIMALS` decimals are one configuration.
    values : (n, n_λ) float.

    Returns
    -------
    theta_i_deg, theta_o_deg : (m,) float, configurations sorted by θi then θo.
    mean : (m, n_λ) float.
    std : (m, n_λ) float, sample standard deviation (ddof = 1), 0 for a single row.
    n_repeats : (m,) int.
    """
    keys, inv = np.unique(_rounded_keys(np.asarray(theta_i_deg, float),
                                        np.asarray(theta_o_deg, float)),
                          axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    values = np.asarray(values, dtype=float)
    order = np.argsort(inv, kind="stable")
    sorted_inv = inv[order]
    starts = np.flatnonzero(np.r_[True, sorted_inv[1:] != sorted_inv[:-1]])
    counts = np.diff(np.r_[starts, inv.size])
    v = values[order]
    mean = np.add.reduceat(v, starts, axis=0) / counts[:, None]
    sq = np.add.reduceat((v - mean[sorted_inv]) ** 2, starts, axis=0)
    std = np.sqrt(sq / np.maximum(counts - 1, 1)[:, None]) * (counts > 1)[:, None]
    return keys[:, 0], keys[:, 1], mean, std, counts


# ------------------------------------------------------------- other input formats --

@dataclass(frozen=True)
class InputFormat:
    """An input format besides CSV, routed by file suffix to its own module.

    The module (imported on first use, so a CSV run never loads it) has the three
    functions the CSV path has here: ``resolve_parameters(paths, **options)``,
    ``ingest(paths, **options)`` and ``file_lines(info)`` (its ``--summary`` lines).
    """

    name: str
    suffix: str
    module: str

    def load(self):
        import importlib

        return importlib.import_module(self.module)


#: Input formats besides CSV by name; :func:`input_format` picks one by file suffix.
FORMATS = {"rgl-bsdf": InputFormat("rgl-bsdf", ".bsdf", "gonio_cli.rgl")}


def input_format(paths: Sequence[str | os.PathLike]) -> InputFormat | None:
    """The :data:`FORMATS` entry of the first input with its suffix (any case), or None
    for CSV input."""
    for p in paths:
        suffix = Path(p).suffix.lower()
        for fmt in FORMATS.values():
            if suffix == fmt.suffix:
                return fmt
    return None


# ------------------------------------------------------------------------ the stage --

def ingest(paths: Sequence[str | os.PathLike], *, quantity: str | None = None,
           white_reflectance: float | str | None = None, aperture_mm: float | None = None,
           distance_mm: float | None = None, dark: str | os.PathLike | None = None,
           grid_nm: str | None = None, scale: float | None = None,
           sample: str | None = None, theta_i_deg: str | None = None,
           theta_o_deg: str | None = None) -> Measurement:
    """Read goniometer CSVs and return one measurement on the working grid.

    Parameters
    ----------
    paths : sequence of path, at least one CSV (any of :data:`LAYOUTS`); several files
        merge (e.g. one per angle of incidence) and must share their wavelengths.
    quantity : key of :data:`QUANTITIES`, what the files hold (default ``"brdf"``; not
        given, a multi-angle file gets a warning that such instruments export reflectance
        factors).
    white_reflectance : number in (0, 1] or path of a ``wavelength_nm,value`` CSV, the
        white standard's reflectance for ``ratio-to-white`` (default 0.99).
    aperture_mm, distance_mm : receptor aperture diameter and distance for ``flux-ratio``
        (seed 004 eq. 7).
    dark : path of a ``wavelength_nm,value`` CSV subtracted from every row before the
        conversion, in the units of the files' value columns (:func:`subtract_dark`).
    grid_nm : working grid ``"START:STOP:STEP"`` in nm (default ``"380:780:10"``).
    scale : positive factor the values are multiplied by after the dark subtraction and
        before the conversion (``0.01`` for percent; default 1). Values that still look
        like percent are refused (:func:`check_percent`).
    sample : of files holding several samples (a ``Name``, ``Sample`` or ``ID`` column
        with several values), the one to read (:func:`select_sample`).
    theta_i_deg, theta_o_deg : for an input of another format (:data:`FORMATS`, e.g. an
        RGL ``.bsdf``, read by :func:`gonio_cli.rgl.ingest`), the in-plane grid to
        evaluate it at; refused for CSV input.

    Returns
    -------
    Measurement
        ``brdf`` (n_cfg, n_λ) in sr⁻¹ without the cosine factor, ``brdf_std`` where a
        configuration repeated, ``n_repeats`` and a ``summary`` (:func:`format_summary`).
    """
    if not paths:
        raise InputError("no input files", fix="gonio ingest INPUT.csv [...] -o OUT.json")
    fmt = input_format(paths)
    if fmt is not None:
        return fmt.load().ingest(
            paths, theta_i_deg=theta_i_deg, theta_o_deg=theta_o_deg, grid_nm=grid_nm,
            quantity=quantity, white_reflectance=white_reflectance, aperture_mm=aperture_mm,
            distance_mm=distance_mm, dark=dark, scale=scale, sample=sample)
    params = resolve_parameters(paths, quantity=quantity, white_reflectance=white_reflectance,
                                aperture_mm=aperture_mm, distance_mm=distance_mm, dark=dark,
                                grid_nm=grid_nm, scale=scale, sample=sample,
                                theta_i_deg=theta_i_deg, theta_o_deg=theta_o_deg)
    _refuse_repeated_inputs(paths)
    grid = parse_grid(params["grid_nm"])
    dark_spectrum = read_spectrum(dark, "dark") if dark is not None else None
    parts, grids, negatives = [], [], 0
    for path in log.progress(paths, "reading CSV files", total=len(paths)):
        spectra = read_spectra(path, params["sample"])
        grids.append(spectra.wavelength_nm)
        spectra = crop(spectra, grid)
        if dark_spectrum is not None:
            spectra = subtract_dark(spectra, dark_spectrum)
        if params["scale"] != 1.0:
            spectra = replace(spectra, values=spectra.values * params["scale"])
        negatives += check_negatives(spectra)
        parts.append(spectra)
    merged = merge(parts, grids)
    brdf = _convert(merged, params)
    check_percent(parts, brdf, params)
    ti, to, mean, std, counts = average_repeats(merged.theta_i_deg, merged.theta_o_deg, brdf)
    clipped = int(np.count_nonzero(mean < 0))
    mean = np.maximum(mean, 0.0)
    notes = _quantity_notes(parts, quantity is not None)
    notes += _grid_notes(parts, grids, grid, params["grid_nm"])
    if clipped:
        notes.append(f"clipped {clipped} small negative value{'s' if clipped > 1 else ''} "
                     f"(noise, above -{NEGATIVE_NOISE_FRACTION:.0%} of the peak) to 0 "
                     f"after averaging repeats")
    wl = merged.wavelength_nm
    repeated = bool(counts.max() > 1)
    m = Measurement(grid, ti, to, resample(wl, mean, grid),
                    resample(wl, std, grid) if repeated else None, counts,
                    params["quantity"])
    resampled = not all(same_grid(g, grid) for g in grids)
    m.summary = _summary(m, parts, params, resampled, negatives, clipped, notes)
    for note in notes:  # only now: a failing run prints one line, its error
        log.warn(note)
    return m


def _refuse_repeated_inputs(paths: Sequence[str | os.PathLike]) -> None:
    """The same file twice would count its rows as repeats with a spread of 0."""
    seen: dict[str, str] = {}
    for p in paths:
        key = os.path.realpath(p)
        if key in seen:
            raise InputError(f"is given twice (also as {seen[key]})", path=p,
                             fix="pass each file once; check overlapping wildcards")
        seen[key] = os.fspath(p)


def median_of(values: np.ndarray) -> float:
    """``float(np.median(values))`` over every value (NaN if any is NaN), without the
    ``numpy.ma`` import that ``np.median`` makes on its first call (~10 ms of a run)."""
    a = np.asarray(values).ravel()
    if a.size == 0 or np.isnan(a).any():
        return math.nan
    k = a.size // 2
    if a.size % 2:
        return float(np.partition(a, k)[k])
    part = np.partition(a, (k - 1, k))
    return float(np.mean(part[k - 1:k + 1]))


def distinct(values: np.ndarray) -> np.ndarray:
    """``np.unique(values)`` (the sorted distinct values) without the ``numpy.ma`` import
    that ``np.unique`` makes when asked for the values alone (see :func:`median_of`)."""
    a = np.sort(np.asarray(values).ravel())
    return a[np.r_[True, a[1:] != a[:-1]]] if a.size else a


def check_percent(parts: Sequence[Spectra], brdf: np.ndarray,
                  params: dict[str, Any]) -> None:
    """Refuse a file whose values look like percent, not fractions.

    Per file (``parts``, whose rows are ``brdf``'s (n, n_λ) rows in order), the median
    of the quantity's :attr:`Quantity.level` over every value must not exceed
    :data:`PERCENT_MEDIAN_LIMIT`: a glossy peak is far above it at a few configurations,
    but the median of any real sample is not. The error names the value nearest the
    median and the options that read percent.
    """
    q = QUANTITIES[params["quantity"]]
    start = 0
    for part in parts:
        rows = slice(start, start + part.values.shape[0])
        start = rows.stop
        level = q.level(part.values, brdf[rows])
        median = median_of(level)
        if not median > PERCENT_MEDIAN_LIMIT:
            continue
        r, c = np.unravel_index(np.argmin(np.abs(level - median)), level.shape)
        after = f" after --scale {params['scale']:g}" if params["scale"] != 1.0 else ""
        # percent of anything real stays below 100 x the limit; beyond, another unit
        percent = median <= 100 * PERCENT_MEDIAN_LIMIT
        raise InputError(f"the values {'look like percent' if percent else 'are far too large'}"
                         f": their median {q.level_name}{after} is {median:.4g}, above "
                         f"{PERCENT_MEDIAN_LIMIT:g}, which a real sample exceeds at a few "
                         "near-specular geometries at most", path=part.path,
                         row=int(part.lines[r, c]), column=part.columns[c],
                         fix=q.percent_fix if percent else
                         "check --quantity and its options, or give the factor to "
                         "fractions with --scale")


def _quantity_notes(parts: Sequence[Spectra], quantity_given: bool) -> list[str]:
    """The warning for a multi-angle file read as BRDF because ``--quantity`` was not
    given (:data:`REFLECTANCE_FACTOR_LAYOUTS`)."""
    if quantity_given:
        return []
    return [f"{p.path}: a {p.layout} file read as BRDF in sr^-1 (the default --quantity "
            f"{DEFAULT_QUANTITY}), but {p.layout} instruments export reflectance factors: "
            "pass --quantity reflectance-factor if these are (f = R/pi), or --quantity "
            f"{DEFAULT_QUANTITY} to keep them and silence this"
            for p in parts if p.layout in REFLECTANCE_FACTOR_LAYOUTS]


def _convert(spectra: Spectra, params: dict[str, Any]) -> np.ndarray:
    """Values → BRDF (sr⁻¹) by the quantity's rule (:data:`QUANTITIES`)."""
    q = QUANTITIES[params["quantity"]]
    white = (white_spectrum(params["white_reflectance"], spectra.wavelength_nm,
                            spectra.path) if "white_reflectance" in q.options else None)
    omega = (receptor_solid_angle(params["aperture_mm"], params["distance_mm"])
             if "aperture_mm" in q.options else None)
    return q.convert(spectra.values, theta_o_deg=spectra.theta_o_deg, white=white,
                     solid_angle_sr=omega)


def _grid_notes(parts, grids, grid, grid_spec) -> list[str]:
    """The resampling (or trimming) warning per file (docs/conventions.md: never silent)."""
    notes = []
    for part, read in zip(parts, grids):
        if same_grid(read, grid):
            continue
        how = "trimmed to" if same_grid(part.wavelength_nm, grid) else "resampled onto"
        notes.append(f"{part.path}: wavelengths {_grid_text(read)} {how} the working grid "
                     f"{grid_spec} ({grid.size} samples)")
    return notes


def _summary(m: Measurement, parts, params, resampled, negatives, clipped,
             notes) -> dict[str, Any]:
    """What was read, dropped, clipped and resampled (JSON-ready; :func:`format_summary`)."""
    per_theta_i = []
    theta_i = distinct(m.theta_i_deg)
    for t in theta_i:
        sel = m.theta_i_deg == t
        per_theta_i.append({"theta_i_deg": float(t),
                            "theta_o_min_deg": float(m.theta_o_deg[sel].min()),
                            "theta_o_max_deg": float(m.theta_o_deg[sel].max()),
                            "configurations": int(sel.sum())})
    return {
        "files": [p.info for p in parts],
        "quantity": params["quantity"],
        "conversion": QUANTITIES[params["quantity"]].formula,
        "scale": params["scale"],
        "theta_i_deg": [float(t) for t in theta_i],
        "theta_o_by_theta_i": per_theta_i,
        "working_grid_nm": params["grid_nm"],
        "resampled": resampled,
        "configurations": m.n_configurations,
        "spectra": int(m.n_repeats.sum()),
        "repeats_min": int(m.n_repeats.min()),
        "repeats_max": int(m.n_repeats.max()),
        "brdf_min_per_sr": float(m.brdf.min()),
        "brdf_max_per_sr": float(m.brdf.max()),
        "negative_values_read": negatives,
        "clipped_to_zero": clipped,
        "warnings": list(notes),
    }


#: Lines without data that ``format_summary`` reports as skipped (``Spectra.info`` keys).
_SKIPPED = {"preamble_lines": "preamble lines", "comment_lines": "comment lines",
            "empty_rows": "empty rows", "rows_other_samples": "rows of other samples"}


def format_summary(summary: dict[str, Any]) -> str:
    """The human summary printed by ``gonio ingest --summary`` (a string, not printed)."""
    out = []
    for f in summary["files"]:
        if f.get("format") in FORMATS:
            out += FORMATS[f["format"]].load().file_lines(f)
            continue
        out.append(f"read {f['path']}: {f['layout']} layout, {f['delimiter']}-delimited"
                   f"{', decimal comma' if f['decimal_comma'] else ''}, {f['rows']} rows, "
                   f"{f['spectra']} spectra, {f['wavelength_nm']}")
        skipped = [f"{f[k]} {what}" for k, what in _SKIPPED.items() if f.get(k)]
        dropped = f.get("wavelengths_dropped", 0)
        out.append(f"  skipped: {', '.join(skipped) or 'nothing'}; dropped: "
                   + (f"{dropped} wavelengths outside the working grid" if dropped
                      else "nothing"))
        if f.get("label_columns"):
            n = len(f.get("samples") or ())
            of = f" (1 of {n} in the file)" if n > 1 else ""
            sample = (f"; sample {f['sample']}{of} from column {f['sample_column']}"
                      if f.get("sample_column") else "")
            out.append(f"  label columns set aside: {', '.join(f['label_columns'])}{sample}")
    scale = summary.get("scale", 1.0)
    out.append(f"quantity: {summary['quantity']} ({summary['conversion']})"
               + (f", values x {scale:g} (--scale)" if scale != 1.0 else ""))
    out.append("angles of incidence (deg): "
               + ", ".join(f"{t:g}" for t in summary["theta_i_deg"]))
    for row in summary["theta_o_by_theta_i"]:
        out.append(f"  theta_i {row['theta_i_deg']:g}: theta_o {row['theta_o_min_deg']:g} "
                   f"to {row['theta_o_max_deg']:g} deg, {row['configurations']} "
                   "configurations")
    out.append(f"grid: {summary['working_grid_nm']} nm"
               f"{' (resampled)' if summary['resampled'] else ''}")
    lo, hi = summary["repeats_min"], summary["repeats_max"]
    rep = ("no repeats" if hi == 1 else f"{lo} repeats each" if lo == hi
           else f"{lo}-{hi} repeats each")
    out.append(f"configurations: {summary['configurations']} from {summary['spectra']} "
               f"spectra ({rep})")
    out.append(f"BRDF: {summary['brdf_min_per_sr']:.4g} to {summary['brdf_max_per_sr']:.4g} "
               "sr^-1")
    out.append(f"clipped to 0: {summary['clipped_to_zero']} (of "
               f"{summary['negative_values_read']} small negative values read)")
    for note in summary["warnings"]:
        out.append(f"warning: {note}")
    return "\n".join(out)
