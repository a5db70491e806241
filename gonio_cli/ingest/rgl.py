"""RGL measured BSDFs (``.bsdf``) in: Mitsuba 3's ``measured`` plugin, evaluated on a
goniometer grid over the hemisphere, dense around the mirror (:mod:`.hemisphere`).

The RGL material database (Dupuy & Jakob 2018, "An adaptive parameterization for efficient
material acquisition and rendering") ships each material as a Mitsuba *tensor file*, RGB
(``*_rgb.bsdf``) or spectral (``*_spec.bsdf``). :func:`ingest` turns one into a
:class:`~gonio_cli.schemas.Measurement` on a goniometer grid (in the plane of incidence
and, with ``--phi-o-deg`` and the mirror ring, out of it), so it fits and renders like a
CSV measurement:

1. :func:`read_tensor_header` and :func:`check_bsdf` read and check the file without
   Mitsuba: the ``tensor_file`` header, every field inside the file, and the fields,
   ranks, types and shapes the ``measured`` plugin requires (its constructor,
   ``src/bsdfs/measured.cpp``). Mitsuba maps the file into memory and trusts it, so a
   truncated file would crash it; here it is one line naming the field.
2. :func:`evaluate_in_plane` loads the file with Mitsuba's ``measured`` plugin (a scalar
   variant, ``scalar_spectral`` for spectral files, ``scalar_rgb`` for RGB ones: the plugin
   accepts nothing else) and evaluates it for the light at θi on the −x side and the
   detector at θo, φo (docs/conventions.md; φo = 0: signed θo in the plane). The plugin's ``eval`` returns f·cos θo,
   Mitsuba's convention for every BSDF (its tables store the BRDF times the cosine); it is
   divided by cos θo here, so the measurement holds f in sr⁻¹ without any cosine.
3. Spectral files are evaluated at their own wavelengths and resampled onto the working
   grid by :func:`gonio_cli.spectra.resample` (as CSV input is); RGB files (linear sRGB)
   become spectra through the Mallett–Yuksel 2019 basis without an illuminant
   (:func:`gonio_cli.spectra.rgb_reflectance_basis`, docs/conventions.md), which is named
   in the artifact's parameters (``rgb_to_spectrum``).

Mitsuba is the optional extra ``gonio[mitsuba]``, imported only here and only when a
``.bsdf`` is read. The tensor file itself (read, and written for the synthetic samples)
is :mod:`.tensorfile`.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from .. import log
from ..errors import InputError
from ..geometry import measurement_directions
from ..numbers import NumberList
from ..schemas import Measurement
from ..spectra import (DEFAULT_GRID_NM, covers, parse_grid, resample, rgb_reflectance_basis,
                       rgb_reflectance_basis_range_nm, same_grid)
from .hemisphere import (DEFAULT_MIRROR_DEG, DEFAULT_PHI_O_DEG, NO_MIRROR, hemisphere_grid,
                         parse_azimuths, parse_mirror)
from .steps import distinct, used_wavelengths
from .tensorfile import TensorField, read_tensor_file, read_tensor_header

#: The format's name in summaries and in the artifact's parameters.
FORMAT = "rgl-bsdf"

#: File suffix that routes an input here (:data:`gonio_cli.ingest.FORMATS`).
SUFFIX = ".bsdf"

#: What to install when Mitsuba is missing (the optional extra of pyproject.toml).
INSTALL_FIX = "pip install 'gonio[mitsuba]'"

#: Default in-plane grid, as a goniometer run measures it (θi 10…70° by 10, θo −80…85° by 5).
DEFAULT_THETA_I_DEG = "10:70:10"
DEFAULT_THETA_O_DEG = "-80:85:5"

#: What an RGB file's linear sRGB triples become (docs/conventions.md, reflectances).
RGB_TO_SPECTRUM = ("Mallett-Yuksel 2019 sRGB basis, no illuminant (reflectance: "
                   "(1, 1, 1) -> 1), as in docs/conventions.md")

#: Mitsuba's scalar variants evaluate 4 wavelengths per call (``UnpolarizedSpectrum``).
SPECTRAL_LANES = 4

# ------------------------------------------------------------- the measured plugin --

@dataclass(frozen=True)
class Kind:
    """An RGL file kind: the field holding its values and the Mitsuba variant it needs."""

    name: str
    field: str
    variant: str


#: The two kinds of RGL file, told apart by a ``wavelengths`` field (as measured.cpp does).
KINDS = {"spectral": Kind("spectral", "spectra", "scalar_spectral"),
         "rgb": Kind("rgb", "rgb", "scalar_rgb")}


def kind_of(fields: dict[str, TensorField]) -> Kind:
    """The :data:`KINDS` entry of a file from its header: spectral if it has wavelengths."""
    return KINDS["spectral" if "wavelengths" in fields else "rgb"]


#: Fields the ``measured`` plugin reads, with their rank (all float32 unless named).
_RANKS = {"description": 1, "jacobian": 1, "theta_i": 1, "phi_i": 1, "ndf": 2, "sigma": 2,
          "vndf": 4, "luminance": 4}
_UINT8 = ("description", "jacobian")


def check_bsdf(path: str | os.PathLike) -> tuple[Kind, dict[str, TensorField]]:
    """Check a ``.bsdf`` file the way Mitsuba's ``measured`` plugin needs it.

    The structure check of ``src/bsdfs/measured.cpp`` (fields, ranks, types and the shapes
    that must agree), plus what its 2-D interpolants need (at least 2 × 2 samples), finite
    angles and values, and increasing ``theta_i``, ``phi_i`` and ``wavelengths``, each
    refused with the field's name. Returns the kind (:data:`KINDS`) and the header.
    """
    fields = read_tensor_header(path)
    kind = kind_of(fields)
    wanted = dict(_RANKS, **{kind.field: 5}, **({"wavelengths": 1}
                                                 if kind.name == "spectral" else {}))
    for name, rank in wanted.items():
        if name not in fields:
            raise InputError(f"has no field {name!r} (fields: {', '.join(fields) or 'none'}), "
                             f"which an RGL {kind.name} .bsdf has", path=path,
                             fix="pass a material file from the RGL database; a tensor file "
                                 "of anything else is not a measured BSDF")
        f = fields[name]
        dtype = np.uint8 if name in _UINT8 else np.float32
        if len(f.shape) != rank or f.dtype != np.dtype(dtype):
            raise InputError(f"field {name!r} is {len(f.shape)}-D {f.dtype.name}, the "
                             f"measured BSDF needs {rank}-D {np.dtype(dtype).name}",
                             path=path, fix="pass an unmodified RGL .bsdf file")
    shape = {n: fields[n].shape for n in wanted}
    n_phi, n_theta = shape["phi_i"][0], shape["theta_i"][0]
    n_channels = shape["wavelengths"][0] if kind.name == "spectral" else 3
    values = shape[kind.field]
    rules = [
        ("vndf", shape["vndf"][:2] == (n_phi, n_theta), "(phi_i, theta_i, ...)"),
        ("luminance", shape["luminance"][:2] == (n_phi, n_theta)
         and shape["luminance"][2] == shape["luminance"][3], "(phi_i, theta_i, n, n)"),
        (kind.field, values[:3] == (n_phi, n_theta, n_channels) and values[3] == values[4]
         and values[3:] == shape["luminance"][2:],
         f"(phi_i, theta_i, {'wavelengths' if kind.name == 'spectral' else '3'}, n, n) "
         "with n x n that of 'luminance'"),
        ("jacobian", shape["jacobian"] == (1,), "(1,)"),
        ("theta_i", n_theta >= 1 and n_phi >= 1, "at least one angle"),
    ]
    rules += [(n, min(shape[n][-2:]) >= 2, "at least 2 x 2 samples")
              for n in ("ndf", "sigma", "vndf", "luminance", kind.field)]
    for name, ok, needed in rules:
        if not ok:
            raise InputError(f"field {name!r} has shape {'x'.join(map(str, shape[name]))}, "
                             f"the measured BSDF needs {needed} (phi_i {n_phi}, theta_i "
                             f"{n_theta})", path=path, fix="pass an unmodified RGL .bsdf file")
    data = read_tensor_file(path, [n for n in wanted if n not in _UINT8])
    for name, a in data.items():
        if not np.isfinite(a).all():
            bad = np.argwhere(~np.isfinite(a))[0]
            raise InputError(f"field {name!r} holds {a[tuple(bad)]} at index "
                             f"{tuple(int(b) for b in bad)}", path=path,
                             fix="the file is damaged; download it again")
    for name in ("theta_i", "phi_i", "wavelengths"):  # interpolation nodes
        if name in data and np.any(np.diff(data[name]) <= 0):
            raise InputError(f"field {name!r} is not increasing", path=path,
                             fix="pass an unmodified RGL .bsdf file")
    return kind, fields


# ------------------------------------------------------------------------ options --

def parse_angles(spec: str, flag: str, theta_i: bool, path=None) -> np.ndarray:
    """An angle list option in degrees → sorted distinct (n,) array.

    ``spec`` is comma-separated numbers and inclusive ``START:STOP:STEP`` ranges, e.g.
    ``10:70:10`` or ``-80:85:5,44,46`` (:class:`gonio_cli.numbers.NumberList`). θi must
    lie in [0, 90), θo in (−90, 90) (docs/conventions.md). Overlapping items are merged.
    ``path``: the input the angles are for, named in an error.
    """
    option = NumberList(flag, DEFAULT_THETA_I_DEG if theta_i else DEFAULT_THETA_O_DEG,
                        unit="deg", lo=0.0 if theta_i else -90.0, lo_open=not theta_i,
                        hi=90.0, hi_open=True)
    values = option.parse(spec, path)
    return distinct(np.round(np.asarray(values, dtype=float), 6)) + 0.0  # + 0.0: −0 → 0


def resolve_parameters(paths: Sequence[str | os.PathLike], *,
                       theta_i_deg: str | None = None, theta_o_deg: str | None = None,
                       phi_o_deg: str | None = None, mirror_deg: str | None = None,
                       grid_nm: str | None = None, **csv_options) -> dict[str, Any]:
    """Check the options for an RGL input and fill in defaults (recorded in the artifact).

    One ``.bsdf`` at a time; the CSV-only options (``csv_options``, e.g. ``quantity``) are
    refused when given, since the file holds BRDFs. Reads the file's header (cheap) to
    record its kind and, for RGB, the RGB → spectrum rule; :func:`ingest` checks the rest
    of the file (:func:`check_bsdf`). The mirror ring defaults to
    :data:`~.hemisphere.DEFAULT_MIRROR_DEG` with the default θo grid and to none with a
    θo list given (that list is the grid, as before).
    """
    where = os.fspath(paths[0])
    if len(paths) != 1:
        raise InputError(f"{len(paths)} inputs given with an RGL .bsdf: one .bsdf is read "
                         "at a time, not merged", path=where,
                         fix="ingest each .bsdf into its own measurement")
    for name, value in csv_options.items():
        if value is not None:
            flag = "--" + name.replace("_", "-")
            raise InputError(f"{flag} is for CSV input; an RGL .bsdf holds BRDF values",
                             path=where, fix=f"drop {flag}")
    theta_i = theta_i_deg if theta_i_deg is not None else DEFAULT_THETA_I_DEG
    theta_o = theta_o_deg if theta_o_deg is not None else DEFAULT_THETA_O_DEG
    phi = phi_o_deg if phi_o_deg is not None else DEFAULT_PHI_O_DEG
    mirror = mirror_deg if mirror_deg is not None else (
        DEFAULT_MIRROR_DEG if theta_o_deg is None else NO_MIRROR)
    parse_angles(theta_i, "--theta-i-deg", True, where)
    parse_angles(theta_o, "--theta-o-deg", False, where)
    parse_azimuths(phi, where)
    parse_mirror(mirror, where)
    grid = grid_nm if grid_nm is not None else DEFAULT_GRID_NM
    parse_grid(grid)
    kind = kind_of(read_tensor_header(where))
    return {"format": FORMAT, "kind": kind.name, "quantity": "brdf", "theta_i_deg": theta_i,
            "theta_o_deg": theta_o, "phi_o_deg": phi, "mirror_deg": mirror, "grid_nm": grid,
            "rgb_to_spectrum": RGB_TO_SPECTRUM if kind.name == "rgb" else None,
            "mitsuba_variant": kind.variant, "mitsuba_version": mitsuba_version()}


def mitsuba_version() -> str | None:
    """The installed Mitsuba's version (package metadata, without importing it), or None."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("mitsuba")
    except PackageNotFoundError:
        return None


