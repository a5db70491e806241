"""The C build of the environment light through a material's lobes (``_envlookup.c``, its
header says why C): whether it was compiled, and its call over threads. The tables, the
equations and the numpy build are :mod:`.env_model`'s."""

from __future__ import annotations

import numpy as np

from .. import machine

#: Builds of :func:`.env_model.model_environment_xyz`, in order of preference: the C
#: extension module built by pip (``_envlookup.c``, optional: skipped where no C compiler
#: was found) and numpy. They agree to 2e-3 of the largest value (``tests/test_env_model.py``).
BUILDS = ("c", "numpy")

#: Pixels per thread of the C build below which one thread does it all.
C_MIN_PIXELS_PER_THREAD = 16384


def c_build_available() -> bool:
    """Whether the C build (``_envlookup.c``) was compiled when gonio was installed."""
    try:
        # lazy: whether the C build is there is the question (an ImportError when not)
        from . import _envlookup  # noqa: F401
    except ImportError:
        return False
    return True


def c_environment(environment, tables, matrices, normal, view, out, view_angle_deg) -> None:
    """:func:`.env_model.model_environment_xyz` by the C build (``_envlookup.c``, its
    header): the tables stacked, the maps of the levels some lobe uses, the pixels split over
    threads (the kernel releases the GIL; plain threads: concurrent.futures would be a 5-10 ms
    import inside the frame)."""
    import threading

    from ._envlookup import run

    used = sorted({int(level) for t in tables for level in t.levels})
    maps = tuple(np.ascontiguousarray(environment.level(i), dtype=np.float32)
                 if i in used else None for i in range(len(environment.exponents)))
    shapes = np.array([(0, 0) if m is None else m.shape[:2] for m in maps], dtype=np.int64)
    heights, widths = np.ascontiguousarray(shapes[:, 0]), np.ascontiguousarray(shapes[:, 1])
    beta = np.array([t.beta for t in tables], dtype=float)                       # (K, V)
    cos_beta, sin_beta = np.cos(beta), np.sin(beta)
    weights = np.ascontiguousarray([t.weights for t in tables], dtype=float)     # (K, V, L)
    mats = np.ascontiguousarray(matrices, dtype=float)                       # (K, V, 3, C)
    # (3, n) float32 rows: the G-buffer's own layout, so no copy (float64 (n, 3) cost 6-7 ms)
    normal = np.ascontiguousarray(np.asarray(normal).T, dtype=np.float32)
    view = np.ascontiguousarray(np.asarray(view).T, dtype=np.float32)
    views = np.ascontiguousarray(view_angle_deg, dtype=float)
    n, channels = out.shape

    def part(b: slice) -> None:
        run(normal, view, n, b.start, b.stop, views, views.size, cos_beta, sin_beta, weights,
            mats, len(tables), maps, heights, widths, len(maps), channels, out)

    threads = max(1, min(machine.cpu_count(), n // C_MIN_PIXELS_PER_THREAD))
    edges = np.linspace(0, n, threads + 1).astype(int)
    parts = [slice(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]
    errors: list[BaseException] = []

    def guarded(b: slice) -> None:                  # a thread's error raised here, below
        try:
            part(b)
        except BaseException as exc:                # noqa: BLE001 (re-raised after join)
            errors.append(exc)

    workers = [threading.Thread(target=guarded, args=(b,)) for b in parts[1:]]
    for w in workers:
        w.start()
    guarded(parts[0])                                # this thread takes the first part
    for w in workers:
        w.join()
    if errors:
        raise errors[0]
