"""The batched z-buffer rasterizer against closed forms (silhouettes, ray–plane hits)."""

from __future__ import annotations

import numpy as np
import pytest

from gonio_cli.render import Camera, Mesh
from gonio_cli.render import mesh as M
from gonio_cli.render import raster as R
from gonio_cli.render import visibility as V


def camera(eye=(0, 0, 4.0), target=(0, 0, 0), up=(0, 1, 0), fov=35.0, w=96, h=96):
    return Camera(np.asarray(eye, float), np.asarray(target, float), np.asarray(up, float),
                  fov, w, h)


def sphere_silhouette_area_px(cam, centre, radius=1.0, ssaa=1):
    """Exact image area (px²) of a sphere's perspective silhouette: an ellipse.

    The silhouette is the cone from the eye with half-angle α = asin(ρ / L) around the
    direction to the centre, at angle β to the optical axis; its section by the image
    plane at focal distance F has semi-axes F sinα cosα / (cos²β − sin²α) and
    F sinα / √(cos²β − sin²α).
    """
    eye, r, u, f = R.camera_basis(cam)
    to_c = np.asarray(centre, float) - eye
    L = np.linalg.norm(to_c)
    sin_a = radius / L
    cos_a = np.sqrt(1 - sin_a**2)
    cos_b = to_c @ f / L
    k = cos_b**2 - sin_a**2
    F = R.focal_px(cam, ssaa)
    return np.pi * F**2 * (sin_a * cos_a / k) * (sin_a / np.sqrt(k))


def ray_plane_hits(cam, ssaa, point, normal):
    """World hit points (H, W, 3) of every pixel's ray with a plane, and ray lengths t."""
    eye = np.asarray(cam.eye, float)
    d = R.pixel_rays(cam, ssaa)
    t = ((np.asarray(point) - eye) @ normal) / (d @ normal)
    return eye + t[..., None] * d, t


# ----------------------------------------------------------------------------- coverage

@pytest.mark.parametrize("centre", [(0, 0, 0), (0.5, -0.3, 0.3)])
def test_sphere_silhouette_area_matches_the_projected_ellipse(centre):
    cam = camera(w=240, h=160, fov=50.0)
    rings = 128
    sphere = M.transform(M.uv_sphere(2 * rings, rings), translate=centre)
    gb = R.rasterize(cam, [sphere])
    border = np.r_[gb.covered[[0, -1]].ravel(), gb.covered[:, [0, -1]].ravel()]
    assert not border.any()                               # the whole outline is in frame
    exact = sphere_silhouette_area_px(cam, centre)
    # an inscribed polygonal silhouette loses ≤ 2(1 − cos(π / rings)) of the area
    # (6e-4 here); pixel counting along a ~400 px outline adds ~√400 px of noise
    tessellation = 2 * (1 - np.cos(np.pi / rings))
    pixels = 3 * np.sqrt(2 * np.sqrt(np.pi * exact)) / exact
    assert abs(gb.covered.sum() / exact - 1) < tessellation + pixels


def test_sphere_has_no_holes_inside_its_silhouette():
    cam = camera(w=128, h=128)
    gb = R.rasterize(cam, [M.uv_sphere(64, 32)])
    F = R.focal_px(cam)
    radius = F * np.tan(np.arcsin(1 / 4.0)) * np.cos(np.pi / 32)   # inscribed polygon
    yy, xx = np.mgrid[0:128, 0:128] + 0.5
    inner = np.hypot(xx - 64, yy - 64) < radius - 1.0
    assert gb.covered[inner].all()
    assert not gb.covered[np.hypot(xx - 64, yy - 64) > F * np.tan(np.arcsin(0.25)) + 1].any()


