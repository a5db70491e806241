"""gonio's OBJ reader (:mod:`gonio_cli.render.obj`) against trimesh and hand-written truth,
its errors (file and line, one stderr line, exit 2) and its content-hash cache."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from gonio_cli.errors import InputError
from gonio_cli.render import mesh as mesh_module
from gonio_cli.render.mesh import load_mesh, uv_sphere
from gonio_cli.render.obj import read_obj

ROOT = Path(__file__).resolve().parent.parent


def write_sphere_obj(path: Path, segments: int = 24) -> int:
    """The built-in UV sphere as an OBJ with v, vt, vn and f v/vt/vn (6 decimals); returns
    its triangles (also the render benchmark's meshes)."""
    m = uv_sphere(segments)
    with open(path, "w") as f:
        np.savetxt(f, m.vertices, fmt="v %.6f %.6f %.6f")
        np.savetxt(f, m.uvs, fmt="vt %.6f %.6f")
        np.savetxt(f, m.normals, fmt="vn %.6f %.6f %.6f")
        np.savetxt(f, np.repeat(m.faces + 1, 3, axis=1), fmt="f %d/%d/%d %d/%d/%d %d/%d/%d")
    return len(m.faces)


def corners(vertices, faces, attr=None):
    """The triangle soup (F, 3 · k) of an attribute, rows sorted: independent of vertex
    order and of how a reader welds vertices."""
    values = (vertices if attr is None else attr)[faces].reshape(len(faces), -1)
    return values[np.lexsort(np.round(values, 6).T[::-1])]


@pytest.mark.parametrize("name", ["sheet", "sphere"])
def test_same_geometry_as_trimesh(tmp_path, name):
    import trimesh.exchange.obj as obj
    if name == "sheet":
        path = ROOT / "sample_data/scenes/sheet.obj"
    else:
        path = tmp_path / "sphere.obj"
        write_sphere_obj(path)
    v, f, n, uv = read_obj(path)
    with open(path, "rb") as fh:
        parts = list(obj.load_obj(fh, skip_materials=True)["geometry"].values())
    assert len(parts) == 1
    t = parts[0]
    assert f.shape == np.asarray(t["faces"]).shape
    # the same triangles with the same corner positions, normals and uvs (the file's six
    # decimals are what both read; 1e-12 is float64 round-off of the same text)
    for ours, theirs in ((v, t["vertices"]), (n, t["vertex_normals"]), (uv, t["visual"].uv)):
        np.testing.assert_allclose(corners(v, f, ours), corners(t["vertices"], t["faces"], theirs),
                                   atol=1e-12)


def test_polygons_formats_negative_indices_and_welding(tmp_path):
    """Hand-checked: a quad with v/vt/vn, a pentagon with negative v//vn, a triangle with
    v/vt … each written out here, fan-split as (0, k, k+1)."""
    path = tmp_path / "mix.obj"
    path.write_text(textwrap.dedent("""\
        # comment\r
        mtllib x.mtl
        o thing
        v 0 0 0
        v 1 0 0\t
        v 1 1 0
          v 0 1 0
        v 0.5 1.5 0 1.0
        vt 0 0
        vt 1 0
        vt 1 1
        vt 0 1
        vt 0.5 1
        vn 0 0 1
        usemtl red
        s off
        f 1/1/1 2/2/1 3/3/1 4/4/1
        f -5/-5/1 -4/-4/1 -1/-1/1 -2/-2/1 -3/-3/1
        """))
    v, f, n, uv = read_obj(path)
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 1.5, 0]], float)
    # quad (1 2 3 4) → (1 2 3), (1 3 4); pentagon (1 2 5 4 3) → (1 2 5), (1 5 4), (1 4 3)
    expected = V[np.array([[0, 1, 2], [0, 2, 3], [0, 1, 4], [0, 4, 3], [0, 3, 2]])]
    np.testing.assert_array_equal(v[f], expected)
    assert np.all(n[f] == [0, 0, 1])
    np.testing.assert_array_equal(uv[f[0]], [[0, 0], [1, 0], [1, 1]])
    np.testing.assert_array_equal(uv[f[2]], [[0, 0], [1, 0], [0.5, 1]])

    # the same vertex with two different uvs becomes two vertices (a uv seam)
    seam = tmp_path / "seam.obj"
    seam.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvt 1 1\n"
                    "f 1/1 2/2 3/3\nf 1/4 3/3 2/2\n")
    v, f, n, uv = read_obj(seam)
    assert n is None and len(v) == 4
    np.testing.assert_array_equal(uv[f], [[[0, 0], [1, 0], [0, 1]], [[1, 1], [0, 1], [1, 0]]])
    np.testing.assert_array_equal(v[f[1]], [[0, 0, 0], [0, 1, 0], [1, 0, 0]])

    # plain v indices: no uvs, no normals
    plain = tmp_path / "plain.obj"
    plain.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    v, f, n, uv = read_obj(plain)
    assert n is None and uv is None and f.tolist() == [[0, 1, 2]]


