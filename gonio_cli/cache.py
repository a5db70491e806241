"""gonio's on-disk cache: results that are expensive to make and never change for a key.

``$GONIO_CACHE_DIR``, else ``$XDG_CACHE_HOME/gonio``, else ``~/.cache/gonio``. Entries are
``.npz``/``.npy`` files whose names carry everything they depend on (a version, sizes, a
seed); a file that cannot be read or fails its check is recomputed, never trusted, and a
cache that cannot be written is only slower (STYLE 14: caches keyed by content).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Callable

import numpy as np

from .artifact import atomic_path

#: Environment variable naming the folder of gonio's caches (tests point it at tmp_path).
CACHE_ENV = "GONIO_CACHE_DIR"


def cache_dir() -> Path:
    """``$GONIO_CACHE_DIR``, else ``$XDG_CACHE_HOME/gonio``, else ``~/.cache/gonio``."""
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV])
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "gonio"


def cached_arrays(name: str, compute: Callable[[], dict[str, np.ndarray]],
                  check: Callable[[dict[str, np.ndarray]], bool] = lambda d: True
                  ) -> dict[str, np.ndarray]:
    """Arrays stored under ``name`` (an .npz in :func:`cache_dir`), computed on a miss."""
    path = cache_dir() / name
    try:
        with np.load(path, allow_pickle=False) as npz:
            data = {k: npz[k] for k in npz.files}
        if check(data):
            return data
    except (OSError, ValueError, KeyError):
        pass
    data = compute()
    try:
        with atomic_path(path, immediate=True) as tmp, open(tmp, "wb") as fh:
            np.savez(fh, **data)
    except OSError:
        pass  # read-only cache: computed again next time
    return data