def test_background_is_minus_one_and_zeros():
    gb = R.rasterize(camera(w=40, h=30), [M.transform(M.uv_sphere(16, 8), scale=0.5)])
    bg = ~gb.covered
    assert bg.any() and gb.covered.any()
    assert np.all(gb.object_id[bg] == -1)
    for a in (gb.position, gb.normal, gb.view, gb.uv):
        assert np.all(a[bg] == 0) and np.isfinite(a).all()
    assert np.all(gb.uv_footprint[bg] == 0)
    assert gb.object_id.shape == (30, 40) and gb.position.shape == (30, 40, 3)


def test_nothing_to_draw_gives_an_empty_buffer():
    cam = camera(w=8, h=6)
    behind = M.transform(M.uv_sphere(8, 4), translate=(0, 0, 10))   # behind the eye
    for meshes in ([], [behind]):
        gb = R.rasterize(cam, meshes, ssaa=2)
        assert gb.object_id.shape == (12, 16) and not gb.covered.any()


# ----------------------------------------------------------------------------- depth

def triangle(z, colour_id=0):
    """A big triangle facing +z at height z (front towards a camera on +z)."""
    v = np.array([[-2.0, -2.0, z], [2.0, -2.0, z], [0.0, 2.0, z]])
    return Mesh(v, np.array([[0, 1, 2]]), np.tile([0.0, 0.0, 1.0], (3, 1)))


@pytest.mark.parametrize("order", [(0, 1), (1, 0)])
def test_nearer_triangle_wins_whatever_the_order(order):
    near, far = triangle(0.5), Mesh(*(lambda t: (t.vertices * [1, -1, 1] + [0, 0, -1.0],
                                                t.faces[:, ::-1], t.normals))(triangle(0.0)))
    meshes = [near, far]
    gb = R.rasterize(camera(w=64, h=64), [meshes[i] for i in order])
    both = gb.covered
    z = gb.position[..., 2]
    # where both cover a pixel the one at z = 0.5 is seen; elsewhere the far one at z = −1
    near_id = order.index(0)
    seen_near = gb.object_id == near_id
    assert seen_near.sum() > 100 and (both & ~seen_near).sum() > 100
    np.testing.assert_allclose(z[seen_near], 0.5, atol=1e-12)
    np.testing.assert_allclose(z[both & ~seen_near], -1.0, atol=1e-12)
    # every pixel the near triangle covers on its own shows it
    alone = R.rasterize(camera(w=64, h=64), [near]).covered
    assert np.array_equal(alone, seen_near)


# ----------------------------------------------------------------------------- interpolation

def tilted_plane():
    """builtin:plane turned 60° about x and moved back: seen at a steep angle."""
    return M.transform(M.load_mesh("builtin:plane?segments=2"), translate=(0.2, -0.3, -1.0),
                       rotate_deg=(-60.0, 10.0, 0.0), scale=(1.5, 1.0, 1.0))


def plane_frame():
    r = M.rotation_matrix((-60.0, 10.0, 0.0))
    origin = np.array([0.2, -0.3, -1.0])
    return origin, r, np.array([1.5, 1.0, 1.0])


@pytest.mark.parametrize("ssaa", [1, 2])
def test_perspective_correct_uv_and_position_on_a_tilted_plane(ssaa):
    cam = camera(eye=(0.3, 0.8, 3.0), target=(0, -0.2, -1), w=64, h=48, fov=50.0)
    gb = R.rasterize(cam, [tilted_plane()], ssaa=ssaa)
    origin, rot, scale = plane_frame()
    hit, t = ray_plane_hits(cam, ssaa, origin, rot[:, 2])
    local = ((hit - origin) @ rot) / scale                 # plane coordinates in [−1, 1]²
    inside = (np.abs(local[..., 0]) <= 1) & (np.abs(local[..., 1]) <= 1) & (t > 0)
    cov = gb.covered
    assert cov.sum() > 500 * ssaa**2
    # coverage equals the exact ray–square test except on the outline's pixels
    assert (cov != inside).sum() <= 2 * (gb.object_id.shape[0] + gb.object_id.shape[1])
    both = cov & inside
    np.testing.assert_allclose(gb.position[both], hit[both], atol=1e-9)
    np.testing.assert_allclose(gb.uv[both], (local[both][:, :2] + 1) / 2, atol=1e-9)
    np.testing.assert_allclose(gb.normal[both], np.broadcast_to(rot[:, 2], (both.sum(), 3)),
                               atol=1e-12)
    to_eye = cam.eye - hit[both]
    np.testing.assert_allclose(gb.view[both],
                               to_eye / np.linalg.norm(to_eye, axis=-1, keepdims=True),
                               atol=1e-12)


