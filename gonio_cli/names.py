"""The names of every registry's choices, in one light module.

The cores build their registries (dicts of callables) keyed by these names and the typer
shells spell their ``--help`` and metavars from them, so importing this module costs
nothing at ``gonio --version`` (no numpy). ``tests/test_cli_help.py`` asserts that each
registry's keys equal the names here, in order, and that every command's help shows them.
"""

from __future__ import annotations

from .errors import InputError

# ---------------------------------------------------------------------------- gonio fit --

#: ``--model``: the fitters of :data:`gonio_cli.fit.FITTERS`, in that order.
FIT_MODEL_NAMES = ("goniochromatic", "goniochromatic-diffuse", "goniochromatic-coat",
                   "goniochromatic-backscatter", "goniochromatic-undercoat",
                   "goniochromatic-two-lobe", "torrance-sparrow", "cook-torrance",
                   "cook-torrance-2", "cook-torrance-3", "sheen", "tabulated-colour")
#: The ``--model`` value that chooses among the fitters by held-out error.
AUTO_MODEL = "auto"
FIT_MODEL_CHOICES = FIT_MODEL_NAMES + (AUTO_MODEL,)
#: ``--step2``: :data:`gonio_cli.fit.goniochromatic.STEP2_MODES`.
STEP2_NAMES = ("mirror", "all")
#: ``--residuals``: :data:`gonio_cli.fit.common.RESIDUALS`.
RESIDUAL_NAMES = ("compressive", "log", "linear")
#: ``--optimizer``: each fitter's own ``OPTIMIZERS`` dict, keyed by a subset of these, the
#: first being that fitter's default (:data:`gonio_cli.fit.OPTIMIZERS_BY_MODEL`).
OPTIMIZERS_BY_MODEL = {
    "goniochromatic": ("nlopt-bobyqa", "nlopt-lbfgs", "scipy-least-squares"),
    "goniochromatic-diffuse": ("nlopt-bobyqa", "nlopt-lbfgs"),
    "goniochromatic-coat": ("nlopt-bobyqa", "nlopt-lbfgs"),
    "goniochromatic-backscatter": ("nlopt-bobyqa", "nlopt-lbfgs"),
    "goniochromatic-undercoat": ("nlopt-bobyqa", "nlopt-lbfgs"),
    "goniochromatic-two-lobe": ("nlopt-bobyqa", "nlopt-lbfgs"),
    "torrance-sparrow": ("nlopt-bobyqa", "nlopt-lbfgs", "scipy-least-squares"),
    "cook-torrance": ("golden-section", "scipy-least-squares"),
    "cook-torrance-2": ("nlopt-bobyqa",),
    "cook-torrance-3": ("nlopt-bobyqa",),
    "sheen": ("nlopt-bobyqa",),
    "tabulated-colour": ("nlopt-bobyqa", "nlopt-lbfgs"),
}
#: Every ``--optimizer`` value, in order of first appearance.
OPTIMIZER_NAMES = tuple(dict.fromkeys(n for v in OPTIMIZERS_BY_MODEL.values() for n in v))
#: ``--sweep-gain`` (gonio fit, gonio eval): :data:`gonio_cli.fit.gains.CHOICES`.
SWEEP_GAIN_NAMES = ("auto", "on", "off")

# ------------------------------------------------------------------------- gonio render --

#: ``--spectral`` / ``[output] spectral``: the paths of :mod:`gonio_cli.render.shade`
#: (which uses this tuple).
SPECTRAL_PATHS = ("table", "exact")
#: ``--tonemap``: :data:`gonio_cli.render.tonemap.TONEMAPS`.
TONEMAP_NAMES = ("neutral", "none", "clip", "reinhard", "filmic")
#: ``--adapt``: :data:`gonio_cli.render.tonemap.ADAPTATIONS`.
ADAPTATION_NAMES = ("bradford", "cat16", "none")
#: ``--exr-space``: :data:`gonio_cli.render.tonemap.EXR_SPACES`.
EXR_SPACE_NAMES = ("srgb", "xyz", "acescg")

# ----------------------------------------------------------------------- gonio halftone --

#: ``--method``: :data:`gonio_cli.halftone.METHODS`.
HALFTONE_METHOD_NAMES = ("floyd-steinberg", "jarvis", "stucki", "bayer", "clustered",
                         "clustered-3x3", "blue-noise")
