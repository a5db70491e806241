"""What this machine offers a command: the cores it may use."""

from __future__ import annotations

import os


def cpu_count() -> int:
    """The cores this process may run on (its CPU affinity, which containers and
    ``taskset`` narrow), or the machine's count where the OS does not say."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


#: The variables that size numpy's BLAS thread pool (OpenBLAS, MKL), read when it loads.
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def one_blas_thread() -> None:
    """Give numpy's BLAS one thread, unless the user sized it: for a command whose own
    threads use every core and whose matrix products are small (``gonio render``: the C
    environment kernel runs on :func:`cpu_count` threads; its products are n × 3 @ 3 × 3).

    OpenBLAS's idle threads spin after each call, and on this project's 2-core machine
    they took a core from the environment kernel (a 512² coat-paint frame, best of 10
    in-process: 143 → 97 ms under load). Takes effect only before numpy is imported (a
    command run as its own process, as ``gonio`` is); Dask workers already set these to 1.
    """
    for name in BLAS_THREAD_VARIABLES:
        os.environ.setdefault(name, "1")