def import_mitsuba(path=None):
    """The ``mitsuba`` module; a one-line error naming the extra (and ``path``, the file
    that needs it) if it is not installed."""
    try:
        import mitsuba as mi
    except ImportError:
        raise InputError("reading an RGL .bsdf needs Mitsuba 3 (the optional extra "
                         "gonio[mitsuba]), which is not installed", path=path,
                         fix=INSTALL_FIX) from None
    return mi


# --------------------------------------------------------------------- evaluation --

def evaluate_in_plane(path: str | os.PathLike, kind: Kind, theta_i_deg, theta_o_deg,
                      channels, phi_o_deg=None) -> np.ndarray:
    """BRDF f in sr⁻¹ (no cosine) of an RGL file at goniometer configurations.

    ``theta_i_deg``, ``theta_o_deg``, ``phi_o_deg`` (None: in plane): (n,) in degrees,
    light at (−sin θi, 0, cos θi), detector at (sin θo cos φo, sin θo sin φo, cos θo)
    (docs/conventions.md; Mitsuba's local frame has the normal on
    +z too; ωi's 0 is −0.0, see the comment in the code). ``channels``: (n_c,) wavelengths in nm for a spectral file, or ``(0, 1, 2)``
    (R, G, B) for an RGB one. Returns (n, n_c) float64: Mitsuba's ``eval`` (f·cos θo, in
    float32, as its scalar variants compute) divided by cos θo.
    """
    mi = import_mitsuba(path)
    previous = mi.variant()  # a caller's variant is set back afterwards
    if kind.variant not in mi.variants():
        raise InputError(f"this Mitsuba ({mi.__version__}) has no {kind.variant} variant "
                         f"(it has {', '.join(mi.variants())})",
                         fix=INSTALL_FIX + " (the PyPI wheels include it)")
    mi.set_variant(kind.variant)
    try:
        return _evaluate(mi, path, theta_i_deg, theta_o_deg, channels,
                         kind.name == "spectral", phi_o_deg)
    finally:
        if previous is not None:
            mi.set_variant(previous)


