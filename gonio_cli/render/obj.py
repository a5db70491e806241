"""Wavefront OBJ reader: ``v``, ``vt``, ``vn`` and ``f`` lines, parsed with numpy.

Why a reader of our own: trimesh's OBJ loader (with its import of scipy and networkx)
took 0.9–2.4 s for a 20 000-triangle sphere, longer than the rest of ``gonio render``; this
one reads it in a few milliseconds and a 1 M-triangle file in a few seconds, with no
Python loop over lines. The file is read as bytes; lines are classified from their first
bytes; each run of consecutive ``v`` (``vt``, ``vn``) lines is one :func:`numpy.fromstring`
call after the keyword is blanked; face lines are tokenised on the byte array (token starts,
slashes per token) and their indices parsed by one integer :func:`numpy.fromstring`.

Supported (Wavefront OBJ, polygonal subset):

* ``v x y z [w]`` (extra values, e.g. vertex colours, are ignored), ``vt u [v [w]]``,
  ``vn x y z``;
* ``f`` with 3 or more vertices, each ``v``, ``v/vt``, ``v//vn`` or ``v/vt/vn``; polygons
  are fan-split (v0, v_k, v_k+1) in file order; negative indices count back from the
  last element defined before the line;
* a vertex used with different ``vt`` / ``vn`` indices is split (one vertex per distinct
  combination), as renderers need one attribute set per vertex;
* texture coordinates (normals) are kept only if every face corner has them;
* ``#`` comments, blank lines, CRLF, tabs, leading blanks; ``o``, ``g``, ``s``, ``usemtl``,
  ``mtllib`` are ignored; other OBJ statements (lines ``l``, points ``p``, free-form
  ``curv``, ``surf`` …) are skipped with one warning that names them.

Bad input (STYLE 7) is one :class:`~gonio_cli.errors.InputError` naming the file and the
line: a value that is not a number, a face with fewer than 3 vertices, an index that is
0 or out of range, a keyword that is not OBJ, a binary file.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from .. import log
from ..errors import InputError

#: Statements that carry no geometry gonio draws and are skipped silently.
IGNORED = frozenset({"o", "g", "s", "usemtl", "mtllib"})
#: OBJ statements that are valid but not drawn (lines, points, free-form geometry,
#: display attributes): skipped with one warning.
UNSUPPORTED = frozenset({"l", "p", "vp", "cstype", "deg", "bmat", "step", "curv", "curv2",
                         "surf", "parm", "trim", "hole", "scrv", "sp", "end", "con", "mg",
                         "bevel", "c_interp", "d_interp", "lod", "shadow_obj", "trace_obj",
                         "ctech", "stech", "maplib", "usemap", "call", "csh"})
#: Bytes looked at for a NUL to recognise a binary file given as an OBJ.
BINARY_SNIFF_BYTES = 4096

_SPACE, _NL, _SLASH = 32, 10, 47
_V, _T, _N, _F, _HASH = (ord(c) for c in "vtnf#")


class _Lines:
    """The file's lines: ``starts``, ``ends`` (byte offsets, end exclusive) and a kind
    code per line (0 blank/comment/ignored, 1 v, 2 vt, 3 vn, 4 f)."""

    def __init__(self, data: bytes):
        a = np.frombuffer(data, np.uint8)
        nl = np.flatnonzero(a == _NL)
        self.starts = np.r_[0, nl + 1]
        self.ends = np.r_[nl, len(a)]
        length = self.ends - self.starts
        pad = np.r_[a, np.zeros(3, np.uint8)]                 # c1, c2 readable at the end
        c0, c1, c2 = pad[self.starts], pad[self.starts + 1], pad[self.starts + 2]
        c0 = np.where(length > 0, c0, 0)
        c1 = np.where(length > 1, c1, 0)
        c2 = np.where(length > 2, c2, 0)
        kind = np.zeros(len(self.starts), np.int8)
        kind[(c0 == _V) & (c1 == _SPACE)] = 1
        kind[(c0 == _V) & (c1 == _T) & (c2 == _SPACE)] = 2
        kind[(c0 == _V) & (c1 == _N) & (c2 == _SPACE)] = 3
        kind[(c0 == _F) & (c1 == _SPACE)] = 4
        self.kind = kind
        self.other = np.flatnonzero((kind == 0) & (length > 0) & (c0 != _HASH))


def _runs(lines: np.ndarray) -> list[tuple[int, int]]:
    """Consecutive line indices as (first, last) pairs."""
    if lines.size == 0:
        return []
    cut = np.flatnonzero(np.diff(lines) != 1)
    return list(zip(lines[np.r_[0, cut + 1]].tolist(), lines[np.r_[cut, lines.size - 1]].tolist()))


def _token_starts(a: np.ndarray) -> np.ndarray:
    """Byte offsets where a blank-separated token starts (blanks: space, newline)."""
    blank = (a == _SPACE) | (a == _NL)
    start = ~blank
    start[1:] &= blank[:-1]
    return np.flatnonzero(start)


def _first_bad_number(path, data: bytes, L: _Lines, first: int, last: int,
                      integer: bool = False) -> InputError:
    """The error for the first line of a run whose values do not parse (the slow path)."""
    for i in range(first, last + 1):
        text = data[L.starts[i]:L.ends[i]].decode("utf-8", "replace")
        for token in text.split()[1:]:
            parts = token.split("/") if integer else [token]
            for k, part in enumerate(parts):
                if integer and part == "" and k == 1 and len(parts) == 3:
                    continue                                   # v//vn
                try:
                    int(part) if integer else float(part)
                except ValueError:
                    what = "an integer index" if integer else "a number"
                    return InputError(f"{text.split()[0]} line: {token!r} is not {what}",
                                      path=path, row=i + 1,
                                      fix="repair or re-export the mesh")
    return InputError("cannot parse the values", path=path, row=first + 1,
                      fix="repair or re-export the mesh")


def _floats(path, data: bytes, L: _Lines, kind: int, keyword: bytes, need: int, keep: int):
    """(n, keep) float64 of every line of ``kind`` (missing optional values: 0) and the
    line indices. A line with fewer than ``need`` values is an error naming it."""
    lines = np.flatnonzero(L.kind == kind)
    out = np.zeros((lines.size, keep))
    row = 0
    for first, last in _runs(lines):
        n = last - first + 1
        chunk = data[L.starts[first]:L.ends[last]].replace(keyword, b" " * len(keyword))
        try:
            values = np.fromstring(chunk, dtype=np.float64, sep=" ")
        except ValueError:
            raise _first_bad_number(path, data, L, first, last) from None
        a = np.frombuffer(chunk, np.uint8)
        tokens = _token_starts(a)
        line_start = L.starts[first:last + 1] - L.starts[first]
        begin = np.searchsorted(tokens, line_start)
        counts = np.diff(np.r_[begin, tokens.size])
        if values.size != tokens.size:
            raise _first_bad_number(path, data, L, first, last)
        short = np.flatnonzero(counts < need)
        if short.size:
            i = first + int(short[0])
            raise InputError(f"{keyword.decode()} line has {int(counts[short[0]])} value(s), "
                             f"needs {need}", path=path, row=i + 1,
                             fix="repair or re-export the mesh")
        if np.all(counts == counts[0]):
            block = values.reshape(n, int(counts[0]))[:, :keep]
            out[row:row + n, :block.shape[1]] = block
        else:
            for j in range(keep):
                has = counts > j
                out[row:row + n][has, j] = values[begin[has] + j]
        row += n
    return out, lines


def _faces(path, data: bytes, L: _Lines):
    """Per face corner token: v, vt, vn indices as written (0 = absent), the token's line
    index, and per face line its first token and token count."""
    lines = np.flatnonzero(L.kind == 4)
    vi, ti, ni, tline, first_tok, ntok = [], [], [], [], [], []
    offset = 0
    for first, last in _runs(lines):
        chunk = data[L.starts[first]:L.ends[last]].replace(b"f", b" ")
        a = np.frombuffer(chunk, np.uint8)
        tokens = _token_starts(a)
        line_start = L.starts[first:last + 1] - L.starts[first]
        begin = np.searchsorted(tokens, line_start)
        counts = np.diff(np.r_[begin, tokens.size])
        slash_tok = np.searchsorted(tokens, np.flatnonzero(a == _SLASH), "right") - 1
        nslash = np.bincount(slash_tok, minlength=tokens.size)
        double = np.zeros(tokens.size, bool)
        double[np.searchsorted(tokens, np.flatnonzero((a[:-1] == _SLASH) & (a[1:] == _SLASH)),
                               "right") - 1] = True
        line_of_tok = np.repeat(np.arange(first, last + 1), counts)
        if np.any(nslash > 2):
            i = int(line_of_tok[np.argmax(nslash > 2)])
            raise InputError("f line: a vertex has more than 2 slashes", path=path, row=i + 1,
                             fix="write v, v/vt, v//vn or v/vt/vn")
        try:
            nums = np.fromstring(chunk.replace(b"//", b"/0/").replace(b"/", b" "),
                                 dtype=np.int64, sep=" ")
        except ValueError:
            raise _first_bad_number(path, data, L, first, last, integer=True) from None
        per = nslash + 1
        if nums.size != per.sum():
            raise _first_bad_number(path, data, L, first, last, integer=True)
        at = np.cumsum(per) - per
        vi.append(nums[at])
        t = np.where(nslash >= 1, nums[np.minimum(at + 1, nums.size - 1)], 0)
        t[double] = 0
        ti.append(np.where(nslash >= 1, t, 0))
        ni.append(np.where(nslash == 2, nums[np.minimum(at + 2, nums.size - 1)], 0))
        # a written vt of 0 (not the empty field of v//vn) is an error below
        bad_t = (nslash >= 1) & ~double & (ti[-1] == 0)
        if bad_t.any():
            i = int(line_of_tok[np.argmax(bad_t)])
            raise InputError("f line: texture index 0 (OBJ indices start at 1)", path=path,
                             row=i + 1, fix="repair or re-export the mesh")
        tline.append(line_of_tok)
        first_tok.append(begin + offset)
        ntok.append(counts)
        offset += tokens.size
    def cat(parts):
        return parts[0] if len(parts) == 1 else (np.concatenate(parts) if parts
                                                 else np.zeros(0, np.int64))

    return (cat(vi), cat(ti), cat(ni), cat(tline), cat(first_tok), cat(ntok), lines)


def _resolve(path, idx: np.ndarray, tline: np.ndarray, defined_lines: np.ndarray,
             what: str) -> np.ndarray:
    """0-based indices from OBJ's 1-based (negative: relative to the elements defined
    before the line). Out of range or 0 is an error naming the line."""
    before = np.searchsorted(defined_lines, tline)            # elements defined earlier
    out = np.where(idx < 0, before + idx, idx - 1)
    bad = (idx == 0) | (out < 0) | (out >= defined_lines.size)
    if bad.any():
        k = int(np.argmax(bad))
        raise InputError(f"f line: {what} index {int(idx[k])} does not exist (the file "
                         f"defines {defined_lines.size}, {int(before[k])} before this line)",
                         path=path, row=int(tline[k]) + 1,
                         fix="OBJ indices start at 1; negative ones count back")
    return out


def read_obj(path, data: bytes | None = None, warnings: list[str] | None = None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Read an OBJ file (module docstring).

    Parameters
    ----------
    path : the file (named in messages) ; data : its bytes, if already read
    warnings : a list to append warnings to (for a cache to replay them); default: shown
        with :func:`gonio_cli.log.warn`

    Returns
    -------
    vertices : (V, 3) float64 ; faces : (F, 3) int64, fan-split polygons in file order ;
    normals : (V, 3) float64 from ``vn`` or None ; uvs : (V, 2) float64 from ``vt`` or None.

    Raises
    ------
    InputError : naming the file and the line.
    """
    path = str(path)
    data = Path(path).read_bytes() if data is None else data
    warn = warnings.append if warnings is not None else log.warn
    data, L = _lines(path, data)
    _check_statements(path, data, L, warn)
    V, v_lines = _floats(path, data, L, 1, b"v", 3, 3)
    VT, vt_lines = _floats(path, data, L, 2, b"vt", 1, 2)
    VN, vn_lines = _floats(path, data, L, 3, b"vn", 3, 3)
    vi, ti, ni, tline, first_tok, ntok, f_lines = _faces(path, data, L)
    if f_lines.size == 0:
        return V, np.zeros((0, 3), np.int64), None, None
    few = np.flatnonzero(ntok < 3)
    if few.size:
        raise InputError(f"f line has {int(ntok[few[0]])} vertex(es), needs at least 3",
                         path=path, row=int(f_lines[few[0]]) + 1,
                         fix="repair or re-export the mesh")
    v = _resolve(path, vi, tline, v_lines, "vertex")
    has_t, has_n = ti != 0, ni != 0
    use_t = bool(has_t.all())
    use_n = bool(has_n.all())
    if has_t.any() and not use_t:
        warn(f"{path}:{int(tline[np.argmin(has_t)]) + 1}: some face corners have no "
                 "texture coordinate; texture coordinates are not used")
    if has_n.any() and not use_n:
        warn(f"{path}:{int(tline[np.argmin(has_n)]) + 1}: some face corners have no "
                 "normal; smooth normals are computed instead")
    t = _resolve(path, ti, tline, vt_lines, "texture") if use_t else None
    n = _resolve(path, ni, tline, vn_lines, "normal") if use_n else None
    corner, vertices, normals, uvs = _split_vertices(v, t, n, V, VT, VN)
    # fan split: face line k with m corners gives (c0, c_j, c_j+1), j = 1 … m − 2
    tris = ntok - 2
    face_of = np.repeat(np.arange(ntok.size), tris)
    j = np.arange(face_of.size) - np.repeat(np.cumsum(tris) - tris, tris) + 1
    c0 = first_tok[face_of]
    faces = np.stack([corner[c0], corner[c0 + j], corner[c0 + j + 1]], axis=1).astype(np.int64)
    return vertices, faces, normals, uvs


