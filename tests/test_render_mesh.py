"""Meshes for ``gonio render``: built-ins, OBJ loading, normals, transforms, validation."""

from __future__ import annotations

import numpy as np
import pytest

from gonio_cli import envmap
from gonio_cli.errors import InputError
from gonio_cli.render import mesh as M
from gonio_cli.render.solid import closed_surface


def face_normals(m):
    v, f = m.vertices, m.faces
    return np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])


def write_obj(path, vertices, faces, uvs=None, normals=None):
    """A small OBJ writer (1-based indices, v/vt/vn sharing one index)."""
    lines = [f"v {float(x)!r} {float(y)!r} {float(z)!r}" for x, y, z in vertices]
    if uvs is not None:
        lines += [f"vt {float(u)!r} {float(v)!r}" for u, v in uvs]
    if normals is not None:
        lines += [f"vn {float(x)!r} {float(y)!r} {float(z)!r}" for x, y, z in normals]
    for f in np.asarray(faces) + 1:
        if uvs is not None and normals is not None:
            lines.append("f " + " ".join(f"{i}/{i}/{i}" for i in f))
        elif uvs is not None:
            lines.append("f " + " ".join(f"{i}/{i}" for i in f))
        elif normals is not None:
            lines.append("f " + " ".join(f"{i}//{i}" for i in f))
        else:
            lines.append("f " + " ".join(str(i) for i in f))
    path.write_text("\n".join(lines) + "\n")
    return path


# ----------------------------------------------------------------------------- built-ins

def test_default_sphere_is_the_benchmark_size():
    m = M.load_mesh("builtin:sphere")
    assert 19_000 <= len(m.faces) <= 21_000            # the target's ~20 000 triangles
    assert len(m.faces) == 2 * M.SPHERE_SEGMENTS * (M.SPHERE_SEGMENTS // 2 - 1)


@pytest.mark.parametrize("segments,rings", [(3, 2), (16, 8), (40, 13)])
def test_sphere_geometry_winding_and_normals(segments, rings):
    m = M.load_mesh(f"builtin:sphere?segments={segments}&rings={rings}")
    assert len(m.faces) == 2 * segments * (rings - 1)
    np.testing.assert_allclose(np.linalg.norm(m.vertices, axis=1), 1.0, atol=1e-15)
    np.testing.assert_allclose(m.normals, m.vertices, atol=1e-15)
    centroid = m.vertices[m.faces].mean(axis=1)
    fn = face_normals(m)
    assert np.all(np.einsum("ij,ij->i", fn, centroid) > 0)   # counter-clockwise = outwards
    assert np.all(np.linalg.norm(fn, axis=1) > 0)             # no degenerate pole triangle


def test_sphere_uvs_follow_the_environment_map_convention():
    m = M.uv_sphere(24, 12)
    body = np.abs(m.vertices[:, 1]) < 1 - 1e-12                # poles have per-triangle u
    u, v = m.uvs[body].T
    theta, phi = np.pi * (1.0 - v), 2.0 * np.pi * u
    np.testing.assert_allclose(envmap.spherical_to_direction(theta, phi), m.vertices[body],
                               atol=1e-12)
    assert m.uvs[:, 0].min() >= -0.5 / 24 and m.uvs[:, 0].max() <= 1 + 0.5 / 24
    # the +y pole is the top row of a texture: v = 1
    np.testing.assert_allclose(m.uvs[m.vertices[:, 1] > 1 - 1e-12, 1], 1.0)


def test_plane_is_mitsubas_rectangle():
    m = M.load_mesh("builtin:plane?segments=3")
    assert len(m.faces) == 18
    np.testing.assert_allclose(m.vertices[:, 2], 0.0)
    assert m.vertices[:, :2].min() == -1.0 and m.vertices[:, :2].max() == 1.0
    fn = face_normals(m)
    assert np.all(fn[:, 2] > 0) and np.allclose(fn[:, :2], 0)   # front towards +z
    np.testing.assert_allclose(m.uvs, (m.vertices[:, :2] + 1) / 2)
    np.testing.assert_allclose(m.normals, [[0, 0, 1]] * len(m.vertices))


@pytest.mark.parametrize("spec", ["builtin:cube", "builtin:sphere?segments=2",
                                  "builtin:sphere?segments=abc", "builtin:sphere?size=3",
                                  "builtin:plane?segments=0"])
def test_bad_builtin_specs_are_errors(spec):
    with pytest.raises(InputError, match="builtin"):
        M.load_mesh(spec)


# ----------------------------------------------------------------------------- files

def test_obj_without_normals_gets_smooth_normals_across_uv_seams(tmp_path):
    s = M.uv_sphere(32, 16)            # the seam column and the poles are duplicated vertices
    path = write_obj(tmp_path / "ball.obj", s.vertices, s.faces, uvs=s.uvs)
    m = M.load_mesh("ball.obj", base_dir=tmp_path)
    assert m.uvs is not None and len(m.uvs) == len(m.vertices)
    # area-weighted normals of an inscribed sphere: close to the radial direction, and the
    # same on both copies of a seam vertex (pooled by position)
    radial = m.vertices / np.linalg.norm(m.vertices, axis=1, keepdims=True)
    cos = np.einsum("ij,ij->i", m.normals, radial)
    assert cos.min() > np.cos(np.pi / 16)          # within one ring's angle
    _, inverse = np.unique(m.vertices, axis=0, return_inverse=True)
    seam = inverse.ravel()
    for group in np.unique(seam[np.bincount(seam)[seam] > 1])[:20]:
        same = m.normals[seam == group]
        np.testing.assert_allclose(same, same[:1].repeat(len(same), 0), atol=1e-12)
    assert path.exists()


def test_obj_normals_are_kept(tmp_path):
    v = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
    n = [(0.2, 0, 0.9797958971132712)] * 3             # deliberately not the face normal
    write_obj(tmp_path / "t.obj", v, [(0, 1, 2)], uvs=[(0, 0), (1, 0), (0, 1)], normals=n)
    m = M.load_mesh(str(tmp_path / "t.obj"))
    np.testing.assert_allclose(m.normals, np.array(n), atol=1e-12)
    np.testing.assert_allclose(m.uvs, [(0, 0), (1, 0), (0, 1)])


def test_obj_without_uvs_and_a_mask_is_an_error(tmp_path):
    write_obj(tmp_path / "nouv.obj", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 2)])
    m = M.load_mesh("nouv.obj", base_dir=tmp_path)
    assert m.uvs is None
    with pytest.raises(InputError, match="mesh nouv.obj has no texture coordinates, which "
                                         "the mask of object 2 needs"):
        M.require_uvs(m, "the mask of object 2")
    M.require_uvs(M.load_mesh("builtin:plane"), "the mask of object 1")   # has uvs: fine


