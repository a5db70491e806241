"""Artifact schemas: what each stage writes and the next reads, in one place.

Each schema is a dataclass with ``to_payload()`` (fields written after the envelope of
:mod:`gonio_cli.artifact`) and ``from_document(doc, path)`` that validates shapes, finiteness
and field names (unknown fields are errors, STYLE 7) and names the file in every error.

- ``gonio.measurement`` v1, :class:`Measurement` (``gonio ingest``)
- ``gonio.material`` v1, :class:`Material` (``gonio fit``)
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .artifact import ENVELOPE_KEYS, check_keys, read_artifact, write_artifact
from .errors import ArtifactError, num


def _array(doc, key, path, ndim, dtype=float) -> np.ndarray:
    try:
        a = np.asarray(doc[key], dtype=dtype)
    except KeyError:
        raise ArtifactError(f"missing field {key!r}", path=path) from None
    except (TypeError, ValueError):
        raise ArtifactError(f"field {key!r} is not a numeric array", path=path) from None
    if a.ndim != ndim:
        raise ArtifactError(f"field {key!r} has {a.ndim} dimensions, expected {ndim}",
                            path=path)
    if np.issubdtype(a.dtype, np.floating) and not np.all(np.isfinite(a)):
        raise ArtifactError(f"field {key!r} holds NaN or inf", path=path)
    return a


# -------------------------------------------------------------------------- measurement --

@dataclass
class Measurement:
    """In-plane goniometer measurement on one spectral grid (``gonio.measurement`` v1).

    Attributes
    ----------
    wavelength_nm : (n_λ,) float, increasing.
    theta_i_deg : (n_cfg,) float in [0, 90); theta_o_deg : (n_cfg,) float in (−90, 90),
        signed as in docs/conventions.md (θo = θi is the mirror configuration).
    brdf : (n_cfg, n_λ) float, sr⁻¹, the mean of the repeats (no cosine factor).
    brdf_std : (n_cfg, n_λ) float or None, sample standard deviation of the repeats
        (0 where a configuration was read once); None if no configuration repeated.
    n_repeats : (n_cfg,) int ≥ 1, how many rows were averaged per configuration.
    quantity : what the instrument reported before conversion to BRDF.
    summary : what ingest read, dropped, clipped and resampled (for ``--summary``).
    """

    wavelength_nm: np.ndarray
    theta_i_deg: np.ndarray
    theta_o_deg: np.ndarray
    brdf: np.ndarray
    brdf_std: np.ndarray | None = None
    n_repeats: np.ndarray | None = None
    quantity: str = "brdf"
    summary: dict[str, Any] = field(default_factory=dict)

    SCHEMA = "gonio.measurement"
    VERSION = 1
    FIELDS = ("wavelength_nm", "theta_i_deg", "theta_o_deg", "brdf", "brdf_std",
              "n_repeats", "quantity", "summary")

    def __post_init__(self):
        self.wavelength_nm = np.asarray(self.wavelength_nm, dtype=float)
        self.theta_i_deg = np.asarray(self.theta_i_deg, dtype=float)
        self.theta_o_deg = np.asarray(self.theta_o_deg, dtype=float)
        self.brdf = np.asarray(self.brdf, dtype=float)
        if self.brdf_std is not None:
            self.brdf_std = np.asarray(self.brdf_std, dtype=float)
        if self.n_repeats is None:
            self.n_repeats = np.ones(self.theta_i_deg.shape, dtype=int)
        self.n_repeats = np.asarray(self.n_repeats, dtype=int)

    @property
    def n_configurations(self) -> int:
        return int(self.theta_i_deg.size)

    def to_payload(self) -> dict[str, Any]:
        return {
            "wavelength_nm": self.wavelength_nm,
            "theta_i_deg": self.theta_i_deg,
            "theta_o_deg": self.theta_o_deg,
            "brdf": self.brdf,
            "brdf_std": self.brdf_std,
            "n_repeats": self.n_repeats,
            "quantity": self.quantity,
            "summary": self.summary,
        }

    @classmethod
    def from_document(cls, doc: dict[str, Any], path=None) -> "Measurement":
        check_keys(doc, ENVELOPE_KEYS + cls.FIELDS, path=path)
        wl = _array(doc, "wavelength_nm", path, 1)
        ti = _array(doc, "theta_i_deg", path, 1)
        to = _array(doc, "theta_o_deg", path, 1)
        brdf = _array(doc, "brdf", path, 2)
        std = _array(doc, "brdf_std", path, 2) if doc.get("brdf_std") is not None else None
        reps = _array(doc, "n_repeats", path, 1, dtype=int) if "n_repeats" in doc else None
        n, nl = ti.size, wl.size
        if to.size != n or brdf.shape != (n, nl) or (std is not None and std.shape != (n, nl)) \
                or (reps is not None and reps.size != n):
            raise ArtifactError(f"inconsistent shapes: {n} theta_i_deg, {to.size} theta_o_deg, "
                                f"brdf {brdf.shape}, {nl} wavelengths", path=path,
                                fix="regenerate it with gonio ingest")
        if n == 0:
            raise ArtifactError("holds no configurations", path=path)
        if wl.size > 1 and not np.all(np.diff(wl) > 0):
            raise ArtifactError("wavelength_nm is not increasing", path=path)
        if np.any((ti < 0) | (ti >= 90)) or np.any(np.abs(to) >= 90):
            raise ArtifactError("theta_i_deg outside [0, 90) or theta_o_deg outside (-90, 90)",
                                path=path)
        if reps is not None and np.any(reps < 1):
            raise ArtifactError("n_repeats below 1", path=path)
        summary = doc.get("summary") or {}
        if not isinstance(summary, dict) or not isinstance(doc.get("quantity", "brdf"), str):
            raise ArtifactError("field 'summary' is not an object or 'quantity' not a string",
                                path=path)
        return cls(wl, ti, to, brdf, std, reps, doc.get("quantity", "brdf"), dict(summary))


def read_measurement(path: str | os.PathLike) -> Measurement:
    """Read and validate a ``gonio.measurement`` artifact."""
    doc = read_artifact(path, Measurement.SCHEMA, (Measurement.VERSION,))
    return Measurement.from_document(doc, path=path)


def write_measurement(path: str | os.PathLike, m: Measurement, **envelope) -> dict:
    """Write a measurement atomically with provenance (inputs, parameters, time_s)."""
    return write_artifact(path, Measurement.SCHEMA, Measurement.VERSION, m.to_payload(),
                          **envelope)


# ----------------------------------------------------------------------------- material --

@dataclass
class Material:
    """A fitted reflectance model (``gonio.material`` v2), read by lobes and render.

    Attributes
    ----------
    model : a key of :data:`gonio_cli.brdf.MODELS` (``goniochromatic`` …).
    wavelength_nm : (n_λ,) the grid of the spectral parameters.
    params : the model's parameters by name: scalars (``alpha``) as float, spectra
        (``rho``, ``c``, ``f0``, ``kd`` …) as (n_λ,) arrays. Written at the top level of
        the artifact, so a material reads like the paper: ``alpha``, ``rho``, ``c``.
    status : the fit's verdict, "good", "poor" or "failed" (:mod:`gonio_cli.fit.verdict`;
        a failed fit is written only on request). Version 1 files said "success" or
        "failed"; they are read as they are.
    fit : how it was obtained: ``final`` (the method whose parameters these are) and
        ``methods`` (per method: parameters, errors, optimiser, evaluations, time_s).
    """

    model: str
    wavelength_nm: np.ndarray
    params: dict[str, Any]
    status: str = "good"
    fit: dict[str, Any] = field(default_factory=dict)

    SCHEMA = "gonio.material"
    VERSION = 2
    #: Versions read: 1 (status success/failed) and 2 (status good/poor/failed).
    READ_VERSIONS = (1, 2)
    STATUSES = {1: ("success", "failed"), 2: ("good", "poor", "failed")}
    FIELDS = ("model", "wavelength_nm", "status", "fit")


    def to_payload(self) -> dict[str, Any]:
        out: dict[str, Any] = {"model": self.model, "status": self.status,
                               "wavelength_nm": self.wavelength_nm}
        out.update(self.params)
        out["fit"] = self.fit
        return out

    def evaluate(self, cos) -> np.ndarray:
        """f in sr⁻¹ at :class:`~gonio_cli.geometry.Cosines` (...,) → (..., n_λ)."""
        from .brdf import evaluate

        return evaluate(self.model, cos, self.params)

    @classmethod
    def from_document(cls, doc: dict[str, Any], path=None) -> "Material":
        from .brdf import MODELS

        model = doc.get("model")
        if model not in MODELS:
            raise ArtifactError(f"model {model!r} is unknown", path=path,
                                fix=f"one of {', '.join(MODELS)}")
        spec = MODELS[model]
        check_keys(doc, ENVELOPE_KEYS + cls.FIELDS + spec.scalar_params
                   + spec.spectral_params, path=path)
        wl = _array(doc, "wavelength_nm", path, 1)
        params: dict[str, Any] = {}
        for name in spec.scalar_params:
            params[name] = float(_array(doc, name, path, 0))
        for name in spec.spectral_params:
            params[name] = _array(doc, name, path, 1)
            if params[name].shape != wl.shape:
                raise ArtifactError(f"field {name!r} has {params[name].size} values for "
                                    f"{wl.size} wavelengths", path=path)
        version = doc.get("schema_version", cls.VERSION)
        status = doc.get("status", cls.STATUSES.get(version, ("good",))[0])
        if status not in cls.STATUSES.get(version, ()):
            raise ArtifactError(f"field 'status' is {status!r}", path=path,
                                fix=f"version {version} uses one of "
                                    f"{', '.join(cls.STATUSES.get(version, ()))}")
        fit = doc.get("fit") or {}
        if not isinstance(fit, dict):
            raise ArtifactError("field 'fit' is not an object", path=path)
        return cls(model, wl, params, str(status), dict(fit))


def read_material(path: str | os.PathLike) -> Material:
    """Read and validate a ``gonio.material`` artifact."""
    doc = read_artifact(path, Material.SCHEMA, Material.READ_VERSIONS)
    return Material.from_document(doc, path=path)


def write_material(path: str | os.PathLike, m: Material, **envelope) -> dict:
    """Write a material atomically with provenance."""
    return write_artifact(path, Material.SCHEMA, Material.VERSION, m.to_payload(),
                          **envelope)


# ------------------------------------------------------------------------ lobe basis --

def _exponent_list(values, path, where: str) -> np.ndarray:
    """Exponents (m,) of a basis: at least one, finite, > 0 (seed 001 eq. 2)."""
    try:
        e = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise ArtifactError(f"{where} is not a list of numbers", path=path) from None
    if e.ndim != 1 or e.size == 0:
        raise ArtifactError(f"{where} is empty", path=path,
                            fix="choose a basis with gonio lobes basis")
    bad = e[~(np.isfinite(e) & (e > 0))]
    if bad.size:
        raise ArtifactError(f"{where} holds the exponent {num(bad[0])}, not a positive number",
                            path=path, fix="every cosine-lobe exponent must be > 0")
    return e


@dataclass
class LobeBasis:
    """Cosine-lobe exponents for 1 … N lobes (``gonio.lobe_basis`` v1, seed 001 §3.2).

    Attributes
    ----------
    bases : one dict per lobe count, ascending: ``n_lobes``, ``exponents`` (m,) sorted,
        ``error`` (seed 001 eq. 4: max + mean relative RMS over the materials),
        ``max_error``, ``mean_error``, ``per_material`` (n,), ``evaluations``, ``time_s``,
        ``message``.
    materials : the database: [{"path", "model"}] in the order of ``per_material``.
    sample_set, channels, solver : how the errors were measured.
    exponent_range : [min, max] of the search.
    """

    bases: list[dict[str, Any]]
    materials: list[dict[str, Any]]
    sample_set: str
    channels: str
    solver: str
    exponent_range: list[float]
    view_angle_deg: list[float]

    SCHEMA = "gonio.lobe_basis"
    VERSION = 1
    FIELDS = ("bases", "materials", "sample_set", "channels", "solver", "exponent_range",
              "view_angle_deg")
    BASIS_FIELDS = ("n_lobes", "exponents", "error", "max_error", "mean_error",
                    "per_material", "evaluations", "time_s", "message")

    def to_payload(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in self.FIELDS}

    def exponents(self, n_lobes: int | None = None, path=None) -> np.ndarray:
        """The exponents of the basis with ``n_lobes`` lobes (default: the largest)."""
        counts = [b["n_lobes"] for b in self.bases]
        if n_lobes is None:
            n_lobes = max(counts)
        if n_lobes not in counts:
            from .errors import InputError

            raise InputError(f"--lobes {n_lobes}: the basis has no {n_lobes}-lobe set",
                             path=path, fix=f"choose one of {', '.join(map(str, counts))}")
        return np.asarray(self.bases[counts.index(n_lobes)]["exponents"], dtype=float)

    @classmethod
    def from_document(cls, doc: dict[str, Any], path=None) -> "LobeBasis":
        check_keys(doc, ENVELOPE_KEYS + cls.FIELDS, path=path)
        bases = doc.get("bases")
        if not isinstance(bases, list) or not bases:
            raise ArtifactError("field 'bases' is missing or empty (an empty basis)",
                                path=path, fix="choose a basis with gonio lobes basis")
        for k, b in enumerate(bases):
            if not isinstance(b, dict):
                raise ArtifactError(f"bases[{k}] is not an object", path=path)
            check_keys(b, cls.BASIS_FIELDS, path=path, where=f"bases[{k}].")
            e = _exponent_list(b.get("exponents"), path, f"bases[{k}].exponents")
            if b.get("n_lobes") != e.size:
                raise ArtifactError(f"bases[{k}].n_lobes={b.get('n_lobes')!r} but it holds "
                                    f"{e.size} exponents", path=path)
        for key in ("sample_set", "channels", "solver"):
            if not isinstance(doc.get(key), str):
                raise ArtifactError(f"field {key!r} is missing or not a string", path=path)
        return cls(list(bases), list(doc.get("materials") or []), doc["sample_set"],
                   doc["channels"], doc["solver"], list(doc.get("exponent_range") or []),
                   list(doc.get("view_angle_deg") or []))


def _read_as(cls, path):
    """Read an artifact of ``cls.SCHEMA`` / ``cls.VERSION`` and validate it into ``cls``."""
    return cls.from_document(read_artifact(path, cls.SCHEMA, (cls.VERSION,)), path=path)


def _write_as(path, obj, **envelope) -> dict:
    """Write ``obj`` (a schema dataclass) atomically with provenance."""
    return write_artifact(path, obj.SCHEMA, obj.VERSION, obj.to_payload(), **envelope)


def read_lobe_basis(path: str | os.PathLike) -> LobeBasis:
    """Read and validate a ``gonio.lobe_basis`` artifact."""
    return _read_as(LobeBasis, path)


def write_lobe_basis(path: str | os.PathLike, b: LobeBasis, **envelope) -> dict:
    """Write a lobe basis atomically with provenance."""
    return _write_as(path, b, **envelope)


# ----------------------------------------------------------------------------- lobes --

@dataclass
class Lobes:
    """Cosine-lobe weights of one material (``gonio.lobes`` v1, seed 001 eqs. 1-3, §5.2).

    f cos θi ≈ K_D (L·N) + (L·N) Σ K_DD,i (R·V)^E_i + Σ K_G,i (R·V)^E_i, weights in sr⁻¹.

    Attributes
    ----------
    exponents : (m,) float > 0, the basis (read by ``gonio prefilter``).
    channel_kind : "spectral" or "xyz"; channels : (C,) wavelength_nm or ["X", "Y", "Z"].
    view_angle_deg : (V,) the table's view angles (the renderer interpolates).
    diffuse : (V, C) K_D ; directional_diffuse : (V, m, C) K_DD ; gloss : (V, m, C) K_G,
        all ≥ 0.
    errors : per solver {"l1", "rms", "rms_relative", "time_s"}: (V,) lists.
    solver, sample_set : how the weights were fitted ; n_samples : (V,) per view angle.
    """

    exponents: np.ndarray
    channel_kind: str
    channels: list
    view_angle_deg: np.ndarray
    diffuse: np.ndarray
    directional_diffuse: np.ndarray
    gloss: np.ndarray
    errors: dict[str, Any]
    solver: str
    sample_set: str
    n_samples: list

    SCHEMA = "gonio.lobes"
    VERSION = 1
    FIELDS = ("exponents", "channel_kind", "channels", "view_angle_deg", "diffuse",
              "directional_diffuse", "gloss", "errors", "solver", "sample_set", "n_samples")

    def to_payload(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in self.FIELDS}

    @classmethod
    def from_document(cls, doc: dict[str, Any], path=None) -> "Lobes":
        check_keys(doc, ENVELOPE_KEYS + cls.FIELDS, path=path)
        e = _exponent_list(doc.get("exponents"), path, "field 'exponents'")
        views = _array(doc, "view_angle_deg", path, 1)
        kd = _array(doc, "diffuse", path, 2)
        kdd = _array(doc, "directional_diffuse", path, 3)
        kg = _array(doc, "gloss", path, 3)
        channels = doc.get("channels")
        if doc.get("channel_kind") not in ("spectral", "xyz") or not isinstance(channels, list):
            raise ArtifactError("field 'channel_kind' is not spectral or xyz, or 'channels' "
                                "is not a list", path=path)
        V, m, C = views.size, e.size, len(channels)
        if kd.shape != (V, C) or kdd.shape != (V, m, C) or kg.shape != (V, m, C):
            raise ArtifactError(f"inconsistent shapes: {V} view angles, {m} exponents, {C} "
                                f"channels but diffuse {kd.shape}, directional_diffuse "
                                f"{kdd.shape}, gloss {kg.shape}", path=path,
                                fix="regenerate it with gonio lobes fit")
        if min(kd.min(), kdd.min(), kg.min()) < 0:
            raise ArtifactError("holds a negative weight", path=path)
        return cls(e, doc["channel_kind"], channels, views, kd, kdd, kg,
                   dict(doc.get("errors") or {}), str(doc.get("solver", "")),
                   str(doc.get("sample_set", "")), list(doc.get("n_samples") or []))


def read_lobes(path: str | os.PathLike) -> Lobes:
    """Read and validate a ``gonio.lobes`` artifact."""
    return _read_as(Lobes, path)


def write_lobes(path: str | os.PathLike, lobes: Lobes, **envelope) -> dict:
    """Write lobe weights atomically with provenance."""
    return _write_as(path, lobes, **envelope)
