"""Artifact schemas: what each stage writes and the next reads, in one place.

Each artifact has ONE definition of its fields (a tree of :class:`Spec`: types, shapes,
ranges, required or not, unknown fields refused, STYLE 7). It validates every file a stage
reads, naming the file, the field and the fix in one line, and it generates the JSON
Schema published in ``docs/schemas/`` (``python -m gonio_cli.schemas docs/schemas``,
``make schemas``), so users can check their own files with any validator. The dataclasses
add ``to_payload()`` (fields written after the envelope of :mod:`gonio_cli.artifact`) and
``from_document(doc, path)``: the definition's checks, then those between fields.

- ``gonio.measurement`` v1, :class:`Measurement` (``gonio ingest``, ``gonio eval``)
- ``gonio.material`` v1 and v2, :class:`Material` (``gonio fit``)
- ``gonio.lobe_basis`` v1, :class:`LobeBasis` (``gonio lobes basis``)
- ``gonio.lobes`` v1, :class:`Lobes` (``gonio lobes fit``)
- ``gonio.prefilter`` v1, :class:`PrefilterIndex` (``gonio prefilter``'s index.json)
- ``gonio.render-report`` v1, :func:`render_report_spec` (``gonio render --report``)

The ranges are docs/conventions.md's table "Numeric ranges".

Why one module: every artifact's definition in one place, on purpose: one file to read
to know every format gonio writes, and the JSON Schemas in docs/schemas/ are generated
from it.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .artifact import check_keys, make_document, read_artifact, write_artifact, write_json
from .errors import ArtifactError, num


# ------------------------------------------------------------------- field specs --
#
# One definition per artifact: a tree of the small specs below says, for every field, its
# type, shape, range and whether it is required. The same tree validates a document
# (:meth:`Spec.check`, one :class:`ArtifactError` naming the file, the field and the fix)
# and produces the published JSON Schema (:meth:`Spec.json`, ``docs/schemas/``, written by
# ``python -m gonio_cli.schemas docs/schemas``), so the two cannot disagree. Checks between
# fields (shapes that must agree, the spectral grid of a lobe table) follow in each
# dataclass's ``from_document``. The ranges are the table "Numeric ranges" of
# docs/conventions.md.

#: Largest magnitude of a number that enters arithmetic from a file or an option (a BRDF
#: value, ρ, a weight, an irradiance, a light's intensity). Products of two such numbers
#: (1e60) stay finite in float64 (max 1.8e308) and a sum over a frame stays far from it;
#: a value beyond this is a typo or a unit error, not a measurement. (The renderer shades
#: in float32, where such a product can overflow: that is an error naming the scene.)
MAX_MAGNITUDE = 1e30

#: Cosine-lobe exponents (seed 001 eq. 2): 1 is the diffuse lobe; above 1e6 the lobe is
#: ~0.1° wide, below any map's texel (gonio prefilter's MAX_EXPONENT).
EXPONENT_RANGE = (1.0, 1e6)

#: ``--exposure-stops`` / ``[output] exposure`` in stops: 2^60 ≈ 1e18 still leaves a float32
#: pixel (max 3.4e38) room for any radiance below 1e20; a real scene needs ±20.
EXPOSURE_MAX_STOPS = 60.0

#: Wavelengths (nm) an artifact may hold: positive, and below 1e5 nm (100 µm, far infrared).
WAVELENGTH_MAX_NM = 1e5


def _where(where: str) -> str:
    return f"field {where!r}" if where else "the document"


class Spec:
    """A field's type, shape and range: ``check`` validates, ``json`` is its JSON Schema."""

    def check(self, value, where: str, path, fix: str):  # pragma: no cover (abstract)
        raise NotImplementedError

    def json(self) -> dict[str, Any]:  # pragma: no cover (abstract)
        raise NotImplementedError

    def error(self, where: str, message: str, path, fix: str) -> ArtifactError:
        return ArtifactError(f"{_where(where)} {message}", path=path, fix=fix)

    def type_error(self, where: str, message: str, path, fix: str) -> ArtifactError:
        """A value of the wrong JSON type (for :class:`AnyOf`: try the next option)."""
        exc = self.error(where, message, path, fix)
        exc.wrong_type = True
        return exc


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


