"""Whether a mesh is a closed surface facing outwards (:func:`closed_surface`: the
rasterizer then skips its back faces), and whether such a closed mesh is convex: a convex
solid cannot shadow itself.

The shadow stage (:mod:`.shadow`) skips its maps when a scene is one such solid (a
material previewed on a sphere): every ray from a lit point of a convex surface towards
the light leaves the solid for good. Checked only then, and remembered per loaded mesh
(:func:`is_convex`): ~10 ms for the 20 448-triangle built-in sphere.
"""

from __future__ import annotations

import weakref

import numpy as np

from . import Mesh

#: An edge is convex when the far corner of the face across it lies no more than this
#: fraction of the mesh's size in front of the face's plane. Not float64 round-off (~1e-15)
#: but the file's: an OBJ written with 6 decimals (Blender's default) rounds coordinates by
#: 5e-7, so the 20 448-triangle sphere written so has neighbours up to ~1e-6 of its size
#: "concave" (1e-7 refused it: its shadow maps, 50-60 ms, were computed for nothing). A
#: dent 1e-5 of the size deep shadows at most 6e-4 of it even under a light 1° above the
#: surface: a fraction of a pixel at any size the renderer draws.
CONVEX_TOLERANCE = 1e-5
#: Largest mesh checked (~0.5 µs a face); larger ones are taken as not convex, so their
#: shadows are computed (the check would cost about what the maps do).
CONVEX_CHECK_MAX_FACES = 1 << 18

#: Largest mesh whose closedness is checked at load (:func:`closed_surface`, ~5 ms per
#: 20 000 faces, two sorts): above, the check would cost more than the back faces it lets
#: the rasterizer skip save in a frame, and the mesh is drawn as an open one.
CLOSED_CHECK_MAX_FACES = 1 << 18


def closed_surface(vertices: np.ndarray, faces: np.ndarray) -> bool:
    """True when the faces form closed surfaces facing outwards.

    Vertices at exactly the same position are one (an OBJ repeats a position for each
    uv or normal it has there; the rasterizer's edges are watertight wherever two
    triangles share the same numbers). Closed and consistently oriented: every directed
    edge (a, b) of a face is used once, and (b, a) once by another face. Outwards: the
    signed volume Σ p0 · (p1 × p2) / 6 is positive. From an eye outside such a surface
    every ray that meets it enters through a front face before it leaves through a back
    face, so no back face is ever the nearest hit.
    """
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    if len(f) == 0:
        return False
    order = np.lexsort(v.T[::-1])                             # by x, then y, then z
    sv = v[order]
    new = np.ones(len(v), bool)
    new[1:] = (sv[1:] != sv[:-1]).any(axis=1)
    ids = np.empty(len(v), np.int64)
    ids[order] = np.cumsum(new) - 1
    g = ids[f]
    a, b = g.reshape(-1), g[:, [1, 2, 0]].reshape(-1)        # directed edges a → b
    if (a == b).any():                                        # a face with a repeated corner
        return False
    # one sort of (edge, direction) codes: a closed, consistently oriented surface has
    # each edge exactly twice, once a → b (code even) and once b → a (odd)
    n = int(ids.max()) + 1
    code = np.sort((np.minimum(a, b) * n + np.maximum(a, b)) * 2 + (a > b))
    first, second = code[0::2], code[1::2]
    if (first.size != second.size or (first >> 1 != second >> 1).any()
            or (first & 1).any() or not (second & 1).all()
            or (first[1:] >> 1 == second[:-1] >> 1).any()):   # an edge in 4 faces
        return False
    p0, p1, p2 = (v[f[:, k]] for k in range(3))
    return bool(np.einsum("ij,ij->", p0, np.cross(p1, p2)) > 0.0)


_KNOWN: dict[int, tuple[weakref.ref, bool]] = {}


def is_convex(mesh: Mesh) -> bool:
    """Whether ``mesh`` is the boundary of one convex solid (:func:`convex_surface`),
    for a mesh known closed and facing outwards (``Mesh.closed``); False otherwise or
    above :data:`CONVEX_CHECK_MAX_FACES`. Remembered per faces array: a placed mesh
    (:func:`.mesh.transform`, an affine map, which keeps convexity) shares its faces
    with the loaded one, so a process checks each loaded mesh once."""
    faces = mesh.faces
    if not mesh.closed or len(faces) > CONVEX_CHECK_MAX_FACES:
        return False
    known = _KNOWN.get(id(faces))
    if known is not None and known[0]() is faces:
        return known[1]
    result = convex_surface(mesh.vertices, faces)
    for key in [k for k, (ref, _) in _KNOWN.items() if ref() is None]:
        del _KNOWN[key]                                       # arrays since freed
    try:
        _KNOWN[id(faces)] = (weakref.ref(faces), result)
    except TypeError:                                         # not weak-referenceable
        pass
    return result


def convex_surface(vertices: np.ndarray, faces: np.ndarray) -> bool:
    """Whether a closed, consistently oriented, outward surface bounds one convex solid:
    every edge convex (the far corner of the face across it not in front of the face's
    plane, within :data:`CONVEX_TOLERANCE`) and one piece (V − E + F = 2 over its
    distinct positions). A closed surface convex at every edge bounds a convex solid,
    one per piece (Tietze 1928). Vertices at the same position are one (OBJ seams)."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    order = np.lexsort(v.T[::-1])
    sv = v[order]
    new = np.ones(len(v), bool)
    new[1:] = (sv[1:] != sv[:-1]).any(axis=1)
    ids = np.empty(len(v), np.int64)
    ids[order] = np.cumsum(new) - 1
    pos = np.ascontiguousarray(sv[new].T)                     # (3, V′)
    n_pos, n_faces = pos.shape[1], len(f)
    if n_faces == 0 or n_pos - n_faces // 2 != 2:             # V − E + F, E = 3F / 2
        return False
    g = ids[f]                                                # (F, 3) on the positions
    a, b = g.reshape(-1), g[:, [1, 2, 0]].reshape(-1)         # directed edges a → b
    # each edge's two directions side by side: sorted by (edge, direction)
    by_code = np.argsort((np.minimum(a, b) * n_pos + np.maximum(a, b)) * 2 + (a > b))
    partner = np.empty_like(by_code)                          # the same edge, b → a
    partner[by_code[0::2]] = by_code[1::2]
    partner[by_code[1::2]] = by_code[0::2]
    across = g[:, [2, 0, 1]].reshape(-1)[partner].reshape(n_faces, 3)   # far corners
    corner = [pos[:, g[:, k]] for k in range(3)]              # 3 × (3, F)
    e1, e2 = corner[1] - corner[0], corner[2] - corner[0]
    normal = np.stack([e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                       e1[0] * e2[1] - e1[1] * e2[0]])        # (3, F) outwards
    ahead = sum((pos[c][across] - corner[0][c][:, None]) * normal[c][:, None]
                for c in range(3))                            # (F, 3)
    size = float(np.linalg.norm(pos.max(axis=1) - pos.min(axis=1)))
    limit = CONVEX_TOLERANCE * size * np.sqrt((normal * normal).sum(axis=0))
    return bool(np.all(ahead <= limit[:, None]))
