"""``gonio.measurement`` v1: in-plane goniometer spectra (``gonio ingest`` writes them,
``gonio fit`` and ``gonio eval`` read them)."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import ArtifactError
from .records import MEASUREMENT_SUMMARY
from .spec import (NON_NEGATIVE, POSITIVE_COUNT, WAVELENGTHS, Array, Nullable, Number,
                   Obj, Text, envelope_fields, optional, read_artifact_as, required, validate,
                   write_artifact_as)


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
                    "wavelength_nm": required(WAVELENGTHS),
                    "theta_i_deg": required(Array(1, Number(0.0, 90.0, hi_open=True))),
                    "theta_o_deg": required(Array(1, Number(-90.0, 90.0, True, True))),
                    "brdf": required(Array(2)),
                    "brdf_std": optional(Nullable(Array(2, NON_NEGATIVE))),
                    "n_repeats": optional(Array(1, POSITIVE_COUNT)),
                    "quantity": optional(Text(cls.QUANTITIES)),
                    "summary": optional(MEASUREMENT_SUMMARY)})

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
    return read_artifact_as(Measurement, path)


def write_measurement(path: str | os.PathLike, m: Measurement, **envelope) -> dict:
    """Write a measurement atomically with provenance (inputs, parameters, time_s)."""
    return write_artifact_as(path, m, **envelope)
