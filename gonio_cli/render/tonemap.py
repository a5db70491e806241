"""XYZ → display: linear sRGB, exposure, a tone map, the sRGB transfer function, 8 bits.

docs/conventions.md: linear sRGB from XYZ by the IEC 61966-2-1 matrix, after the chromatic
adaptation that maps the scene's white to D65 (:data:`ADAPTATIONS`, default ``bradford``);
the EXR holds that linear sRGB before any exposure; the PNG is 8-bit, sRGB-encoded after
exposure and tone mapping. Tone maps take linear values (..., 3) (negative linear sRGB,
i.e. colours outside the sRGB gamut, are clipped to 0 first; :func:`display` counts
them) and return display-linear values in [0, 1]:

- ``neutral`` (the default): hue-preserving. The identity while the pixel's peak channel
  p = max(R, G, B) is below the knee k = 0.76; above it the pixel is scaled by p'/p with
  p' = 1 − (1 − k)² / (p − 2k + 1) (the peak compressed smoothly toward 1, with slope 1
  at the knee), then mixed toward the grey p' (1, 1, 1) by g = 1 − 1 / (δ (p − p') + 1),
  δ = 0.05. Scaling all channels by one factor keeps their ratios, hence chromaticity and
  CIELAB hue; the small mix toward grey whitens very bright pixels and turns their CIELAB
  hue by a few degrees at most. This is the compression of the Khronos PBR Neutral tone
  mapper (Khronos Group, "PBR Neutral Specification", 2024) without its toe and with a
  third of its desaturation (:data:`NEUTRAL_DESATURATION` says why): Khronos subtracts up
  to 0.04 from every channel to cancel the 4 % Fresnel floor of product shots, which would
  darken a proof's dark inks; here pixels below the knee are left exactly as they are.
- ``none``: min(x, 1) per channel (linear values clipped; the run report counts the
  clipped pixels). ``clip`` is the same operator under its older name.
- ``reinhard``: x / (1 + x), the simple global operator of Reinhard et al. 2002,
  "Photographic tone reproduction for digital images", eq. 3 (applied per channel).
- ``filmic``: the ACES filmic curve as fitted by K. Narkowicz, "ACES Filmic Tone Mapping
  Curve" (2015): x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14), clipped to [0, 1]. It is
  monotone for x ≥ 0 (the numerator of its derivative is 1.408 x² + 0.7028 x + 0.0042)
  and reaches 1 at x ≈ 7.24.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..names import pick
from ..spectra import (chromatic_adaptation_matrix, rgb_space_chromaticities,
                       rgb_space_matrix, rgb_space_white_xyz, spectrum_to_xyz, srgb_encode,
                       srgb_white_xyz, xyz_to_linear_srgb)


def clip(x: np.ndarray) -> np.ndarray:
    """Display value min(max(x, 0), 1)."""
    return np.clip(x, 0, 1)


def reinhard(x: np.ndarray) -> np.ndarray:
    """Reinhard et al. 2002 eq. 3 per channel: x / (1 + x), x ≥ 0."""
    x = np.maximum(x, 0)
    return x / (1 + x)


#: Narkowicz 2015 coefficients of the fitted ACES curve.
ACES_A, ACES_B, ACES_C, ACES_D, ACES_E = 2.51, 0.03, 2.43, 0.59, 0.14


def filmic(x: np.ndarray) -> np.ndarray:
    """Narkowicz 2015 ACES fit: x(a x + b) / (x(c x + d) + e), clipped to [0, 1]."""
    x = np.maximum(x, 0)
    t = x.dtype.type if isinstance(x, np.ndarray) and x.dtype.kind == "f" else float
    a, b, c, d, e = (t(k) for k in (ACES_A, ACES_B, ACES_C, ACES_D, ACES_E))
    return np.clip(x * (a * x + b) / (x * (c * x + d) + e), 0, 1)


#: Khronos PBR Neutral: the peak channel value where compression starts (0.8 − 0.04; the
#: Khronos toe that the 0.04 stands for is not applied, so the knee is kept where Khronos
#: has it in display terms).
NEUTRAL_KNEE = 0.76
#: How fast pixels compressed far above the knee blend toward white: a third of Khronos's
#: 0.15. CIELAB hue is not constant along a straight line to white in linear sRGB, so the
#: blend turns hue; measured over the sample inks' mirror spectra (peak 0.7, scaled
#: × 0.5–4, tests/test_render_proof.py): at 0.15 the red ink turns 7.6° toward yellow, at
#: 0.05 3.9° (green 0.8°, blue 2.3°); at 0 no hue turns but highlights never whiten.
NEUTRAL_DESATURATION = 0.05


def neutral(x: np.ndarray) -> np.ndarray:
    """Hue-preserving compression (Khronos PBR Neutral without its toe) of (..., 3) x ≥ 0.

    Identity where max(x) < :data:`NEUTRAL_KNEE`; above, x · p'/p mixed toward p' (1, 1, 1)
    (module docstring). Output in [0, 1), monotone in a uniform scale of x.
    """
    x = np.maximum(x, 0)                                  # a new array: changed in place
    t = x.dtype.type if x.dtype.kind == "f" else np.float64
    x = x.astype(t, copy=False)
    k, desat, one, zero = t(NEUTRAL_KNEE), t(NEUTRAL_DESATURATION), t(1.0), t(0.0)
    # per pixel, not per channel (a reduction over a 3-long last axis is slow in numpy)
    peak = np.maximum(np.maximum(x[..., 0], x[..., 1]), x[..., 2])
    below = peak < k
    if below.all():
        return x
    p = np.maximum(peak, k)
    d = one - k
    new_peak = one - d * d / (p + (d - k))
    g = one - one / (desat * (p - new_peak) + one)
    # mix(x · p'/p, p' (1, 1, 1), g) = x · (1 − g) p'/p + g p'; exactly x below the knee
    x *= np.where(below, one, (one - g) * new_peak / p)[..., None]
    x += np.where(below, zero, g * new_peak)[..., None]
    return x


#: Tone maps by name (STYLE 3): display-linear (..., 3) in [0, 1] from scene-linear
#: (..., 3) x ≥ 0. The first is the default.
TONEMAPS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "neutral": neutral,
    "none": clip,
    "clip": clip,
    "reinhard": reinhard,
    "filmic": filmic,
}
#: The display transform of a scene that names none: hue-preserving (module docstring).
DEFAULT_TONEMAP = "neutral"


def get_tonemap(name: str) -> Callable[[np.ndarray], np.ndarray]:
    """The tone map called ``name``; an unknown name gets the list of valid ones."""
    return pick(TONEMAPS, name, "tone map")


def _von_kries(method: str) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    def matrix(white_src_xyz, white_dst_xyz):
        return chromatic_adaptation_matrix(white_src_xyz, white_dst_xyz, method)
    return matrix


def _no_adaptation(white_src_xyz, white_dst_xyz) -> np.ndarray:
    return np.eye(3)


#: Chromatic adaptations by name (STYLE 3): (scene white XYZ, display white XYZ) → (3, 3)
#: matrix on XYZ. The von Kries transforms of :data:`gonio_cli.spectra.CAT_MATRICES`, and
#: ``none``, which shows the light's colour as a colorimeter would see it.
ADAPTATIONS: dict[str, Callable[[np.ndarray, np.ndarray], np.ndarray]] = {
    "bradford": _von_kries("bradford"),
    "cat16": _von_kries("cat16"),
    "none": _no_adaptation,
}
#: The default adaptation: Bradford, the transform ICC colour management (ICC.1 Annex E),
#: and so the proofing chains built on it, use. CAT16 is the choice for CIECAM16 work; on
#: the sample print under A the two differ by mean CIEDE2000 0.9 (99th percentile 2.8),
#: against 14 (28) between adapted and unadapted.
DEFAULT_ADAPTATION = "bradford"
#: The colour EXR's adaptation unless asked (``gonio render --exr-adapt``): none. The EXR
#: is scene-referred (docs/conventions.md, "Light and colour": linear sRGB with no
#: chromatic adaptation unless asked for): the light's colour stays in it, as in a
#: colorimeter's reading; the display's adaptation is the PNG's (``--adapt``).
DEFAULT_EXR_ADAPTATION = "none"


def get_adaptation(name: str) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """The adaptation called ``name``; an unknown name gets the list of valid ones."""
    return pick(ADAPTATIONS, name, "chromatic adaptation")


def scene_white_xyz(lights, grid_nm, target) -> np.ndarray | None:
    """The white the viewer adapts to: XYZ (3,), Y = 1, of the lights' summed spectra.

    Each light's spectrum S (Σ S ȳ / Σ ȳ = 1) weighted by the irradiance it gives at normal
    incidence: E of a directional light, I / d² of a point light at the distance d from
    the camera's ``target`` (3,). None when there is no light with power (a scene lit
    only by an environment map, whose linear sRGB already has the display's white).
    """
    total = np.zeros(3)
    for light in lights:
        if light.kind == "directional":
            weight = light.irradiance
        else:
            d2 = float(np.sum((np.asarray(light.position, float) - target) ** 2))
            weight = light.intensity / max(d2, MIN_DISTANCE_SQ)
        total += weight * spectrum_to_xyz(light.spectrum, grid_nm)
    if not total[1] > 0:
        return None
    return total / total[1]


def scene_white(scene) -> np.ndarray | None:
    """The white of a :class:`~gonio_cli.render.scene.Scene`, XYZ (3,) with Y = 1: its
    lights' irradiance-weighted spectra (:func:`scene_white_xyz`); None without lights."""
    return scene_white_xyz(scene.lights, scene.grid_nm, scene.camera.target)


