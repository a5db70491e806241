"""Reproducible artifacts: paths relative to the artifact, times in a side record.

The same inputs and options give an artifact of the same bytes (docs/conventions.md,
"Files and errors"), so "up to date" can follow content hashes (``gonio batch``). What a
run measures, and what only says where and when it ran, moves out of the artifact:

* **Times** (the envelope's ``created_utc`` and ``time_s``, and every payload field named
  ``time_s`` or ``…_time_s``: a fit method's, a lobe solver's per view, a prefiltered
  level's, the halftone's stages) go into the artifact's *side record*, ``NAME.run.json``
  beside ``NAME.json`` (schema ``gonio.run``): the timing fields in the artifact's own
  shape, with the run's date, host and the artifact's sha256.
  :func:`gonio_cli.artifact.read_artifact` puts them back when the side record matches the
  artifact's bytes, so every reader (``gonio report`` too) sees the times as before.
  Documents whose subject is the run itself (:data:`RUN_RECORDS`: ``gonio report``'s
  ``report.json``, ``gonio render --report``) keep their times.
* **Paths** an artifact records are made relative to the artifact's folder
  (:func:`portable`): every input's, and the absolute paths among its options and the
  outputs it names (:data:`PATH_FIELDS`: a scene, a ``--var`` value, ``--dark``, a
  halftone's ``mask``). A relative path given on the command line for anything but an
  input is kept as given, and so is a path inside a message.

Images take the same paths, and carry no times at all (:func:`drop_timings`).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Mapping

from . import __version__

#: Schema and version of a side record.
RUN_SCHEMA = "gonio.run"
RUN_VERSION = 1

#: Documents that are records of a run: their times are their content, so they keep them
#: (paths are still made relative).
RUN_RECORDS = frozenset({"gonio.report", "gonio.render-report", RUN_SCHEMA})

#: Envelope fields that say when a run was, not what it made.
_WHEN = ("created_utc",)

#: Values taken as they are when walking a document (a list of them is not walked).
_SCALARS = (str, int, float, bool, type(None))


def is_timing(key: str) -> bool:
    """Is ``key`` a field that holds a run's date or a duration (never hashed content)?"""
    return key == "time_s" or key.endswith("_time_s") or key in _WHEN


def side_path(path: str | os.PathLike) -> Path:
    """The side record of ``path``: ``red.material.json`` → ``red.material.run.json``."""
    path = Path(path)
    stem = path.name[:-len(".json")] if path.name.endswith(".json") else path.name
    return path.with_name(stem + ".run.json")


def split_timings(obj: Any) -> tuple[Any, Any]:
    """``(obj without its timing fields, those fields in obj's shape or None)``.

    Dicts lose every :func:`is_timing` key; lists keep their length, and their timing
    part has None where an element has none. ``obj`` is JSON-able (plain types).
    """
    if isinstance(obj, dict):
        kept, taken = {}, {}
        for key, value in obj.items():
            if is_timing(key):
                taken[key] = value
                continue
            kept[key], part = split_timings(value)
            if part is not None:
                taken[key] = part
        return kept, (taken or None)
    if isinstance(obj, list) and not all(isinstance(v, _SCALARS) for v in obj):
        pairs = [split_timings(v) for v in obj]
        parts = [t for _, t in pairs]
        return [k for k, _ in pairs], (parts if any(t is not None for t in parts) else None)
    return obj, None


def merge_timings(obj: Any, timings: Any) -> Any:
    """``obj`` with the fields :func:`split_timings` took put back (a new object)."""
    if isinstance(timings, dict) and isinstance(obj, dict):
        out = dict(obj)
        for key, value in timings.items():
            out[key] = value if is_timing(key) else merge_timings(obj.get(key), value)
        return out
    if isinstance(timings, list) and isinstance(obj, list) and len(timings) == len(obj):
        return [v if t is None else merge_timings(v, t) for v, t in zip(obj, timings)]
    return obj