@dataclass(frozen=True)
class Number(Spec):
    """A finite number in [lo, hi] (open ends on request), optionally an integer."""

    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    integer: bool = False

    def range_text(self) -> str:
        lo = "-inf" if self.lo is None else num(self.lo)
        hi = "inf" if self.hi is None else num(self.hi)
        return f"{'(' if self.lo_open else '['}{lo}, {hi}{')' if self.hi_open else ']'}"

    def outside(self, x) -> np.ndarray:
        """True where ``x`` (any shape, float) is NaN, inf or outside the range."""
        x = np.asarray(x, dtype=float)
        bad = ~np.isfinite(x)
        with np.errstate(invalid="ignore"):
            if self.lo is not None:
                bad |= (x <= self.lo) if self.lo_open else (x < self.lo)
            if self.hi is not None:
                bad |= (x >= self.hi) if self.hi_open else (x > self.hi)
        return bad

    def check(self, value, where, path, fix):
        if not _is_number(value):
            raise self.type_error(where, f"is {_kind(value)}, expected "
                                  f"{'an integer' if self.integer else 'a number'}", path, fix)
        if self.integer and not isinstance(value, int):
            raise self.error(where, f"is {num(value)}, expected an integer", path, fix)
        if not math.isfinite(value):
            raise self.error(where, f"is {num(value)}, not a finite number", path, fix)
        if ((self.lo is not None and (value < self.lo or (self.lo_open and value == self.lo)))
                or (self.hi is not None
                    and (value > self.hi or (self.hi_open and value == self.hi)))):
            raise self.error(where, f"is {num(value)}, outside {self.range_text()}", path, fix)
        return value

    def json(self):
        out: dict[str, Any] = {"type": "integer" if self.integer else "number"}
        if self.lo is not None:
            out["exclusiveMinimum" if self.lo_open else "minimum"] = self.lo
        if self.hi is not None:
            out["exclusiveMaximum" if self.hi_open else "maximum"] = self.hi
        return out


@dataclass(frozen=True)
class Text(Spec):
    """A string, one of ``enum`` if given (or exactly ``const``)."""

    enum: tuple[str, ...] | None = None

    def check(self, value, where, path, fix):
        if not isinstance(value, str):
            raise self.type_error(where, f"is {_kind(value)}, expected a string", path, fix)
        if self.enum is not None and value not in self.enum:
            raise self.error(where, f"is {value!r}, not one of {', '.join(self.enum)}",
                             path, fix)
        return value

    def json(self):
        if self.enum is not None and len(self.enum) == 1:
            return {"const": self.enum[0]}
        return {"type": "string", **({"enum": list(self.enum)} if self.enum else {})}


@dataclass(frozen=True)
class Array(Spec):
    """An ndim-deep nested list of numbers (each within ``item``), every axis non-empty
    unless ``min_size`` is 0; ``increasing``: strictly (1-D). ``check`` returns the array."""

    ndim: int
    item: Number = Number(-MAX_MAGNITUDE, MAX_MAGNITUDE)
    increasing: bool = False
    min_size: int = 1
    size: int | None = None

    def check(self, value, where, path, fix):
        if not isinstance(value, (list, np.ndarray)):
            kind = "a list" if self.ndim == 1 else f"a {self.ndim}-deep list"
            raise self.type_error(where, f"is {_kind(value)}, expected {kind} of numbers",
                                  path, fix)
        try:
            a = np.asarray(value)
        except ValueError:  # ragged rows
            raise self.type_error(where, "is not a numeric array (rows of different "
                                  "lengths)", path, fix) from None
        if a.size == 0 and self.min_size > 0:
            raise self.error(where, "is empty", path, fix)
        if a.ndim != self.ndim and a.size:
            raise self.error(where, f"has {a.ndim} dimensions, expected {self.ndim}", path,
                             fix)
        if a.size and a.dtype.kind not in ("iu" if self.item.integer else "iuf"):
            bad = next((v for v in a.ravel().tolist()
                        if not _is_number(v) or (self.item.integer and not isinstance(v, int))),
                       a.ravel()[0])
            wanted = "integers" if self.item.integer else "numbers"
            raise self.type_error(where, f"is not a numeric array (holds {_kind(bad)}, "
                                  f"expected {wanted} only)", path, fix)
        if self.size is not None and a.size != self.size:
            raise self.error(where, f"has {a.size} values, expected {self.size}", path, fix)
        a = a.astype(int if self.item.integer else float)
        bad = self.item.outside(a)
        if np.any(bad):
            k = tuple(int(i) for i in np.argwhere(bad)[0])
            at = "[" + ", ".join(map(str, k)) + "]"
            if not np.isfinite(a[k]):
                raise self.error(where, f"holds NaN or inf ({num(a[k])} at {at})", path, fix)
            raise self.error(where, f"holds {num(a[k])} at {at}, outside "
                             f"{self.item.range_text()}", path, fix)
        if self.increasing and a.size > 1 and not np.all(np.diff(a) > 0):
            k = int(np.flatnonzero(np.diff(a) <= 0)[0])
            raise self.error(where, f"is not strictly increasing ({num(a[k])} then "
                             f"{num(a[k + 1])} at [{k}], [{k + 1}])", path, fix)
        return a

    def json(self):
        out: dict[str, Any] = self.item.json()
        for depth in range(self.ndim):
            out = {"type": "array", "items": out}
            if self.min_size:
                out["minItems"] = 1
            if depth == 0 and self.size is not None and self.ndim == 1:
                out["minItems"] = out["maxItems"] = self.size
        if self.increasing:  # not expressible in JSON Schema: said in the description
            out["description"] = "strictly increasing"
        return out


