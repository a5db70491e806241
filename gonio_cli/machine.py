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
