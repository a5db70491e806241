"""``gonio.lobe_basis`` v1 and ``gonio.lobes`` v1: the cosine-lobe exponents ``gonio lobes
basis`` chooses and the weights ``gonio lobes fit`` solves for (seed 001), read by
``gonio lobes fit``, ``gonio prefilter`` and ``gonio render``."""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..artifact import read_artifact
from ..errors import ArtifactError, InputError
from .spec import (COUNT, EXPONENT_RANGE, EXPONENTS, FREE, NON_NEGATIVE, POSITIVE_COUNT,
                   SECONDS, WAVELENGTHS, AnyOf, Array, ListOf, Nullable, Number, Obj, Text,
                   envelope_fields, optional, read_artifact_as, required, validate,
                   write_artifact_as)


#: Channel kinds of lobe weights: per wavelength, or CIE XYZ.
LOBE_CHANNELS = ("spectral", "xyz")


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
            raise InputError(f"--lobes {n_lobes}: the basis has no {n_lobes}-lobe set",
                             path=path, fix=f"choose one of {', '.join(map(str, counts))}")
        return np.asarray(self.bases[counts.index(n_lobes)]["exponents"], dtype=float)

    FIX = "choose a basis with gonio lobes basis"

    @classmethod
    def spec(cls) -> Obj:
        """The one definition of a ``gonio.lobe_basis`` document (docs/schemas/)."""
        basis = Obj({"n_lobes": required(POSITIVE_COUNT), "exponents": required(EXPONENTS),
                     "error": optional(Nullable(Number(0.0, None))),
                     "max_error": optional(Nullable(Number(0.0, None))),
                     "mean_error": optional(Nullable(Number(0.0, None))),
                     "per_material": optional(Array(1, Number(0.0, None), min_size=0)),
                     "evaluations": optional(COUNT), "time_s": optional(SECONDS),
                     "message": optional(Text())})
        return Obj({**envelope_fields(cls.SCHEMA, (cls.VERSION,)),
                    "bases": required(ListOf(basis, min_items=1)),
                    "materials": optional(ListOf(Obj({"path": required(Text()),
                                                  "model": optional(Text())}))),
                    "sample_set": required(Text()), "channels": required(Text(LOBE_CHANNELS)),
                    "solver": required(Text()),
                    "exponent_range": optional(Array(1, Number(*EXPONENT_RANGE), size=2)),
                    "view_angle_deg": optional(Array(1, Number(0.0, 90.0), min_size=0))})

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


def read_lobe_basis(path: str | os.PathLike) -> LobeBasis:
    """Read and validate a ``gonio.lobe_basis`` artifact."""
    return read_artifact_as(LobeBasis, path)


def write_lobe_basis(path: str | os.PathLike, b: LobeBasis, **envelope) -> dict:
    """Write a lobe basis atomically with provenance."""
    return write_artifact_as(path, b, **envelope)


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
                    "exponents": required(EXPONENTS),
                    "channel_kind": required(Text(LOBE_CHANNELS)),
                    "channels": required(AnyOf((WAVELENGTHS,
                                            ListOf(Text(("X", "Y", "Z")), min_items=3)))),
                    "view_angle_deg": required(Array(1, Number(0.0, 90.0), increasing=True)),
                    "diffuse": required(Array(2, weights.item)),
                    "directional_diffuse": required(Array(3, weights.item)),
                    "gloss": required(Array(3, weights.item)),
                    "errors": optional(FREE), "solver": optional(Text()), "sample_set": optional(Text()),
                    "n_samples": optional(ListOf(COUNT))})

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
    return read_artifact_as(Lobes, path)


def write_lobes(path: str | os.PathLike, lobes: Lobes, **envelope) -> dict:
    """Write lobe weights atomically with provenance."""
    return write_artifact_as(path, lobes, **envelope)


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
