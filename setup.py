"""The one thing pyproject.toml cannot say without an experimental table: gonio's C kernels.

gonio_cli/halftone/_diffuse.c is the error-diffusion kernel in C, and
gonio_cli/render/_envlookup.c the environment light of a material's lobes,
gonio_cli/render/_rasterscan.c the rasterizer's depth test (each header says why). All are
optional: where no C compiler is found the install goes on, halftone uses the numba build
of its kernel and render the numpy builds. _diffuse and _rasterscan: -ffp-contract=off, no
fused multiply-add, so the labels (the depth keys) equal the reference's (the numpy
build's) bit for bit; _envlookup: -fno-math-errno lets sqrt be one instruction (it only
sees non-negatives).
"""

from setuptools import Extension, setup

setup(ext_modules=[Extension("gonio_cli.halftone._diffuse",
                             sources=["gonio_cli/halftone/_diffuse.c"],
                             extra_compile_args=["-O2", "-ffp-contract=off"],
                             optional=True),
               Extension("gonio_cli.render._envlookup",
                         sources=["gonio_cli/render/_envlookup.c"],
                         extra_compile_args=["-O3", "-fno-math-errno"], optional=True),
               Extension("gonio_cli.render._rasterscan",
                         sources=["gonio_cli/render/_rasterscan.c"],
                         extra_compile_args=["-O2", "-ffp-contract=off"], optional=True)])
