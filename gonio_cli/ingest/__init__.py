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
   look like percent (:func:`~gonio_cli.percent.check_percent`) is refused.
5. Repeated rows of one configuration are averaged, their sample standard deviation kept
   (seed 000 averages ten spectra per configuration).
6. Small negative means are clipped to 0 (counted), and everything is resampled onto
   the working grid (:func:`gonio_cli.spectra.resample`), with a warning if the grid
   differs.

Arrays: wavelength is the last axis (STYLE 6); ``values`` are (n_spectra, n_λ).

The package: step 1, the CSV layer, is :mod:`gonio_cli.csvio`; steps 2, 3, 5 and the
merge :mod:`.steps`; the quantities of step 4 :mod:`.quantities`; other input formats
(RGL ``.bsdf``, :mod:`.rgl`) :mod:`.formats`; here the stage itself and its summary.

As a library call (what ``gonio ingest`` runs): :func:`run` returns the measurement with
the effective parameters and every file read, :func:`write` writes the artifact.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from .. import log
from ..csvio import Spectra, grid_text, read_spectrum
from ..csvlayouts import read_spectra
from ..errors import InputError
from ..percent import check_percent
from ..schemas import Measurement, write_measurement
from ..spectra import parse_grid, resample, same_grid
from .formats import FORMATS, input_format
from .quantities import (DEFAULT_QUANTITY, QUANTITIES, REFLECTANCE_FACTOR_LAYOUTS,
                         receptor_solid_angle, resolve_parameters, white_spectrum)
from .steps import (NEGATIVE_NOISE_FRACTION, average_repeats, check_negatives, crop, distinct,
                    merge, subtract_dark)

# ------------------------------------------------------------------------ the stage --

