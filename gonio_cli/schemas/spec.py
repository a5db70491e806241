"""The spec kit: one definition per artifact field validates documents and publishes them.

A tree of the small specs here says, for every field of an artifact, its type, shape,
range and whether it is required. The same tree validates a document (:meth:`Spec.check`,
one :class:`~gonio_cli.errors.ArtifactError` naming the file, the field and the fix) and
produces the published JSON Schema (:meth:`Spec.json`, ``docs/schemas/``, written by
``python -m gonio_cli.schemas docs/schemas``), so the two cannot disagree. Checks between
fields (shapes that must agree, the spectral grid of a lobe table) follow in each
artifact dataclass's ``from_document`` (:mod:`gonio_cli.schemas.measurement` …). The
ranges are the table "Numeric ranges" of docs/conventions.md.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..artifact import check_keys, read_artifact, write_artifact
from ..errors import ArtifactError, num

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
            raise self.type_error(where, f"is {json_kind(value)}, expected "
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
            raise self.type_error(where, f"is {json_kind(value)}, expected a string", path, fix)
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
            raise self.type_error(where, f"is {json_kind(value)}, expected {kind} of numbers",
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
            raise self.type_error(where, f"is not a numeric array (holds {json_kind(bad)}, "
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
            raise self.type_error(where, f"is {json_kind(value)}, expected a list", path, fix)
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
            raise self.type_error(where, f"is {json_kind(value)}, expected an object", path, fix)
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


def json_kind(value) -> str:
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


def required(spec: Spec) -> tuple[Spec, bool]:
    """A field of an :class:`Obj` that must be present."""
    return (spec, True)


def optional(spec: Spec) -> tuple[Spec, bool]:
    """A field of an :class:`Obj` that may be left out."""
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
    return {"schema": required(Text((schema,))),
            "schema_version": required(Number(min(versions), max(versions), integer=True)),
            "gonio_version": optional(Text()),
            "created_utc": optional(Text()),
            "inputs": optional(ListOf(Obj({"path": required(Text()), "sha256": optional(Text())}))),
            "parameters": optional(FREE),
            "time_s": optional(SECONDS)}


def validate(doc: dict[str, Any], spec: Obj, path, fix: str) -> dict[str, Any]:
    """Check ``doc`` against ``spec``: the checked fields (arrays as numpy arrays)."""
    return spec.check(doc, "", path, fix)


def read_artifact_as(cls, path: str | os.PathLike):
    """Read an artifact of ``cls.SCHEMA`` (any of ``cls.READ_VERSIONS``, else
    ``cls.VERSION``) and validate it into ``cls`` (``cls.from_document``)."""
    versions = getattr(cls, "READ_VERSIONS", (cls.VERSION,))
    return cls.from_document(read_artifact(path, cls.SCHEMA, versions), path=path)


def write_artifact_as(path: str | os.PathLike, obj, **envelope) -> dict:
    """Write ``obj`` (an artifact dataclass: ``SCHEMA``, ``VERSION``, ``to_payload()``)
    atomically with provenance (:func:`gonio_cli.artifact.write_artifact`)."""
    return write_artifact(path, obj.SCHEMA, obj.VERSION, obj.to_payload(), **envelope)
