"""Whole commands as users time them: wall time and peak memory of one process.

Shared by every benchmark (``make bench``). The peak resident memory is the child's own:
Linux keeps a process's peak RSS across exec, so a command forked straight from a large
benchmark process would report the benchmark's pages. GNU time (``/usr/bin/time``) forks
from a small process and reports ``%M``; where it is missing, a small Python launcher does
the same with ``os.wait4``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

GNU_TIME = "/usr/bin/time"

#: Forks and execs the command, waits with wait4, prints wall time, CPU time (user +
#: system of the process and every child it waited for, e.g. gonio fit's forked fitters)
#: and peak RSS as JSON.
_LAUNCHER = """
import json, os, sys, time
start = time.perf_counter()
pid = os.fork()
if pid == 0:
    null = os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, 1)
    os.execv(sys.argv[1], sys.argv[1:])
_, status, usage = os.wait4(pid, 0)
print(json.dumps({"wall_s": time.perf_counter() - start, "maxrss_kib": usage.ru_maxrss,
                  "cpu_s": usage.ru_utime + usage.ru_stime,
                  "status": os.waitstatus_to_exitcode(status)}))
"""


def user_environment(env: dict[str, str] | None = None) -> dict[str, str]:
    """The environment a user's command runs in: ``env`` (default: this one) without
    ``PYTHONDONTWRITEBYTECODE``. Python normally caches each module's compiled bytecode
    (``__pycache__``, and pip compiles installed packages); a build sandbox that sets the
    variable makes every process compile every module it imports again (~0.1 s of a
    ``gonio render``), which no user pays."""
    out = dict(os.environ if env is None else env)
    out.pop("PYTHONDONTWRITEBYTECODE", None)
    return out


def run_measured(argv: list[str], env: dict[str, str] | None = None,
                 check: bool = True) -> tuple[float, float, int]:
    """(wall s, peak resident MB, exit status) of one process running ``argv``, in
    :func:`user_environment` (bytecode cached, as on a user's machine).

    ``check``: a non-zero exit ends the benchmark with the command and its stderr."""
    env = user_environment(env)
    if os.access(GNU_TIME, os.X_OK):
        done = subprocess.run([GNU_TIME, "-f", "%e %M", *argv], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        last = done.stderr.strip().splitlines()[-1].split() if done.stderr.strip() else []
        try:
            wall, peak_kib = float(last[-2]), float(last[-1])
        except (IndexError, ValueError):
            raise SystemExit(f"{argv[0]}: GNU time gave no figures: {done.stderr.strip()}")
        code = done.returncode
    else:
        done = subprocess.run([sys.executable, "-I", "-S", "-c", _LAUNCHER, *argv], env=env,
                              capture_output=True, text=True)
        if not done.stdout.strip():
            raise SystemExit(f"{argv[0]}: the launcher failed: {done.stderr.strip()}")
        result = json.loads(done.stdout.strip().splitlines()[-1])
        wall, peak_kib, code = result["wall_s"], result["maxrss_kib"], result["status"]
    if check and code != 0:
        tail = done.stderr.strip().splitlines()
        raise SystemExit(f"{' '.join(map(str, argv))} failed ({code}): "
                         f"{tail[-2] if len(tail) > 1 else ''}")
    return wall, peak_kib / 1024.0, code


def run_with_cpu(argv: list[str], env: dict[str, str] | None = None) -> dict:
    """``wall_s``, ``cpu_s``, ``maxrss_kib`` and ``status`` of one process running ``argv``
    (:data:`_LAUNCHER`, in :func:`user_environment`); a non-zero exit ends the benchmark."""
    done = subprocess.run([sys.executable, "-I", "-S", "-c", _LAUNCHER, *argv],
                          env=user_environment(env), capture_output=True, text=True)
    if not done.stdout.strip():
        raise SystemExit(f"{argv[0]}: the launcher failed: {done.stderr.strip()}")
    out = json.loads(done.stdout.strip().splitlines()[-1])
    if out["status"] != 0:
        raise SystemExit(f"{' '.join(map(str, argv))} failed ({out['status']})")
    return out


def gonio_command() -> str:
    """The ``gonio`` entry point of the interpreter running the benchmark."""
    return str(Path(sys.executable).with_name("gonio"))


def load_average() -> str:
    """The 1, 5 and 15 min load averages, for the header of a table of times."""
    return " ".join(f"{x:.1f}" for x in os.getloadavg())
