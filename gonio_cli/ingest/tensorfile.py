"""Mitsuba's tensor file (the RGL database's ``.bsdf`` container): its header and fields read
and checked without Mitsuba, and written (sample_data/make_rgl_wrap.py makes the synthetic
samples with it). :mod:`.rgl` checks the fields the ``measured`` plugin needs."""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..artifact import atomic_path
from ..errors import InputError, binary_kind

#: Mitsuba's tensor file: 12-byte magic, version (major, minor), field count, then per field
#: name, rank, type code, offset and shape, all little-endian (``src/core/tensor.cpp``,
#: ``mitsuba/python/tensor_io.py``).
TENSOR_MAGIC = b"tensor_file\0"
TENSOR_VERSION = (1, 0)

#: Type codes of the tensor file (Mitsuba's ``Struct`` types, as tensor_io.py maps them).
TENSOR_DTYPES = {1: np.uint8, 2: np.int8, 3: np.uint16, 4: np.int16, 5: np.uint32,
                 6: np.int32, 7: np.uint64, 8: np.int64, 9: np.float16, 10: np.float32,
                 11: np.float64}
_DTYPE_CODES = {np.dtype(t): code for code, t in TENSOR_DTYPES.items()}

#: Fields are written at offsets aligned to this many bytes (as tensor_io.write does).
TENSOR_ALIGN = 8


@dataclass(frozen=True)
class TensorField:
    """One field of a tensor file: its type, shape and where its data start."""

    dtype: np.dtype
    shape: tuple[int, ...]
    offset: int

    @property
    def nbytes(self) -> int:
        return int(np.prod(self.shape, dtype=np.int64)) * self.dtype.itemsize


def not_bsdf(path, what: str) -> InputError:
    return InputError(f"is not an RGL .bsdf file ({what})", path=path,
                      fix="pass a material file from the RGL database (rgl.epfl.ch/materials)"
                          ", downloaded completely; CSV spectra go in as CSV")


def read_tensor_header(path: str | os.PathLike) -> dict[str, TensorField]:
    """The fields of a Mitsuba tensor file by name, each checked to lie inside the file.

    Raises :class:`InputError` for a missing or unreadable file, another kind of file, an
    unknown version or type code, and a truncated file (a header or a field running past
    its end), naming the field.
    """
    try:
        size = os.path.getsize(path)
        with open(path, "rb") as f:
            head = f.read(min(size, 1 << 20))
    except OSError as exc:
        raise InputError(f"cannot read it ({exc.strerror or exc})", path=path) from None
    if not head.startswith(TENSOR_MAGIC):
        kind = binary_kind(head[:16]) or ("empty" if size == 0 else
                                          "no 'tensor_file' header")
        raise not_bsdf(path, kind)
    pos = len(TENSOR_MAGIC)

    def take(fmt: str, what: str):
        nonlocal pos
        n = struct.calcsize(fmt)
        if pos + n > len(head):
            raise InputError(f"is truncated: the header ends inside {what} (file size "
                             f"{size} bytes)", path=path,
                             fix="download the .bsdf file again")
        out = struct.unpack_from(fmt, head, pos)
        pos += n
        return out

    version = take("<BB", "the version")
    if version != TENSOR_VERSION:
        raise InputError(f"tensor file version {version[0]}.{version[1]} is unknown (gonio "
                         f"reads {TENSOR_VERSION[0]}.{TENSOR_VERSION[1]})", path=path,
                         fix="pass a .bsdf file of the RGL database")
    (n_fields,) = take("<I", "the field count")
    fields: dict[str, TensorField] = {}
    for k in range(n_fields):
        (name_length,) = take("<H", f"field {k + 1}'s name")
        (raw,) = take(f"<{name_length}s", f"field {k + 1}'s name")
        name = raw.decode("utf-8", "replace")
        ndim, code, offset = take("<HBQ", f"field {name!r}")
        shape = take(f"<{ndim}Q", f"field {name!r}'s shape")
        if code not in TENSOR_DTYPES:
            raise InputError(f"field {name!r} has the unknown type code {code}", path=path,
                             fix="download the .bsdf file again")
        field = TensorField(np.dtype(TENSOR_DTYPES[code]).newbyteorder("<"),
                            tuple(int(s) for s in shape), int(offset))
        if field.offset + field.nbytes > size:
            raise InputError(f"is truncated: field {name!r} ({'x'.join(map(str, shape))} "
                             f"{field.dtype.name}) runs to byte {field.offset + field.nbytes}, "
                             f"the file has {size}", path=path,
                             fix="download the .bsdf file again (it is incomplete)")
        fields[name] = field
    return fields


def read_tensor_file(path: str | os.PathLike,
                     names: Sequence[str] | None = None) -> dict[str, np.ndarray]:
    """The fields ``names`` (default: all) of a tensor file as read-only numpy arrays
    (memory-mapped: a database file can be large). Checked by :func:`read_tensor_header`.
    """
    fields = read_tensor_header(path)
    out = {}
    for name in fields if names is None else names:
        f = fields[name]
        if f.nbytes == 0:
            out[name] = np.zeros(f.shape, f.dtype)
        else:
            out[name] = np.memmap(path, dtype=f.dtype, mode="r", offset=f.offset,
                                  shape=f.shape)
    return out


def write_tensor_file(path: str | os.PathLike, fields: dict[str, Any]) -> None:
    """Write ``fields`` (name → numpy array, or str, stored as uint8 text) as a Mitsuba
    tensor file, atomically; the layout :func:`read_tensor_header` and Mitsuba read."""
    arrays = {k: (np.frombuffer(v.encode("utf-8"), np.uint8) if isinstance(v, str)
                  else np.ascontiguousarray(v)) for k, v in fields.items()}
    for name, a in arrays.items():
        if a.dtype not in _DTYPE_CODES:
            raise InputError(f"field {name!r}: type {a.dtype} has no tensor file code",
                             fix="use one of " + ", ".join(str(np.dtype(t))
                                                           for t in TENSOR_DTYPES.values()))
    header = bytearray(TENSOR_MAGIC + struct.pack("<BBI", *TENSOR_VERSION, len(arrays)))
    header_size = len(header) + sum(2 + len(k.encode()) + 11 + 8 * a.ndim
                                    for k, a in arrays.items())
    pad = lambda n: -n % TENSOR_ALIGN  # noqa: E731
    body, offsets = bytearray(), {}
    start = header_size + pad(header_size)
    for name, a in arrays.items():
        offsets[name] = start + len(body)
        body += a.astype(a.dtype.newbyteorder("<"), copy=False).tobytes()
        body += b"\0" * pad(len(body))
    for name, a in arrays.items():
        label = name.encode("utf-8")
        header += struct.pack("<H", len(label)) + label
        header += struct.pack("<HBQ", a.ndim, _DTYPE_CODES[a.dtype], offsets[name])
        header += struct.pack(f"<{a.ndim}Q", *a.shape)
    header += b"\0" * (start - len(header))
    with atomic_path(path) as tmp:
        Path(tmp).write_bytes(bytes(header + body))
