"""The three layouts of a goniometer CSV (:data:`LAYOUTS`: long, wide, multi-angle,
detected from the header by :func:`detect_layout`): their checks of header, angles and
wavelengths, their readers into :class:`~gonio_cli.csvio.Spectra`, and
:func:`read_spectra`, which ``gonio ingest`` reads a file with. The table underneath
(delimiters, preamble, label columns, row-numbered errors) is :mod:`gonio_cli.csvio`'s."""

from __future__ import annotations

import os
import re
from dataclasses import replace
from typing import Any, Sequence

import numpy as np

from .csvio import (ANGLE_DECIMALS, DELIMITER_NAMES, GEOMETRY, LABEL_COLUMNS,
                    MAX_LISTED_SAMPLES, PHI_O, RADIAN_LIMIT, THETA_I, THETA_O, VALUE,
                    WAVELENGTH,
                    WAVELENGTH_DECIMALS, Layout, Spectra, Table, check_wavelengths,
                    float_cells, grid_text, header_wavelength, label_key, label_kind,
                    read_table)
from .errors import InputError
from .geometry import canonical_azimuth

#: ASTM E2194 aspecular label: ``45as15`` = light at 45°, detector 15° from the specular
#: direction towards the light (θo = 45 − 15 = 30°); a degree sign is tolerated.
ASPECULAR_LABEL = re.compile(r"^\s*(\d+(?:\.\d*)?)\s*°?\s*as\s*([+-]?\d+(?:\.\d*)?)\s*°?\s*$",
                             re.IGNORECASE)


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
                     key=lambda h: order.index(label_key(h)))
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


def _wavelength_columns(table: Table) -> tuple[list[int], np.ndarray]:
    """Indices and values (nm) of the numeric header cells, checked increasing."""
    idx = [k for k, h in enumerate(table.header) if header_wavelength(h) is not None]
    wl = np.array([header_wavelength(table.header[k]) for k in idx], dtype=float)
    check_wavelengths(wl, [table.header[k] for k in idx], table.path, table.header_line)
    return idx, wl


def _check_header(table: Table, layout: Layout) -> None:
    """Refuse unknown and missing columns (STYLE 7), naming them: an unknown one first, as
    a misspelt name (``Geometri``) is what leaves the right one missing."""
    names = [h.lower() for h in table.header]
    # a header with wavelength columns may be meant as either layout that has them
    example = (" or ".join(lay.example for lay in LAYOUTS.values() if lay.wide)
               if layout.wide else layout.example)
    allowed = set(layout.columns) | {PHI_O}
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
    dup = [h for h in (*layout.columns, PHI_O) if names.count(h) > 1]
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


def _azimuths(table: Table, theta_o: np.ndarray):
    """(θo, φo) of the rows, canonical (:func:`gonio_cli.geometry.canonical_azimuth`),
    with φo from the optional ``phi_o_deg`` column checked in [−180, 180]; (θo, None)
    without that column (every row in the plane of incidence)."""
    if PHI_O not in [h.lower() for h in table.header]:
        return theta_o, None
    phi = float_cells(table, [table.index(PHI_O)])[:, 0]
    bad = np.flatnonzero(np.abs(phi) > 180.0)
    if bad.size:
        k = int(bad[0])
        raise InputError(f"{PHI_O}={phi[k]:g}, outside [-180, 180]", path=table.path,
                         row=int(table.lines[k]), column=PHI_O,
                         fix="the detector's azimuth is degrees from the plane of incidence "
                             "(0: in plane, theta_o signed); fix or drop the row")
    return canonical_azimuth(theta_o, phi)


def rounded_keys(*cols: np.ndarray) -> np.ndarray:
    """(n, k) array of angle columns rounded to :data:`ANGLE_DECIMALS` (grouping keys)."""
    return np.round(np.stack(cols, axis=-1), ANGLE_DECIMALS) + 0.0  # + 0.0: −0 → 0


def _read_long(table: Table) -> Spectra:
    """Long layout: one row per (θi, θo, λ); repeats are later rows of the same triple."""
    cols = [table.index(n) for n in (THETA_I, THETA_O, WAVELENGTH, VALUE)]
    ti, to, wl, v = float_cells(table, cols).T
    _check_angles(ti, to, table.lines, table.path)
    to, phi = _azimuths(table, to)
    wl_r = np.round(wl, WAVELENGTH_DECIMALS)
    if wl_r.min() <= 0:
        k = int(np.argmin(wl_r))
        raise InputError(f"wavelength {wl[k]:g} nm is not positive", path=table.path,
                         row=int(table.lines[k]), column=WAVELENGTH,
                         fix="wavelengths are in nm, e.g. 380")
    w_u, j = np.unique(wl_r, return_inverse=True)
    cfg_u, c = np.unique(rounded_keys(ti, to, *(() if phi is None else (phi,))), axis=0,
                         return_inverse=True)
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
                   lines, [VALUE] * n_wl,
                   phi_o_deg=None if phi is None else cfg_u[cfg_of, 2])


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
    values = float_cells(table, idx)
    lines = np.broadcast_to(table.lines[:, None], values.shape).copy()
    to, phi = _azimuths(table, to)
    return Spectra(table.path, layout, wl, ti, to, values, lines,
                   [table.header[k] for k in idx], phi_o_deg=phi)


def _read_wide(table: Table) -> Spectra:
    """Wide layout: one row per measured spectrum, one column per wavelength (nm)."""
    ti, to = float_cells(table, [table.index(THETA_I), table.index(THETA_O)]).T
    _check_angles(ti, to, table.lines, table.path)
    return _wide_spectra(table, "wide", ti, to)


def aspecular_angles(label: str) -> tuple[float, float] | None:
    """θi and θo (degrees) of an ASTM E2194 multi-angle label, or None if it is not one.

    ``"45as15"`` is light at 45° and the detector 15° from the specular direction towards
    the light, so θo = 45 − 15 = 30°; ``"45as-15"`` → 60°; ``"45as110"`` → −65°.

    >>> aspecular_angles("45as110")
    (45.0, -65.0)
    """
    m = ASPECULAR_LABEL.match(label)
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


def is_layout_header(names: Sequence[str]) -> bool:
    """Whether header cells ``names`` (lower case) hold every column of the layout they
    select (:func:`detect_layout`), label columns and empty cells aside."""
    columns = [n for n in names if n and label_kind(n) is None]
    return all(c in columns for c in detect_layout(columns).columns)


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
    table, labels = split_labels(read_table(path, is_header=is_layout_header))
    layout = detect_layout(table.header)
    _check_header(table, layout)
    rows_read = int(table.lines.size)
    table, samples = select_sample(table, labels, sample)
    spectra = layout.read(table)
    spectra.info = {"path": table.path, "layout": layout.name,
                    "header_line": table.header_line,
                    "delimiter": DELIMITER_NAMES[table.delimiter],
                    "decimal_comma": table.decimal_comma, "rows": rows_read,
                    "spectra": int(spectra.values.shape[0]),
                    "preamble_lines": table.preamble_lines,
                    "comment_lines": table.comment_lines, "empty_rows": table.empty_rows,
                    **samples,
                    "wavelength_nm": grid_text(spectra.wavelength_nm)}
    return spectra
