"""Meshes for ``gonio render``: built-ins and OBJ files → :class:`~gonio_cli.render.Mesh`.

Mesh specs (the ``mesh`` key of a scene object):

``builtin:sphere[?segments=S[&rings=R]]``
    The unit sphere at the origin (docs/conventions.md): a UV sphere of ``S`` segments in φ and
    ``R`` rings in θ (default S = 144, R = S / 2: 20 448 triangles, the target's ~20 000
    triangle benchmark). Vertices sit at θ = π j / R, φ = 2π i / S on the environment-map
    direction (sin θ sin φ, cos θ, −sin θ cos φ) (:func:`gonio_cli.envmap.spherical_to_direction`),
    with u = φ / 2π and v = 1 − θ / π; the seam column i = S repeats column 0 with u = 1,
    and each pole is one vertex per segment so every triangle has its own pole u.
    Normals are the analytic ones (the position).
``builtin:plane[?segments=N]``
    Mitsuba 3's ``rectangle``: the square [−1, 1]² in the xy-plane at z = 0, front face
    towards +z, u = (x + 1) / 2, v = (y + 1) / 2 (seen from +z with +y up a texture appears
    upright, OpenGL v = 0 at the bottom), split into N × N quads (default 1).
``path/to/file.obj`` (or any format trimesh reads)
    Relative to ``base_dir``. OBJ files are read by gonio's own vectorised reader
    (:mod:`.obj`: ``vt`` texture coordinates and ``vn`` normals kept, polygons fan-split,
    large files cached by content hash); trimesh is imported only for other formats
    (``trimesh.load(path, process=False, force="mesh")``). Without normals in the file,
    smooth area-weighted vertex normals are computed with vertices that share a position
    (duplicated at UV seams) pooled, so seams do not show.

Validation (STYLE 7, 10): non-finite vertices are an :class:`InputError` naming the file
and the count; zero-area triangles are dropped with one :func:`gonio_cli.log.warn` that
counts them; a mesh with no triangle left is an error.
"""

from __future__ import annotations

import os
from pathlib import Path
from urllib.parse import parse_qsl

import numpy as np

from .. import log
from ..cache import cached_arrays
from ..envmap import spherical_to_direction
from ..errors import InputError
from ..schemas import MAX_MAGNITUDE
from . import Mesh
from .obj import read_obj
from .solid import CLOSED_CHECK_MAX_FACES, closed_surface

#: Default φ segments of ``builtin:sphere`` (rings = segments / 2): 2 · 144 · 71 = 20 448
#: triangles, the target's ~20 000-triangle benchmark sphere.
SPHERE_SEGMENTS = 144
#: Fewest segments / rings that still make a closed solid.
SPHERE_MIN_SEGMENTS = 3
SPHERE_MIN_RINGS = 2
#: Most segments accepted (2 · 4096 · 2048 ≈ 17 M triangles is already far beyond a frame).
BUILTIN_MAX_SEGMENTS = 4096
#: A triangle is degenerate if its area is at most this fraction of the squared diagonal of
#: the mesh's bounding box: float64 cross products of nearly collinear edges carry round-off
#: ~1e-16 of the squared size, so 1e-14 separates true zero-area faces from small ones.
DEGENERATE_REL_AREA = 1e-14
#: Normals shorter than this (after summing face normals) are replaced by the face normal.
MIN_NORMAL_LENGTH = 1e-12

BUILTIN_PREFIX = "builtin:"
#: OBJ files at least this large (bytes, ~100 000 triangles) are cached by content hash:
#: below, parsing (~1 µs per byte) is as quick as loading a cache file.
OBJ_CACHE_MIN_BYTES = 8 << 20
#: Bump when :mod:`.obj` changes what it returns for the same file.
OBJ_CACHE_VERSION = 1


# ----------------------------------------------------------------------------- built-ins