#: Squared distance floor (scene units²) for a point light sitting on the camera target:
#: its weight stays finite and it then dominates the white, as it dominates the image.
MIN_DISTANCE_SQ = 1e-12


def xyz_to_linear_matrix(adapt: str = DEFAULT_ADAPTATION,
                         white_xyz: np.ndarray | None = None) -> np.ndarray:
    """(3, 3): XYZ → linear sRGB after adapting ``white_xyz`` (the scene white) to the
    display white (:func:`gonio_cli.spectra.srgb_white_xyz`, D65). No white: no adaptation."""
    return xyz_to_exr_matrix("srgb", adapt, white_xyz)


@dataclass(frozen=True)
class ExrSpace:
    """A colour space of the colour EXR (``gonio render --exr-space``).

    Attributes
    ----------
    matrix : () → (3, 3), XYZ as seen under the display white (after ``--adapt``: D65)
        → the EXR's three channels.
    chromaticities : () → 8 floats, CIE xy of R, G, B and white for the EXR header's
        ``chromaticities`` attribute (OpenEXR's order).
    channels : the channel names in the file.
    help : what the file then holds.
    """

    matrix: Callable[[], np.ndarray]
    chromaticities: Callable[[], tuple]
    channels: tuple[str, str, str]
    help: str


def _rgb_space(key: str) -> Callable[[], np.ndarray]:
    def matrix():
        m = rgb_space_matrix(key)
        white = rgb_space_white_xyz(key)
        if np.allclose(white, srgb_white_xyz(), rtol=0, atol=1e-9):
            return m
        # the display white (D65) to the space's white: Bradford, as the ACES
        # reference transforms convert Rec. 709 / sRGB to ACES
        return m @ chromatic_adaptation_matrix(srgb_white_xyz(), white, "bradford")
    return matrix