@dataclass(frozen=True)
class ListOf(Spec):
    """A list whose items all follow ``item``; at least ``min_items``."""

    item: Spec
    min_items: int = 0

    def check(self, value, where, path, fix):
        if not isinstance(value, list):
            raise self.type_error(where, f"is {_kind(value)}, expected a list", path, fix)
        if len(value) < self.min_items:
            raise self.error(where, "is empty", path, fix)
        return [self.item.check(v, f"{where}[{k}]", path, fix) for k, v in enumerate(value)]

    def json(self):
        out = {"type": "array", "items": self.item.json()}
        if self.min_items:
            out["minItems"] = self.min_items
        return out


@dataclass(frozen=True)
class Nullable(Spec):
    """``inner`` or JSON null."""

    inner: Spec

    def check(self, value, where, path, fix):
        return None if value is None else self.inner.check(value, where, path, fix)

    def json(self):
        return {"anyOf": [self.inner.json(), {"type": "null"}]}


@dataclass(frozen=True)
class AnyOf(Spec):
    """The first of ``options`` that accepts the value; else the error of the first option
    of the value's type (or of the first option)."""

    options: tuple[Spec, ...]

    def check(self, value, where, path, fix):
        errors = []
        for option in self.options:
            try:
                return option.check(value, where, path, fix)
            except ArtifactError as exc:
                errors.append(exc)
        # the option of the value's type says what is wrong with it; else the first
        raise next((e for e in errors if not getattr(e, "wrong_type", False)), errors[0])

    def json(self):
        return {"anyOf": [o.json() for o in self.options]}


@dataclass(frozen=True)
class Obj(Spec):
    """A JSON object: ``fields`` name → (spec, required). Unknown keys are errors
    (STYLE 7) unless ``fields`` is None (a free-form record, such as ``parameters``)."""

    fields: dict[str, tuple[Spec, bool]] | None = None

    def check(self, value, where, path, fix):
        if not isinstance(value, dict):
            raise self.type_error(where, f"is {_kind(value)}, expected an object", path, fix)
        if self.fields is None:
            return value
        prefix = f"{where}." if where else ""
        check_keys(value, self.fields, path=path, where=prefix)
        out = {}
        for name, (spec, required) in self.fields.items():
            if name in value:
                out[name] = spec.check(value[name], prefix + name, path, fix)
            elif required:
                raise ArtifactError(f"missing field {prefix + name!r}", path=path, fix=fix)
        return out

    def json(self):
        if self.fields is None:
            return {"type": "object"}
        return {"type": "object",
                "properties": {k: s.json() for k, (s, _) in self.fields.items()},
                "required": [k for k, (_, r) in self.fields.items() if r],
                "additionalProperties": False}