def drop_timings(meta: Mapping[str, Any]) -> dict[str, Any]:
    """Image metadata without its times (an image's bytes never hold one)."""
    return split_timings(dict(meta))[0]


def relative_path(path: str | os.PathLike, folder: str | os.PathLike) -> str:
    """``path`` (absolute, or relative to the working folder) as seen from ``folder``,
    with ``/`` separators; absolute where no relative path exists (another drive)."""
    try:
        rel = os.path.relpath(os.path.abspath(path), os.path.abspath(folder))
    except ValueError:
        return os.path.abspath(path)
    return rel.replace(os.sep, "/")


def _relative_strings(obj: Any, folder: str) -> Any:
    """Every string of ``obj`` that is an absolute path, relative to ``folder``."""
    if isinstance(obj, str):
        return relative_path(obj, folder) if os.path.isabs(obj) else obj
    if isinstance(obj, dict):
        return {k: _relative_strings(v, folder) for k, v in obj.items()}
    if isinstance(obj, list) and any(isinstance(v, (str, dict, list)) for v in obj):
        return [_relative_strings(v, folder) for v in obj]
    return obj


#: Fields that hold options or output paths: an absolute path anywhere in them is made
#: relative (other fields, such as messages that start with a file's name, are kept).
PATH_FIELDS = frozenset({"parameters", "settings", "outputs", "mask", "split"})


def portable(doc: Mapping[str, Any], path: str | os.PathLike) -> dict[str, Any]:
    """``doc`` (to be written at ``path``) with its paths relative to ``path``'s folder:
    each input's path, and the absolute paths among its options and outputs
    (:data:`PATH_FIELDS`)."""
    folder = os.path.dirname(os.path.abspath(path))
    out = {}
    for key, value in doc.items():
        if key == "inputs" and isinstance(value, list):
            value = [{**i, "path": relative_path(i["path"], folder)} if isinstance(i, dict)
                     and isinstance(i.get("path"), str) else i for i in value]
        elif key in PATH_FIELDS:
            value = _relative_strings(value, folder)
        out[key] = value
    return out


def prepare(doc: Mapping[str, Any], path: str | os.PathLike
            ) -> tuple[dict[str, Any], dict[str, Any] | None]:
    """The artifact to write at ``path`` and its side record's content (None: none).

    Only documents with a ``schema`` are touched; a run record (:data:`RUN_RECORDS`)
    gets portable paths and keeps its times.
    """
    if not isinstance(doc, Mapping) or "schema" not in doc:
        return dict(doc), None
    doc = portable(doc, path)
    if doc["schema"] in RUN_RECORDS:
        return doc, None
    return split_timings(doc)


def side_record(path: str | os.PathLike, artifact_sha256: str,
                timings: Mapping[str, Any]) -> dict[str, Any]:
    """The side record of the artifact at ``path``: what ran, where, when, how long."""
    import socket

    when = {k: timings[k] for k in _WHEN if k in timings}
    return {"schema": RUN_SCHEMA, "schema_version": RUN_VERSION, "gonio_version": __version__,
            "artifact": Path(path).name, "artifact_sha256": artifact_sha256, **when,
            "host": socket.gethostname(), "pid": os.getpid(),
            "timings": {k: v for k, v in timings.items() if k not in _WHEN}}


def read_timings(path: str | os.PathLike, artifact_bytes: bytes) -> dict[str, Any] | None:
    """The timing fields of the artifact at ``path`` from its side record, with the run's
    ``created_utc``; None when there is no side record, it cannot be read, or it belongs
    to other bytes than ``artifact_bytes`` (an artifact rewritten since)."""
    import hashlib

    try:
        record = json.loads(side_path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(record, dict) or record.get("schema") != RUN_SCHEMA or \
            record.get("schema_version") != RUN_VERSION or \
            record.get("artifact_sha256") != hashlib.sha256(artifact_bytes).hexdigest() or \
            not isinstance(record.get("timings"), dict):
        return None
    return {**{k: record[k] for k in _WHEN if isinstance(record.get(k), str)},
            **record["timings"]}
