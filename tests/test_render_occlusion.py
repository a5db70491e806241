"""Occlusion of environment light by the scene (gonio_cli.render.occlusion, skycut).

Truths: the view factor of a sphere from a point on a plane (a sphere of radius R whose
centre is at distance D from the point, seen at angle θ from the plane's normal and
wholly above the plane: F = (R / D)² cos θ; J. R. Howell, "A catalog of radiation heat
transfer configuration factors", B-20), so under a uniform sky the share of the
irradiance a floor point receives is V = 1 − F; a lone convex solid, which nothing can
occlude (the stage is skipped and the frame is the unoccluded one, pixel for pixel);
the median cut's equal shares of a uniform sky.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest

from gonio_cli.errors import InputError
from gonio_cli.render import Stats
from gonio_cli.render.mesh import load_mesh, transform
from gonio_cli.render.occlusion import (DEFAULT_DIRECTIONS, occludes_itself, proxy_mesh,
                                        visible_fraction)
from gonio_cli.render.pipeline import render_scene
from gonio_cli.render.scene import load_scene
from gonio_cli.render.skycut import median_cut, sky_directions
from gonio_cli.schemas import Material, write_material
from gonio_cli.spectra import parse_grid

from test_render_environment import write_env

#: A unit sphere floating with its centre this high over an infinite floor (a plane of
#: half-size 8, flat: it occludes nothing of itself).
HEIGHT = 1.5
#: Horizontal distances of the floor points from the point under the centre.
DISTANCES = np.array([0.0, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0])
#: |V − (1 − F)| bounds. Each region of the sky is taken as a disc about its flux centre
#: (docs/render.md): a sphere's outline that cuts a region's edge is counted by the
#: disc's overlap, not the region's. Measured over these points in two azimuths: largest
#: error 0.041 with the default 24 regions (~0.5 sr each), 0.028 with 64; without
#: occlusion the error is F itself, up to 0.44.
TOL_DEFAULT = 0.05
TOL_64 = 0.035
UNIFORM_SKY = np.ones((64, 128, 3))
SPOT_OBJ = (Path(__file__).resolve().parent.parent / "sample_data/meshes/spot.obj")


def placed(mesh: str, translate, rotate_deg, scale):
    return transform(load_mesh(mesh, "."), translate, rotate_deg, scale)


@pytest.mark.parametrize("k, tol", [(DEFAULT_DIRECTIONS, TOL_DEFAULT), (64, TOL_64)])
@pytest.mark.parametrize("azimuth_deg", [0.0, 53.0])
def test_floor_under_a_sphere_sees_one_minus_the_view_factor(k, tol, azimuth_deg):
    sphere = placed("builtin:sphere", [0.0, HEIGHT, 0.0], [0.0, 0.0, 0.0], 1.0)
    floor = placed("builtin:plane", [0.0, 0.0, 0.0], [-90.0, 0.0, 0.0], 8.0)
    a = np.radians(azimuth_deg)
    p = np.stack([DISTANCES * np.cos(a), np.zeros_like(DISTANCES),
                  DISTANCES * np.sin(a)]).astype(np.float32)
    up = np.tile(np.array([[0.0], [1.0], [0.0]], np.float32), (1, DISTANCES.size))
    v, _ = visible_fraction(sky_directions(UNIFORM_SKY, k), [sphere, floor], p, up, up,
                            np.ones(DISTANCES.size, int))
    d = np.hypot(DISTANCES, HEIGHT)
    truth = 1.0 - (1.0 / d) ** 2 * (HEIGHT / d)              # F = (R/D)² cos θ, R = 1
    np.testing.assert_array_less(np.abs(v - truth), tol)


def test_median_cut_of_a_uniform_sky_has_equal_shares():
    """A uniform sky cut into 16: every region holds 4π/16 sr within a texel row's share
    (the cuts fall on texel boundaries of a 64 × 128 map); their flux-weighted
    directions average to 0 (the sphere is covered evenly)."""
    sky = sky_directions(UNIFORM_SKY, 16)
    np.testing.assert_allclose(sky.solid_angle_sr.sum(), 4 * np.pi, rtol=1e-12)
    np.testing.assert_allclose(sky.flux, sky.solid_angle_sr)   # luminance 1
    np.testing.assert_allclose(sky.solid_angle_sr, 4 * np.pi / 16, rtol=0.05)
    assert np.linalg.norm((sky.direction * sky.flux[:, None]).sum(axis=0)) < 0.05 * 4 * np.pi
    assert len(median_cut(np.ones((2, 2)), 16)) == 4           # no cut below a texel


def test_which_meshes_occlude_themselves():
    assert not occludes_itself(placed("builtin:sphere", [0, 0, 0], [0, 0, 0], 1.0))
    assert not occludes_itself(placed("builtin:plane", [0, -1, 0], [-90, 0, 0], 6.0))
    spot = placed(str(SPOT_OBJ), [0, 0, 0], [0, 150, 0], 1.0)
    assert occludes_itself(spot)
    proxy = proxy_mesh(spot)
    assert proxy.closed and len(proxy.faces) < len(spot.faces)
    # the stand-in stays within a cell of the mesh: its box within 1/16 of the extent
    extent = np.ptp(spot.vertices, axis=0).max()
    np.testing.assert_allclose(proxy.vertices.min(axis=0), spot.vertices.min(axis=0),
                               atol=extent / 16)


# ---------------------------------------------------------------------- the pipeline --

@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    d = tmp_path_factory.mktemp("occlusion")
    grid = parse_grid()
    n = grid.size
    write_material(d / "matte.json", Material("cook-torrance", grid, {
        "kd": np.full(n, 0.5), "ks": np.zeros(n), "m": np.full(n, 0.3),
        "f0": np.full(n, 0.04)}))
    write_env(d / "env", [1.0, 2.0, 4.0, 8.0, 16.0], value=np.ones(3, np.float32))
    return d


def render(folder, objects: str, occlusion: str | None, stats=None):
    """Luminance (H, W) of a 48² render under the uniform environment."""
    text = textwrap.dedent("""
        [camera]
        eye = [0.0, 1.5, 4.0]
        target = [0.0, 0.0, 0.0]
        fov_deg = 45.0
        width = 48
        height = 48
        [output]
        ssaa = 1
        tonemap = "none"
        [environment]
        prefiltered = "env/index.json"
        method = "model"
        """) + ("" if occlusion is None else f"occlusion = {occlusion}\n") + \
        textwrap.dedent(objects)
    path = folder / "scene.toml"
    path.write_text(text)
    return render_scene(load_scene(path), stats).xyz[..., 1]


SPHERE = """
    [[object]]
    mesh = "builtin:sphere"
    material = "matte.json"
    """
FAR = """
    [[object]]
    mesh = "builtin:sphere?segments=16"
    material = "matte.json"
    translate = [-6.0, -6.0, -6.0]
    scale = 0.1
    """


def test_lone_convex_solid_skips_the_occlusion(folder):
    """Nothing can hide a lone convex solid's sky: no map, the run report says so, the
    frame is the unoccluded one; a far object makes the stage run, and the sphere's
    pixels still do not change (no region of its sky is hidden)."""
    stats = Stats()
    alone = render(folder, SPHERE, None, stats)
    assert stats.counts["occlusion"] == {"directions": DEFAULT_DIRECTIONS,
                                         "skipped": "one convex solid"}
    off_stats = Stats()
    np.testing.assert_array_equal(render(folder, SPHERE, "false", off_stats), alone)
    assert "occlusion" not in off_stats.counts and "occlusion" not in off_stats.time_s
    stats = Stats()
    two = render(folder, SPHERE + FAR, "8", stats)
    assert stats.counts["occlusion"]["directions"] == 8
    assert stats.counts["occlusion"]["nodes"] > 0
    np.testing.assert_array_equal(two, alone)


def test_concave_mesh_darkens_itself(folder):
    """Spot alone (concave, closed): its belly and the insides of its legs see less sky;
    the occlusion only darkens (V ≤ 1) and the lit top does not change much."""
    spot = """
        [[object]]
        mesh = "SPOT"
        material = "matte.json"
        rotate_deg = [0.0, 150.0, 0.0]
        """.replace("SPOT", str(SPOT_OBJ))
    stats = Stats()
    on = render(folder, spot, None, stats)
    off = render(folder, spot, "false")
    counts = stats.counts["occlusion"]
    assert counts["occluded_samples"] > 0 and counts["mean_visibility"] < 1
    assert np.all(on <= off * (1 + 1e-6))
    assert (on < 0.9 * off).sum() > 20                         # clearly darker somewhere


@pytest.mark.parametrize("value, message", [
    ('"yes"', "expected true, false or a number"),
    ("0", "outside"),
    ("1000", "outside"),
    ("2.5", "expected true, false or a number"),
])
def test_bad_occlusion_key_is_refused(folder, value, message):
    with pytest.raises(InputError, match=message):
        render(folder, SPHERE, value)