def _kind(value) -> str:
    """What a JSON value is, for messages: 'a string ('abc')', 'the number 3'."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return f"the boolean {str(value).lower()}"
    if _is_number(value):
        return f"the number {num(value)}"
    if isinstance(value, str):
        return f"the string {value[:40]!r}"
    if isinstance(value, list):
        return f"a list of {len(value)}"
    if isinstance(value, dict):
        return "an object"
    return type(value).__name__


def _req(spec: Spec) -> tuple[Spec, bool]:
    return (spec, True)


def _opt(spec: Spec) -> tuple[Spec, bool]:
    return (spec, False)


NON_NEGATIVE = Number(0.0, MAX_MAGNITUDE)
COUNT = Number(0, None, integer=True)
POSITIVE_COUNT = Number(1, None, integer=True)
SECONDS = Number(0.0, None)
FREE = Obj(None)
WAVELENGTHS = Array(1, Number(0.0, WAVELENGTH_MAX_NM, lo_open=True), increasing=True)
EXPONENTS = Array(1, Number(*EXPONENT_RANGE))


def envelope_fields(schema: str, versions: tuple[int, ...]) -> dict[str, tuple[Spec, bool]]:
    """The fields every artifact starts with (:data:`gonio_cli.artifact.ENVELOPE_KEYS`)."""
    return {"schema": _req(Text((schema,))),
            "schema_version": _req(Number(min(versions), max(versions), integer=True)),
            "gonio_version": _opt(Text()),
            "created_utc": _opt(Text()),
            "inputs": _opt(ListOf(Obj({"path": _req(Text()), "sha256": _opt(Text())}))),
            "parameters": _opt(FREE),
            "time_s": _opt(SECONDS)}


def validate(doc: dict[str, Any], spec: Obj, path, fix: str) -> dict[str, Any]:
    """Check ``doc`` against ``spec``: the checked fields (arrays as numpy arrays)."""
    return spec.check(doc, "", path, fix)


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

    #: What ingest reports (the keys of :data:`gonio_cli.ingest.QUANTITIES`; a test checks).
    QUANTITIES = ("brdf", "ratio-to-white", "reflectance-factor", "flux-ratio")
    FIX = "regenerate it with gonio ingest"

    @classmethod
    def spec(cls) -> Obj:
        """The one definition of a ``gonio.measurement`` document (docs/schemas/)."""
        return Obj({**envelope_fields(cls.SCHEMA, (cls.VERSION,)),
                    "wavelength_nm": _req(WAVELENGTHS),
                    "theta_i_deg": _req(Array(1, Number(0.0, 90.0, hi_open=True))),
                    "theta_o_deg": _req(Array(1, Number(-90.0, 90.0, True, True))),
                    "brdf": _req(Array(2)),
                    "brdf_std": _opt(Nullable(Array(2, NON_NEGATIVE))),
                    "n_repeats": _opt(Array(1, POSITIVE_COUNT)),
                    "quantity": _opt(Text(cls.QUANTITIES)),
                    "summary": _opt(FREE)})

    @classmethod
    def from_document(cls, doc: dict[str, Any], path=None) -> "Measurement":
        f = validate(doc, cls.spec(), path, cls.FIX)
        wl, ti, to, brdf = f["wavelength_nm"], f["theta_i_deg"], f["theta_o_deg"], f["brdf"]
        std, reps = f.get("brdf_std"), f.get("n_repeats")
        n, nl = ti.size, wl.size
        if to.size != n or brdf.shape != (n, nl) or (std is not None and std.shape != (n, nl)) \
                or (reps is not None and reps.size != n):
            raise ArtifactError(f"inconsistent shapes: {n} theta_i_deg, {to.size} theta_o_deg, "
                                f"brdf {brdf.shape}, {nl} wavelengths"
                                + (f", brdf_std {std.shape}" if std is not None else "")
                                + (f", {reps.size} n_repeats" if reps is not None else ""),
                                path=path, fix=cls.FIX)
        return cls(wl, ti, to, brdf, std, reps, f.get("quantity", "brdf"),
                   dict(f.get("summary") or {}))


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

    FIX = "regenerate it with gonio fit"

    @classmethod
    def spec(cls, model: str, version: int = VERSION) -> Obj:
        """The one definition of a ``gonio.material`` document of ``model`` (docs/schemas/)."""
        from .brdf import MODELS

        m = MODELS[model]
        return Obj({**envelope_fields(cls.SCHEMA, (version,)),
                    "model": _req(Text((model,))),
                    "status": _opt(Text(cls.STATUSES[version])),
                    "wavelength_nm": _req(WAVELENGTHS),
                    **{k: _req(PARAM_RANGES[k]) for k in m.scalar_params},
                    **{k: _req(Array(1, PARAM_RANGES[k])) for k in m.spectral_params},
                    "fit": _opt(FREE)})

    @classmethod
    def from_document(cls, doc: dict[str, Any], path=None) -> "Material":
        from .brdf import MODELS

        model = doc.get("model")
        if not isinstance(model, str) or model not in MODELS:
            raise ArtifactError(f"field 'model' is {_kind(model)}, not a known model",
                                path=path, fix=f"one of {', '.join(MODELS)}")
        version = doc.get("schema_version", cls.VERSION)
        f = validate(doc, cls.spec(model, version if version in cls.STATUSES else cls.VERSION),
                     path, cls.FIX)
        wl = f["wavelength_nm"]
        spec = MODELS[model]
        params: dict[str, Any] = {k: float(f[k]) for k in spec.scalar_params}
        for name in spec.spectral_params:
            params[name] = f[name]
            if params[name].shape != wl.shape:
                raise ArtifactError(f"field {name!r} has {params[name].size} values for "
                                    f"{wl.size} wavelengths", path=path, fix=cls.FIX)
        status = f.get("status", cls.STATUSES[version][0])
        return cls(model, wl, params, status, dict(f.get("fit") or {}))


#: Bound of |c(λ)| in seed 000 eq. 5's exp(c x), x in [0, 1]: e^100 ≈ 3e43, so ρ e^{c x}
#: stays finite in float64 for any ρ ≤ MAX_MAGNITUDE; gonio fit searches |c| ≤ 60
#: (fit.separable.C_LIMIT), so nothing it writes is refused.
C_MAX = 100.0

#: The range of every material parameter (brdf.MODELS), by name: α of GGX in (0, 1]
#: (seed 000 eq. 3, fit.common.ALPHA_MAX); Beckmann m in (0, 1] (seed 004 eq. 9,
#: fit.cook_torrance.M_MAX); Fresnel F0 in [0, 1]; scales and albedos in
#: [0, MAX_MAGNITUDE]. A test checks that every model parameter is listed.
PARAM_RANGES: dict[str, Number] = {
    **{k: Number(0.0, 1.0, lo_open=True) for k in ("alpha", "alpha_coat", "alpha_2")},
    **{k: Number(0.0, 1.0, lo_open=True) for k in ("m", "m_1", "m_2", "m_3")},
    **{k: Number(0.0, 1.0) for k in ("f0", "f0_coat")},
    **{k: NON_NEGATIVE for k in ("rho", "rho_d", "rho_2", "kd", "ks", "ks_1", "ks_2", "ks_3",
                                 "k_coat")},
    "c": Number(-C_MAX, C_MAX),
    "b0": NON_NEGATIVE, "h": Number(0.0, MAX_MAGNITUDE, lo_open=True),
}


def read_material(path: str | os.PathLike) -> Material:
    """Read and validate a ``gonio.material`` artifact."""
    doc = read_artifact(path, Material.SCHEMA, Material.READ_VERSIONS)
    return Material.from_document(doc, path=path)


def write_material(path: str | os.PathLike, m: Material, **envelope) -> dict:
    """Write a material atomically with provenance."""
    return write_artifact(path, Material.SCHEMA, Material.VERSION, m.to_payload(),
                          **envelope)


# ------------------------------------------------------------------------ lobe basis --

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

    FIX = "choose a basis with gonio lobes basis"

    @classmethod
    def spec(cls) -> Obj:
        """The one definition of a ``gonio.lobe_basis`` document (docs/schemas/)."""
        basis = Obj({"n_lobes": _req(POSITIVE_COUNT), "exponents": _req(EXPONENTS),
                     "error": _opt(Nullable(Number(0.0, None))),
                     "max_error": _opt(Nullable(Number(0.0, None))),
                     "mean_error": _opt(Nullable(Number(0.0, None))),
                     "per_material": _opt(Array(1, Number(0.0, None), min_size=0)),
                     "evaluations": _opt(COUNT), "time_s": _opt(SECONDS),
                     "message": _opt(Text())})
        return Obj({**envelope_fields(cls.SCHEMA, (cls.VERSION,)),
                    "bases": _req(ListOf(basis, min_items=1)),
                    "materials": _opt(ListOf(Obj({"path": _req(Text()),
                                                  "model": _opt(Text())}))),
                    "sample_set": _req(Text()), "channels": _req(Text(LOBE_CHANNELS)),
                    "solver": _req(Text()),
                    "exponent_range": _opt(Array(1, Number(*EXPONENT_RANGE), size=2)),
                    "view_angle_deg": _opt(Array(1, Number(0.0, 90.0), min_size=0))})

    @classmethod
    def from_document(cls, doc: dict[str, Any], path=None) -> "LobeBasis":
        f = validate(doc, cls.spec(), path, cls.FIX)
        bases = [dict(doc["bases"][k]) for k in range(len(f["bases"]))]
        for k, b in enumerate(f["bases"]):
            if b["n_lobes"] != b["exponents"].size:
                raise ArtifactError(f"field 'bases[{k}].n_lobes' is {b['n_lobes']} but "
                                    f"'bases[{k}].exponents' holds {b['exponents'].size}",
                                    path=path, fix=cls.FIX)
        return cls(bases, list(doc.get("materials") or []), f["sample_set"], f["channels"],
                   f["solver"], list(doc.get("exponent_range") or []),
                   list(doc.get("view_angle_deg") or []))


#: Channel kinds of lobe weights: per wavelength, or CIE XYZ.
LOBE_CHANNELS = ("spectral", "xyz")


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

    FIX = "regenerate it with gonio lobes fit"

    @classmethod
    def spec(cls) -> Obj:
        """The one definition of a ``gonio.lobes`` document (docs/schemas/)."""
        weights = Array(1, NON_NEGATIVE)
        return Obj({**envelope_fields(cls.SCHEMA, (cls.VERSION,)),
                    "exponents": _req(EXPONENTS),
                    "channel_kind": _req(Text(LOBE_CHANNELS)),
                    "channels": _req(AnyOf((WAVELENGTHS,
                                            ListOf(Text(("X", "Y", "Z")), min_items=3)))),
                    "view_angle_deg": _req(Array(1, Number(0.0, 90.0), increasing=True)),
                    "diffuse": _req(Array(2, weights.item)),
                    "directional_diffuse": _req(Array(3, weights.item)),
                    "gloss": _req(Array(3, weights.item)),
                    "errors": _opt(FREE), "solver": _opt(Text()), "sample_set": _opt(Text()),
                    "n_samples": _opt(ListOf(COUNT))})

    @classmethod
    def from_document(cls, doc: dict[str, Any], path=None) -> "Lobes":
        f = validate(doc, cls.spec(), path, cls.FIX)
        e, views = f["exponents"], f["view_angle_deg"]
        kd, kdd, kg = f["diffuse"], f["directional_diffuse"], f["gloss"]
        channels = list(doc["channels"])
        spectral = f["channel_kind"] == "spectral"
        if spectral != isinstance(f["channels"], np.ndarray):
            raise ArtifactError(f"field 'channels' does not fit channel_kind "
                                f"{f['channel_kind']!r}", path=path,
                                fix="spectral weights list wavelength_nm, xyz ones X, Y, Z")
        V, m, C = views.size, e.size, len(channels)
        if kd.shape != (V, C) or kdd.shape != (V, m, C) or kg.shape != (V, m, C) or (
                "n_samples" in f and len(f["n_samples"]) != V):
            raise ArtifactError(f"inconsistent shapes: {V} view angles, {m} exponents, {C} "
                                f"channels but diffuse {kd.shape}, directional_diffuse "
                                f"{kdd.shape}, gloss {kg.shape}"
                                + (f", {len(f['n_samples'])} n_samples" if "n_samples" in f
                                   else ""), path=path, fix=cls.FIX)
        return cls(e, f["channel_kind"], channels, views, kd, kdd, kg,
                   dict(f.get("errors") or {}), f.get("solver", ""),
                   f.get("sample_set", ""), list(f.get("n_samples") or []))


def read_lobes(path: str | os.PathLike) -> Lobes:
    """Read and validate a ``gonio.lobes`` artifact."""
    return _read_as(Lobes, path)


def write_lobes(path: str | os.PathLike, lobes: Lobes, **envelope) -> dict:
    """Write lobe weights atomically with provenance."""
    return _write_as(path, lobes, **envelope)


def read_lobe_exponents(path: str | os.PathLike) -> list[float]:
    """Only the top-level ``exponents`` of a ``gonio.lobes`` artifact (what ``gonio
    prefilter --lobes`` needs), checked by the field's definition in :meth:`Lobes.spec`;
    the other fields are neither needed nor checked."""
    doc = read_artifact(path, Lobes.SCHEMA, (Lobes.VERSION,))
    if "exponents" not in doc:
        raise ArtifactError("has no top-level 'exponents' list of numbers", path=path,
                            fix="pass the lobes file written by gonio lobes")
    spec, _ = Lobes.spec().fields["exponents"]
    return spec.check(doc["exponents"], "exponents", path,
                      "pass the lobes file written by gonio lobes").tolist()


# ------------------------------------------------------------------ prefilter index --

@dataclass
class PrefilterIndex:
    """The ``index.json`` of a prefiltered environment (``gonio.prefilter`` v1): written by
    ``gonio prefilter`` (:func:`write_prefilter_index`), read by
    :func:`gonio_cli.render.environment.load_environment` (:func:`read_prefilter_index`).

    Attributes
    ----------
    maps : one dict per map: ``exponent``, ``path`` (beside index.json), ``width``,
        ``height`` (px), and how it was made (``method``, ``error_estimate``,
        ``checked_texels``, ``working_width``, ``working_height``, ``time_s``).
    source : the input map's ``width``, ``height``, ``channels``,
        ``invalid_texels_replaced`` ; diffuse : the file name of the E = 1 map.
    sun : (version 2, ``gonio prefilter --sun``) the sun split off the map before it was
        prefiltered (:class:`gonio_cli.envsun.Sun`): ``direction`` (3, towards it),
        ``irradiance_rgb`` (3, linear sRGB at normal incidence), ``angular_diameter_deg``,
        ``solid_angle_sr``, ``texels``, ``flux_share``, ``fill_share``; the renderer lights
        the scene with it as a directional light that casts shadows.
    """

    maps: list[dict[str, Any]]
    source: dict[str, Any] | None = None
    diffuse: str | None = None
    sun: dict[str, Any] | None = None

    SCHEMA = "gonio.prefilter"
    VERSION = 2
    #: Versions read: 1 (no sun) and 2.
    READ_VERSIONS = (1, 2)
    FIX = "regenerate the folder with gonio prefilter"

    def to_payload(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        if self.source is not None:
            out["source"] = self.source
        if self.diffuse is not None:
            out["diffuse"] = self.diffuse
        if self.sun is not None:
            out["sun"] = self.sun
        out["maps"] = self.maps
        return out

    @classmethod
    def spec(cls) -> Obj:
        """The one definition of a ``gonio.prefilter`` ``index.json`` (docs/schemas/)."""
        entry = Obj({"exponent": _req(Number(*EXPONENT_RANGE)), "path": _req(Text()),
                     "width": _req(POSITIVE_COUNT), "height": _req(POSITIVE_COUNT),
                     "method": _opt(Text()),
                     "error_estimate": _opt(Nullable(Number(0.0, None))),
                     "checked_texels": _opt(COUNT), "working_width": _opt(POSITIVE_COUNT),
                     "working_height": _opt(POSITIVE_COUNT), "time_s": _opt(SECONDS)})
        source = Obj({"width": _req(POSITIVE_COUNT), "height": _req(POSITIVE_COUNT),
                      "channels": _req(POSITIVE_COUNT), "invalid_texels_replaced": _opt(COUNT)})
        vector = ListOf(Number(-MAX_MAGNITUDE, MAX_MAGNITUDE), min_items=3)
        sun = Obj({"direction": _req(vector), "irradiance_rgb": _req(vector),
                   "angular_diameter_deg": _req(Number(0.0, 180.0)),
                   "solid_angle_sr": _req(NON_NEGATIVE), "texels": _opt(COUNT),
                   "flux_share": _opt(Number(0.0, 1.0)), "fill_share": _opt(Number(0.0, 1.0))})
        return Obj({**envelope_fields(cls.SCHEMA, cls.READ_VERSIONS),
                    "source": _opt(source), "diffuse": _opt(Text()), "sun": _opt(sun),
                    "maps": _req(ListOf(entry, min_items=1))})

    @classmethod
    def from_document(cls, doc: dict[str, Any], path=None) -> "PrefilterIndex":
        f = validate(doc, cls.spec(), path, cls.FIX)
        return cls([dict(m) for m in f["maps"]], f.get("source"), f.get("diffuse"),
                   f.get("sun"))


def read_prefilter_index(path: str | os.PathLike) -> PrefilterIndex:
    """Read and validate a prefiltered environment's ``index.json`` (versions 1 and 2)."""
    doc = read_artifact(path, PrefilterIndex.SCHEMA, PrefilterIndex.READ_VERSIONS)
    return PrefilterIndex.from_document(doc, path=path)