def ingest(paths: Sequence[str | os.PathLike], *, quantity: str | None = None,
           white_reflectance: float | str | None = None, aperture_mm: float | None = None,
           distance_mm: float | None = None, dark: str | os.PathLike | None = None,
           grid_nm: str | None = None, scale: float | None = None,
           sample: str | None = None, theta_i_deg: str | None = None,
           theta_o_deg: str | None = None, phi_o_deg: str | None = None,
           mirror_deg: str | None = None) -> Measurement:
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
        like percent are refused (:func:`~gonio_cli.percent.check_percent`), unless
        ``scale`` is given as 1: the user confirms the values are in the quantity's units.
    sample : of files holding several samples (a ``Name``, ``Sample`` or ``ID`` column
        with several values), the one to read (:func:`select_sample`).
    theta_i_deg, theta_o_deg : for an input of another format (:data:`FORMATS`, e.g. an
        RGL ``.bsdf``, read by :func:`gonio_cli.ingest.rgl.ingest`), the grid to
        evaluate it at; refused for CSV input.
    phi_o_deg, mirror_deg : the same input's azimuths and mirror ring
        (:mod:`gonio_cli.ingest.hemisphere`); refused for CSV input.

    Returns
    -------
    Measurement
        ``brdf`` (n_cfg, n_λ) in sr⁻¹ without the cosine factor, ``brdf_std`` where a
        configuration repeated, ``n_repeats`` and a ``summary`` (:func:`format_summary`).
    """
    if not paths:
        raise InputError("no input files", fix="gonio ingest INPUT.csv [...] -o OUT.json")
    options = dict(quantity=quantity, white_reflectance=white_reflectance,
                   aperture_mm=aperture_mm, distance_mm=distance_mm, dark=dark,
                   grid_nm=grid_nm, scale=scale, sample=sample, theta_i_deg=theta_i_deg,
                   theta_o_deg=theta_o_deg, phi_o_deg=phi_o_deg, mirror_deg=mirror_deg)
    fmt = input_format(paths)
    if fmt is not None:
        return fmt.load().ingest(paths, **options)
    params = resolve_parameters(paths, **options)
    _refuse_repeated_inputs(paths)
    grid = parse_grid(params["grid_nm"])
    parts, grids, negatives = _read_files(paths, params, grid, dark)
    merged = merge(parts, grids)
    brdf = _convert(merged, params)
    # an explicit --scale 1 states that the values are in the quantity's units
    confirmed = scale is not None and float(scale) == 1.0
    percent_notes = check_percent(parts, brdf, params, QUANTITIES[params["quantity"]],
                                  units_confirmed=confirmed)
    ti, to, mean, std, counts, phi = average_repeats(merged.theta_i_deg, merged.theta_o_deg,
                                                     brdf, merged.phi_o_deg)
    clipped = int(np.count_nonzero(mean < 0))
    mean = np.maximum(mean, 0.0)
    notes = _quantity_notes(parts, quantity is not None) + percent_notes
    notes += _grid_notes(parts, grids, grid, params["grid_nm"])
    if clipped:
        notes.append(f"clipped {clipped} small negative value{'s' if clipped > 1 else ''} "
                     f"(noise, above -{NEGATIVE_NOISE_FRACTION:.0%} of the peak) to 0 "
                     f"after averaging repeats")
    wl = merged.wavelength_nm
    repeated = bool(counts.max() > 1)
    m = Measurement(grid, ti, to, resample(wl, mean, grid),
                    resample(wl, std, grid) if repeated else None, counts,
                    params["quantity"], phi_o_deg=phi)
    resampled = not all(same_grid(g, grid) for g in grids)
    m.summary = _summary(m, parts, params, resampled, negatives, clipped, notes)
    for note in notes:  # only now: a failing run prints one line, its error
        log.warn(note)
    return m


@dataclass
class IngestRun:
    """What :func:`run` made: the measurement, the effective parameters (recorded in the
    artifact), the files ingested and the other files read (``--dark``, a white standard's
    CSV), and the time (s)."""

    measurement: Measurement
    parameters: dict[str, Any]
    paths: list
    extra: list
    time_s: float

    def summary_line(self, output: Path | str) -> str:
        """The one line every run ends with (on stderr, unless --quiet)."""
        def count(n: int, noun: str) -> str:
            return f"{n} {noun}{'' if n == 1 else 's'}"

        m = self.measurement
        n_theta_i = len(set(m.theta_i_deg.tolist()))
        return (f"{output}: {count(m.theta_i_deg.size, 'configuration')} "
                f"({count(n_theta_i, 'angle')} of incidence) x "
                f"{count(m.wavelength_nm.size, 'wavelength')}, {m.quantity} "
                f"from {count(len(self.paths), 'file')}, {self.time_s:.2f} s")


def run(paths: Sequence[str | os.PathLike], **options: Any) -> IngestRun:
    """``gonio ingest`` as a library call: :func:`ingest` of ``paths`` with ``options``
    (its keyword arguments, as given: the core warns about a default it had to choose),
    the options checked first (:func:`resolve_parameters`: refused before anything is
    read)."""
    params = resolve_parameters(paths, **options)
    start = time.perf_counter()
    measurement = ingest(paths, **options)
    time_s = time.perf_counter() - start
    extra = [p for p in (params.get("dark"), params.get("white_reflectance"))
             if isinstance(p, str)]
    return IngestRun(measurement, params, list(paths), extra, time_s)


def write(result: IngestRun, output: str | os.PathLike) -> None:
    """Write the ``gonio.measurement`` artifact of :func:`run` (atomically, with its
    inputs' hashes and the parameters)."""
    write_measurement(output, result.measurement, inputs=[*result.paths, *result.extra],
                      parameters=result.parameters, time_s=result.time_s)


def _read_files(paths, params: dict[str, Any], grid: np.ndarray, dark
                ) -> tuple[list[Spectra], list[np.ndarray], int]:
    """Steps 1-3 per file: the spectra read and cropped to the working grid, the dark
    subtracted and the scale applied; each file's own grid; the negative values counted."""
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
    return parts, grids, negatives


def _refuse_repeated_inputs(paths: Sequence[str | os.PathLike]) -> None:
    """The same file twice would count its rows as repeats with a spread of 0."""
    seen: dict[str, str] = {}
    for p in paths:
        key = os.path.realpath(p)
        if key in seen:
            raise InputError(f"is given twice (also as {seen[key]})", path=p,
                             fix="pass each file once; check overlapping wildcards")
        seen[key] = os.fspath(p)


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
        notes.append(f"{part.path}: wavelengths {grid_text(read)} {how} the working grid "
                     f"{grid_spec} ({grid.size} samples)")
    return notes


def _summary(m: Measurement, parts, params, resampled, negatives, clipped,
             notes) -> dict[str, Any]:
    """What was read, dropped, clipped and resampled (JSON-ready; :func:`format_summary`)."""
    per_theta_i = []
    theta_i = distinct(m.theta_i_deg)
    for t in theta_i:
        sel = m.theta_i_deg == t
        n_out = int(np.count_nonzero(m.azimuths_deg[sel]))
        per_theta_i.append({"theta_i_deg": float(t),
                            "theta_o_min_deg": float(m.theta_o_deg[sel].min()),
                            "theta_o_max_deg": float(m.theta_o_deg[sel].max()),
                            "configurations": int(sel.sum()),
                            **({"out_of_plane": n_out} if n_out else {})})
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
                   "configurations" + (f" ({row['out_of_plane']} out of the plane, phi_o "
                                       "not 0)" if row.get("out_of_plane") else ""))
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