def test_missing_mesh_file_names_it(tmp_path):
    with pytest.raises(InputError, match="nothere.obj: no such mesh file"):
        M.load_mesh("nothere.obj", base_dir=tmp_path)


def test_nan_vertices_are_an_error_naming_file_and_count(tmp_path):
    path = tmp_path / "bad.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv nan 1 0\nv 0 inf 1\nf 1 2 3\nf 1 2 4\n")
    with pytest.raises(InputError, match=r"bad.obj: 2 of 4 vertices are not finite"):
        M.load_mesh(str(path))


def test_degenerate_triangles_are_skipped_and_counted(tmp_path, capsys):
    v = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (2, 0, 0), (1, 1, 0)]
    faces = [(0, 1, 2), (0, 1, 3), (1, 1, 4), (1, 4, 2)]    # 2nd: collinear, 3rd: repeated
    write_obj(tmp_path / "deg.obj", v, faces)
    m = M.load_mesh(str(tmp_path / "deg.obj"))
    assert len(m.faces) == 2
    err = capsys.readouterr().err
    assert "deg.obj: skipped 2 degenerate (zero-area) triangle(s) of 4" in err
    assert err.count("warning") == 1


def test_only_degenerate_triangles_is_an_error(tmp_path):
    write_obj(tmp_path / "line.obj", [(0, 0, 0), (1, 0, 0), (2, 0, 0)], [(0, 1, 2)])
    with pytest.raises(InputError, match="no .*triangles"):
        M.load_mesh(str(tmp_path / "line.obj"))


