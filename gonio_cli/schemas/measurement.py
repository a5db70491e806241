"""``gonio.measurement`` v1 (in-plane) and v2 (with the detector's azimuth ``phi_o_deg``):
goniometer spectra (``gonio ingest`` writes them, ``gonio fit`` and ``gonio eval`` read
them). A measurement without azimuths is written as v1, so in-plane files are unchanged;
a v1 file reads as in-plane (φo = 0)."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..artifact import write_artifact
from ..errors import ArtifactError
from ..geometry import canonical_azimuth
from .records import MEASUREMENT_SUMMARY
from .spec import (NON_NEGATIVE, POSITIVE_COUNT, WAVELENGTHS, Array, Nullable, Number,
                   Obj, Text, envelope_fields, optional, read_artifact_as, required, validate)


@dataclass
class Measurement:
    """Goniometer measurement on one spectral grid (``gonio.measurement`` v1, v2).

    Attributes
    ----------
    wavelength_nm : (n_λ,) float, increasing.
    theta_i_deg : (n_cfg,) float in [0, 90); theta_o_deg : (n_cfg,) float in (−90, 90),
        signed as in docs/conventions.md (θo = θi, φo = 0 is the mirror configuration).
    phi_o_deg : (n_cfg,) float in (−180, 180] or None (every configuration in the plane of
        incidence): the detector's azimuth from the plane (docs/conventions.md, "Out of
        the plane of incidence"); (θo, φo) are kept in their canonical form, and a
        measurement whose azimuths are all 0 holds None.
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
    phi_o_deg: np.ndarray | None = None

    SCHEMA = "gonio.measurement"
    VERSION = 2
    READ_VERSIONS = (1, 2)

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
        if self.phi_o_deg is not None:
            to, po = canonical_azimuth(self.theta_o_deg, self.phi_o_deg)
            self.theta_o_deg = to.reshape(self.theta_i_deg.shape)
            self.phi_o_deg = None if not np.any(po) else po.reshape(self.theta_i_deg.shape)

    @property
    def schema_version(self) -> int:
        """1 for an in-plane measurement (as before azimuths), 2 when it holds ``phi_o_deg``."""
        return 1 if self.phi_o_deg is None else 2

    @property
    def azimuths_deg(self) -> np.ndarray:
        """φo (n_cfg,) in degrees, zeros for an in-plane measurement."""
        return np.zeros(self.theta_i_deg.shape) if self.phi_o_deg is None else self.phi_o_deg

    @property
    def n_configurations(self) -> int:
        return int(self.theta_i_deg.size)

    def in_plane(self) -> "Measurement":
        """The configurations in the plane of incidence (φo = 0): ``self`` when all are,
        else a copy of those rows (the in-plane interpolants of ``gonio render`` use it)."""
        if self.phi_o_deg is None:
            return self
        rows = self.phi_o_deg == 0
        return Measurement(self.wavelength_nm, self.theta_i_deg[rows], self.theta_o_deg[rows],
                           self.brdf[rows],
                           None if self.brdf_std is None else self.brdf_std[rows],
                           self.n_repeats[rows], self.quantity, dict(self.summary))

    def to_payload(self) -> dict[str, Any]:
        azimuth = {} if self.phi_o_deg is None else {"phi_o_deg": self.phi_o_deg}
        return {
            "wavelength_nm": self.wavelength_nm,
            "theta_i_deg": self.theta_i_deg,
            "theta_o_deg": self.theta_o_deg,
            **azimuth,
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
        return Obj({**envelope_fields(cls.SCHEMA, cls.READ_VERSIONS),
                    "wavelength_nm": required(WAVELENGTHS),
                    "theta_i_deg": required(Array(1, Number(0.0, 90.0, hi_open=True))),
                    "theta_o_deg": required(Array(1, Number(-90.0, 90.0, True, True))),
                    "phi_o_deg": optional(Array(1, Number(-180.0, 180.0, lo_open=True))),
                    "brdf": required(Array(2)),
                    "brdf_std": optional(Nullable(Array(2, NON_NEGATIVE))),
                    "n_repeats": optional(Array(1, POSITIVE_COUNT)),
                    "quantity": optional(Text(cls.QUANTITIES)),
                    "summary": optional(MEASUREMENT_SUMMARY)})

    @classmethod
    def from_document(cls, doc: dict[str, Any], path=None) -> "Measurement":
        f = validate(doc, cls.spec(), path, cls.FIX)
        wl, ti, to, brdf = f["wavelength_nm"], f["theta_i_deg"], f["theta_o_deg"], f["brdf"]
        std, reps, phi = f.get("brdf_std"), f.get("n_repeats"), f.get("phi_o_deg")
        n, nl = ti.size, wl.size
        if phi is not None and phi.size != n:
            raise ArtifactError(f"inconsistent shapes: {n} theta_i_deg, {phi.size} phi_o_deg",
                                path=path, fix=cls.FIX)
        if to.size != n or brdf.shape != (n, nl) or (std is not None and std.shape != (n, nl)) \
                or (reps is not None and reps.size != n):
            raise ArtifactError(f"inconsistent shapes: {n} theta_i_deg, {to.size} theta_o_deg, "
                                f"brdf {brdf.shape}, {nl} wavelengths"
                                + (f", brdf_std {std.shape}" if std is not None else "")
                                + (f", {reps.size} n_repeats" if reps is not None else ""),
                                path=path, fix=cls.FIX)
        return cls(wl, ti, to, brdf, std, reps, f.get("quantity", "brdf"),
                   dict(f.get("summary") or {}), phi)


def read_measurement(path: str | os.PathLike) -> Measurement:
    """Read and validate a ``gonio.measurement`` artifact."""
    return read_artifact_as(Measurement, path)


def write_measurement(path: str | os.PathLike, m: Measurement, **envelope) -> dict:
    """Write a measurement atomically with provenance (inputs, parameters, time_s): v1
    when every configuration is in the plane of incidence, else v2 (``phi_o_deg``)."""
    return write_artifact(path, m.SCHEMA, m.schema_version, m.to_payload(), **envelope)