def _evaluate(mi, path, theta_i_deg, theta_o_deg, channels, spectral: bool,
              phi_o_deg=None) -> np.ndarray:
    """:func:`evaluate_in_plane` with ``mi``'s variant set."""
    try:
        bsdf = mi.load_dict({"type": "measured", "filename": os.fspath(path)})
    except RuntimeError as exc:
        lines = [ln.strip() for ln in str(exc).splitlines() if ln.strip()]
        text = lines[0].split("] ", 1)[-1] if lines else type(exc).__name__
        raise InputError(f"Mitsuba cannot load it: {text}", path=path,
                         fix="pass an unmodified RGL .bsdf file") from None
    wi, wo = measurement_directions(theta_i_deg, theta_o_deg, phi_o_deg)
    # ωi's y is −0.0 (the same direction): Mitsuba 3.9.1's measured plugin leaves its
    # symmetry reduction (m_reduction) uninitialised for isotropic files (open upstream fix:
    # github.com/mitsuba-renderer/mitsuba3/pull/1850) and then flips x and y unless their
    # sign bits are set, which at the mirror configuration moves the value by ~1e-4 from
    # run to run. With a sign bit on y (and x < 0) that branch is the identity whatever
    # value it holds.
    wi[..., 1] = -0.0
    channels = np.asarray(channels, dtype=float)
    ctx = mi.BSDFContext()
    si = mi.SurfaceInteraction3f()
    out = np.zeros((wi.shape[0], channels.size))
    # lanes of SPECTRAL_LANES wavelengths (the last one padded with its last wavelength)
    lanes = [channels[k:k + SPECTRAL_LANES] for k in range(0, channels.size, SPECTRAL_LANES)]
    for n in range(wi.shape[0]):
        si.wi = mi.Vector3f(*wi[n])
        w = mi.Vector3f(*wo[n])
        if spectral:
            k = 0
            for lane in lanes:
                padded = np.concatenate([lane, np.repeat(lane[-1], SPECTRAL_LANES - lane.size)])
                si.wavelengths = mi.Spectrum(padded.tolist())
                v = bsdf.eval(ctx, si, w)
                out[n, k:k + lane.size] = [v[j] for j in range(lane.size)]
                k += lane.size
        else:
            v = bsdf.eval(ctx, si, w)
            out[n] = [v[j] for j in range(3)]
    return out / wo[:, 2:3]


