"""What the render stage reads and writes besides images: ``gonio.prefilter`` (the
``index.json`` of a prefiltered environment, ``gonio prefilter`` → ``gonio render``) and
``gonio.render-report`` (``gonio render --report``)."""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

from ..artifact import make_document, read_artifact, write_json
from .spec import (COUNT, EXPONENT_RANGE, FREE, MAX_MAGNITUDE, NON_NEGATIVE, POSITIVE_COUNT,
                   SECONDS, ListOf, Nullable, Number, Obj, Text, envelope_fields, optional,
                   read_artifact_as, required, validate)


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
        entry = Obj({"exponent": required(Number(*EXPONENT_RANGE)), "path": required(Text()),
                     "width": required(POSITIVE_COUNT), "height": required(POSITIVE_COUNT),
                     "method": optional(Text()),
                     "error_estimate": optional(Nullable(Number(0.0, None))),
                     "checked_texels": optional(COUNT), "working_width": optional(POSITIVE_COUNT),
                     "working_height": optional(POSITIVE_COUNT), "time_s": optional(SECONDS)})
        source = Obj({"width": required(POSITIVE_COUNT), "height": required(POSITIVE_COUNT),
                      "channels": required(POSITIVE_COUNT), "invalid_texels_replaced": optional(COUNT)})
        vector = ListOf(Number(-MAX_MAGNITUDE, MAX_MAGNITUDE), min_items=3)
        sun = Obj({"direction": required(vector), "irradiance_rgb": required(vector),
                   "angular_diameter_deg": required(Number(0.0, 180.0)),
                   "solid_angle_sr": required(NON_NEGATIVE), "texels": optional(COUNT),
                   "flux_share": optional(Number(0.0, 1.0)), "fill_share": optional(Number(0.0, 1.0))})
        return Obj({**envelope_fields(cls.SCHEMA, cls.READ_VERSIONS),
                    "source": optional(source), "diffuse": optional(Text()), "sun": optional(sun),
                    "maps": required(ListOf(entry, min_items=1))})

    @classmethod
    def from_document(cls, doc: dict[str, Any], path=None) -> "PrefilterIndex":
        f = validate(doc, cls.spec(), path, cls.FIX)
        return cls([dict(m) for m in f["maps"]], f.get("source"), f.get("diffuse"),
                   f.get("sun"))


def read_prefilter_index(path: str | os.PathLike) -> PrefilterIndex:
    """Read and validate a prefiltered environment's ``index.json`` (versions 1 and 2)."""
    return read_artifact_as(PrefilterIndex, path)


def write_prefilter_index(path: str | os.PathLike, index: PrefilterIndex, **envelope) -> dict:
    """Write ``index.json`` atomically with provenance, after checking the document against
    the reader's definition (a failure there is a bug in the writer, nothing is written)."""
    doc = make_document(index.SCHEMA, index.VERSION, index.to_payload(), **envelope)
    validate(doc, index.spec(), path, "a bug in gonio prefilter: please report it")
    write_json(path, doc)
    return doc


#: ``gonio render --report`` (:func:`gonio_cli.render.pipeline.write_report`).
RENDER_REPORT_SCHEMA = "gonio.render-report"
RENDER_REPORT_VERSION = 1


def render_report_spec() -> Obj:
    """The one definition of a ``gonio.render-report`` document (docs/schemas/)."""
    stage = Obj({"stage": required(Text()), "time_s": required(SECONDS)})
    return Obj({**envelope_fields(RENDER_REPORT_SCHEMA, (RENDER_REPORT_VERSION,)),
                "stages": required(ListOf(stage)), "substages": optional(ListOf(stage)),
                "frame_time_s": required(SECONDS), "frame_stages": optional(ListOf(Text())),
                "outputs": required(Obj({"png": required(Text()), "exr": optional(Nullable(Text())),
                                     "gamut_warning": optional(Nullable(Text()))})),
                "image": required(Obj({"width": required(POSITIVE_COUNT),
                                   "height": required(POSITIVE_COUNT)})),
                "counts": optional(FREE)})


def read_render_report(path: str | os.PathLike) -> dict[str, Any]:
    """Read and validate a render report (checked fields)."""
    doc = read_artifact(path, RENDER_REPORT_SCHEMA, (RENDER_REPORT_VERSION,))
    return validate(doc, render_report_spec(), path, "regenerate it with gonio render --report")
