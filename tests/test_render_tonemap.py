"""Tone maps and the XYZ → 8-bit display chain (``gonio_cli.render.tonemap``)."""

from __future__ import annotations

import numpy as np
import pytest

from gonio_cli.errors import InputError
from gonio_cli.render import tonemap
from gonio_cli.spectra import srgb_encode, xyz_to_linear_srgb

X = np.concatenate([[0.0], np.geomspace(1e-6, 1e4, 400)])


def grey(x):
    """(n,) values → (n, 3) grey pixels (tone maps act on pixels, the last axis RGB)."""
    return np.repeat(np.asarray(x, dtype=float)[..., None], 3, axis=-1)


def test_registry_names():
    assert list(tonemap.TONEMAPS) == ["neutral", "none", "clip", "reinhard", "filmic"]
    assert tonemap.DEFAULT_TONEMAP == "neutral"
    with pytest.raises(InputError, match="neutral, none, clip, reinhard, filmic"):
        tonemap.get_tonemap("aces")


def test_clip_is_identity_below_one_and_one_above():
    np.testing.assert_array_equal(tonemap.clip(X), np.minimum(X, 1.0))


def test_reinhard_closed_form():
    np.testing.assert_allclose(tonemap.reinhard(X), X / (1.0 + X), rtol=1e-15)
    assert tonemap.reinhard(np.array(1.0)) == 0.5


def test_none_is_clip():
    assert tonemap.TONEMAPS["none"] is tonemap.clip is tonemap.TONEMAPS["clip"]


def test_neutral_is_the_identity_below_the_knee_and_keeps_ratios_above():
    rng = np.random.default_rng(5)
    below = rng.random((1000, 3)) * tonemap.NEUTRAL_KNEE * 0.999
    np.testing.assert_array_equal(tonemap.neutral(below), below)
    above = rng.random((1000, 3)) + 0.01
    above *= (rng.random((1000, 1)) * 50 + 0.77) / above.max(-1, keepdims=True)
    y = tonemap.neutral(above)
    peak = above.max(-1)
    k, d = tonemap.NEUTRAL_KNEE, 1 - tonemap.NEUTRAL_KNEE
    new_peak = 1 - d * d / (peak + d - k)            # Khronos PBR Neutral, by hand
    g = 1 - 1 / (tonemap.NEUTRAL_DESATURATION * (peak - new_peak) + 1)
    expected = (1 - g)[:, None] * above * (new_peak / peak)[:, None] + (g * new_peak)[:, None]
    np.testing.assert_allclose(y, expected, rtol=1e-12)
    # the peak channel lands on the compressed peak, below 1, and order is kept
    np.testing.assert_allclose(y.max(-1), new_peak, rtol=1e-12)
    assert y.max() < 1.0
    np.testing.assert_array_equal(np.argsort(y, -1), np.argsort(above, -1))
    # continuous with slope 1 at the knee (the compressed peak's derivative there is 1)
    eps = 1e-6
    np.testing.assert_allclose(tonemap.neutral(grey([k + eps]))[0, 0], k + eps, atol=1e-10)


def test_filmic_is_narkowicz_2015():
    # values of x(2.51x+0.03)/(x(2.43x+0.59)+0.14) computed by hand
    x = np.array([0.18, 1.0])
    expected = np.array([0.18 * (2.51 * 0.18 + 0.03) / (0.18 * (2.43 * 0.18 + 0.59) + 0.14),
                         2.54 / 3.16])
    np.testing.assert_allclose(tonemap.filmic(x), expected, rtol=1e-12)
    assert tonemap.filmic(np.array(7.3)) == 1.0  # the curve crosses 1 at x ≈ 7.24


@pytest.mark.parametrize("name", list(tonemap.TONEMAPS))
def test_every_tonemap_zero_to_zero_monotone_bounded(name):
    op = tonemap.TONEMAPS[name]
    y = op(grey(X))
    assert np.all(y == y[:, :1])                        # grey stays grey
    y = y[:, 0]
    assert y[0] == 0.0
    assert np.all(np.diff(y) >= 0.0)
    assert np.all((y >= 0.0) & (y <= 1.0))
    # negative (out-of-gamut) linear values become 0, NaN never comes out for finite input
    assert op(grey([-1.0, -1e6])).tolist() == [[0.0] * 3] * 2
    # broadcasts over leading axes (STYLE 6)
    np.testing.assert_array_equal(op(grey(np.tile(X[:6], (2, 1)))),
                                  grey(np.tile(y[:6], (2, 1))))


