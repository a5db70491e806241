"""``gonio.material`` v1 and v2: a fitted reflectance model (``gonio fit`` writes it,
``gonio lobes``, ``gonio render`` and ``gonio export`` read it), and the range of every
model parameter (:data:`PARAM_RANGES`)."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .. import brdf
from ..brdf import MODELS
from ..errors import ArtifactError
from .records import Flag, Record
from .spec import (COUNT, MAX_MAGNITUDE, NON_NEGATIVE, SECONDS, WAVELENGTHS, AnyOf, Array,
                   ListOf, Number, Obj, Text, envelope_fields, json_kind, optional,
                   read_artifact_as, required, validate, write_artifact_as)


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
        return brdf.evaluate(self.model, cos, self.params)

    FIX = "regenerate it with gonio fit"

    @classmethod
    def spec(cls, model: str, version: int = VERSION) -> Obj:
        """The one definition of a ``gonio.material`` document of ``model`` (docs/schemas/)."""
        m = MODELS[model]
        return Obj({**envelope_fields(cls.SCHEMA, (version,)),
                    "model": required(Text((model,))),
                    "status": optional(Text(cls.STATUSES[version])),
                    "wavelength_nm": required(WAVELENGTHS),
                    **{k: required(PARAM_RANGES[k]) for k in m.scalar_params},
                    **{k: required(Array(1, PARAM_RANGES[k])) for k in m.spectral_params},
                    **{k: required(TABLE_SPECS[k]) for k in m.table_params},
                    "fit": optional(Record((("intervals", intervals_spec(model)),)))})

    @classmethod
    def from_document(cls, doc: dict[str, Any], path=None) -> "Material":
        model = doc.get("model")
        if not isinstance(model, str) or model not in MODELS:
            raise ArtifactError(f"field 'model' is {json_kind(model)}, not a known model",
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
        params.update(_table(f, spec.table_params, wl.size, path, cls.FIX))
        status = f.get("status", cls.STATUSES[version][0])
        return cls(model, wl, params, status, dict(f.get("fit") or {}))


#: Bound of |c(λ)| in seed 000 eq. 5's exp(c x), x in [0, 1]: e^100 ≈ 3e43, so ρ e^{c x}
#: stays finite in float64 for any ρ ≤ MAX_MAGNITUDE; gonio fit searches |c| ≤ 60
#: (fit.separable.C_LIMIT), so nothing it writes is refused.
C_MAX = 100.0

#: The range of every material parameter (brdf.MODELS), by name: α of GGX in (0, 1]
#: (seed 000 eq. 3, fit.common.ALPHA_MAX); Beckmann m in (0, 1] (seed 004 eq. 9,
#: fit.cook_torrance_profile.M_MAX); Fresnel F0 in [0, 1]; scales and albedos in
#: [0, MAX_MAGNITUDE]. A test checks that every model parameter is listed.
PARAM_RANGES: dict[str, Number] = {
    **{k: Number(0.0, 1.0, lo_open=True) for k in ("alpha", "alpha_coat", "alpha_2")},
    **{k: Number(0.0, 1.0, lo_open=True) for k in ("m", "m_1", "m_2", "m_3")},
    **{k: Number(0.0, 1.0) for k in ("f0", "f0_coat")},
    **{k: NON_NEGATIVE for k in ("rho", "rho_d", "rho_2", "kd", "ks", "ks_1", "ks_2", "ks_3",
                                 "k_coat")},
    "c": Number(-C_MAX, C_MAX),
    "b0": NON_NEGATIVE, "h": Number(0.0, MAX_MAGNITUDE, lo_open=True),
    # sheen: the Charlie roughness r in (0, 1] (glTF's sheenRoughness²), its colour, a scale
    "r_sheen": Number(0.0, 1.0, lo_open=True), "rho_sheen": NON_NEGATIVE, "k_spec": NON_NEGATIVE,
}


_NUMBERS = AnyOf((Number(), Array(1, Number(), min_size=0)))
_INDICES = ListOf(COUNT)


def intervals_spec(model: str) -> Obj:
    """``fit.intervals`` of a ``model`` material (gonio_cli.fit.uncertainty, docs/fit.md):
    the level, the method, per parameter ``low``/``high`` (numbers, lists per wavelength,
    or for the colour table nested as the table, n_h x n_d x n_λ), its transform and the
    elements at a bound or undetermined (flat indices), the light-source gains' intervals
    and the covariance blocks ``gonio eval`` draws from (per wavelength as blocks, or for
    the table's model as a factor F of each block given the scalars, F Fᵀ, with
    ``table_shape``). Older
    materials have none."""
    m = MODELS[model]
    entry = Obj({"low": required(_NUMBERS), "high": required(_NUMBERS),
                 "transform": required(Text(("log", "logit", "identity"))),
                 "one_sided_at": optional(_INDICES), "undetermined_at": optional(_INDICES)})
    table = Obj({"low": required(Array(3, NON_NEGATIVE)), "high": required(Array(3, NON_NEGATIVE)),
                 "transform": required(Text(("identity",))),
                 "one_sided_at": optional(_INDICES), "undetermined_at": optional(_INDICES)})
    nested = ListOf(ListOf(Number()))
    return Obj({
        "level": required(Number(0.0, 1.0, lo_open=True, hi_open=True)),
        "method": required(Text(("gauss-newton",))),
        "available": required(Flag()), "why": optional(Text()),
        "residuals": optional(Text()), "sigma2": optional(NON_NEGATIVE),
        "dof": optional(Number(0.0, None)), "sigma2_from": optional(Text()),
        "time_s": optional(SECONDS),
        "effective_parameters": optional(NON_NEGATIVE), "smoothness": optional(NON_NEGATIVE),
        "parameters": optional(Obj({**{k: optional(entry)
                                       for k in m.scalar_params + m.spectral_params},
                                    **{k: optional(table) for k in m.table_params[:1]}})),
        "sweep_gain": optional(Obj({"theta_i_deg": required(Array(1, Number())),
                                    "low": required(Array(1, NON_NEGATIVE)),
                                    "high": required(Array(1, NON_NEGATIVE)),
                                    "transform": required(Text(("log",)))})),
        "covariance": optional(Obj({"scalar_names": required(ListOf(Text())),
                                    "spectral_names": required(ListOf(Text())),
                                    "scalar": required(nested),
                                    "cross": required(ListOf(nested)),
                                    "spectral": optional(ListOf(nested)),
                                    "conditional_factor": optional(ListOf(nested)),
                                    "table_shape": optional(ListOf(COUNT))}))})


#: The table parameters of a model (:attr:`gonio_cli.brdf.Model.table_params`,
#: ``tabulated-colour``): the table T (n_h, n_d, n_λ) ≥ 0 and its node angles, increasing,
#: in [0, 90]°.
TABLE_SPECS = {"colour_table": Array(3, NON_NEGATIVE),
               **{k: Array(1, Number(0.0, 90.0), increasing=True)
                  for k in ("theta_h_nodes_deg", "theta_d_nodes_deg")}}


def _table(f: dict, names: tuple, n_wavelengths: int, path, fix: str) -> dict[str, Any]:
    """The validated table parameters ``names`` of ``f``, the table's shape checked
    against its nodes and the wavelengths (a table of another shape is one error)."""
    if not names:
        return {}
    table, nh, nd = (f[k] for k in names)
    want = (nh.size, nd.size, n_wavelengths)
    if table.shape != want:
        raise ArtifactError(f"field {names[0]!r} has shape {'x'.join(map(str, table.shape))}"
                            f", not {'x'.join(map(str, want))} ({names[1]} x {names[2]} x "
                            f"wavelength_nm)", path=path, fix=fix)
    return {k: f[k] for k in names}


def read_material(path: str | os.PathLike) -> Material:
    """Read and validate a ``gonio.material`` artifact."""
    return read_artifact_as(Material, path)


def write_material(path: str | os.PathLike, m: Material, **envelope) -> dict:
    """Write a material atomically with provenance."""
    return write_artifact_as(path, m, **envelope)