def ingest(paths: Sequence[str | os.PathLike], *, theta_i_deg: str | None = None,
                theta_o_deg: str | None = None, grid_nm: str | None = None,
                phi_o_deg: str | None = None, mirror_deg: str | None = None,
                **csv_options) -> Measurement:
    """Read one RGL ``.bsdf`` into a measurement: BRDF on the working grid.

    Parameters
    ----------
    paths : one path of an RGL ``.bsdf`` file (RGB or spectral).
    theta_i_deg, theta_o_deg : angle lists (:func:`parse_angles`; defaults
        :data:`DEFAULT_THETA_I_DEG`, :data:`DEFAULT_THETA_O_DEG`); every θo for every θi.
    phi_o_deg, mirror_deg : the azimuths of that grid and the mirror ring
        (:func:`~.hemisphere.hemisphere_grid`; :func:`resolve_parameters`'s defaults).
    grid_nm : working grid ``"START:STOP:STEP"`` (default ``380:780:10``).
    csv_options : the CSV-only options of :func:`gonio_cli.ingest.ingest`, which must be
        None here.

    Returns
    -------
    Measurement
        ``brdf`` (n_cfg, n_λ) in sr⁻¹ without the cosine factor, one repeat each,
        quantity ``brdf``, and a ``summary`` (:func:`gonio_cli.ingest.format_summary`).
    """
    params = resolve_parameters(paths, theta_i_deg=theta_i_deg, theta_o_deg=theta_o_deg,
                                phi_o_deg=phi_o_deg, mirror_deg=mirror_deg, grid_nm=grid_nm,
                                **csv_options)
    path = os.fspath(paths[0])
    kind, fields = check_bsdf(path)
    grid = parse_grid(params["grid_nm"])
    ti = parse_angles(params["theta_i_deg"], "--theta-i-deg", True, path)
    to = parse_angles(params["theta_o_deg"], "--theta-o-deg", False, path)
    ti_all, to_all, po_all = hemisphere_grid(ti, to, parse_azimuths(params["phi_o_deg"]),
                                             parse_mirror(params["mirror_deg"]))
    po_all = po_all if np.any(po_all) else None
    notes: list[str] = []
    meta = read_tensor_file(path, ["description", "jacobian", "phi_i", "theta_i"])
    convert = _spectral_brdf if kind.name == "spectral" else _rgb_brdf
    brdf, resampled, file_grid = convert(path, kind, (ti_all, to_all, po_all), grid, params,
                                         notes)
    negative = int(np.count_nonzero(brdf < 0))
    if negative:
        notes.append(f"{path}: clipped {negative} negative values (RGB outside the basis' "
                     "gamut or interpolation round-off) to 0")
    brdf = np.maximum(brdf, 0.0)
    m = Measurement(grid, ti_all, to_all, brdf, None, np.ones(ti_all.size, dtype=int), "brdf",
                    phi_o_deg=po_all)
    description = bytes(np.asarray(meta["description"])).decode("utf-8", "replace")
    info = {"format": FORMAT, "path": path, "kind": kind.name, "description": description,
            "isotropic": bool(meta["phi_i"].shape[0] <= 2),
            "theta_i_samples": int(meta["theta_i"].shape[0]),
            "resolution": list(fields[kind.field].shape[3:]),
            "jacobian": bool(np.asarray(meta["jacobian"])[0]),
            "wavelength_nm": file_grid, "rgb_to_spectrum": params["rgb_to_spectrum"],
            "mitsuba_variant": kind.variant, "mitsuba_version": params["mitsuba_version"]}
    m.summary = single_file_summary(m, info, params, resampled, negative, notes)
    for note in notes:
        log.warn(note)
    return m