def test_display_chain_and_exposure():
    xyz = np.array([[[0.2, 0.3, 0.1], [0.95047, 1.0, 1.08883]]])
    lin = tonemap.xyz_to_linear(xyz)
    assert lin.dtype == np.float32
    np.testing.assert_allclose(lin, xyz_to_linear_srgb(xyz), rtol=1e-6)
    # D65 white (Y = 1) is linear sRGB (1, 1, 1) (IEC matrix, no adaptation)
    np.testing.assert_allclose(lin[0, 1], 1.0, atol=1e-3)
    out = tonemap.xyz_to_display(xyz, exposure=0.0, tonemap="clip")
    assert out.dtype == np.uint8 and out.shape == (1, 2, 3)
    np.testing.assert_array_equal(out, np.round(srgb_encode(np.clip(lin, 0, 1)) * 255))
    # +1 stop doubles the linear value before the tone map
    half = tonemap.display(np.full((1, 1, 3), 0.1), exposure=1.0, tonemap="reinhard")
    assert half[0, 0, 0] == np.round(srgb_encode(0.2 / 1.2) * 255)
    # white at 0 stops under clip is 255; black is 0
    assert tonemap.display(np.ones((1, 1, 3)), 0.0, "clip").tolist() == [[[255] * 3]]
    assert tonemap.display(np.zeros((1, 1, 3)), 5.0, "filmic").tolist() == [[[0] * 3]]


def test_display_counts_out_of_gamut_and_clipped_pixels():
    lin = np.array([[[0.5, 0.2, -0.01], [2.0, 0.5, 0.5], [0.3, 0.3, 0.3], [-1e-6, 0.2, 0.2],
                     [9.0, 9.0, 9.0]]], np.float32)
    png, masks = tonemap.display(lin, 0.0, "none", counts=True)
    np.testing.assert_array_equal(png, tonemap.display(lin, 0.0, "none"))
    # −0.01 is outside sRGB; −1e-6 is matrix round-off (within GAMUT_TOLERANCE)
    assert masks["out_of_gamut"].tolist() == [[True, False, False, False, False]]
    assert masks["clipped"].tolist() == [[False, True, False, False, True]]
    # neutral compresses instead of clipping; filmic reaches 1 above x ≈ 7.24 only
    assert not tonemap.display(lin, 0.0, "neutral", counts=True)[1]["clipped"].any()
    assert tonemap.display(lin, 0.0, "filmic", counts=True)[1]["clipped"].tolist() == [
        [False, False, False, False, True]]


@pytest.mark.parametrize("name", list(tonemap.TONEMAPS))
def test_display_table_is_within_one_code_of_the_exact_encoding(name):
    """The 2^16-entry encoding table (tonemap.ENCODE_TABLE_SIZE) against the IEC transfer
    function evaluated in float64: at most one code off, and rarely (< 1 % of values)."""
    x = np.concatenate([[0.0], np.geomspace(1e-7, 50.0, 300000)])
    exact = np.round(srgb_encode(tonemap.TONEMAPS[name](grey(x))[:, 0]) * 255).astype(int)
    got = tonemap.display(np.repeat(x[:, None], 3, axis=1), 0.0, name)[:, 0].astype(int)
    diff = np.abs(got - exact)
    assert diff.max() <= 1 and np.mean(diff > 0) < 0.01
    assert got[0] == 0 and np.all(np.diff(got) >= 0)  # monotone, black stays black


def test_display_masks_and_guard_on_in_range_and_non_finite_frames():
    """Masks come from two reductions when nothing reaches their bounds, and a NaN or inf
    value (never in a valid frame) is shown black, the rest as without it."""
    rng = np.random.default_rng(3)
    lin = rng.uniform(0.0, 0.99, (4, 5, 3)).astype(np.float32)
    png, masks = tonemap.display(lin, 0.0, "clip", counts=True)
    assert not masks["out_of_gamut"].any() and not masks["clipped"].any()
    np.testing.assert_array_equal(png, np.round(srgb_encode(lin.astype(float)) * 255))
    bad = lin.copy()
    bad[1, 2] = [np.nan, np.inf, -np.inf]
    out = tonemap.display(bad, 0.0, "clip")
    assert out[1, 2].tolist() == [0, 0, 0]
    keep = np.ones((4, 5), bool)
    keep[1, 2] = False
    np.testing.assert_array_equal(out[keep], png[keep])