def _chromaticities(key: str) -> Callable[[], tuple]:
    def chromaticities():
        return rgb_space_chromaticities(key)
    return chromaticities


#: OpenEXR's ``chromaticities`` for CIE XYZ data (OpenEXR, "Technical Introduction":
#: red (1, 0), green (0, 1), blue (0, 0), white (1/3, 1/3)).
XYZ_CHROMATICITIES = (1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0 / 3.0, 1.0 / 3.0)

#: Colour spaces of the colour EXR by name (STYLE 3). Every one holds the same colours
#: (the XYZ after ``--adapt``), so they differ only by a 3 × 3 matrix; the matrices come
#: from colour-science's tables (:func:`gonio_cli.spectra.rgb_space_matrix`). The first
#: is the default (docs/conventions.md).
EXR_SPACES: dict[str, ExrSpace] = {
    "srgb": ExrSpace(_rgb_space("srgb"), _chromaticities("srgb"), ("R", "G", "B"),
                     "linear sRGB (IEC 61966-2-1 primaries, D65 white); colours outside "
                     "sRGB have negative channels"),
    "xyz": ExrSpace(lambda: np.eye(3), lambda: XYZ_CHROMATICITIES, ("X", "Y", "Z"),
                    "CIE 1931 XYZ (2°), never negative"),
    "acescg": ExrSpace(_rgb_space("acescg"), _chromaticities("acescg"), ("R", "G", "B"),
                       "linear ACEScg (AP1 primaries, ACES white; Bradford from D65), "
                       "holds nearly every surface colour"),
}
DEFAULT_EXR_SPACE = "srgb"


def get_exr_space(name: str) -> ExrSpace:
    """The EXR colour space called ``name``; an unknown name gets the list of valid ones."""
    return pick(EXR_SPACES, name, "EXR colour space")


def xyz_to_exr_matrix(space: str = DEFAULT_EXR_SPACE, adapt: str = DEFAULT_ADAPTATION,
                      white_xyz: np.ndarray | None = None) -> np.ndarray:
    """(3, 3): XYZ → the EXR's channels in ``space`` (:data:`EXR_SPACES`), after adapting
    ``white_xyz`` (the scene white) to the display white as :func:`xyz_to_linear_matrix`."""
    m = get_exr_space(space).matrix()
    if white_xyz is None:
        return m
    return m @ get_adaptation(adapt)(white_xyz, srgb_white_xyz())