def _spectral_brdf(path: str, kind: Kind, configurations, grid: np.ndarray,
                   params: dict, notes: list[str]) -> tuple[np.ndarray, bool, str]:
    """A spectral file's BRDF (N, n_λ) on the working grid, whether it was resampled, and
    the file's grid as the summary says it; a resampling note appended to ``notes``."""
    wl = np.asarray(read_tensor_file(path, ["wavelengths"])["wavelengths"], dtype=float)
    if not covers(wl, grid):
        raise InputError(f"its wavelengths {wl[0]:g}-{wl[-1]:g} nm do not cover the "
                         f"working grid {grid[0]:g}-{grid[-1]:g} nm", path=path,
                         column="wavelengths",
                         fix=f"choose a grid inside the file's, e.g. --grid-nm "
                             f"{math.ceil(wl[0] / 10) * 10:g}:"
                             f"{math.floor(wl[-1] / 10) * 10:g}:10")
    used = wl[used_wavelengths(wl, grid)]
    ti, to, po = configurations
    f = evaluate_in_plane(path, kind, ti, to, used, po)
    brdf = resample(used, f, grid)
    resampled = not same_grid(used, grid)
    if resampled:
        notes.append(f"{path}: resampled from the file's {wl.size} wavelengths "
                     f"({wl[0]:g}-{wl[-1]:g} nm, {used.size} used) onto the working grid "
                     f"{params['grid_nm']} nm")
    return brdf, resampled, f"{wl[0]:g}-{wl[-1]:g} nm ({wl.size} wavelengths)"


