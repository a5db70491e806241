"""Free-form records with named parts checked: the material's ``fit`` (its ``intervals``,
:func:`gonio_cli.schemas.material.intervals_spec`) and the summary of the measurement
``gonio eval`` writes (its ``colour_band``, :data:`COLOUR_BAND`)."""

from __future__ import annotations

from dataclasses import dataclass

from .spec import (COUNT, NON_NEGATIVE, Array, Number, Obj, Spec, Text, json_kind, optional,
                   required)


class Flag(Spec):
    """true or false."""

    def check(self, value, where, path, fix):
        if not isinstance(value, bool):
            raise self.type_error(where, f"is {json_kind(value)}, expected true or false",
                                  path, fix)
        return value

    def json(self):
        return {"type": "boolean"}


@dataclass(frozen=True)
class Record(Spec):
    """A JSON object whose keys are free except those of ``parts``, each checked by its
    spec when present; the object is returned as it is."""

    parts: tuple[tuple[str, Spec], ...]

    def check(self, value, where, path, fix):
        Obj(None).check(value, where, path, fix)
        prefix = f"{where}." if where else ""
        for name, spec in self.parts:
            if name in value:
                spec.check(value[name], prefix + name, path, fix)
        return value

    def json(self):
        return {"type": "object", "properties": {k: s.json() for k, s in self.parts}}


#: ``summary.colour_band`` of ``gonio eval``'s output (gonio_cli/evaluate.py, docs/fit.md):
#: per configuration the 95th percentile of CIEDE2000 between the model drawn from the
#: fit's intervals and the fitted one, its median and worst; or ``available`` false and why.
COLOUR_BAND = Obj({
    "available": required(Flag()), "why": optional(Text()),
    "delta_e2000_p95": optional(Array(1, NON_NEGATIVE)),
    "median_delta_e2000_p95": optional(NON_NEGATIVE),
    "worst_delta_e2000_p95": optional(NON_NEGATIVE),
    "worst_configuration": optional(Obj({"theta_i_deg": required(Number()),
                                         "theta_o_deg": required(Number()),
                                         "phi_o_deg": optional(Number())})),
    "draws": optional(COUNT), "seed": optional(COUNT),
    "percentile": optional(Number(0.0, 100.0)), "level": optional(Number(0.0, 1.0)),
    "method": optional(Text())})

#: The summary of a measurement: free (what ingest read and did), its ``colour_band``
#: checked (an evaluated measurement's).
MEASUREMENT_SUMMARY = Record((("colour_band", COLOUR_BAND),))