def write_prefilter_index(path: str | os.PathLike, index: PrefilterIndex, **envelope) -> dict:
    """Write ``index.json`` atomically with provenance, after checking the document against
    the reader's definition (a failure there is a bug in the writer, nothing is written)."""
    doc = make_document(index.SCHEMA, index.VERSION, index.to_payload(), **envelope)
    validate(doc, index.spec(), path, "a bug in gonio prefilter: please report it")
    write_json(path, doc)
    return doc


# --------------------------------------------------------------------- render report --

#: ``gonio render --report`` (:func:`gonio_cli.render.output.write_report`).
RENDER_REPORT_SCHEMA = "gonio.render-report"
RENDER_REPORT_VERSION = 1


def render_report_spec() -> Obj:
    """The one definition of a ``gonio.render-report`` document (docs/schemas/)."""
    stage = Obj({"stage": _req(Text()), "time_s": _req(SECONDS)})
    return Obj({**envelope_fields(RENDER_REPORT_SCHEMA, (RENDER_REPORT_VERSION,)),
                "stages": _req(ListOf(stage)), "substages": _opt(ListOf(stage)),
                "frame_time_s": _req(SECONDS), "frame_stages": _opt(ListOf(Text())),
                "outputs": _req(Obj({"png": _req(Text()), "exr": _opt(Nullable(Text())),
                                     "gamut_warning": _opt(Nullable(Text()))})),
                "image": _req(Obj({"width": _req(POSITIVE_COUNT),
                                   "height": _req(POSITIVE_COUNT)})),
                "counts": _opt(FREE)})


