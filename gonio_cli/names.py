"""The names of every registry's choices, in one light module.

The cores build their registries (dicts of callables) keyed by these names and the typer
shells spell their ``--help`` and metavars from them, so importing this module costs
nothing at ``gonio --version`` (no numpy). ``tests/test_cli_help.py`` asserts that each
registry's keys equal the names here, in order, and that every command's help shows them.
"""

from __future__ import annotations

# ---------------------------------------------------------------------------- gonio fit --

#: ``--model``: the fitters of :data:`gonio_cli.fit.FITTERS`, in that order.
FIT_MODEL_NAMES = ("goniochromatic", "goniochromatic-diffuse", "goniochromatic-coat",
                   "torrance-sparrow", "cook-torrance", "cook-torrance-2", "cook-torrance-3")
#: The ``--model`` value that chooses among the fitters by held-out error.
AUTO_MODEL = "auto"
FIT_MODEL_CHOICES = FIT_MODEL_NAMES + (AUTO_MODEL,)
#: ``--residuals``: :data:`gonio_cli.fit.common.RESIDUALS`.
RESIDUAL_NAMES = ("compressive", "log", "linear")
#: ``--optimizer``: each fitter's own ``OPTIMIZERS`` dict, keyed by a subset of these, the
#: first being that fitter's default (:data:`gonio_cli.fit.OPTIMIZERS_BY_MODEL`).
OPTIMIZERS_BY_MODEL = {
    "goniochromatic": ("nlopt-bobyqa", "nlopt-lbfgs", "scipy-least-squares"),
    "goniochromatic-diffuse": ("nlopt-bobyqa", "nlopt-lbfgs"),
    "goniochromatic-coat": ("nlopt-bobyqa", "nlopt-lbfgs"),
    "torrance-sparrow": ("nlopt-bobyqa", "nlopt-lbfgs", "scipy-least-squares"),
    "cook-torrance": ("golden-section", "scipy-least-squares"),
    "cook-torrance-2": ("nlopt-bobyqa",),
    "cook-torrance-3": ("nlopt-bobyqa",),
}
#: Every ``--optimizer`` value, in order of first appearance.
OPTIMIZER_NAMES = tuple(dict.fromkeys(n for v in OPTIMIZERS_BY_MODEL.values() for n in v))
