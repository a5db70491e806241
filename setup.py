"""The one thing pyproject.toml cannot say without an experimental table: gonio's C kernel.

gonio_cli/halftone/_diffuse.c is the error-diffusion kernel in C (its header says why).
It is optional: where no C compiler is found the install goes on, and halftone uses the
numba build of the same kernel. -ffp-contract=off: no fused multiply-add, so the labels
equal the reference's bit for bit.
"""

from setuptools import Extension, setup

setup(ext_modules=[Extension("gonio_cli.halftone._diffuse",
                             sources=["gonio_cli/halftone/_diffuse.c"],
                             extra_compile_args=["-O2", "-ffp-contract=off"],
                             optional=True)])