def read_render_report(path: str | os.PathLike) -> dict[str, Any]:
    """Read and validate a render report (checked fields)."""
    doc = read_artifact(path, RENDER_REPORT_SCHEMA, (RENDER_REPORT_VERSION,))
    return validate(doc, render_report_spec(), path, "regenerate it with gonio render --report")


# -------------------------------------------------------------- published JSON Schema --

#: JSON Schema dialect of the files in docs/schemas/.
JSON_SCHEMA_DIALECT = "https://json-schema.org/draft/2020-12/schema"


def _material_json() -> dict[str, Any]:
    """Every model and version of a material: one branch per (model, version)."""
    from .brdf import MODELS

    return {"oneOf": [Material.spec(model, version).json() for model in MODELS
                      for version in Material.READ_VERSIONS]}


#: Artifact → (file name in docs/schemas/, title, the JSON Schema of its one definition).
PUBLISHED: dict[str, tuple[str, str, Any]] = {
    Measurement.SCHEMA: ("measurement.schema.json", "gonio measurement (gonio ingest)",
                         lambda: Measurement.spec().json()),
    Material.SCHEMA: ("material.schema.json", "gonio material (gonio fit), versions 1 and 2",
                      _material_json),
    LobeBasis.SCHEMA: ("lobe_basis.schema.json", "gonio lobe basis (gonio lobes basis)",
                       lambda: LobeBasis.spec().json()),
    Lobes.SCHEMA: ("lobes.schema.json", "gonio lobe weights (gonio lobes fit)",
                   lambda: Lobes.spec().json()),
    PrefilterIndex.SCHEMA: ("prefilter.schema.json",
                            "gonio prefiltered environment index.json (gonio prefilter)",
                            lambda: PrefilterIndex.spec().json()),
    RENDER_REPORT_SCHEMA: ("render_report.schema.json", "gonio render report (gonio render "
                           "--report)", lambda: render_report_spec().json()),
}