def _lines(path: str, data: bytes) -> tuple[bytes, _Lines]:
    """The file's text made regular (CR and tabs as blanks, no leading blanks) and its
    lines; a binary file or a line continuation is refused."""
    if b"\0" in data[:BINARY_SNIFF_BYTES]:
        raise InputError("is a binary file, not a text OBJ", path=path,
                         fix="export the mesh as Wavefront OBJ (text)")
    if b"\r" in data or b"\t" in data:
        data = data.replace(b"\r", b" ").replace(b"\t", b" ")
    if b"\n " in data or data.startswith(b" "):
        data = re.sub(rb"(?m)^ +", b"", data)                  # leading blanks
    L = _Lines(data)
    if b"\\\n" in data or data.endswith(b"\\"):
        i = int(np.searchsorted(L.starts, data.find(b"\\\n") if b"\\\n" in data
                                else len(data) - 1, "right")) - 1
        raise InputError("line continuation (\\ at the end of a line) is not supported",
                         path=path, row=i + 1, fix="join the continued lines")
    return data, L


def _check_statements(path: str, data: bytes, L: _Lines, warn) -> None:
    """The lines that are not v, vt, vn or f: ignored (:data:`IGNORED`), skipped with one
    warning (:data:`UNSUPPORTED`), or refused (an empty v, vt, vn or f line, not OBJ)."""
    skipped: dict[str, int] = {}
    for i in L.other.tolist():
        keyword = data[L.starts[i]:L.ends[i]].split(None, 1)
        word = keyword[0].decode("utf-8", "replace") if keyword else ""
        if not word or word in IGNORED:
            continue
        if word in UNSUPPORTED:
            skipped[word] = skipped.get(word, 0) + 1
            continue
        if word in ("v", "vt", "vn", "f"):
            raise InputError(f"{word} line has no values", path=path, row=i + 1,
                             fix="repair or re-export the mesh")
        raise InputError(f"{word[:20]!r} is not an OBJ statement", path=path, row=i + 1,
                         fix="is this an OBJ file? (v, vt, vn, f lines)")
    if skipped:
        warn(f"{path}: skipped " + ", ".join(f"{n} {w!r} line(s)" for w, n in
                                                 sorted(skipped.items()))
                 + " (gonio draws faces only)")


def _split_vertices(v, t, n, V, VT, VN):
    """One vertex per distinct (v, vt, vn) combination of the face corners (identity when
    they all agree): each corner's vertex, and the vertices, normals and uvs (None where
    the corners have none)."""
    if (t is None or (VT.shape[0] == V.shape[0] and np.array_equal(t, v))) and \
            (n is None or (VN.shape[0] == V.shape[0] and np.array_equal(n, v))):
        return v, V, VN if n is not None else None, VT if t is not None else None
    key = v.astype(np.int64)
    for other, size in ((t, VT.shape[0]), (n, VN.shape[0])):
        if other is None:
            continue
        if key.max(initial=0) >= np.iinfo(np.int64).max // (size + 1):
            key = np.unique(key, return_inverse=True)[1].ravel()
        key = key * (size + 1) + other
    _, first_of, corner = np.unique(key, return_index=True, return_inverse=True)
    return (corner.ravel(), V[v[first_of]], VN[n[first_of]] if n is not None else None,
            VT[t[first_of]] if t is not None else None)