def test_skipped_statements_warn_once(tmp_path, capsys):
    path = tmp_path / "l.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2\nl 2 3\nf 1 2 3\n")
    v, f, _, _ = read_obj(path)
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "2 'l' line(s)" in err and len(f) == 1


@pytest.mark.parametrize("text,row,match", [
    ("v 0 0 0\nv 1 zero 0\nv 0 1 0\nf 1 2 3\n", 2, "'zero' is not a number"),
    ("v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n", 2, "has 2 value(s), needs 3"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", 4, "needs at least 3"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", 4, "vertex index 0 does not exist"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", 4, "vertex index 4 does not exist"),
    ("v 0 0 0\nf -1 -2 -3\nv 1 0 0\nv 0 1 0\n", 2, "vertex index -2 does not exist"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3.5\n", 4, "'3.5' is not an integer index"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nbogus 1\nf 1 2 3\n", 4, "'bogus' is not an OBJ statement"),
])
def test_bad_obj_names_file_and_line(tmp_path, run_gonio, text, row, match):
    path = tmp_path / "bad.obj"
    path.write_text(text)
    with pytest.raises(InputError) as exc:
        read_obj(path)
    assert exc.value.row == row and match in exc.value.message
    # through the CLI: one line on stderr, exit 2, no image
    (tmp_path / "m.json").write_text("{}")
    (tmp_path / "s.toml").write_text(textwrap.dedent("""
        [camera]
        eye = [0.0, 0.0, 3.0]
        target = [0.0, 0.0, 0.0]
        fov_deg = 40.0
        width = 8
        height = 8
        [[object]]
        mesh = "bad.obj"
        material = "m.json"
        [[light]]
        type = "directional"
        direction = [0.0, 0.0, 1.0]
        irradiance = 1.0
        """))
    r = run_gonio("render", tmp_path / "s.toml", "-o", tmp_path / "o.png")
    assert r.exit_code == 2 and r.stderr.count("\n") == 1
    assert f"bad.obj:{row}: " in r.stderr and match in r.stderr
    assert not (tmp_path / "o.png").exists()


def test_binary_file_is_refused(tmp_path):
    path = tmp_path / "mesh.obj"
    path.write_bytes(b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR")
    with pytest.raises(InputError, match="binary file"):
        read_obj(path)


def test_cache_is_keyed_by_content(tmp_path, monkeypatch):
    monkeypatch.setenv("GONIO_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(mesh_module, "OBJ_CACHE_MIN_BYTES", 0)
    path = tmp_path / "s.obj"
    write_sphere_obj(path, 12)
    first = load_mesh(str(path))
    assert len(list((tmp_path / "cache").glob("obj-*.npz"))) == 1
    calls = []
    real = mesh_module.read_obj
    monkeypatch.setattr(mesh_module, "read_obj", lambda *a, **k: calls.append(1) or real(*a, **k))
    again = load_mesh(str(path))                      # a hit: the parser does not run
    assert calls == []
    np.testing.assert_array_equal(again.vertices, first.vertices)
    np.testing.assert_array_equal(again.faces, first.faces)
    np.testing.assert_array_equal(again.uvs, first.uvs)
    path.write_text(path.read_text().replace("v 0.000000 1.000000", "v 0.000000 2.000000", 1))
    changed = load_mesh(str(path))                    # new content: parsed again
    assert calls == [1] and changed.vertices[:, 1].max() == 2.0


def test_builtin_render_does_not_import_trimesh(tmp_path):
    """The OBJ reader is gonio's; trimesh (~1 s of imports) only for other formats."""
    write_sphere_obj(tmp_path / "s.obj", 12)
    code = textwrap.dedent(f"""
        import sys
        from gonio_cli.render.mesh import load_mesh
        load_mesh("builtin:sphere")
        load_mesh({str(tmp_path / 's.obj')!r})
        print("trimesh" in sys.modules)
        """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False"
