"""Self-describing artifacts: schema, version, provenance, atomic writes (STYLE 13).

Every file a stage writes for another stage to read is a JSON document of the form::

    {
      "schema": "gonio.measurement", "schema_version": 1,
      "gonio_version": "0.1.0",
      "inputs": [{"path": "../../sample_data/ink_red.csv", "sha256": "..."}],
      "parameters": {...},            # the options that produced it
      ...payload (units in field names: wavelength_nm, theta_i_deg, brdf_per_sr)...
    }

and the same inputs and options give the same bytes: input paths are relative to the
artifact's folder, and the run's ``created_utc`` and ``time_s`` (the stage's wall time,
and every ``…time_s`` of the payload) are in its side record ``NAME.run.json``
(:mod:`gonio_cli.runrecord`), which :func:`read_artifact` merges back in.

Writes go to a temporary file in the destination folder and are moved into place with
:func:`os.replace`, so a failed or interrupted run leaves the previous file (or none),
never a half-written one. Readers refuse another schema or an unknown version, naming
the file.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import errno
import json
import os
import tempfile
from pathlib import Path
from typing import Any, Iterable, Iterator, Mapping

import numpy as np

from . import __version__, outputs, runrecord
from .errors import ArtifactError, GonioError, NumericError, WriteError, binary_kind
from .folders import folder_error, make_folder
from .makers import artifact_name, make_fix
from .names import choices_fix, closest

#: Keys every artifact carries besides its payload.
ENVELOPE_KEYS = ("schema", "schema_version", "gonio_version", "created_utc", "inputs",
                 "parameters", "time_s")


def sha256_file(path: str | os.PathLike) -> str:
    """Hex SHA-256 of a file's bytes (read in 1 MiB blocks)."""
    import hashlib  # (loads OpenSSL, ~4 ms: only for runs that record their inputs)

    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def input_records(paths: Iterable[str | os.PathLike]) -> list[dict[str, str]]:
    """Provenance of input files: ``[{"path": ..., "sha256": ...}, ...]``. An input this
    command wrote itself and still holds back (a turntable's frames) is hashed where it is
    staged (:func:`gonio_cli.outputs.readable`)."""
    return [{"path": os.fspath(p), "sha256": sha256_file(outputs.readable(p))}
            for p in paths]