def uv_sphere(segments: int = SPHERE_SEGMENTS, rings: int | None = None) -> Mesh:
    """The unit UV sphere of ``builtin:sphere`` (see the module docstring).

    Parameters
    ----------
    segments : int
        Divisions in φ (≥ 3).
    rings : int, optional
        Divisions in θ (≥ 2); default ``segments // 2``.

    Returns
    -------
    Mesh with (R + 1)(S + 1) vertices and 2 S (R − 1) counter-clockwise (outward) faces;
    normals = positions, uvs (u = φ / 2π, v = 1 − θ / π).
    """
    S = int(segments)
    R = int(rings) if rings is not None else max(SPHERE_MIN_RINGS, S // 2)
    theta = np.pi * np.arange(R + 1) / R
    phi = 2.0 * np.pi * np.arange(S + 1) / S
    pos = spherical_to_direction(theta[:, None], phi[None, :])          # (R+1, S+1, 3)
    pos[0, :] = (0.0, 1.0, 0.0)                                          # exact poles
    pos[-1, :] = (0.0, -1.0, 0.0)
    pos[:, -1] = pos[:, 0]               # the seam's two columns at exactly one place
    u = np.broadcast_to(phi / (2.0 * np.pi), (R + 1, S + 1)).copy()
    v = np.broadcast_to((1.0 - theta / np.pi)[:, None], (R + 1, S + 1)).copy()
    # a pole vertex serves one triangle: give it the u of that triangle's middle
    u[0, :] -= 0.5 / S    # north triangle of column i uses pole vertex i + 1
    u[-1, :] += 0.5 / S   # south triangle of column i uses pole vertex i
    idx = np.arange((R + 1) * (S + 1)).reshape(R + 1, S + 1)
    a, b = idx[:-1, :-1], idx[:-1, 1:]       # (j, i), (j, i+1)
    c, d = idx[1:, :-1], idx[1:, 1:]         # (j+1, i), (j+1, i+1)
    # ∂/∂φ × ∂/∂θ points outwards, so (j,i) → (j,i+1) → (j+1,i) is counter-clockwise
    upper = np.stack([a, b, c], axis=-1)[1:]           # degenerate in ring 0 (a, b at pole)
    lower = np.stack([b, d, c], axis=-1)[:-1]          # degenerate in ring R−1
    faces = np.concatenate([upper.reshape(-1, 3), lower.reshape(-1, 3)]).astype(np.int64)
    vertices = pos.reshape(-1, 3)
    return Mesh(vertices=vertices, faces=faces, normals=vertices.copy(),
                uvs=np.stack([u.ravel(), v.ravel()], axis=-1), name="builtin:sphere")


def plane(segments: int = 1) -> Mesh:
    """The square [−1, 1]² at z = 0 of ``builtin:plane``, facing +z, N × N quads.

    Returns
    -------
    Mesh with (N + 1)² vertices, 2 N² faces, normals +z, u = (x + 1) / 2, v = (y + 1) / 2.
    """
    n = int(segments)
    t = np.linspace(-1.0, 1.0, n + 1)
    x, y = np.meshgrid(t, t)                          # x along columns, y along rows
    vertices = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=-1)
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b = idx[:-1, :-1], idx[:-1, 1:]                # (y0, x0), (y0, x1)
    c, d = idx[1:, :-1], idx[1:, 1:]                  # (y1, x0), (y1, x1)
    faces = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3),
                            np.stack([a, d, c], -1).reshape(-1, 3)]).astype(np.int64)
    normals = np.tile([0.0, 0.0, 1.0], (len(vertices), 1))
    uvs = (vertices[:, :2] + 1.0) / 2.0
    return Mesh(vertices=vertices, faces=faces, normals=normals, uvs=uvs,
                name="builtin:plane")


def _int_option(options: dict, key: str, default, lo: int, spec: str) -> int | None:
    if key not in options:
        return default
    text = options.pop(key)
    try:
        value = int(text)
    except ValueError:
        value = None
    if value is None or not lo <= value <= BUILTIN_MAX_SEGMENTS:
        raise InputError(f"mesh {spec!r}: {key}={text!r} is not an integer in "
                         f"[{lo}, {BUILTIN_MAX_SEGMENTS}]")
    return value