def xyz_to_linear(xyz: np.ndarray, matrix: np.ndarray | None = None) -> np.ndarray:
    """XYZ (..., 3) → linear sRGB (..., 3) float32 (what the EXR holds); ``matrix`` from
    :func:`xyz_to_linear_matrix` (default: the IEC matrix, no adaptation)."""
    if matrix is None:
        return xyz_to_linear_srgb(xyz).astype(np.float32)
    return (np.asarray(xyz, dtype=float) @ matrix.T).astype(np.float32)


#: Entries of the 8-bit sRGB encoding table over display-linear [0, 1]: with 2^16 steps
#: a value lands on the code :func:`gonio_cli.spectra.srgb_encode` gives, except within
#: half a step (1/131070) of a rounding threshold, where it may be one code off (measured:
#: 0.3 % of the values of a random HDR image, never more than one code), at a fraction
#: of the cost of the power function per pixel.
ENCODE_TABLE_SIZE = 1 << 16


@functools.lru_cache(maxsize=1)
def encode_table() -> np.ndarray:
    """round(255 · srgb_encode(k / (N − 1))), k = 0 … N − 1: (N,) uint8."""
    y = np.arange(ENCODE_TABLE_SIZE) / (ENCODE_TABLE_SIZE - 1)
    return np.round(srgb_encode(y) * 255.0).astype(np.uint8)


#: A linear sRGB channel below −this is outside the display's gamut: float32 round-off of
#: the XYZ → sRGB matrix on an in-gamut colour is ~1e-7 of its size, and 1e-4 is a 30th
#: of the smallest 8-bit step above 0, so only real excursions are flagged.
GAMUT_TOLERANCE = 1e-4


def display(linear_srgb: np.ndarray, exposure: float = 0.0, tonemap: str = DEFAULT_TONEMAP,
            *, counts: bool = False):
    """Linear sRGB (..., 3) → 8-bit sRGB-encoded (..., 3) uint8.

    ``exposure``: stops; values are multiplied by 2^exposure before the tone map. The
    tone map runs in float32 (display values need ~1e-4, float32 gives 6e-8); the sRGB
    transfer function is read from :func:`encode_table`.

    With ``counts``, returns (uint8 image, masks): ``out_of_gamut`` (...) bool — a channel
    below −:data:`GAMUT_TOLERANCE`, a colour outside sRGB (shown with that channel at 0);
    ``clipped`` (...) bool — a channel above 1 after exposure that the tone map left at 1
    (``none``: every such pixel; ``filmic`` above x ≈ 7.24; never for ``neutral`` and
    ``reinhard``, which compress).
    """
    op = get_tonemap(tonemap)
    x = np.multiply(linear_srgb, np.float32(2.0 ** float(exposure)), dtype=np.float32)
    with np.errstate(over="ignore", invalid="ignore"):
        finite = np.isfinite(x.sum())
    if not finite:                  # never for a valid frame (a sum of finite values that
        x[~np.isfinite(x)] = 0.0    # overflows only costs this mask); guards the cast
    y = op(x)
    masks = None
    if counts:
        def any_channel(a):                     # faster than .any(-1) over 3 channels
            return a[..., 0] | a[..., 1] | a[..., 2]
        low = np.float32(-GAMUT_TOLERANCE * 2.0 ** float(exposure))
        none = np.zeros(x.shape[:-1], bool)
        # the masks only where some value reaches their bounds (two reductions otherwise)
        masks = {"out_of_gamut": any_channel(x < low) if x.min() < low else none,
                 "clipped": (any_channel((y >= 1.0) & (x > 1.0))
                             if x.max() > 1.0 and y.max() >= 1.0 else none.copy())}
    # y is x or a new array: both this function's own, so the rest works in place
    y = np.clip(y, 0.0, 1.0, out=y if y.dtype == np.float32 else None)
    y *= np.float32(ENCODE_TABLE_SIZE - 1)
    y += np.float32(0.5)
    png = encode_table()[y.astype(np.intp)]
    return (png, masks) if counts else png


def xyz_to_display(xyz: np.ndarray, exposure: float = 0.0, tonemap: str = DEFAULT_TONEMAP
                   ) -> np.ndarray:
    """XYZ → linear sRGB → exposure → tone map → sRGB encode → uint8 (docs/conventions.md)."""
    return display(xyz_to_linear(xyz), exposure, tonemap)