def image_metadata(schema: str, schema_version: int, *,
                   inputs: Iterable[str | os.PathLike] | None = (),
                   parameters: Mapping[str, Any] | None = None,
                   **fields: Any) -> dict[str, Any]:
    """The gonio metadata of an image file (PNG text chunks, EXR header attributes):
    ``schema``, ``schema_version``, ``gonio_version``, the ``inputs`` with their SHA-256,
    the ``parameters``, then ``fields``. No time stamp, so the same pixels and settings
    give the same bytes (:mod:`gonio_cli.imageio`). ``inputs=None`` leaves the inputs out,
    for an image whose bytes must not change when only its inputs' provenance did (the
    caller says why)."""
    clash = set(fields) & {"schema", "schema_version", "gonio_version", "inputs", "parameters"}
    if clash:
        raise ValueError(f"image metadata fields may not use the keys {sorted(clash)}")
    meta: dict[str, Any] = {"schema": schema, "schema_version": int(schema_version),
                            "gonio_version": __version__}
    if inputs is not None:
        meta["inputs"] = input_records(inputs)
    if parameters is not None:
        meta["parameters"] = dict(parameters)
    meta.update(fields)
    return _to_jsonable(meta)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, *, immediate: bool = False) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; move it onto ``path`` only on success.

    Any writer (JSON, PNG through OpenImageIO, EXR) writes to the yielded path, named
    ``.gonio-tmp-<pid>-<random>-<name>`` (:mod:`gonio_cli.outputs`). If the block raises,
    or the run is interrupted (Ctrl-C), the temporary file is removed and ``path`` is
    untouched. A command's declared output (:func:`gonio_cli.outputs.declare`) is staged
    and moved at the transaction's commit, with the command's other outputs; anything else
    (``immediate=True``: caches; intermediate files; files inside a staged folder) is
    moved at once. A folder that cannot take the file is a
    :class:`WriteError` naming the folder, not the temporary file (it is also an
    ``OSError``, so optional writes such as caches can still ignore it).
    """
    path = Path(path)
    folder = make_folder(path.parent)
    if path.is_dir():
        raise WriteError("is a folder", path=path, fix="give a file name for the output")
    tx = None if immediate else outputs.current()
    if tx is not None and not tx.is_output(path):
        tx = None  # not a declared output: a cache or a file the command reads back
    outputs.clean_stale(folder)
    try:
        fd, tmp = tempfile.mkstemp(prefix=outputs.tmp_prefix(),
                                   suffix=outputs.tmp_suffix(path.name), dir=folder)
    except OSError as exc:
        raise folder_error(folder, exc) from None
    tmp_path = Path(tmp)
    try:
        os.close(fd)
        yield tmp_path
        # mkstemp creates the file 0600; give the result the permissions of a normal file
        os.chmod(tmp_path, 0o666 & ~outputs.umask())
        if tx is None:
            os.replace(tmp_path, path)
    except BaseException as exc:  # KeyboardInterrupt too: never leave the temporary file
        tmp_path.unlink(missing_ok=True)
        if isinstance(exc, OSError) and not isinstance(exc, GonioError) and (
                exc.errno in _FULL_OR_READ_ONLY):
            raise folder_error(folder, exc) from None
        raise
    if tx is None:
        outputs.note_written(path)
    else:
        tx.stage(tmp_path, path)


#: errno values of a write that fails for the folder's disk, not for the writer.
_FULL_OR_READ_ONLY = (errno.ENOSPC, errno.EROFS)


#: Values JSON takes as they are (exact types: numpy's float64 is a float subclass).
_JSON_SCALARS = frozenset({str, int, float, bool, type(None)})


def _to_jsonable(obj: Any) -> Any:
    """numpy arrays and scalars to lists and Python numbers, recursively."""
    kind = type(obj)
    if kind in _JSON_SCALARS:
        return obj
    if kind is dict or isinstance(obj, Mapping):
        return {str(k): _to_jsonable(v) for k, v in obj.items()}
    if kind is list or kind is tuple or isinstance(obj, (list, tuple)):
        # a list of plain numbers (an array written before, a spectrum) is not walked
        if all(type(v) in _JSON_SCALARS for v in obj):
            return list(obj)
        return [_to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        # numbers come out of tolist() as Python numbers already: no walk over elements
        return obj.tolist() if obj.dtype.kind in "biuf" else _to_jsonable(obj.tolist())
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating):
        return float(obj)
    if isinstance(obj, Path):
        return os.fspath(obj)
    return obj


def make_document(schema: str, schema_version: int, payload: Mapping[str, Any], *,
                  inputs: Iterable[str | os.PathLike] = (),
                  parameters: Mapping[str, Any] | None = None,
                  time_s: float = 0.0) -> dict[str, Any]:
    """The artifact as a dict: envelope (schema, provenance) followed by the payload."""
    clash = set(payload) & set(ENVELOPE_KEYS)
    if clash:
        raise ValueError(f"payload may not use envelope keys {sorted(clash)}")
    doc: dict[str, Any] = {
        "schema": schema,
        "schema_version": int(schema_version),
        "gonio_version": __version__,
        "created_utc": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "inputs": input_records(inputs),
        "parameters": dict(parameters or {}),
        "time_s": float(time_s),
    }
    doc.update(payload)
    return _to_jsonable(doc)


def check_finite(values, what: str, path=None, fix: str | None = None) -> None:
    """Refuse an array about to be written (an image, a table) that holds NaN or inf.

    One check for every writer (:func:`write_json`, :mod:`gonio_cli.imageio`): a NaN or
    inf is never written with exit status 0. ``what`` names the array (``the rendered
    image``, ``field 'rho'``); the error says how many values and where the first is.
    """
    a = np.asarray(values)
    if a.dtype.kind not in "fc" or a.size == 0:
        return
    bad = ~np.isfinite(a)
    if not bad.any():
        return
    k = tuple(int(i) for i in np.argwhere(bad)[0])
    at = f" at [{', '.join(map(str, k))}]" if k else ""
    raise NumericError(
        f"{what} holds {int(bad.sum())} NaN or inf value{'s' if bad.sum() > 1 else ''} "
        f"(the first, {a[k]}{at}): a number overflowed; nothing written", path=path,
        fix=fix or "check the inputs for huge values (docs/conventions.md, Numeric ranges)")


def _first_nonfinite(obj: Any, where: str = "") -> tuple[str, Any] | None:
    """Where in a JSON-able document the first NaN or inf is: ("brdf[3][2]", nan)."""
    if isinstance(obj, float):
        return None if np.isfinite(obj) else (where, obj)
    if isinstance(obj, Mapping):
        items = ((f"{where}.{k}" if where else str(k), v) for k, v in obj.items())
    elif isinstance(obj, (list, tuple)):
        items = ((f"{where}[{i}]", v) for i, v in enumerate(obj))
    else:
        return None
    return next((hit for w, v in items if (hit := _first_nonfinite(v, w))), None)


def write_json(path: str | os.PathLike, doc: Mapping[str, Any]) -> None:
    """Write a JSON document atomically. NaN and inf are refused, naming the field
    (:class:`~gonio_cli.errors.NumericError`): JSON has no such numbers.

    An artifact (a document with a ``schema``) is written reproducibly
    (:mod:`gonio_cli.runrecord`): its paths relative to its folder, its date and times in
    its side record ``NAME.run.json``, written (and committed) with it."""
    plain, timings = runrecord.prepare(_to_jsonable(doc), path)
    try:
        text = json.dumps(plain, indent=1, allow_nan=False)
    except ValueError:
        hit = _first_nonfinite(plain)
        if hit is None:
            raise
        raise NumericError(f"field {hit[0]!r} is {hit[1]}, which JSON cannot hold: a number "
                           "overflowed; nothing written", path=path,
                           fix="check the inputs for huge or all-zero values (docs/"
                               "conventions.md, Numeric ranges)") from None
    data = (text + "\n").encode("utf-8")
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    if timings is not None:
        _write_side_record(path, data, timings)


def _write_side_record(path: str | os.PathLike, data: bytes, timings: Mapping[str, Any]
                       ) -> None:
    """Write the side record of the artifact ``data`` at ``path``; staged with it when
    the artifact is one of the command's declared outputs (so the two land together)."""
    import hashlib

    side = runrecord.side_path(path)
    tx = outputs.current()
    if tx is not None and tx.is_output(path):
        outputs.declare({"the side record": side})
    record = runrecord.side_record(path, hashlib.sha256(data).hexdigest(), timings)
    with atomic_path(side) as tmp:
        tmp.write_text(json.dumps(record, indent=1, allow_nan=False) + "\n",
                       encoding="utf-8")