def builtin_triangles(spec: str) -> int | None:
    """Triangles of a ``builtin:`` mesh without building it (None for anything else or
    options that :func:`_builtin` refuses): 2 S (R − 1) for the sphere, 2 N² for the
    plane. The memory estimate of a render counts them (:mod:`gonio_cli.memory`)."""
    if not spec.startswith(BUILTIN_PREFIX):
        return None
    kind, _, query = spec[len(BUILTIN_PREFIX):].partition("?")
    options = dict(parse_qsl(query, keep_blank_values=True))
    try:
        if kind == "sphere":
            s = int(options.get("segments", SPHERE_SEGMENTS))
            r = int(options.get("rings", max(SPHERE_MIN_RINGS, s // 2)))
            return 2 * s * max(r - 1, 0)
        if kind == "plane":
            return 2 * int(options.get("segments", 1)) ** 2
    except ValueError:
        return None
    return None


def _builtin(spec: str) -> Mesh:
    body = spec[len(BUILTIN_PREFIX):]
    kind, _, query = body.partition("?")
    options = dict(parse_qsl(query, keep_blank_values=True))
    if kind == "sphere":
        segments = _int_option(options, "segments", SPHERE_SEGMENTS, SPHERE_MIN_SEGMENTS, spec)
        rings = _int_option(options, "rings", None, SPHERE_MIN_RINGS, spec)
        mesh = uv_sphere(segments, rings)
    elif kind == "plane":
        mesh = plane(_int_option(options, "segments", 1, 1, spec))
    else:
        raise InputError(f"unknown built-in mesh {spec!r}",
                         fix="use builtin:sphere or builtin:plane, or an OBJ file")
    if options:
        raise InputError(f"mesh {spec!r}: unknown option(s) {', '.join(sorted(options))}",
                         fix="builtin:sphere takes segments and rings, builtin:plane segments")
    mesh.name = spec
    return mesh


# ----------------------------------------------------------------------------- files

def _load_obj(path: str):
    """(vertices, faces, normals or None, uvs or None) of an OBJ (:mod:`.obj`).

    Files of at least :data:`OBJ_CACHE_MIN_BYTES` are cached by the SHA-256 of their
    content (:func:`gonio_cli.cache.cached_arrays`): hashing costs ~1/10 of parsing, so a
    re-render of a 1 M-triangle mesh reads its arrays instead of its text. Smaller files
    parse faster than a cache file loads. The parser's warnings are stored with the arrays
    and shown again on a hit.
    """
    data = Path(path).read_bytes()
    if len(data) < OBJ_CACHE_MIN_BYTES:
        return read_obj(path, data)
    import hashlib

    def compute():
        warnings: list[str] = []
        v, f, n, uv = read_obj(path, data, warnings)
        return {"vertices": v, "faces": f, "warnings": np.asarray(warnings, dtype=str),
                "normals": n if n is not None else np.zeros((0, 3)),
                "uvs": uv if uv is not None else np.zeros((0, 2))}

    def check(d):
        return (d["vertices"].ndim == 2 and d["faces"].ndim == 2 and
                (d["faces"].size == 0 or int(d["faces"].max()) < len(d["vertices"])))

    name = f"obj-{OBJ_CACHE_VERSION}-{hashlib.sha256(data).hexdigest()}.npz"
    d = cached_arrays(name, compute, check)
    for message in d["warnings"].tolist():
        log.warn(message)
    n, uv = d["normals"], d["uvs"]
    return (d["vertices"], d["faces"], n if len(n) else None, uv if len(uv) else None)


def _load_file(path: str):
    if not Path(path).is_file():
        raise InputError("no such mesh file", path=path, fix="check the path in the scene file")
    try:
        if path.lower().endswith(".obj"):
            return _load_obj(path)
        import trimesh

        m = trimesh.load(path, process=False, force="mesh")
        uv = getattr(getattr(m, "visual", None), "uv", None)
        return (np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64), None,
                None if uv is None else np.asarray(uv, np.float64))
    except InputError:
        raise
    except Exception as exc:  # trimesh raises many types for unreadable files
        raise InputError(f"cannot read it as a mesh ({type(exc).__name__}: {exc})",
                         path=path, fix="use a triangulated OBJ") from exc


def face_cross(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(V1 − V0) × (V2 − V0) per face as (3, F) float64 (length = 2 × area), by
    components (``np.cross`` on (F, 3) rows is several times slower)."""
    vt = np.ascontiguousarray(np.asarray(vertices, np.float64).T)     # (3, V)
    ft = np.asarray(faces, np.int64).T
    x0, y0, z0 = (vt[i][ft[0]] for i in range(3))
    ax, ay, az = vt[0][ft[1]] - x0, vt[1][ft[1]] - y0, vt[2][ft[1]] - z0
    bx, by, bz = vt[0][ft[2]] - x0, vt[1][ft[2]] - y0, vt[2][ft[2]] - z0
    return np.stack([ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx])


def smooth_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted smooth vertex normals, pooled over vertices at the same position.

    Each face adds its unnormalised normal (V1 − V0) × (V2 − V0) (length = 2 × area, so the
    sum is area-weighted) to the vertices of its corners; vertices with identical
    positions (split at UV seams) share one sum, so seams do not show.

    Parameters
    ----------
    vertices : (V, 3) float ; faces : (F, 3) int, counter-clockwise = front

    Returns
    -------
    (V, 3) float64 unit normals (a vertex on no face gets +z).
    """
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    _, group = np.unique(v, axis=0, return_inverse=True)
    group = group.ravel()
    fn = face_cross(v, f).T
    acc = np.zeros((group.max() + 1 if len(group) else 0, 3))
    for k in range(3):
        np.add.at(acc, group[f[:, k]], fn)
    n = acc[group]
    length = np.linalg.norm(n, axis=-1, keepdims=True)
    ok = length[:, 0] > MIN_NORMAL_LENGTH
    out = np.tile([0.0, 0.0, 1.0], (len(v), 1))
    out[ok] = n[ok] / length[ok]
    return out


def validate(mesh: Mesh, source: str | None = None) -> Mesh:
    """Refuse non-finite input, drop zero-area triangles (one counted warning).

    Parameters
    ----------
    mesh : Mesh
    source : str, optional
        The file (or spec) named in messages; default ``mesh.name``.

    Returns
    -------
    The mesh, with degenerate faces removed (vertices kept).
    """
    where = source or mesh.name
    v = np.asarray(mesh.vertices, np.float64)
    bad = ~(np.abs(v) <= MAX_MAGNITUDE).all(axis=-1)    # NaN, inf or beyond Numeric ranges
    if bad.any():
        raise InputError(f"{int(bad.sum())} of {len(v)} vertices are not finite (NaN or inf) "
                         f"or beyond ±{MAX_MAGNITUDE:g}, "
                         f"the first is vertex {int(np.argmax(bad)) + 1}", path=where,
                         fix="repair or re-export the mesh")
    if mesh.uvs is not None and not np.isfinite(mesh.uvs).all():
        raise InputError(f"{int((~np.isfinite(mesh.uvs).all(-1)).sum())} texture coordinates "
                         "are not finite", path=where, fix="repair or re-export the mesh")
    f = np.asarray(mesh.faces, np.int64).reshape(-1, 3)
    if len(f) and (f.min() < 0 or f.max() >= len(v)):
        raise InputError("faces index vertices that do not exist", path=where)
    if len(f):
        diag2 = float(np.sum((v.max(0) - v.min(0)) ** 2))
        area2_sq = np.sum(face_cross(v, f) ** 2, axis=0)      # (2 × area)²
        degenerate = area2_sq <= (2.0 * DEGENERATE_REL_AREA * diag2) ** 2
        if degenerate.any():
            log.warn(f"{where}: skipped {int(degenerate.sum())} degenerate (zero-area) "
                     f"triangle(s) of {len(f)}")
            f = f[~degenerate]
    if len(f) == 0:
        raise InputError("the mesh has no (non-degenerate) triangles", path=where)
    mesh.faces = f
    return mesh


def load_mesh(spec: str, base_dir: str | os.PathLike | None = None) -> Mesh:
    """Load a mesh from a spec (``builtin:…`` or a file path; see the module docstring).

    Parameters
    ----------
    spec : str
        ``builtin:sphere[?segments=S&rings=R]``, ``builtin:plane[?segments=N]`` or a path.
    base_dir : path, optional
        Directory relative paths are resolved against (the scene file's folder).

    Returns
    -------
    Mesh in its own model space (apply :func:`transform` for the object's placement),
    with unit smooth normals, uvs or None, and ``name`` = the spec.

    Raises
    ------
    InputError
        Unknown built-in or option, missing or unreadable file, non-finite vertices, no
        triangles left.
    """
    path = Path(spec)
    if base_dir is not None and not path.is_absolute():
        path = Path(base_dir) / path
    key: tuple = (spec,)
    if not spec.startswith(BUILTIN_PREFIX):
        try:
            st = os.stat(path)
            key = (os.path.realpath(path), st.st_mtime_ns, st.st_size)
        except OSError:
            key = ()  # missing: _load_file says so
    if key and key in _LOADED:
        _LOADED[key] = _LOADED.pop(key)  # most recently used last
        return _LOADED[key]
    mesh = _load_uncached(spec, path)
    if len(mesh.faces) <= CLOSED_CHECK_MAX_FACES:
        mesh.closed = closed_surface(mesh.vertices, mesh.faces)
    if key:
        for a in (mesh.vertices, mesh.faces, mesh.normals, mesh.uvs):
            if a is not None:
                a.setflags(write=False)  # shared by every later load: never written
        _LOADED[key] = mesh
        while len(_LOADED) > LOADED_MESHES:
            _LOADED.pop(next(iter(_LOADED)))
    return mesh


#: Meshes kept loaded in a process (most recently used): a turntable's frames and a batch
#: worker's jobs read each mesh file once (a 1 M-triangle mesh is ~100 MB of arrays).
LOADED_MESHES = 4
_LOADED: dict[tuple, Mesh] = {}


def _load_uncached(spec: str, path: Path) -> Mesh:
    """:func:`load_mesh` without the in-process cache."""
    if spec.startswith(BUILTIN_PREFIX):
        return validate(_builtin(spec))
    path_s = os.fspath(path)
    vertices, faces, normals, uvs = _load_file(path_s)
    mesh = Mesh(vertices=vertices, faces=faces, normals=np.zeros_like(vertices), uvs=uvs,
                name=spec)
    mesh = validate(mesh, path_s)
    if normals is not None:
        length = np.linalg.norm(normals, axis=-1, keepdims=True)
        usable = np.isfinite(normals).all(-1) & (length[:, 0] > MIN_NORMAL_LENGTH)
        if usable.all():
            mesh.normals = normals / length
            return mesh
    mesh.normals = smooth_normals(mesh.vertices, mesh.faces)
    return mesh


def require_uvs(mesh: Mesh, why: str) -> None:
    """Raise :class:`InputError` if ``mesh`` has no texture coordinates.

    ``why`` completes "which … needs", e.g. ``"the mask of object 2"``.
    """
    if mesh.uvs is None:
        raise InputError(f"mesh {mesh.name} has no texture coordinates, which {why} needs",
                         fix="export the mesh with UVs (vt lines in OBJ) or drop the mask")


# ----------------------------------------------------------------------------- placement

def rotation_matrix(rotate_deg) -> np.ndarray:
    """(3, 3) rotation of XYZ Euler angles in degrees: about x first, then y, then z
    (fixed world axes), R = Rz · Ry · Rx, right-handed (counter-clockwise looking down
    the axis)."""
    ax, ay, az = np.radians(np.asarray(rotate_deg, np.float64).reshape(3))
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def transform(mesh: Mesh, translate=(0.0, 0.0, 0.0), rotate_deg=(0.0, 0.0, 0.0),
              scale=1.0) -> Mesh:
    """Place a mesh: p' = R · (s ⊙ p) + t (scale, then rotate, then translate).

    Parameters
    ----------
    mesh : Mesh
    translate : (3,) float
    rotate_deg : (3,) float
        XYZ Euler angles in degrees (:func:`rotation_matrix`).
    scale : float or (3,) float
        Uniform or per-axis; must be non-zero.

    Returns
    -------
    A new Mesh. Normals go through the inverse transpose of R · S (= R · S⁻¹) and are
    renormalised; a mirroring scale (negative determinant) reverses the winding so that
    counter-clockwise stays the front.
    """
    s = np.broadcast_to(np.asarray(scale, np.float64), (3,)).copy()
    if not np.all(np.isfinite(s)) or np.any(s == 0.0):
        raise InputError(f"scale {scale!r} must be finite and non-zero in every axis")
    t = np.asarray(translate, np.float64).reshape(3)
    r = rotation_matrix(rotate_deg)
    if np.all(s == 1.0) and np.all(t == 0.0) and np.array_equal(r, np.eye(3)):
        # the identity: share the arrays (nothing downstream writes into a mesh's arrays)
        return Mesh(vertices=mesh.vertices, faces=mesh.faces, normals=mesh.normals,
                    uvs=mesh.uvs, name=mesh.name, closed=mesh.closed)

    def apply(m, p):                   # rows p (n, 3) → p · mᵀ, without BLAS threads
        p = np.asarray(p, np.float64)
        return p[:, 0:1] * m[:, 0] + p[:, 1:2] * m[:, 1] + p[:, 2:3] * m[:, 2]

    vertices = apply(r * s, mesh.vertices) + t
    normals = apply(r / s, mesh.normals)
    normals /= np.maximum(np.linalg.norm(normals, axis=-1, keepdims=True), MIN_NORMAL_LENGTH)
    faces = mesh.faces[:, ::-1].copy() if np.prod(s) < 0 else mesh.faces
    # closed and outwards stay so: a mirror flips the volume's sign and the winding both
    return Mesh(vertices=vertices, faces=faces, normals=normals, uvs=mesh.uvs,
                name=mesh.name, closed=mesh.closed)
