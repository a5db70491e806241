"""``gonio halftone`` core: an image → binary, exclusive R/G/B ink masks (seed 000,
"Printing application" and Figure 6).

Structural-colour reflective inks are printed side by side on black substrate, at most
one ink per position. A halftone is therefore a *label image* (H, W) uint8 — 0 bare
substrate, 1 R, 2 G, 3 B — shown as an RGB mask whose channels are 0 or 1 with at most
one set per pixel (docs/conventions.md). Pipeline (pure numpy; :mod:`.run`, the stage as
a library call, reads and writes the files; the shell :mod:`gonio_cli.commands.halftone`
parses the options):

1. :func:`prepare`: linear light (:mod:`.coverage`), gamut mapping into the simplex
   r + g + b ≤ 1, optional resampling to print size;
2. :func:`halftone`: one of :data:`METHODS` (error diffusion in :mod:`.diffusion`, threshold
   screens in :mod:`.screens`);
3. :func:`summarize`: coverage per ink against the target (from numbers already at hand);
   :func:`evaluate` adds the tone error — the RMSE between the mask and the target, both
   blurred by a Gaussian of σ = 2 px (a viewer at reading distance no longer resolves the
   dots), which costs more than the halftone itself, so only a report asks for it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

import numpy as np

from ..errors import InputError
from ..names import pick
from . import coverage as _coverage
from . import diffusion, screens

#: Ink names in channel order (label k is ink k − 1).
INKS = ("red", "green", "blue")

#: RGB colour of each label (0 bare substrate black, 1 R, 2 G, 3 B), uint8 0/255: the
#: mask of docs/conventions.md is ``PALETTE[labels]``, and a paletted PNG of the labels
#: with this palette decodes to exactly that mask.
PALETTE = np.array([[0, 0, 0], [255, 0, 0], [0, 255, 0], [0, 0, 255]], dtype=np.uint8)
PALETTE.flags.writeable = False

#: σ (pixels) of the Gaussian that stands for the eye when judging tone ("a
#: viewer at reading distance"); blurring by 2 px averages ~25 pixels, enough to fuse
#: dispersed dots.
TONE_SIGMA_PX = 2.0

REPORT_SCHEMA = "gonio.halftone-report"
REPORT_SCHEMA_VERSION = 1
#: Schema of the masks' PNG metadata (``gonio:schema``), written by ``gonio halftone``.
MASK_SCHEMA = "gonio.halftone-mask"
MASK_SCHEMA_VERSION = 1


@dataclass(frozen=True)
class Parameter:
    """An integer option of a method: default, allowed range, whether it must be a power
    of two or a multiple of some step, and its help text (the CLI flag is ``--`` + name
    with ``-`` for ``_``)."""

    default: int
    lo: int
    hi: int
    help: str
    power_of_two: bool = False
    multiple_of: int = 1

    def check(self, name: str, value: int) -> int:
        flag = "--" + name.replace("_", "-")
        if self.power_of_two:
            screens.check_power_of_two(int(value), flag, self.lo, self.hi)
        else:
            screens.check_range(int(value), flag, self.lo, self.hi, self.multiple_of)
        return int(value)


@dataclass(frozen=True)
class Method:
    """A halftoning method of the registry :data:`METHODS`.

    ``run(coverage, **parameters)`` takes (H, W, 3) float coverage in the simplex and
    returns labels (H, W) uint8 and a dict of facts for the report. ``run_pixels(pixels,
    table, scale_limit, **parameters)``, where a method has it, does the same straight from
    stored 8-bit pixels for ``--gamut scale`` (see :func:`.diffusion.diffuse_pixels`) and
    also returns the out-of-gamut count and the coverage sum per ink.
    """

    name: str
    kind: str
    citation: str
    summary: str
    run: Callable[..., tuple[np.ndarray, dict]]
    parameters: Mapping[str, Parameter] = field(default_factory=dict)
    run_pixels: Callable[..., tuple[np.ndarray, int, np.ndarray, dict]] | None = None


def _error_diffusion(matrix: diffusion.DiffusionMatrix):
    def run(coverage: np.ndarray) -> tuple[np.ndarray, dict]:
        compile_time_s = diffusion.compile_kernel()
        return diffusion.diffuse(coverage, matrix), {"compile_time_s": compile_time_s,
                                                     "kernel": diffusion.kernel_status()}
    return run


def _bayer(coverage: np.ndarray, bayer_size: int) -> tuple[np.ndarray, dict]:
    ranks = screens.bayer_ranks(bayer_size)
    return screens.threshold_stack(coverage, screens.ranks_to_thresholds(ranks)), {}


def _clustered(coverage: np.ndarray, cell_size: int) -> tuple[np.ndarray, dict]:
    ranks = screens.clustered_dot_ranks(cell_size)
    return screens.threshold_stack(coverage, screens.ranks_to_thresholds(ranks)), {}


def _clustered_3x3(coverage: np.ndarray) -> tuple[np.ndarray, dict]:
    ranks = screens.clustered_ranks(screens.SEED_000_CELL_PX)
    return screens.threshold_stack(coverage, screens.ranks_to_thresholds(ranks)), {}


def _blue_noise(coverage: np.ndarray, mask_size: int) -> tuple[np.ndarray, dict]:
    ranks, source = screens.blue_noise_ranks(mask_size)
    return (screens.threshold_stack(coverage, screens.ranks_to_thresholds(ranks)),
            {"blue_noise_mask": source})


def _error_diffusion_pixels(matrix: diffusion.DiffusionMatrix):
    def run_pixels(pixels: np.ndarray, table: np.ndarray, scale_limit: float
                   ) -> tuple[np.ndarray, int, np.ndarray, dict]:
        compile_time_s = diffusion.compile_kernel()
        labels, outside, total = diffusion.diffuse_pixels(pixels, table, scale_limit, matrix)
        return labels, outside, total, {"compile_time_s": compile_time_s,
                                        "kernel": diffusion.kernel_status()}
    return run_pixels


def _diffusion_method(matrix: diffusion.DiffusionMatrix, summary: str) -> Method:
    return Method(matrix.name, "error diffusion", matrix.citation, summary,
                  _error_diffusion(matrix), run_pixels=_error_diffusion_pixels(matrix))


#: Every method by name; drives both :func:`halftone` and the CLI's ``--method``.
METHODS: dict[str, Method] = {m.name: m for m in (
    _diffusion_method(diffusion.FLOYD_STEINBERG,
                      "vector error diffusion, 4 neighbours, serpentine scan"),
    _diffusion_method(diffusion.JARVIS,
                      "vector error diffusion, 12 neighbours over 3 rows, serpentine scan"),
    _diffusion_method(diffusion.STUCKI,
                      "vector error diffusion, 12 neighbours (sharper weights), serpentine"),
    Method("bayer", "ordered dither", "Bayer 1973, IEEE ICC 26-11..26-15",
           "recursive dispersed-dot threshold matrix", _bayer,
           {"bayer_size": Parameter(8, 2, 64, "Bayer matrix size (power of two).",
                                    power_of_two=True)}),
    Method("clustered", "ordered dither",
           "Ulichney 1987, Digital Halftoning (MIT Press); ISO 32000-1 Table 130, Round",
           "round dots on a 45° lattice growing from their centres (R core, G and B "
           "rings), in a supercell of ≥ 1024 levels",
           _clustered,
           {"cell_size": Parameter(8, 4, 32, "Clustered-dot cell in pixels, even: dots "
                                             "every N px across and down plus one at each "
                                             "cell centre (45°, N/√2 px apart, N²/2 "
                                             "pixels per dot).", multiple_of=2)}),
    Method("clustered-3x3", "ordered dither", "seed 000, Printing application (3 × 3 example)",
           "seed 000's illustration: one 3 × 3 cell growing from its centre, 10 levels "
           "per ink (steps of 1/9)",
           _clustered_3x3),
    Method("blue-noise", "ordered dither", "Ulichney 1993, Proc. SPIE 1913, 332-343",
           "void-and-cluster blue-noise threshold mask (generated once, cached)",
           _blue_noise,
           {"mask_size": Parameter(64, 8, 256, "Void-and-cluster mask size in pixels.")}),
)}


def get_method(name: str) -> Method:
    """The method called ``name``; an unknown name gets the list of valid ones."""
    return pick(METHODS, name, "--method")


def resolve_parameters(method: Method, given: Mapping[str, Any]) -> dict[str, int]:
    """The method's parameters: its defaults overridden by ``given`` (None = not given).

    A parameter the method does not take is an error (a typo is never ignored, STYLE 7).
    """
    given = {k: v for k, v in given.items() if v is not None}
    foreign = sorted(set(given) - set(method.parameters))
    if foreign:
        flags = ", ".join("--" + k.replace("_", "-") for k in foreign)
        takes = ", ".join("--" + k.replace("_", "-") for k in method.parameters) or "no options"
        raise InputError(f"{flags} does not apply to --method {method.name}",
                         fix=f"{method.name} takes {takes}")
    return {name: p.check(name, given.get(name, p.default))
            for name, p in method.parameters.items()}


@dataclass
class Prepared:
    """Target coverage and how it was obtained.

    Attributes
    ----------
    coverage : (H, W, 3) float32 or None
        Linear ink coverage in the simplex r, g, b ≥ 0, r + g + b ≤ 1, at print size; None
        where :func:`prepare_and_halftone` never made it.
    input_encoding : str
        ``srgb`` or ``linear``: how the pixels were read.
    gamut : str
        The mapper of :data:`.coverage.GAMUT_MAPPERS` that was applied.
    out_of_gamut_fraction : float
        Fraction of the source pixels outside the simplex before ``gamut`` mapping.
    source_shape : (int, int)
        (H, W) of the source image.
    coverage_mean : (3,) float64
        Mean of ``coverage`` per ink (R, G, B): the target coverage.
    """

    coverage: np.ndarray | None
    input_encoding: str
    gamut: str
    out_of_gamut_fraction: float
    source_shape: tuple[int, int]
    coverage_mean: np.ndarray


def prepare(pixels: np.ndarray, *, is_float: bool, encoding: str = "auto",
            gamut: str = "scale", size: tuple[int, int] | None = None,
            path=None) -> Prepared:
    """Image pixels (H, W, 3|4) → target coverage (see :class:`Prepared`).

    ``pixels`` are float32 as stored (integers scaled to [0, 1]) or the stored uint8/uint16
    values (:func:`.coverage.to_coverage`; same result, a quarter of the memory).
    ``size`` = (width_px, height_px) resamples after gamut mapping (bilinear, convex, so
    the result stays in gamut, :func:`.coverage.resample`); the out-of-gamut fraction is
    that of the source image.
    """
    c, used, fraction, mean = _coverage.to_coverage(pixels, encoding, is_float, gamut,
                                                    path=path)
    source_shape = c.shape[:2]
    if size is not None and (size[1], size[0]) != source_shape:
        c = _coverage.resample(c, *size)
        mean = _coverage.mean_coverage(c)
    return Prepared(c, used, gamut, fraction, source_shape, mean)


@dataclass
class Halftone:
    """A halftone: ``labels`` (H, W) uint8 (0 bare, 1 R, 2 G, 3 B), the method, its
    resolved parameters, facts for the report and the core time ``time_s``, excluding
    ``compile_time_s``, the time the first error-diffusion call of a process spends
    making the kernel ready: ~0.1 ms for the C build, or importing numba and loading the
    kernel from numba's on-disk cache (compiling it, the first time on a machine) for the
    numba build; 0 otherwise. ``info["kernel"]`` says which
    (:func:`.diffusion.kernel_status`)."""

    labels: np.ndarray
    method: str
    parameters: dict[str, int]
    time_s: float
    compile_time_s: float = 0.0
    info: dict[str, Any] = field(default_factory=dict)

    def mask(self) -> np.ndarray:
        """The RGB mask (H, W, 3) uint8, channels 0 or 255, at most one set per pixel."""
        return labels_to_mask(self.labels)


def halftone(coverage: np.ndarray, method: str = "floyd-steinberg",
             **parameters: Any) -> Halftone:
    """Halftone coverage (H, W, 3) in the simplex with a method of :data:`METHODS`.

    Parameters
    ----------
    coverage : (H, W, 3) float
        Linear ink coverage, r, g, b ≥ 0 and r + g + b ≤ 1 (use :func:`prepare`).
    method : str
        A key of :data:`METHODS`.
    **parameters
        The method's options (``bayer_size``, ``cell_size``, ``mask_size``); None means
        the default.
    """
    m = get_method(method)
    params = resolve_parameters(m, parameters)
    c = np.asarray(coverage)
    if c.ndim != 3 or c.shape[2] != 3 or c.shape[0] == 0 or c.shape[1] == 0:
        raise InputError(f"coverage has shape {c.shape}, expected (H, W, 3) with H, W ≥ 1")
    start = time.perf_counter()
    labels, info = m.run(c, **params)
    elapsed = time.perf_counter() - start
    compile_time_s = float(info.pop("compile_time_s", 0.0))
    return Halftone(labels, m.name, params, elapsed - compile_time_s, compile_time_s, info)


#: Peak bytes per output pixel of :func:`prepare_and_halftone` with the report's tone
#: error and the PNG encoders: measured with ru_maxrss from 512² to 4096² (--size) on
#: sample_data/print_image.png: 24 (floyd-steinberg) to 30 (bayer with --report) bytes a
#: pixel above the baseline (tests/test_memory.py checks it).
BYTES_PER_PIXEL = 32


def memory_estimate(width: int, height: int) -> int:
    """Peak bytes of halftoning to ``width`` × ``height`` pixels (:data:`BYTES_PER_PIXEL`;
    the decoded input is counted by the caller)."""
    return int(width) * int(height) * BYTES_PER_PIXEL


def prepare_and_halftone(pixels: np.ndarray, *, is_float: bool, encoding: str = "auto",
                         gamut: str = "scale", size: tuple[int, int] | None = None,
                         method: str = "floyd-steinberg", keep_coverage: bool = False,
                         path=None, **parameters: Any) -> tuple[Prepared, Halftone]:
    """:func:`prepare` then :func:`halftone`, the way that needs least time and memory.

    Where the method can read stored pixels (``run_pixels``: error diffusion), the pixels
    are 8-bit, the gamut mapping is ``scale``, no resampling is asked for and the caller
    does not need the coverage (``keep_coverage``, e.g. for :func:`tone_error`), the
    kernel decodes each pixel as it reaches it and the (H, W, 3) float32 coverage is never
    made (``Prepared.coverage`` is None); the labels and figures are those of the general
    path, bit for bit (a test checks it). Otherwise it is :func:`prepare` then
    :func:`halftone`. ``Halftone.time_s`` is then the time of both, decoding included.
    """
    m = get_method(method)
    params = resolve_parameters(m, parameters)
    px = np.asarray(pixels)
    used = _coverage.check_encoding(encoding, is_float)
    h, w = px.shape[:2]
    fused = (m.run_pixels is not None and px.dtype == np.uint8 and gamut == "scale"
             and (size is None or (size[1], size[0]) == (h, w)) and not keep_coverage)
    if not fused:
        prepared = prepare(px, is_float=is_float, encoding=encoding, gamut=gamut, size=size,
                           path=path)
        return prepared, halftone(prepared.coverage, m.name, **params)
    _coverage.check_pixels(px, path)
    table = _coverage.decode_table(np.uint8, used)
    start = time.perf_counter()
    labels, outside, total, info = m.run_pixels(px, table, _coverage.SCALE_LIMIT, **params)
    elapsed = time.perf_counter() - start
    compile_time_s = float(info.pop("compile_time_s", 0.0))
    prepared = Prepared(None, used, gamut, outside / float(h * w), (h, w), total / float(h * w))
    return prepared, Halftone(labels, m.name, params, elapsed - compile_time_s,
                              compile_time_s, info)


def labels_to_mask(labels: np.ndarray) -> np.ndarray:
    """Labels (H, W) → RGB mask (H, W, 3) uint8 with 255 in channel label − 1
    (:data:`PALETTE`)."""
    lab = np.asarray(labels)
    return ((lab[:, :, None] == np.arange(1, 4, dtype=lab.dtype)) * np.uint8(255)).astype(np.uint8)


def ink_coverage(labels: np.ndarray) -> np.ndarray:
    """Fraction of pixels of each ink, (3,) float (R, G, B) (counted per label: no
    widened copy of the image)."""
    lab = np.asarray(labels)
    return np.array([np.count_nonzero(lab == k) for k in range(1, 4)]) / float(lab.size)


def tone_error(labels: np.ndarray, coverage: np.ndarray, sigma: float = TONE_SIGMA_PX
               ) -> tuple[float, np.ndarray]:
    """RMSE between the Gaussian-blurred mask and the equally blurred target coverage.

    Both are blurred (σ = ``sigma`` px, scipy ``gaussian_filter``, mirrored edges) so that
    the figure measures the halftone, not the detail the blur would remove from the
    original too; on a flat patch it is the blurred mask against the target itself. The
    blur is linear, so the difference mask − target is blurred once.

    Returns
    -------
    rmse : float
        Over all pixels and the three inks (coverage units, 0-1).
    rmse_per_ink : (3,) float
    """
    from scipy.ndimage import gaussian_filter

    lab = np.asarray(labels)
    c = np.asarray(coverage, dtype=np.float32)
    per_ink = np.empty(3)
    for k in range(3):
        difference = (lab == k + 1).astype(np.float32) - c[:, :, k]
        blurred = gaussian_filter(difference, sigma, mode="reflect")
        per_ink[k] = np.sqrt(np.mean(np.square(blurred, dtype=np.float64)))
    return float(np.sqrt(np.mean(per_ink ** 2))), per_ink


def summarize(result: Halftone, prepared: Prepared) -> dict[str, Any]:
    """Sizes, coverage per ink against the target, gamut and times: everything of the
    report but the tone error, from numbers already at hand (cheap; ``prepared.coverage``
    is not read, so the caller may have dropped it). Units are in the names; coverages are
    fractions of the print area."""
    target = np.asarray(prepared.coverage_mean, dtype=np.float64)
    achieved = ink_coverage(result.labels)
    h, w = result.labels.shape
    return {
        "method": result.method,
        "method_parameters": result.parameters,
        "citation": METHODS[result.method].citation,
        "width_px": w, "height_px": h,
        "source_width_px": prepared.source_shape[1],
        "source_height_px": prepared.source_shape[0],
        "input_encoding": prepared.input_encoding,
        "gamut": prepared.gamut,
        "out_of_gamut_fraction": prepared.out_of_gamut_fraction,
        "inks": list(INKS),
        "coverage_target": target,
        "coverage_mask": achieved,
        "coverage_error": achieved - target,
        "bare_fraction_target": 1.0 - float(target.sum()),
        "bare_fraction_mask": 1.0 - float(achieved.sum()),
        "halftone_time_s": result.time_s,
        "compile_time_s": result.compile_time_s,
        **result.info,
    }


def evaluate(result: Halftone, prepared: Prepared) -> dict[str, Any]:
    """The report's payload: :func:`summarize` plus the tone error (:func:`tone_error`,
    over the whole image) and the time it took."""
    payload = summarize(result, prepared)
    start = time.perf_counter()
    rmse, per_ink = tone_error(result.labels, prepared.coverage)
    payload.update(tone_sigma_px=TONE_SIGMA_PX, tone_rmse=rmse, tone_rmse_per_ink=per_ink,
                   tone_time_s=time.perf_counter() - start)
    return payload