def _rgb_brdf(path: str, kind: Kind, configurations, grid: np.ndarray,
              params: dict, notes: list[str]) -> tuple[np.ndarray, bool, str]:
    """An RGB file's BRDF (N, n_λ) through the Mallett-Yuksel basis (as
    :func:`_spectral_brdf` returns it; never resampled)."""
    lo, hi = rgb_reflectance_basis_range_nm()
    if grid[0] < lo - 1e-6 or grid[-1] > hi + 1e-6:
        raise InputError(f"an RGB file becomes spectra through the Mallett-Yuksel basis, "
                         f"defined on {lo:g}-{hi:g} nm, not the working grid "
                         f"{grid[0]:g}-{grid[-1]:g} nm", path=path,
                         fix=f"choose a grid inside it, e.g. --grid-nm {DEFAULT_GRID_NM}")
    ti, to, po = configurations
    rgb = evaluate_in_plane(path, kind, ti, to, (0, 1, 2), po)
    return rgb @ rgb_reflectance_basis(grid).T, False, "linear sRGB"


def single_file_summary(m: Measurement, info: dict, params: dict, resampled: bool,
                        clipped: int, notes: list[str]) -> dict[str, Any]:
    """The summary of :func:`gonio_cli.ingest.ingest`'s shape for one input file of
    another format (an RGL ``.bsdf`` here, a CxF3 file in :mod:`.cxf`): ``info`` is the
    file's entry, ``clipped`` the values clipped to 0."""
    per_theta_i = []
    for t in distinct(m.theta_i_deg):
        sel = m.theta_i_deg == t
        n_out = int(np.count_nonzero(m.azimuths_deg[sel]))
        per_theta_i.append({"theta_i_deg": float(t),
                            "theta_o_min_deg": float(m.theta_o_deg[sel].min()),
                            "theta_o_max_deg": float(m.theta_o_deg[sel].max()),
                            "configurations": int(sel.sum()),
                            **({"out_of_plane": n_out} if n_out else {})})
    return {"files": [info], "quantity": "brdf",
            "conversion": "f = Mitsuba measured eval (f cos theta_o) / cos theta_o",
            "scale": 1.0, "theta_i_deg": [r["theta_i_deg"] for r in per_theta_i],
            "theta_o_by_theta_i": per_theta_i, "working_grid_nm": params["grid_nm"],
            "resampled": resampled, "configurations": m.n_configurations,
            "spectra": m.n_configurations, "repeats_min": 1, "repeats_max": 1,
            "brdf_min_per_sr": float(m.brdf.min()), "brdf_max_per_sr": float(m.brdf.max()),
            "negative_values_read": clipped, "clipped_to_zero": clipped,
            "warnings": list(notes)}


def file_lines(info: dict[str, Any]) -> list[str]:
    """``--summary`` lines for one RGL input (:func:`gonio_cli.ingest.format_summary`)."""
    lines = [f"read {info['path']}: RGL {info['kind']} .bsdf \"{info['description']}\", "
             f"{'isotropic' if info['isotropic'] else 'anisotropic'}, "
             f"{info['theta_i_samples']} theta_i samples, "
             f"{'x'.join(map(str, info['resolution']))} per slice, {info['wavelength_nm']}",
             f"  evaluated by Mitsuba {info['mitsuba_version']} "
             f"({info['mitsuba_variant']}, measured plugin), divided by cos theta_o"]
    if info.get("rgb_to_spectrum"):
        lines.append(f"  RGB to spectrum: {info['rgb_to_spectrum']}")
    return lines


def is_bsdf(path: str | os.PathLike) -> bool:
    """True for a path routed to this module (suffix :data:`SUFFIX`, any case)."""
    return Path(path).suffix.lower() == SUFFIX