def test_uv_footprint_matches_finite_differences_of_exact_uvs():
    cam = camera(eye=(0.3, 0.8, 3.0), target=(0, -0.2, -1), w=64, h=48, fov=50.0)
    gb = R.rasterize(cam, [tilted_plane()])
    origin, rot, scale = plane_frame()
    hit, _ = ray_plane_hits(cam, 1, origin, rot[:, 2])
    uv = (((hit - origin) @ rot) / scale)[..., :2] / 2
    # central differences of the exact uv along rows and columns (second-order accurate)
    du_x = (uv[1:-1, 2:] - uv[1:-1, :-2]) / 2
    du_y = (uv[2:, 1:-1] - uv[:-2, 1:-1]) / 2
    expect = np.maximum(np.linalg.norm(du_x, axis=-1), np.linalg.norm(du_y, axis=-1))
    inner = gb.covered[1:-1, 1:-1] & gb.covered[2:, 1:-1] & gb.covered[:-2, 1:-1] \
        & gb.covered[1:-1, 2:] & gb.covered[1:-1, :-2]
    got = gb.uv_footprint[1:-1, 1:-1][inner]
    # the perspective map's curvature over one pixel: relative error ~ (pixel / depth)²
    np.testing.assert_allclose(got, expect[inner], rtol=2e-3)
    assert got.min() > 0


