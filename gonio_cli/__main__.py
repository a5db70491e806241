"""The ``gonio`` entry point, also ``python -m gonio_cli``.

Importing the CLI (typer, click, rich) takes a noticeable part of a second; a Ctrl-C in
that time arrives before :func:`gonio_cli.cli.run` can turn it into one line. So this
module imports nothing heavy at its top: :func:`main` imports the CLI inside the same
``try`` that catches the interrupt, and a Ctrl-C at any point of start-up ends with the
line every other interrupt gets and exit status 130 (128 + SIGINT), never a traceback.
"""

from __future__ import annotations

import os
import sys

#: BLAS threads for numpy and scipy, unless the user set them. gonio's matrices are small
#: (a fit's normal sums, a lobe LP): extra BLAS threads only add synchronisation, and on a
#: busy machine (make -j, a batch) they spin against each other. Measured on 2 cores under
#: load: a 121 × 273 by 273 × 41 product takes 0.2 ms on one thread, 10–15 ms on two.
BLAS_THREADS_DEFAULT = "1"

#: 128 + SIGINT, as :data:`gonio_cli.errors.EXIT_INTERRUPTED` (not imported: that import
#: could itself be the one interrupted).
EXIT_INTERRUPTED = 130


def use_blas_threads() -> None:
    """:data:`BLAS_THREADS_DEFAULT` unless the user set ``OPENBLAS_NUM_THREADS``; call
    before numpy is imported (OpenBLAS reads it once, at load). The benchmarks call it
    too, so the kernels they time in-process run as in a ``gonio`` process."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", BLAS_THREADS_DEFAULT)


def main() -> None:
    """Console entry point: import the CLI, run it, exit with its status."""
    use_blas_threads()
    try:
        # lazy: the CLI (typer, click, rich) loads inside the try that turns a Ctrl-C into one line
        from .cli import run

        code = run()
    except KeyboardInterrupt:  # during the imports; run() handles its own
        print("gonio: interrupted; nothing was written", file=sys.stderr)
        code = EXIT_INTERRUPTED
    sys.exit(code)


if __name__ == "__main__":
    main()
