"""Sparkles of metallic paint: the 8-bit packed sparkle texture (seed 004 §6, eqs. 15–16)
and its rendering term (seed 004 §6.1, eq. 17). Pure numpy; the shells are
:mod:`gonio_cli.commands.sparkle` (``gonio sparkle``) and :mod:`gonio_cli.render.shade`.

Measurement (seed 004 §6): the camera looks along the sample normal, the light moves in
the plane at angles of incidence θi. A mirror flake lights up when its normal is the half
vector, i.e. tilted by θh = θi / 2 (eq. 15) from the mean normal. Each photo's brightest
pixels become a bitmap b_k and the bitmaps are packed into one byte per pixel,

    t(x, y) = Σ_k b_k(x, y) 2^k                                            (eq. 16)

with bit k for the k-th angle in *decreasing* θi, as the seed writes it: θi = 70 − 10k,
θh = 35 − 5k for θi ∈ {10, …, 70} (bit 0 ↔ 70°, bit 6 ↔ 10°). Other angle sets (≤ 8)
follow the same order; the angles of each bit travel with the texture (PNG metadata
``gonio:theta_i_deg``, :data:`SEED_THETA_I_DEG` when absent).

Segmentation (:data:`SEGMENTATION_RULES`): the brightness of a photo is the mean of its
colour channels as stored. The default rule ``"mad"`` keeps pixels above
median + k · σ, σ = 1.4826 · MAD (the median absolute deviation, the normal-consistent
robust spread) with k = :data:`DEFAULT_MAD_K`: sparkles are a few bright outliers on a
dim, noisy background, so the median and MAD describe the background alone, where
mean + k · std would be pulled up by the sparkles themselves. ``"percentile"`` keeps the
top p % instead (a fixed sparkle density, for photos without a clean background).

Rendering (seed 004 eq. 17): with α = arccos(N·H), the sparkle at (x, y) answers with the
set bit whose θh is nearest α, attenuated as

    term = (cos(α − θh))^e,    e = 24 (the seed's value), 0 where no bit is set.

Since cos^e decreases with |α − θh|, that is the largest cos^e over the set bits.
:func:`sparkle_term` finds the nearest set θh from a table over (texel value, α)
(:class:`SparkleTable`, exact to round-off); ``exact=True`` loops over the bits instead
(the definition, for checking).

Minification: the texture is point-sampled (nearest texel, repeat wrap, OpenGL v). A
sparkle is a sub-pixel glint, so filtering the bits would smear it into a dim glow; a
point sample at each supersample is an unbiased estimate of the footprint's average term,
so supersampling (``ssaa``) averages sparkles correctly and only the noise (flicker under
animation) grows when a pixel covers many texels. The shell reports how many samples were
minified (footprint above one texel).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from .errors import InputError
from .names import pick

#: Bits of the packed texture (eq. 16 packs into one byte).
N_BITS = 8
#: The seed's angles of incidence in bit order: bit k ↔ θi = 70 − 10k (§6).
SEED_THETA_I_DEG = (70.0, 60.0, 50.0, 40.0, 30.0, 20.0, 10.0)
#: Schema of the texture's PNG metadata (``gonio:schema``), written by ``gonio sparkle``.
TEXTURE_SCHEMA = "gonio.sparkle-texture"
TEXTURE_VERSION = 1
#: The seed's sparkle exponent e of eq. 17.
DEFAULT_EXPONENT = 24.0
#: k of the "mad" rule: 5 σ of Gaussian noise is exceeded by 3e-7 of background pixels
#: (≈ 0 false sparkles in a 233² crop, the seed's size), while a lit mirror flake is far
#: brighter than 5 σ of any usable photo.
DEFAULT_MAD_K = 5.0
#: p of the "percentile" rule: keep the brightest 1 % of pixels.
DEFAULT_PERCENT = 1.0
#: 1.4826 · MAD estimates σ of normal noise (1 / Φ⁻¹(3/4)).
MAD_TO_SIGMA = 1.482602218505602
#: Floor of σ in the "mad" rule: half an 8-bit step. A noise-free synthetic photo has
#: MAD = 0, and then anything above the background by more than k/2 steps is a sparkle.
MIN_SIGMA = 0.5 / 255.0
#: Entries over α ∈ [0, π/2] of :class:`SparkleTable` (4 MB for 256 texel values): the
#: step π / 4096 must be finer than the spacing of the angles (the seed's: 5°).
TABLE_SIZE = 2049
#: θh stored for a texel with no bit set: cos(α − 3π) = −cos α ≤ 0 for α ∈ [0, π/2],
#: so the clipped term is 0 without a test per pixel.
NO_SPARKLE_RAD = 3.0 * np.pi


# ----------------------------------------------------------------------- segmentation --

def _brightness(photo: np.ndarray) -> np.ndarray:
    a = np.asarray(photo, dtype=np.float64)
    if a.ndim == 3:
        a = a[..., :3].mean(axis=-1) if a.shape[2] != 2 else a[..., 0]   # drop alpha
    return a


def segment_mad(photo: np.ndarray, k: float = DEFAULT_MAD_K) -> tuple[np.ndarray, float]:
    """Pixels brighter than median + k · max(1.4826 · MAD, :data:`MIN_SIGMA`).

    Returns the (H, W) bool bitmap and the threshold (in the photo's units)."""
    y = _brightness(photo)
    med = float(np.median(y))
    sigma = max(MAD_TO_SIGMA * float(np.median(np.abs(y - med))), MIN_SIGMA)
    threshold = med + k * sigma
    return y > threshold, threshold


def segment_percentile(photo: np.ndarray, p: float = DEFAULT_PERCENT
                       ) -> tuple[np.ndarray, float]:
    """The brightest ``p`` % of pixels (strictly above the (100 − p)-th percentile)."""
    y = _brightness(photo)
    threshold = float(np.percentile(y, 100.0 - p))
    return y > threshold, threshold


#: Segmentation rules (STYLE 3): name → (function, name of its parameter, default).
SEGMENTATION_RULES: dict[str, tuple[Callable, str, float]] = {
    "mad": (segment_mad, "k", DEFAULT_MAD_K),
    "percentile": (segment_percentile, "p", DEFAULT_PERCENT),
}


#: The range of each rule's parameter: k ≥ 0 standard deviations above the median (above
#: 1000 no pixel of an 8- or 16-bit photo qualifies); p in (0, 100] percent.
RULE_PARAMETER_RANGES: dict[str, tuple[float, float]] = {"mad": (0.0, 1e3),
                                                         "percentile": (0.0, 100.0)}


def get_rule(name: str):
    return pick(SEGMENTATION_RULES, name, "segmentation rule")


# -------------------------------------------------------------------------- packing --

def bit_order(theta_i_deg: Sequence[float]) -> np.ndarray:
    """Indices of the angles in bit order (decreasing θi: bit 0 is the largest, §6).

    Validates: 1 to 8 distinct finite angles in (0, 90) degrees."""
    t = np.asarray(theta_i_deg, dtype=float).reshape(-1)
    if t.size == 0 or t.size > N_BITS:
        raise InputError(f"{t.size} angles of incidence; a sparkle texture holds 1 to "
                         f"{N_BITS} (one bit each, eq. 16)")
    if not np.all(np.isfinite(t)) or np.any(t <= 0) or np.any(t >= 90):
        raise InputError(f"angles of incidence {t.tolist()} must be in (0, 90) degrees")
    if np.unique(t).size != t.size:
        raise InputError(f"angles of incidence {t.tolist()} repeat a value",
                         fix="give one photo per angle")
    return np.argsort(-t, kind="stable")


def pack_bits(bitmaps: np.ndarray) -> np.ndarray:
    """Eq. 16: (n_bits, H, W) bool → (H, W) uint8 t = Σ_k b_k 2^k."""
    b = np.asarray(bitmaps, dtype=bool)
    if b.ndim != 3 or b.shape[0] > N_BITS:
        raise InputError(f"bitmaps of shape {b.shape}: expected (≤ {N_BITS}, H, W)")
    t = np.zeros(b.shape[1:], dtype=np.uint8)
    for k in range(b.shape[0]):
        t |= b[k].astype(np.uint8) << np.uint8(k)
    return t


def unpack_bits(texture: np.ndarray, n_bits: int = N_BITS) -> np.ndarray:
    """Inverse of :func:`pack_bits`: (H, W) uint8 → (n_bits, H, W) bool."""
    t = np.asarray(texture, dtype=np.uint8)
    return np.stack([(t >> np.uint8(k)) & np.uint8(1) for k in range(n_bits)]).astype(bool)


def theta_h_deg(theta_i_deg: Sequence[float]) -> np.ndarray:
    """Eq. 15: θh = θi / 2, in the same order (degrees)."""
    return 0.5 * np.asarray(theta_i_deg, dtype=float)


@dataclass
class TextureResult:
    """What :func:`build_texture` made: ``texture`` (H, W) uint8 (eq. 16);
    ``theta_i_deg`` (n_bits,) the angle of each bit (decreasing); ``thresholds`` per bit;
    ``fraction`` of pixels set per bit; ``color`` (3,) mean colour of the segmented
    pixels as stored, normalised to a largest channel of 1 (an estimate of C_s)."""

    texture: np.ndarray
    theta_i_deg: list[float]
    rule: str
    parameter: float
    thresholds: list[float] = field(default_factory=list)
    fraction: list[float] = field(default_factory=list)
    color: list[float] = field(default_factory=lambda: [1.0, 1.0, 1.0])


def build_texture(photos: Sequence[np.ndarray], theta_i_deg: Sequence[float],
                  rule: str = "mad", parameter: float | None = None) -> TextureResult:
    """Seed 004 eqs. 15–16: photos at several angles of incidence → packed sparkle texture.

    Parameters
    ----------
    photos : n arrays (H, W) or (H, W, C), all the same H × W, values as stored.
    theta_i_deg : (n,) the angle of incidence of each photo, degrees, distinct, in (0, 90).
    rule : a key of :data:`SEGMENTATION_RULES`; ``parameter`` its k or p (None: default).

    Returns
    -------
    :class:`TextureResult`; ``texture`` (H, W) uint8, bit k for the k-th largest θi.
    """
    fn, _, default = get_rule(rule)
    parameter = default if parameter is None else float(parameter)
    lo, hi = RULE_PARAMETER_RANGES[rule]
    if not (lo <= parameter <= hi) or (rule == "percentile" and parameter == 0.0):
        raise InputError(f"--parameter {parameter:g} is outside the range of rule {rule!r} "
                         f"({'(' if rule == 'percentile' else '['}{lo:g}, {hi:g}])",
                         fix=f"give {SEGMENTATION_RULES[rule][1]} within it (default "
                             f"{default:g})")
    if len(photos) != len(theta_i_deg):
        raise InputError(f"{len(photos)} photos but {len(theta_i_deg)} angles of incidence",
                         fix="give one angle per photo, in the same order")
    order = bit_order(theta_i_deg)
    shapes = {np.shape(p)[:2] for p in photos}
    if len(shapes) != 1:
        raise InputError(f"the photos differ in size: {sorted(shapes)}",
                         fix="crop them to the same area (seed 004 crops to 233 × 233)")
    bitmaps, thresholds, colours = [], [], []
    for j in order:
        p = np.asarray(photos[j], dtype=np.float64)
        if not np.all(np.isfinite(p)):
            raise InputError(f"the photo at θi = {theta_i_deg[j]:g}° holds NaN or inf")
        b, thr = fn(p, parameter)
        bitmaps.append(b)
        thresholds.append(thr)
        if p.ndim == 3 and p.shape[2] >= 3 and b.any():
            colours.append(p[b][:, :3].sum(axis=0))
    texture = pack_bits(np.stack(bitmaps))
    color = [1.0, 1.0, 1.0]
    if colours:
        c = np.sum(colours, axis=0)
        if c.max() > 0:
            color = (c / c.max()).tolist()
    return TextureResult(texture, [float(theta_i_deg[j]) for j in order], rule, parameter,
                         thresholds, [float(b.mean()) for b in bitmaps], color)


# -------------------------------------------------------------------------- rendering --

def sample_texture(texture: np.ndarray, uv: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """Nearest-texel lookup of a (H, W) texture at uv (..., 2) → (...) uint8.

    Repeat addressing and OpenGL v (v = 0 the bottom row), as :mod:`gonio_cli.render.texture`;
    ``scale``: the texture repeats ``scale`` times over uv ∈ [0, 1]."""
    t = np.asarray(texture)
    h, w = t.shape
    uv = np.asarray(uv, dtype=np.float64)
    x = np.nan_to_num(uv[..., 0] * (scale * w), posinf=0.0, neginf=0.0)
    y = np.nan_to_num(uv[..., 1] * (scale * h), posinf=0.0, neginf=0.0)
    col = np.mod(x, w).astype(np.intp)                 # repeat; texel i covers [i, i + 1)
    row = (h - 1) - np.mod(y, h).astype(np.intp)       # OpenGL: v = 0 is the bottom row
    col = np.minimum(col, w - 1)                       # mod can round up to exactly w
    row = np.clip(row, 0, h - 1)
    return t[row, col]


class SparkleTable:
    """Eq. 17 through a table of the nearest set θh: for texel value t and
    α_j = j π / (2 (n − 1)), the θh of the bit set in t nearest to α_j, stored as its
    cosine and sine (θh = :data:`NO_SPARKLE_RAD` for t = 0).

    The nearest set θh is a step function of α that jumps only at midpoints between set
    angles, so for α in [α_j, α_j+1] it is the nearest to α_j or to α_j+1, and the term
    max(cos(α − θa), cos(α − θb))^e (cos^e falls with |α − θh|) is exact, kinks
    included, as long as set angles are more than one step (π / 4096 ≈ 0.04°) apart
    (the seed's are 5°). cos(α − θ) = cos α cos θ + sin α sin θ with cos α = N·H, so per
    pixel and light: four gathers, an arccos (for the index), one power; no loop over
    the bits and no cosine.

    theta_h_rad : (n_bits,) θh of each bit, radians; exponent : e > 0.
    """

    def __init__(self, theta_h_rad: Sequence[float], exponent: float = DEFAULT_EXPONENT,
                 size: int = TABLE_SIZE):
        th = np.asarray(theta_h_rad, dtype=float).reshape(-1)
        self.exponent = float(exponent)
        self.n = size - 1
        self.step = 0.5 * np.pi / self.n
        alpha = np.arange(size) * self.step
        angles = np.append(th, NO_SPARKLE_RAD)                     # index n_bits: none
        dist = np.abs(alpha - angles[:, None])                       # (n_bits + 1, size)
        nearest = np.full((256, size), th.size, dtype=np.intp)       # index into angles
        columns = np.arange(size)
        # t in [2^k, 2^(k+1)) is t − 2^k plus bit k: keep the nearer of the two, one
        # array operation per bit; bits without an angle are ignored (as the bit loop does)
        for k in range(N_BITS):
            lower = nearest[:1 << k]
            nearest[1 << k:2 << k] = lower if k >= th.size else np.where(
                dist[k] < dist[lower, columns], k, lower)
        # cos(α − θh) = cos α cos θh + sin α sin θh: store cos θh and sin θh, so a lookup
        # needs no cosine per pixel (N·H is cos α already)
        self.cos_theta_h = np.cos(angles)[nearest].reshape(-1)
        self.sin_theta_h = np.sin(angles)[nearest].reshape(-1)

    def __call__(self, t: np.ndarray, cos_nh: np.ndarray) -> np.ndarray:
        """Term (..., n_lights) for texel values t (...) and N·H (..., n_lights);
        N·H is clamped to [0, 1], NaN gives 0."""
        bad = np.isnan(cos_nh)
        c = np.clip(np.where(bad, 0.0, cos_nh), 0.0, 1.0)
        s = np.sqrt(1.0 - c * c)                                      # sin α
        j = np.minimum((np.arccos(c) * (1.0 / self.step)).astype(np.intp), self.n - 1)
        i = np.asarray(t, dtype=np.intp)[..., None] * (self.n + 1) + j
        a = c * np.take(self.cos_theta_h, i) + s * np.take(self.sin_theta_h, i)
        i += 1
        b = c * np.take(self.cos_theta_h, i) + s * np.take(self.sin_theta_h, i)
        np.maximum(a, b, out=a)
        np.clip(a, 0.0, 1.0, out=a)
        a[bad] = 0.0
        return a ** self.exponent


def sparkle_term_exact(t: np.ndarray, cos_nh: np.ndarray, theta_h_rad: Sequence[float],
                       exponent: float = DEFAULT_EXPONENT) -> np.ndarray:
    """Eq. 17 by a loop over the bits: the nearest set θh to α, then (cos(α − θh))^e.
    N·H is clamped to [0, 1], NaN gives 0."""
    bad = np.isnan(cos_nh)
    alpha = np.arccos(np.clip(np.where(bad, 0.0, cos_nh), 0.0, 1.0))
    t = np.asarray(t, dtype=np.uint8)[..., None]
    best = np.full(alpha.shape, np.inf)
    for k, th in enumerate(np.asarray(theta_h_rad, dtype=float).reshape(-1)):
        d = np.where((t >> np.uint8(k)) & np.uint8(1), np.abs(alpha - th), np.inf)
        best = np.minimum(best, d)
    found = np.isfinite(best) & ~bad
    return np.where(found, np.clip(np.cos(np.where(found, best, 0.0)), 0.0, 1.0) ** exponent,
                    0.0)


def sparkle_term(texture: np.ndarray, uv: np.ndarray, cos_nh: np.ndarray,
                 theta_h_rad: Sequence[float], exponent: float = DEFAULT_EXPONENT,
                 scale: float = 1.0, table: SparkleTable | None = None,
                 exact: bool = False) -> np.ndarray:
    """Seed 004 eq. 17 without C_s: (cos(α − θh))^e for the set bit nearest α = arccos N·H.

    Parameters
    ----------
    texture : (H, W) uint8, eq. 16 (bit k ↔ ``theta_h_rad[k]``).
    uv : (..., 2) texture coordinates (OpenGL v, repeat; × ``scale``), point-sampled.
    cos_nh : (..., n_lights) N·H per light.
    table : a :class:`SparkleTable` for these angles and exponent, to reuse (built if None).
    exact : loop over the bits instead of the table.

    Returns
    -------
    (..., n_lights) float64 in [0, 1]; 0 where no bit is set.
    """
    t = sample_texture(texture, uv, scale)
    if exact:
        return sparkle_term_exact(t, cos_nh, theta_h_rad, exponent)
    table = table if table is not None else SparkleTable(theta_h_rad, exponent)
    return table(t, cos_nh)


# --------------------------------------------------------------------- render object --

@dataclass
class SparkleTexture:
    """A sparkle texture ready to render (a scene object's ``sparkle``).

    texture : (H, W) uint8, eq. 16 ; theta_h_rad : (n_bits,) θh of bit k, radians ;
    exponent : e of eq. 17 ; scale : repeats over uv ∈ [0, 1] ; color : (3,) C_s as a
    linear-sRGB reflectance colour (1, 1, 1 = white) ; path : for messages.
    """

    texture: np.ndarray
    theta_h_rad: np.ndarray
    exponent: float = DEFAULT_EXPONENT
    scale: float = 1.0
    color: np.ndarray = field(default_factory=lambda: np.ones(3))
    path: str = ""
    _table: SparkleTable | None = field(default=None, repr=False)

    @property
    def table(self) -> SparkleTable:
        if self._table is None:
            self._table = SparkleTable(self.theta_h_rad, self.exponent)
        return self._table


def texture_from_image(pixels: np.ndarray, metadata: dict | None = None,
                       path: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Validate a decoded sparkle PNG: (H, W, 1) (or grey RGB) values k / 255 → the
    (H, W) uint8 texture and θh (radians) of each bit, from the file's
    ``theta_i_deg`` metadata (``gonio sparkle``) or else :data:`SEED_THETA_I_DEG`."""
    import json

    a = np.asarray(pixels, dtype=np.float64)
    if a.ndim == 3 and a.shape[2] in (3, 4) and np.array_equal(a[..., 0], a[..., 1]) \
            and np.array_equal(a[..., 0], a[..., 2]):
        a = a[..., :1]
    if a.ndim == 3 and a.shape[2] == 1:
        a = a[..., 0]
    if a.ndim != 2 or a.size == 0:
        raise InputError(f"a sparkle texture must be a one-channel image, not shape "
                         f"{np.shape(pixels)}", path=path,
                         fix="use the 8-bit PNG written by gonio sparkle")
    t = np.round(a * 255.0)
    if not np.all(np.isfinite(a)) or np.any(np.abs(t - a * 255.0) > 1e-3) \
            or t.min() < 0 or t.max() > 255:
        raise InputError("a sparkle texture must hold 8-bit values (eq. 16 packs bits into "
                         "one byte)", path=path, fix="save it as an 8-bit PNG")
    schema = (metadata or {}).get("schema")
    if schema is not None and schema != TEXTURE_SCHEMA:
        raise InputError(f"is a {schema}, not a sparkle texture", path=path,
                         fix="build one with gonio sparkle")
    angles = SEED_THETA_I_DEG
    if metadata and "theta_i_deg" in metadata:
        try:
            angles = [float(x) for x in json.loads(metadata["theta_i_deg"])]
        except (TypeError, ValueError):
            raise InputError(f"its gonio:theta_i_deg {metadata['theta_i_deg']!r} is not a "
                             "list of numbers", path=path) from None
        bit_order(angles)
    texture = t.astype(np.uint8)
    if int(texture.max()) >> len(angles):
        raise InputError(f"uses bit {int(texture.max()).bit_length() - 1} but names only "
                         f"{len(angles)} angles", path=path)
    return texture, np.radians(theta_h_deg(angles))
