"""Area-filtered halftone masks: mip coverage, conventions, validation, no moiré."""

from __future__ import annotations

import numpy as np
import pytest

from gonio_cli.errors import InputError
from gonio_cli.render.texture import MaskPyramid


def labels_to_mask(labels):
    """(H, W) labels 0 (substrate), 1–3 (inks) → (H, W, 3) 0/1 mask."""
    return np.stack([labels == k for k in (1, 2, 3)], axis=-1).astype(np.float32)


def random_mask(rng, h, w, p=(0.4, 0.2, 0.25, 0.15)):
    return labels_to_mask(rng.choice(4, size=(h, w), p=p))


def mean_coverage(mask):
    return mask.reshape(-1, 3).mean(axis=0)


@pytest.mark.parametrize("shape", [(64, 64), (37, 53), (1, 7), (5, 1)])
def test_every_level_keeps_the_mean_coverage(rng, shape):
    mask = random_mask(rng, *shape)
    pyr = MaskPyramid(mask)
    assert pyr.levels[-1].shape[:2] == (1, 1)
    for level in pyr.levels:
        # exact area filtering: each level's mean is the mask's (float32 sums)
        np.testing.assert_allclose(mean_coverage(level), mean_coverage(mask), atol=1e-6)
        assert level.min() >= 0 and level.sum(-1).max() <= 1 + 1e-6


@pytest.mark.parametrize("shape", [(256, 256), (200, 120)])
def test_large_footprint_gives_the_mean_coverage_per_ink(rng, shape):
    mask = random_mask(rng, *shape)
    pyr = MaskPyramid(mask)
    uv = rng.random((500, 2)) * 3 - 1                       # wraps, negative too
    got = pyr.coverage(uv, np.full(500, 4.0))               # pixel ≫ the whole mask
    np.testing.assert_allclose(got, np.broadcast_to(mean_coverage(mask), got.shape), atol=1e-6)


def test_fine_checker_at_two_texel_footprint_is_an_even_mix():
    yy, xx = np.mgrid[0:128, 0:128]
    mask = labels_to_mask(np.where((xx + yy) % 2 == 0, 1, 2))     # R/G one-texel checker
    pyr = MaskPyramid(mask)
    rng = np.random.default_rng(3)
    uv = rng.random((1000, 2))
    for footprint_texels in (2.0, 3.0, 16.0):
        got = pyr.coverage(uv, np.full(1000, footprint_texels / 128))
        # every 2 × 2 block holds two R and two G texels: level ≥ 1 is exactly ½, ½, 0
        np.testing.assert_allclose(got, np.broadcast_to([0.5, 0.5, 0.0], got.shape), atol=1e-6)


def test_random_mask_at_a_large_footprint_is_within_the_levels_quantisation(rng):
    mask = random_mask(rng, 512, 512)
    pyr = MaskPyramid(mask)
    uv = rng.random((4000, 2))
    fp = 32 / 512                                          # 32 texels per pixel
    got = pyr.coverage(uv, np.full(4000, fp))
    # a 32 × 32-texel filter of i.i.d. labels: coverage std √(p(1−p)/1024) ≈ 0.015; the
    # bilinear footprint is ~2× wider, so 5 σ of 0.015 bounds every sample
    assert np.abs(got - mean_coverage(mask)).max() < 5 * 0.5 / 32
    np.testing.assert_allclose(got.mean(0), mean_coverage(mask), atol=3e-3)


def test_no_moire_from_a_fine_line_screen():
    """A pixel grid sweeping a line screen finer than the pixels: point sampling beats into
    moiré bands; the filtered coverage stays at the screen's 1/3 everywhere."""
    w = 1024
    cols = np.arange(w)
    labels = np.where((cols % 3) == 0, 1, 0)[None, :].repeat(4, axis=0)   # R lines, 1/3
    pyr = MaskPyramid(labels_to_mask(labels))
    n = 61                                                  # pixels across u: ~17 texels each
    u = (np.arange(n) + 0.5) / n
    uv = np.stack([u, np.full(n, 0.5)], axis=-1)
    point = pyr.coverage(uv, np.zeros(n))[:, 0]
    filtered = pyr.coverage(uv, np.full(n, 1.0 / n))[:, 0]
    assert point.std() > 0.3                                # moiré: 0/1 beats
    # even the exact box over one pixel holds 5 or 6 of its ~17 texels' lines: ±1/17
    assert np.abs(filtered - 1 / 3).max() < 1 / 17
    assert abs(filtered.mean() - 1 / 3) < 5e-3


def test_coverage_is_in_range_and_sums_to_at_most_one(rng):
    pyr = MaskPyramid(random_mask(rng, 33, 65, p=(0.0, 0.5, 0.3, 0.2)))   # full coverage
    uv = np.concatenate([rng.normal(0, 3, (2000, 2)), [[np.nan, 0.5], [1e300, -np.inf]]])
    fp = np.concatenate([10 ** rng.uniform(-6, 1, 2000), [np.nan, np.inf]])
    got = pyr.coverage(uv, fp)
    assert got.shape == (2002, 3) and np.isfinite(got).all()
    assert got.min() >= 0 and got.sum(-1).max() <= 1.0
    np.testing.assert_allclose(got[:2000].sum(-1), 1.0, atol=1e-5)   # no substrate here


