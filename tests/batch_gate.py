"""A gate for batch fault tests: a job that needs a FIFO (named pipe) blocks while its
inputs are hashed, until the test writes to the FIFO. The test thus knows that the job is
running (its attempt log names its worker) without any sleep against the clock."""

from __future__ import annotations

import errno
import os
import subprocess
import time
from pathlib import Path

#: Seconds a wait may take before the test gives up (a hang is a failure, not a timing
#: measurement: every wait ends on an event long before this on any machine).
DEADLINE_S = 180


def wait(what: str, test, proc: subprocess.Popen | None = None):
    """Poll ``test()`` until it is truthy (an event, not a time): its value."""
    deadline = time.monotonic() + DEADLINE_S
    while True:
        value = test()
        if value:
            return value
        assert proc is None or proc.poll() is None, f"gonio batch ended before {what}: " \
            + proc.communicate()[1][-2000:]
        assert time.monotonic() < deadline, f"never: {what}"
        time.sleep(0.05)


def start_cluster(folder: Path, nworkers: int = 2, worker_args: tuple[str, ...] = (),
                  env: dict | None = None) -> tuple[list[subprocess.Popen], str]:
    """A scheduler and ``nworkers`` single-threaded workers (with nannies) on loopback,
    as separate processes (as a job queue starts them); ``worker_args``: more options of
    ``dask worker`` (``--preload …``). Returns the processes (stop them with
    :func:`stop_cluster`) and the scheduler file. Shared by the tests and
    benchmarks/batch_faults.py."""
    import sys

    bindir = Path(sys.executable).parent
    sched = folder / "scheduler.json"
    common = ["--host", "127.0.0.1", "--no-dashboard"]
    procs = [subprocess.Popen([str(bindir / "dask"), "scheduler", "--port", "0",
                               "--scheduler-file", str(sched), *common], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        wait("the scheduler", sched.is_file)
        procs.append(subprocess.Popen([str(bindir / "dask"), "worker", "--scheduler-file",
                                       str(sched), "--nthreads", "1", "--nworkers",
                                       str(nworkers), *common, *worker_args], env=env,
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        from distributed import Client

        with Client(scheduler_file=str(sched), timeout=60) as client:
            client.wait_for_workers(nworkers, timeout=DEADLINE_S)
    except BaseException:
        stop_cluster(procs)
        raise
    return procs, str(sched)


def stop_cluster(procs: list[subprocess.Popen]) -> None:
    """Stop what :func:`start_cluster` started (workers first)."""
    for p in reversed(procs):
        p.terminate()
    for p in procs:
        try:
            p.wait(timeout=30)
        except subprocess.TimeoutExpired:
            p.kill()


def attempts(out: Path, key: str) -> list[str]:
    log = out / ".gonio-batch" / "attempts" / (key.replace("/", "_") + ".log")
    return log.read_text().split() if log.is_file() else []


def open_gate(out: Path, fifo: Path, starts: int, key: str = "gate") -> None:
    """Let the job ``key`` go once its ``starts``-th start is waiting on the FIFO: write
    to it when a reader has it open (open for writing without blocking fails until then)."""
    wait(f"{key} start {starts}", lambda: len(attempts(out, key)) >= starts)

    def opened():
        try:
            return os.open(fifo, os.O_WRONLY | os.O_NONBLOCK)
        except OSError as exc:
            if exc.errno != errno.ENXIO:  # ENXIO: no reader yet
                raise
            return None

    fd = wait("a reader of the gate", opened)
    try:
        os.write(fd, b"go\n")
    finally:
        os.close(fd)


def fifo_as_file(fifo: Path, rec: dict) -> None:
    """Replace the FIFO by a regular file with the bytes and modification time the gated
    job's record ``rec`` holds, so a rerun reads (and trusts) it instead of blocking on it."""
    mtime = next(i["mtime_ns"] for i in rec["inputs"] if i["path"] == str(fifo))
    fifo.unlink()
    fifo.write_bytes(b"go\n")
    os.utime(fifo, ns=(mtime, mtime))