def write_artifact(path: str | os.PathLike, schema: str, schema_version: int,
                   payload: Mapping[str, Any], **envelope: Any) -> dict[str, Any]:
    """Build the document (:func:`make_document`) and write it atomically; return it."""
    doc = make_document(schema, schema_version, payload, **envelope)
    write_json(path, doc)
    return doc


def read_artifact(path: str | os.PathLike, schema: str,
                  versions: Iterable[int]) -> dict[str, Any]:
    """Read an artifact, refusing a missing file, bad JSON, another schema or version."""
    path = Path(path)
    versions = tuple(versions)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise ArtifactError("no such file", path=path,
                            fix=make_fix(schema, path, missing=True)) from None
    except IsADirectoryError:
        raise ArtifactError(f"is a folder, not a {schema} file", path=path,
                            fix=make_fix(schema, path)) from None
    except OSError as exc:
        raise ArtifactError(f"cannot read it ({exc.strerror or exc.__class__.__name__})",
                            path=path) from None
    kind = binary_kind(data[:16])
    if kind is not None:
        raise ArtifactError(f"not a {schema} file (it is a {kind})", path=path,
                            fix=make_fix(schema, path))
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ArtifactError(f"not a {schema} file (not UTF-8 text: byte "
                            f"0x{data[exc.start]:02x} at offset {exc.start})", path=path,
                            fix=make_fix(schema, path)) from None
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ArtifactError(f"not valid JSON ({exc.msg} at line {exc.lineno}), so not a "
                            f"{schema} artifact", path=path,
                            fix=make_fix(schema, path)) from None
    if not isinstance(doc, dict) or "schema" not in doc:
        raise ArtifactError("not a gonio artifact (no 'schema' field)", path=path)
    if doc["schema"] != schema:
        raise ArtifactError(f"schema is {doc['schema']!r}, expected {schema!r}: it is "
                            f"{artifact_name(str(doc['schema']))}, not {artifact_name(schema)}",
                            path=path, fix=make_fix(schema, path, str(doc["schema"])))
    if doc.get("schema_version") not in versions:
        raise ArtifactError(
            f"{schema} schema_version {doc.get('schema_version')!r} is not supported "
            f"(this gonio {__version__} reads {', '.join(map(str, versions))})", path=path,
            fix="regenerate it with this version of gonio")
    timings = runrecord.read_timings(path, data)  # the times of its side record, if its own
    return doc if timings is None else runrecord.merge_timings(doc, timings)


def read_toml(path: str | os.PathLike, what: str, error: type[GonioError],
              display: str | None = None) -> dict[str, Any]:
    """A TOML file (``what``: "scene", "plan") as a dict; a missing file, bad TOML or a
    file that is not UTF-8 is one ``error`` naming ``display`` (default: the path)."""
    import tomllib

    display = display if display is not None else os.fspath(path)
    if not os.path.isfile(path):
        raise error(f"no such {what} file", path=display, fix="check the path")
    try:
        return tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise error(f"not valid TOML: {exc}", path=display) from None
    except UnicodeDecodeError:
        raise error("not a UTF-8 text file", path=display) from None


def check_keys(doc: Mapping[str, Any], allowed: Iterable[str], *, path=None,
               where: str = "") -> None:
    """Refuse unknown keys (STYLE 7): a typo is an error, never silently ignored."""
    unknown = sorted(set(doc) - set(allowed))
    if unknown:
        allowed = sorted(allowed)
        fix = choices_fix(unknown[0], allowed, "allowed:")
        if len(unknown) > 1:  # one question for every misspelt field that has a match
            meant = [f"{where}{near} for {where}{k}" for k in unknown
                     if (near := closest(k, allowed)) is not None]
            fix = (f"did you mean {', '.join(meant)}? " if meant else "") + \
                f"allowed: {', '.join(allowed)}"
        raise ArtifactError(f"unknown field{'s' if len(unknown) > 1 else ''} "
                            f"{', '.join(where + k for k in unknown)}", path=path, fix=fix)