# ----------------------------------------------------------------------------- transforms

def test_rotation_is_xyz_euler_right_handed():
    r = M.rotation_matrix((0, 0, 90))
    np.testing.assert_allclose(r @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    # x first, then z: (90, 0, 90) takes +y → +z (about x) → +z (about z)
    np.testing.assert_allclose(M.rotation_matrix((90, 0, 90)) @ [0, 1, 0], [0, 0, 1],
                               atol=1e-15)
    np.testing.assert_allclose(M.rotation_matrix((90, 0, 90)) @ [1, 0, 0], [0, 1, 0],
                               atol=1e-15)


def test_transform_normals_use_the_inverse_transpose():
    s = M.uv_sphere(24, 12)
    e = M.transform(s, translate=(1, 2, 3), rotate_deg=(10, 20, 30), scale=(2.0, 1.0, 0.5))
    # the exact normal of the ellipsoid at each transformed vertex
    r = M.rotation_matrix((10, 20, 30))
    local = (e.vertices - [1, 2, 3]) @ r                      # undo rotation
    grad = (local / np.array([2.0, 1.0, 0.5]) ** 2) @ r.T
    grad /= np.linalg.norm(grad, axis=1, keepdims=True)
    np.testing.assert_allclose(e.normals, grad, atol=1e-12)
    # counter-clockwise still faces outwards
    centroid = e.vertices[e.faces].mean(axis=1) - [1, 2, 3]
    assert np.all(np.einsum("ij,ij->i", face_normals(e), centroid) > 0)


def test_mirroring_scale_keeps_the_front_outside():
    e = M.transform(M.uv_sphere(16, 8), scale=(-1.0, 1.0, 1.0))
    centroid = e.vertices[e.faces].mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", face_normals(e), centroid) > 0)


def test_zero_scale_is_an_error():
    with pytest.raises(InputError, match="scale"):
        M.transform(M.uv_sphere(8, 4), scale=(1.0, 0.0, 1.0))


def test_a_mesh_file_is_read_once_per_process_until_it_changes(tmp_path):
    """A turntable's frames and a batch worker's jobs load the same mesh: the second load
    is the first one's arrays (read-only, so no caller can change them for the others);
    an edited file is read again."""
    import os

    path = tmp_path / "tri.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    first = M.load_mesh(str(path))
    assert M.load_mesh(str(path)) is first
    assert not first.vertices.flags.writeable
    path.write_text("v 0 0 0\nv 2 0 0\nv 0 2 0\nf 1 2 3\n")
    later = os.stat(path).st_mtime_ns + 10**9
    os.utime(path, ns=(later, later))
    again = M.load_mesh(str(path))
    assert again is not first and again.vertices[1, 0] == 2.0


def test_closed_surface_needs_every_edge_paired_and_the_faces_outwards():
    """Closed and outwards (the rasterizer may skip back faces seen from outside): the
    sphere (its seam and poles repeat positions under other indices, which count as one
    vertex), also split per face as an OBJ with per-corner normals is; not the plane, a
    sphere with a hole, one turned inside out, one with a single face turned."""
    s = M.uv_sphere(24, 12)
    assert closed_surface(s.vertices, s.faces)
    split = s.vertices[s.faces].reshape(-1, 3)                # 3 vertices per face
    assert closed_surface(split, np.arange(len(split)).reshape(-1, 3))
    assert not closed_surface(*(lambda p: (p.vertices, p.faces))(M.plane(2)))
    assert not closed_surface(s.vertices, s.faces[1:])                 # a hole
    assert not closed_surface(s.vertices, np.concatenate([s.faces, s.faces]))  # 4 per edge
    assert not closed_surface(s.vertices, s.faces[:, ::-1])            # inside out
    turned = s.faces.copy()
    turned[5] = turned[5, ::-1]
    assert not closed_surface(s.vertices, turned)
    # the flag comes with the loaded mesh and survives placement, a mirror included
    assert M.load_mesh("builtin:sphere?segments=24").closed
    assert not M.load_mesh("builtin:plane").closed
    assert M.transform(M.load_mesh("builtin:sphere?segments=24"), scale=(1, -2, 1)).closed