#: ``--gamut``: :data:`gonio_cli.halftone.coverage.GAMUT_MAPPERS`.
GAMUT_NAMES = ("scale", "clip")
#: ``--input-encoding``: :data:`gonio_cli.halftone.coverage.INPUT_ENCODINGS`.
INPUT_ENCODING_NAMES = ("auto", "srgb", "linear")
#: ``--compress``: :data:`gonio_cli.imageio.COMPRESSION`.
COMPRESSION_NAMES = ("none", "fast", "balanced", "small")
#: ``--mask-format``: :data:`gonio_cli.halftone.run.MASK_WRITERS`.
MASK_FORMAT_NAMES = ("palette", "rgb")

# ------------------------------------------------------- gonio lobes, prefilter, sparkle --

#: ``--samples`` (or a CSV file): :data:`gonio_cli.lobes.samples.SAMPLE_SETS`.
SAMPLE_SET_NAMES = ("seed001", "dense", "hemisphere")
#: ``--channels``: :data:`gonio_cli.lobes.samples.CHANNELS`.
CHANNEL_NAMES = ("spectral", "xyz")
#: ``gonio lobes fit --solver``: :data:`gonio_cli.lobes.solvers.WEIGHT_SOLVERS`.
WEIGHT_SOLVER_NAMES = ("lp", "highs", "lp-simplex", "nnls", "lsq-clamp")
#: ``gonio lobes basis --solver``: :data:`gonio_cli.lobes.basis.BASIS_SOLVERS`.
BASIS_SOLVER_NAMES = ("nnls", "lp-simplex")
#: ``gonio prefilter --method`` (besides ``auto``): :data:`gonio_cli.prefilter.methods.METHODS`.
PREFILTER_METHOD_NAMES = ("brute", "ring")
PREFILTER_AUTO = "auto"
#: ``gonio sparkle --rule``: :data:`gonio_cli.sparkle.SEGMENTATION_RULES`.
SPARKLE_RULE_NAMES = ("mad", "percentile")

# ------------------------------------------------------------------------- gonio report --

#: ``--sections``: :data:`gonio_cli.report.sections.SECTIONS` (its sections, in order).
REPORT_SECTION_NAMES = ("fit", "lobes", "prefilter", "render", "table1", "sheets")


def metavar(names) -> str:
    """The metavar of a choice option: its names joined by ``|``."""
    return "|".join(names)


# ------------------------------------------------------------------------- the lookup --

#: How alike a misspelt name and a valid one must be to be offered as "did you mean"
#: (difflib's ratio 2M/T; its own default 0.6 pairs 'materal' with 'material' and
#: 'fov' with 'fov_deg', not 'phong' with any model).
CLOSE_MATCH_CUTOFF = 0.6


def closest(name, choices) -> str | None:
    """The valid name ``name`` was probably meant to be (:func:`difflib.get_close_matches`),
    or None when none is close enough."""
    import difflib

    near = difflib.get_close_matches(str(name), [str(c) for c in choices], n=1,
                                     cutoff=CLOSE_MATCH_CUTOFF)
    return near[0] if near else None


def choices_fix(name, choices, lead: str = "use one of") -> str:
    """The fix of an unknown-name message: ``did you mean 'x'? use one of a, b, c``
    (the question only when a choice is close to ``name``). Every check that lists the
    allowed names (:func:`pick`, the scene, plan and artifact key checks) says it so."""
    listed = f"{lead} {', '.join(str(c) for c in choices)}"
    near = closest(name, choices)
    return f"did you mean {near!r}? {listed}" if near is not None else listed


def pick(registry, name: str, what: str, *, path=None, extra=()):
    """``registry[name]`` (``name`` itself where ``registry`` is a tuple of names); a name
    it lacks is one line that lists the ones it has and, if one is close, says which was
    probably meant (``{what} 'nme' is unknown; did you mean 'name'? use one of …``), the
    same wording for every registry and option. ``path`` is the file the name was read
    from (or the command's input); ``extra`` are further valid spellings listed after the
    registry's (``auto``)."""
    if name in extra:
        return name
    if name not in registry:
        raise InputError(f"{what} {name!r} is unknown", path=path,
                         fix=choices_fix(name, tuple(extra) + tuple(registry)))
    return registry[name] if isinstance(registry, dict) else name