def test_sphere_normals_and_positions_match_the_analytic_sphere():
    centre = np.array([0.2, -0.1, 0.5])
    cam = camera(w=80, h=80)
    S = 48
    sphere = M.transform(M.uv_sphere(S, S // 2), translate=centre)
    gb = R.rasterize(cam, [sphere])
    cov = gb.covered
    rel = gb.position[cov] - centre
    radius = np.linalg.norm(rel, axis=-1)
    # points lie on the inscribed polyhedron: between the sphere and its chords' depth
    assert radius.max() <= 1 + 1e-12 and radius.min() >= np.cos(2 * np.pi / S) - 1e-12
    # linear interpolation of vertex normals n_k = p_k − c gives exactly p − c, so the
    # normalised normal is the radial direction up to round-off
    np.testing.assert_allclose(gb.normal[cov], rel / radius[:, None], atol=1e-9)
    assert np.all(np.einsum("ij,ij->i", gb.normal[cov], gb.view[cov]) > -1e-9)


def test_ellipsoid_normals_within_tessellation_tolerance():
    cam = camera(w=80, h=80, eye=(0, 0, 6.0))
    S = 96
    e = M.transform(M.uv_sphere(S, S // 2), scale=(2.0, 1.0, 1.0), rotate_deg=(0, 30, 0))
    gb = R.rasterize(cam, [e])
    cov = gb.covered
    r = M.rotation_matrix((0, 30, 0))
    local = gb.position[cov] @ r
    grad = (local / np.array([4.0, 1.0, 1.0])) @ r.T
    grad /= np.linalg.norm(grad, axis=-1, keepdims=True)
    angle = np.arccos(np.clip(np.einsum("ij,ij->i", grad, gb.normal[cov]), -1, 1))
    # the normal turns by ≤ 2 · 2π / S across a triangle on this 2:1 ellipsoid, and the
    # interpolated normal errs by a fraction of that
    assert angle.max() < 2 * 2 * np.pi / S


def test_back_faces_are_flipped_towards_the_viewer():
    plane = M.load_mesh("builtin:plane")
    front = R.rasterize(camera(eye=(0.1, 0.2, 3.0), w=32, h=32), [plane])
    back = R.rasterize(camera(eye=(0.1, 0.2, -3.0), w=32, h=32), [plane])
    assert front.covered.sum() > 200 and back.covered.sum() > 200
    np.testing.assert_allclose(front.normal[front.covered], [[0, 0, 1]] * front.covered.sum())
    np.testing.assert_allclose(back.normal[back.covered], [[0, 0, -1]] * back.covered.sum())
    assert np.all(np.einsum("...j,...j->...", back.normal, back.view)[back.covered] > 0)


def test_ground_plane_through_the_near_plane_is_exact():
    """A large floor extends behind the eye: crossing triangles are ray cast, not lost."""
    floor = M.transform(M.load_mesh("builtin:plane?segments=4"), rotate_deg=(-90, 0, 0),
                        scale=50.0)                       # y = 0, facing +y, |x|, |z| ≤ 50
    cam = camera(eye=(0.0, 1.0, 0.0), target=(0.0, 0.7, -3.0), w=64, h=48, fov=70.0)
    gb = R.rasterize(cam, [floor])
    hit, t = ray_plane_hits(cam, 1, np.zeros(3), np.array([0.0, 1.0, 0.0]))
    inside = (t > 0) & (np.abs(hit[..., 0]) <= 50) & (np.abs(hit[..., 2]) <= 50)
    assert inside.sum() > 1000
    assert (gb.covered != inside).sum() <= 2 * 64            # the far edge's pixels at most
    both = gb.covered & inside
    np.testing.assert_allclose(gb.position[both], hit[both], atol=1e-6 * 50)


# ----------------------------------------------------------------------------- SSAA

def test_ssaa_buffer_size_and_downsample_of_a_constant():
    cam = camera(w=20, h=10)
    gb = R.rasterize(cam, [M.uv_sphere(16, 8)], ssaa=3)
    assert gb.object_id.shape == (30, 60) and gb.ssaa == 3
    const = np.full((30, 60, 3), 0.37)
    np.testing.assert_allclose(R.downsample(const, 3), np.full((10, 20, 3), 0.37), rtol=1e-15)
    # a box filter: the downsampled coverage is the fraction of covered subpixels
    frac = R.downsample(gb.covered.astype(float), 3)
    assert frac.shape == (10, 20) and set(np.unique(frac * 9).round(9)) <= set(range(10))
    with pytest.raises(ValueError):
        R.downsample(np.zeros((7, 9)), 2)


def test_ssaa_converges_on_the_silhouette_area():
    cam = camera(w=48, h=48)
    sphere = M.uv_sphere(128, 64)
    exact = sphere_silhouette_area_px(cam, (0, 0, 0))
    err = [abs(R.downsample(R.rasterize(cam, [sphere], s).covered.astype(float), s).sum()
               / exact - 1) for s in (1, 4)]
    assert err[1] < 5e-3                                  # tessellation 1.2e-3 + 4× finer edge


# ----------------------------------------------------------------------------- scenes

def test_several_meshes_object_ids_and_uvs_only_where_given():
    no_uv = M.transform(M.uv_sphere(24, 12), translate=(-1.2, 0, 0), scale=0.8)
    no_uv.uvs = None
    with_uv = M.transform(M.uv_sphere(24, 12), translate=(1.2, 0, 0), scale=0.8)
    gb = R.rasterize(camera(w=96, h=48, eye=(0, 0, 6.0)), [no_uv, with_uv])
    left, right = gb.object_id[:, :48], gb.object_id[:, 48:]
    assert set(np.unique(left)) == {-1, 0} and set(np.unique(right)) == {-1, 1}
    assert np.all(gb.uv[gb.object_id == 0] == 0) and np.all(gb.uv_footprint[gb.object_id == 0] == 0)
    assert np.all(gb.uv_footprint[gb.object_id == 1] > 0)
    assert R.rasterize(camera(w=8, h=8), [no_uv]).uv is None
    # a scene that needs no texture skips uv work; the rest is unchanged
    lean = R.rasterize(camera(w=96, h=48, eye=(0, 0, 6.0)), [no_uv, with_uv], uv=False)
    assert lean.uv is None and lean.uv_footprint is None
    assert np.array_equal(lean.object_id, gb.object_id)
    np.testing.assert_array_equal(lean.normal, gb.normal)


@pytest.mark.parametrize("kw", [{"target": (0, 0, 4.0)}, {"up": (0, 0, 1.0)}])
def test_degenerate_cameras_are_input_errors(kw):
    from gonio_cli.errors import InputError

    with pytest.raises(InputError, match="camera"):
        R.rasterize(camera(**kw), [M.uv_sphere(8, 4)])


def test_halftone_on_a_receding_plane_shows_no_moire():
    """End to end with the mask pyramid: a one-texel R/G checker on a plane seen at 70°
    from its normal, ≥ 4 texels per pixel everywhere, reads as an even mix at every pixel
    (point sampling would show 0/1 bands)."""
    from gonio_cli.render.texture import MaskPyramid

    yy, xx = np.mgrid[0:1024, 0:1024]
    checker = (xx + yy) % 2 == 0
    pyr = MaskPyramid(np.stack([checker, ~checker, np.zeros_like(checker)], -1).astype(float))
    plane = M.transform(M.load_mesh("builtin:plane"), rotate_deg=(-70, 0, 0))
    cam = camera(eye=(0, 0.2, 4.0), target=(0, 0, 0), w=64, h=64, fov=30.0)
    gb = R.rasterize(cam, [plane])
    cov = gb.covered
    texels = gb.uv_footprint[cov] * 1024
    assert texels.min() > 4
    got = pyr.coverage(gb.uv[cov], gb.uv_footprint[cov])
    np.testing.assert_allclose(got, np.broadcast_to([0.5, 0.5, 0.0], got.shape), atol=1e-5)
    point = pyr.coverage(gb.uv[cov], np.zeros(cov.sum()))     # level 0, bilinear only
    assert point[:, 0].std() > 0.1 and np.abs(point[:, 0] - 0.5).max() > 0.3


@pytest.mark.parametrize("tilt", [90.0, 89.999, 89.9])
def test_grazing_and_edge_on_planes_give_finite_buffers(tilt):
    """Edge-on (culled) and nearly edge-on planes: no NaN/inf, unit normals, uv in range."""
    plane = M.transform(M.load_mesh("builtin:plane?segments=3"), rotate_deg=(-tilt, 0, 0))
    gb = R.rasterize(camera(eye=(0, 0, 3.0), w=48, h=48), [plane], ssaa=2)
    for a in (gb.position, gb.normal, gb.view, gb.uv, gb.uv_footprint):
        assert np.isfinite(a).all()
    cov = gb.covered
    np.testing.assert_allclose(np.linalg.norm(gb.normal[cov], axis=-1), 1.0, atol=1e-9)
    assert np.all((gb.uv[cov] > -1e-6) & (gb.uv[cov] < 1 + 1e-6))
    if tilt == 90.0:
        assert not cov.any()


# ----------------------------------------------------------------------------- visibility pass

def builds():
    """The depth test's builds to check: numpy, and C where it was compiled (pip builds it
    wherever a compiler is found; CI's machine has one)."""
    return [pytest.param(b, marks=pytest.mark.skipif(
        b == "c" and not V.c_build_available(), reason="_rasterscan.c not built"))
        for b in V.BUILDS]


def brute_force_keys(st, w, h, F):
    """The depth keys of testing every pixel of every box with the float32 edge functions
    (the rasterizer's arithmetic, written out per triangle with no spans, no culling)."""
    f32 = np.float32
    cx, cy, inv_f = f32(w / 2.0 - 0.5), f32(h / 2.0 - 0.5), f32(1.0 / F)
    C = st["C"].astype(f32)
    iz = (st["N"] / st["q"]).astype(f32)
    keys = np.full(h * w, V.KEY_EMPTY, np.int64)
    for t in range(len(st["q"])):
        cols = np.arange(st["x0"][t], st["x0"][t] + st["bw"][t])
        rows = np.arange(st["y0"][t], st["y0"][t] + st["bh"][t])
        dx = (cols.astype(f32) - cx) * inv_f
        dy = (cy - rows.astype(f32)) * inv_f
        e = [dx[None, :] * C[k, 0, t] + (dy * C[k, 1, t] + C[k, 2, t])[:, None] for k in range(3)]
        rz = dx[None, :] * iz[0, t] + (dy * iz[1, t] + iz[2, t])[:, None]
        hit = (np.minimum(np.minimum(e[0], e[1]), e[2]) >= 0) & (rz > 0) & (rz < f32(1 / V.NEAR))
        pix = (rows[:, None] * w + cols[None, :])[hit]
        key = ((np.int64(0x7FFFFFFF) - rz[hit].view(np.int32)).astype(np.int64) << 32) \
            | (t | (int(st["back"][t]) << 31))
        np.minimum.at(keys, pix, key)
    return keys


def setup_of(cam, meshes, ssaa=1):
    verts, _, faces, _, _ = R._concat(meshes)
    eye, r, u, f = R.camera_basis(cam)
    basis = np.stack([r, u, f], axis=1)
    h, w = cam.height * ssaa, cam.width * ssaa
    F = R.focal_px(cam, ssaa)
    st = V.setup((verts - eye) @ basis, faces, float(np.sign(np.linalg.det(basis))), w, h, F)
    return st, w, h, F


def open_bowl():
    """The lower half of a sphere seen from above and the side: its inside (back faces)
    shows through the opening, its outside (front faces) elsewhere."""
    s = M.uv_sphere(32, 16)
    keep = s.vertices[s.faces].mean(axis=1)[:, 1] < 0.05
    return Mesh(s.vertices, s.faces[keep], s.normals)


@pytest.mark.parametrize("build", builds())
@pytest.mark.parametrize("scene", ["sphere", "bowl", "floor", "two spheres"])
def test_spans_and_culling_give_the_keys_of_testing_every_box_pixel(scene, build):
    """The row spans (sure pixels untested) and the hierarchical-z culling of back faces
    change nothing, nor does the C build: the keys equal those of the float32 edge test
    at every pixel of every box — on a closed sphere (back faces culled), an open bowl
    (back faces seen), a floor crossing the near plane (whole-screen boxes) and two
    spheres (one hides part of the other)."""
    cams = {"sphere": camera(w=64, h=48), "bowl": camera(eye=(0.3, 2.5, 2.5), w=64, h=64),
            "floor": camera(eye=(0.0, 1.0, 0.0), target=(0.0, 0.7, -3.0), w=48, h=40, fov=70.0),
            "two spheres": camera(eye=(0.5, 0.2, 5.0), w=80, h=64)}
    meshes = {"sphere": [M.uv_sphere(24, 12)], "bowl": [open_bowl()],
              "floor": [M.transform(M.load_mesh("builtin:plane?segments=4"),
                                    rotate_deg=(-90, 0, 0), scale=50.0)],
              "two spheres": [M.uv_sphere(24, 12),
                              M.transform(M.uv_sphere(20, 10), translate=(0.6, 0.2, -1.5))]}
    st, w, h, F = setup_of(cams[scene], meshes[scene])
    truth = brute_force_keys(st, w, h, F)
    assert (truth != V.KEY_EMPTY).sum() > 200                # the test sees something
    for hiz in (True, False):
        np.testing.assert_array_equal(V.visible_keys(st, w, h, F, hiz=hiz, build=build),
                                      truth)
    if scene == "sphere":
        # culling did happen: measured 22 % of this coarse sphere's back faces (the
        # 2 × 2 cells of a box's level reach past the silhouette), 53 % at 96 segments
        hidden = V.hidden_back_faces(st, V.visible_keys(st, w, h, F), w, h, F)
        assert hidden.sum() > 0.15 * st["back"].sum()
    if scene == "bowl":                                       # the inside is seen
        seen = truth[truth != V.KEY_EMPTY] & V.TRI_INDEX_MASK
        assert st["back"][seen].sum() > 100


def test_culling_keeps_a_back_face_in_front_of_the_front_faces():
    """A back-facing triangle nearer than a front-facing one (an open mesh): never hidden."""
    near = triangle(0.5)
    near = Mesh(near.vertices, near.faces[:, ::-1], near.normals)        # now a back face
    far = triangle(-1.0)
    st, w, h, F = setup_of(camera(w=64, h=64), [near, far])
    assert st["back"].tolist() == [True, False]
    keys = V.visible_keys(st, w, h, F)
    np.testing.assert_array_equal(keys, brute_force_keys(st, w, h, F))
    assert not V.hidden_back_faces(st, keys, w, h, F).any()
    assert ((keys != V.KEY_EMPTY) & ((keys & V.TRI_INDEX_MASK) == 0)).sum() > 100


def test_compact_buffers_store_contiguous_components():
    """Compact rows are the transposes of (c, n) arrays, so each component is contiguous
    for the shading; the values equal the dense layout's (float64 and float32)."""
    cam = camera(w=40, h=40)
    sphere = M.uv_sphere(24, 12)
    dense = R.rasterize(cam, [sphere])
    for dtype, tol in ((np.float64, 0.0), (np.float32, 2e-6)):
        gb = R.rasterize(cam, [sphere], compact=True, dtype=dtype)
        for name in ("position", "normal", "view", "uv"):
            a = getattr(gb, name)
            assert a.dtype == dtype and a.T.flags["C_CONTIGUOUS"], name
            np.testing.assert_allclose(a, getattr(dense, name).reshape(-1, a.shape[1])[gb.pixels],
                                       atol=tol, rtol=0, err_msg=name)


def test_resolve_at_ssaa_1_scatters_rows_and_defers_xyz():
    """At ssaa 1 the resolve is a scatter: XYZ and coverage are the rows at their pixels
    (zero and 0 elsewhere), the linear image is the rows times the matrix (float32 round-
    off), and the frame's XYZ is made only when asked, equal to the eager one."""
    from gonio_cli.render.frame import Frame
    from gonio_cli.render.resolve import resolve

    rng = np.random.default_rng(5)
    h, w = 7, 9
    pixels = np.sort(rng.choice(h * w, 40, replace=False))
    object_id = np.full((h, w), -1, np.int32)
    object_id.reshape(-1)[pixels] = 0
    rows = np.ascontiguousarray(rng.uniform(0, 3, (3, 40)).astype(np.float32)).T
    matrix = rng.uniform(-1, 2, (3, 3))
    xyz, coverage = resolve(rows, pixels, object_id, 1)
    dense = np.zeros((h * w, 3))
    dense[pixels] = rows
    np.testing.assert_array_equal(xyz, dense.reshape(h, w, 3))
    np.testing.assert_array_equal(coverage, (object_id >= 0).astype(float))
    lazy, coverage2, linear = resolve(rows, pixels, object_id, 1, matrix=matrix)
    assert callable(lazy) and linear.dtype == np.float32
    np.testing.assert_allclose(linear, (dense @ matrix.T).reshape(h, w, 3), rtol=1e-6,
                               atol=1e-6 * np.abs(dense).max())
    frame = Frame(linear, None, lazy, coverage2)
    np.testing.assert_array_equal(frame.xyz, xyz)
    # at ssaa 2 the same rows go through the box filter: a mean over each 2 × 2 block
    big = np.full((2 * h, 2 * w), -1, np.int32)
    big[::2, ::2] = object_id
    r, c = np.divmod(pixels, w)
    xyz2, cov2, lin2 = resolve(rows, (2 * r) * (2 * w) + 2 * c, big, 2, matrix=matrix)
    np.testing.assert_allclose(xyz2, xyz / 4, rtol=1e-6)
    np.testing.assert_allclose(cov2, coverage / 4)
    np.testing.assert_allclose(lin2, linear / 4, rtol=1e-5, atol=1e-6 * np.abs(dense).max())


def _culled_and_keys(cam, meshes, build=None):
    verts, _, faces, obj, _ = R._concat(meshes)
    eye, r, u, f = R.camera_basis(cam)
    st, w, h, F = setup_of(cam, meshes)
    culled = V.closed_back_faces(meshes, st, obj, (verts - eye) @ np.stack([r, u, f], 1), eye)
    return (st, culled, V.visible_keys(st, w, h, F, culled=culled, build=build),
            brute_force_keys(st, w, h, F))


@pytest.mark.parametrize("build", builds())
@pytest.mark.parametrize("seed", range(6))
def test_closed_meshes_seen_from_outside_skip_their_back_faces_and_keep_every_key(seed, build):
    """Back faces of closed surfaces seen from outside are not tested at all, and every
    key still equals the float32 test at every pixel of every box: a sphere and a
    mirrored, squashed second one from random eyes around them (measured: 0 differing
    pixels in 160 such scenes, OBJ spheres included)."""
    rng = np.random.default_rng(seed)
    d = rng.normal(size=3)
    cam = camera(eye=tuple(d / np.linalg.norm(d) * rng.uniform(2.5, 6.0)), w=72, h=60,
                 fov=rng.uniform(25.0, 60.0))
    s = M.load_mesh("builtin:sphere?segments=32")
    meshes = [s, M.transform(s, translate=tuple(rng.uniform(-1, 1, 3)), scale=(0.6, -0.3, 0.5))]
    st, culled, keys, truth = _culled_and_keys(cam, meshes, build)
    assert culled is not None and culled.sum() > 0.4 * st["back"].sum()
    assert (truth != V.KEY_EMPTY).sum() > 200
    np.testing.assert_array_equal(keys, truth)


@pytest.mark.parametrize("build", builds())
def test_closed_mesh_around_the_eye_or_through_the_near_plane_keeps_its_back_faces(build):
    """Inside a closed sphere (the eye within its box) its back faces are all one sees;
    a sphere cut by the near plane shows its inside through the cut: neither is culled."""
    s = M.load_mesh("builtin:sphere?segments=32")
    inside = M.transform(s, scale=10.0)
    st, culled, keys, truth = _culled_and_keys(camera(eye=(0, 0, 4.0)), [inside], build)
    assert culled is None and st["back"][keys[keys != V.KEY_EMPTY] & V.TRI_INDEX_MASK].all()
    np.testing.assert_array_equal(keys, truth)
    cut = M.transform(s, translate=(0.0, 0.0, 3.5))          # the eye at z 4: 0.5 away
    st, culled, keys, truth = _culled_and_keys(camera(eye=(0, 0, 4.0), fov=90.0), [cut], build)
    assert culled is None
    np.testing.assert_array_equal(keys, truth)


@pytest.mark.parametrize("build", builds())
def test_a_chunk_of_spans_without_sure_pixels_is_skipped(build):
    """A chunk of row spans whose every pixel lies within round-off of an edge (so all are
    tested, none taken as sure) has no sure hits to scatter: it once raised on the empty
    array. Two spheres, one seen past the other, from the eye that found it."""
    s = M.load_mesh("builtin:sphere?segments=48")
    meshes = [s, M.transform(s, translate=(-1.6480751708556527, 0.16746474422274113,
                                           0.10901408782154753), scale=0.7)]
    cam = camera(eye=(-0.3412587284677959, 1.846145120338649, 0.5844547556699414), w=96,
                 h=80, fov=41.143570530400865)
    st, w, h, F = setup_of(cam, meshes)
    np.testing.assert_array_equal(V.visible_keys(st, w, h, F, build=build),
                                  brute_force_keys(st, w, h, F))