def test_opengl_v_and_wrapping():
    labels = np.zeros((4, 8), int)
    labels[0] = 1                                           # top row red
    labels[-1] = 3                                          # bottom row blue
    pyr = MaskPyramid(labels_to_mask(labels))
    top = pyr.coverage(np.array([[0.3, 1 - 0.125]]), 0.0)   # centre of row 0
    bottom = pyr.coverage(np.array([[0.3, 0.125]]), 0.0)    # centre of row 3
    np.testing.assert_allclose(top, [[1, 0, 0]])
    np.testing.assert_allclose(bottom, [[0, 0, 1]])
    # repeat addressing: u + k and v + k look up the same texel
    a = pyr.coverage(np.array([[0.3, 0.125]]), 0.1, wrap="repeat")
    b = pyr.coverage(np.array([[2.3, -0.875]]), 0.1, wrap="repeat")
    np.testing.assert_allclose(a, b, atol=1e-6)


def test_coverage_broadcasts_over_leading_axes(rng):
    pyr = MaskPyramid(random_mask(rng, 16, 16))
    uv = rng.random((6, 2))
    fp = rng.random(6) * 0.2
    flat = pyr.coverage(uv, fp)
    np.testing.assert_allclose(pyr.coverage(uv.reshape(2, 3, 2), fp.reshape(2, 3)),
                               flat.reshape(2, 3, 3))


@pytest.mark.parametrize("bad,match", [
    (np.full((4, 4, 3), 0.5), "not 0 or 1"),
    (np.dstack([np.ones((4, 4)), np.ones((4, 4)), np.zeros((4, 4))]), "more than one ink"),
    (np.zeros((4, 4)), "RGB"),
    (np.dstack([np.zeros((4, 4, 3)), np.full((4, 4), 0.5)]), "alpha"),
])
def test_bad_masks_are_errors_naming_the_file(bad, match):
    with pytest.raises(InputError, match=f"print.png: .*{match}"):
        MaskPyramid(bad, path="print.png")


def test_mask_from_a_png_file(tmp_path, rng):
    from gonio_cli.imageio import write_png

    mask = random_mask(rng, 20, 30)
    path = tmp_path / "mask.png"
    write_png(path, mask)
    pyr = MaskPyramid.from_file(path)
    np.testing.assert_allclose(pyr.levels[0], mask)
    np.testing.assert_allclose(pyr.mean_coverage(), mean_coverage(mask), atol=1e-6)


# ------------------------------------------------------------------------ addressing --

def edge_mask():
    """8 × 8: left column red, right column empty, the rest green."""
    labels = np.full((8, 8), 2)
    labels[:, 0] = 1
    labels[:, -1] = 0
    return labels_to_mask(labels)


@pytest.mark.parametrize("footprint_texels", [0.0, 1.0, 2.0, 3.0])
def test_clamp_reads_no_dot_of_the_opposite_edge(footprint_texels):
    """A print's right edge (empty column) never pulls in the left edge's red dots."""
    pyr = MaskPyramid(edge_mask())
    v = np.linspace(0.02, 0.98, 25)
    right = np.column_stack([np.full_like(v, 1.0 - 0.5 / 8), v])      # centre of the last column
    edge = np.column_stack([np.full_like(v, 1.0), v])                 # on the border itself
    for uv in (right, edge):
        got = pyr.coverage(uv, np.full(len(v), footprint_texels / 8))   # default: clamp
        # red exists only in column 0: a clamped filter at the right edge reaches at most
        # the mip texels holding columns 4–7 (level ≤ 2 covers ≤ 4 columns), never column 0
        assert got[:, 0].max() == 0.0
    # the same lookups with repeat addressing do pull red in (the bug this guards against)
    got = pyr.coverage(edge, np.full(len(v), 0.0), wrap="repeat")
    np.testing.assert_allclose(got[:, 0], 0.5, atol=1e-6)              # half-way to column 0


def test_clamp_matches_repeat_inside_and_holds_the_edge_texel_outside(rng):
    pyr = MaskPyramid(random_mask(rng, 16, 16))
    uv = 0.1 + 0.8 * rng.random((200, 2))          # ≥ 1.6 texels from every edge
    fp = np.full(200, 0.5 / 16)                    # level < 1: taps stay inside the image
    np.testing.assert_allclose(pyr.coverage(uv, fp, wrap="clamp"),
                               pyr.coverage(uv, fp, wrap="repeat"), atol=1e-6)
    # outside [0, 1] clamp reads the border: u = 3 is u = 1, v = -2 is v = 0
    np.testing.assert_allclose(pyr.coverage(np.array([[3.0, -2.0]]), 0.0),
                               pyr.coverage(np.array([[1.0, 0.0]]), 0.0))
    np.testing.assert_allclose(pyr.coverage(np.array([[1.0, 0.0]]), 0.0),
                               pyr.levels[0][-1:, -1].astype(float))        # bottom-right texel


def test_unknown_wrap_names_the_valid_ones():
    pyr = MaskPyramid(edge_mask())
    with pytest.raises(InputError, match="clamp, repeat"):
        pyr.coverage(np.array([[0.5, 0.5]]), 0.0, wrap="mirror")