def json_schema(schema: str) -> dict[str, Any]:
    """The published JSON Schema of an artifact, generated from its one definition."""
    name, title, make = PUBLISHED[schema]
    return {"$schema": JSON_SCHEMA_DIALECT,
            "$id": f"https://gonio.invalid/schemas/{name}",
            "title": title,
            "description": "Generated by python -m gonio_cli.schemas from gonio_cli/schemas.py; "
                           "ranges: docs/conventions.md, Numeric ranges. Checks between "
                           "fields (shapes, strictly increasing lists) are made by gonio "
                           "itself.",
            **make()}


def schema_files() -> dict[str, str]:
    """File name → text of every published schema (what docs/schemas/ must hold)."""
    import json

    return {PUBLISHED[s][0]: json.dumps(json_schema(s), indent=1, ensure_ascii=False) + "\n"
            for s in PUBLISHED}


def main(argv: list[str] | None = None) -> int:
    """``python -m gonio_cli.schemas DIR``: write the JSON Schema files into DIR."""
    import sys
    from pathlib import Path

    args = sys.argv[1:] if argv is None else argv
    folder = Path(args[0] if args else "docs/schemas")
    folder.mkdir(parents=True, exist_ok=True)
    for name, text in schema_files().items():
        (folder / name).write_text(text, encoding="utf-8")
        print(folder / name)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
