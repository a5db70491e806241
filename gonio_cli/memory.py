"""Memory estimates before large allocations: refuse a run the machine cannot hold.

A stage that allocates in proportion to a user's option (render buffers × ssaa², the
tessellation of ``builtin:sphere?segments=N``, a prefilter at full resolution, a
halftone at ``--size-px``) estimates its peak bytes with an estimator next to the code that
allocates, and calls :func:`check` before the work. Beyond what the machine has, the run
ends at once with one line giving the estimate, the memory available and the option to
change (exit status 2), instead of a ``MemoryError`` or the kernel's OOM killer minutes
later.

What the machine has: ``MemAvailable`` of ``/proc/meminfo`` (Linux: free memory plus the
page cache the kernel can drop), else the physical memory (``os.sysconf``), and never more
than the process's address-space limit (``ulimit -v``). A run may use :data:`MARGIN` of it:
the estimators are within a factor 1.5 of the measured peak (tests/test_memory.py) and the
rest of the machine keeps running. The environment variable :data:`MEMORY_ENV`
(``GONIO_MEMORY_AVAILABLE=512M``) sets the available memory instead: to keep a run
within a share of a shared machine, and for tests.
"""

from __future__ import annotations

import os
import re

from .errors import InputError, MemoryLimitError

#: Environment variable that sets the available memory (bytes, or with K, M, G, T: 1024-based).
MEMORY_ENV = "GONIO_MEMORY_AVAILABLE"

#: Share of the available memory one run may plan to use: the estimates are within 1.5×
#: of the measured peaks, and the OS, the page cache and other processes need the rest.
MARGIN = 0.8

_SIZE = re.compile(r"\s*([0-9]+(?:\.[0-9]*)?)\s*([KMGT]?)i?B?\s*\Z", re.I)
_UNITS = {"": 1, "K": 1 << 10, "M": 1 << 20, "G": 1 << 30, "T": 1 << 40}


def parse_bytes(text: str) -> int:
    """``"512M"`` → 536870912; ``"2G"``, ``"1.5GiB"``, ``"100000"`` (bytes)."""
    m = _SIZE.match(text)
    if m is None:
        raise InputError(f"{MEMORY_ENV}={text!r} is not a size",
                         fix="give bytes or a number with K, M, G or T, e.g. 4G")
    return int(float(m.group(1)) * _UNITS[m.group(2).upper()])


def _meminfo_available() -> int | None:
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def _physical() -> int | None:
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return None


def available_bytes() -> tuple[int | None, str]:
    """Memory this run may count on, and where the number comes from (for the message)."""
    text = os.environ.get(MEMORY_ENV)
    if text:
        return parse_bytes(text), f"set by {MEMORY_ENV}"
    have, source = _meminfo_available(), "available"
    if have is None:
        have, source = _physical(), "of this machine"
    try:
        import resource

        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
        if soft != resource.RLIM_INFINITY and (have is None or soft < have):
            have, source = soft, "allowed by ulimit -v"
    except (ImportError, OSError, ValueError):
        pass
    return have, source


def gib(n: float) -> str:
    """Bytes as a message shows them: ``24.0 GiB``, ``310 MiB``."""
    return f"{n / 2**30:.1f} GiB" if n >= 2**30 else f"{n / 2**20:.0f} MiB"


def check(need: int, what: str, *, fix: str, path=None) -> int:
    """Refuse ``need`` bytes beyond :data:`MARGIN` of the available memory.

    Parameters
    ----------
    need : int
        The stage's estimated peak bytes.
    what : str
        The work, as the message names it: ``"a 2048x2048 render at ssaa 16"``.
    fix : str
        The option(s) that lower the estimate: ``"lower --ssaa or --width-px/--height-px"``.
    path : optional
        The file the work comes from (printed first).

    Returns ``need``. Raises :class:`~gonio_cli.errors.MemoryLimitError`.
    """
    have, source = available_bytes()
    if have is not None and need > MARGIN * have:
        raise MemoryLimitError(
            f"{what} needs about {gib(need)}, more than {100 * MARGIN:.0f} % of the "
            f"{gib(have)} {source}",
            path=path, fix=fix)
    return int(need)
