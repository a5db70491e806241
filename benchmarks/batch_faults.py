"""The fault mode of benchmarks/bench_batch.py (``--faults``): ``gonio batch`` on an
external scheduler with two workers, killed in three ways mid-run; what each costs.

For each fault: the jobs started more than once within the run (attempt logs), the
outputs whose sha256 is not the journal's, and how many jobs the rerun runs against how
many had not finished when the fault hit (± those running then). A clean run first gives
the driver's CPU time and wall time per job.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

import batch_gate  # noqa: E402  (the cluster the fault tests start)
import process  # noqa: E402

#: Share of the jobs recorded when a fault is sent (the run is then well under way).
FAULT_AT = 1 / 3


def _journal(out: Path) -> dict[str, dict]:
    from gonio_cli.batch.journal import read_journal

    return read_journal(out)


def _started_twice(out: Path) -> set[str]:
    """File names (:func:`gonio_cli.batch.plan.file_name_of`) of the jobs started more
    than once in the run (a start after the first that finds the job's receipt returns
    it without running the job)."""
    folder = out / ".gonio-batch" / "attempts"
    return {p.stem for p in folder.glob("*.log") if len(p.read_text().split()) > 1} \
        if folder.is_dir() else set()


def _mismatches(out: Path) -> int:
    from gonio_cli.artifact import sha256_file

    return sum(1 for r in _journal(out).values() if r["status"] in ("ok", "skipped")
               for o in r["outputs"] if not os.path.exists(o["path"])
               or sha256_file(o["path"]) != o["sha256"])


def run_batch(gonio: str, plan: Path, out: Path, sched: str, fault=None, extra=()):
    """Run the batch (``extra``: more options); ``fault(proc)`` once FAULT_AT of the jobs
    are recorded. Returns
    (exit status, wall s, driver CPU s, keys recorded at the fault)."""
    env = process.user_environment()
    start = time.perf_counter()
    proc = subprocess.Popen([gonio, "-q", "batch", str(plan), "-o", str(out), "--scheduler",
                             sched, "--retries", "1", *extra], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    at_fault: set[str] = set()
    if fault is not None:
        from gonio_cli.batch.plan import read_plan

        n = len(read_plan(plan, out).jobs)
        while len(_journal(out)) < FAULT_AT * n:
            time.sleep(0.05)
        at_fault = set(_journal(out))
        fault(proc)
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    return (proc.returncode, time.perf_counter() - start, usage.ru_utime + usage.ru_stime,
            at_fault)


def _rerun(gonio: str, plan: Path, out: Path, sched: str) -> int:
    """Jobs the rerun ran (ok or failed in its journal)."""
    before = {k: r.get("run") for k, r in _journal(out).items()}
    subprocess.run([gonio, "-q", "batch", str(plan), "-o", str(out), "--scheduler", sched],
                   env=process.user_environment(), stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    return sum(1 for k, r in _journal(out).items() if r["status"] in ("ok", "failed")
               and r.get("run") != before.get(k))


def start_cluster(folder: Path, nworkers: int = 2, worker_args: tuple[str, ...] = ()
                  ) -> tuple[list[subprocess.Popen], str]:
    """tests/batch_gate.py's cluster (a scheduler and ``nworkers`` workers as separate
    processes) in the user's environment (:func:`process.user_environment`)."""
    return batch_gate.start_cluster(folder, nworkers, worker_args,
                                    env=process.user_environment())


stop_cluster = batch_gate.stop_cluster


def _kill_a_worker(sched: str):
    def fault(proc):  # noqa: ARG001
        from distributed import Client

        with Client(scheduler_file=sched, timeout=60) as client:
            pid = sorted(client.run(os.getpid).values())[0]
        os.kill(pid, signal.SIGKILL)
    return fault


def run_faults(gonio: str, tmp: Path, jobs: int = 280, size: int = 64) -> None:
    """Print the clean run's driver time per job, then each fault's cost, on a plan of
    about ``jobs`` jobs (:func:`batch_scale.scale_plan`) rendering at ``size``²."""
    from batch_scale import scale_plan, shape_for

    from gonio_cli.batch.plan import read_plan

    materials, frames = shape_for(jobs)
    plan = scale_plan(tmp / "data", materials, frames,
                      render=f"width = {size}, height = {size}, ssaa = 2")

    n = len(read_plan(plan, tmp / "x").jobs)
    procs, sched = start_cluster(tmp)
    try:
        print(f"gonio batch under faults: {n} jobs ({materials} materials x 2 scenes x "
              f"{frames} frames at {size}², previews), external scheduler, 2 workers; load "
              f"{process.load_average()}")
        code, wall, cpu, _ = run_batch(gonio, plan, tmp / "clean", sched)
        print(f"  clean run: exit {code}, {wall:.1f} s; driver {cpu / n * 1e3:.1f} ms CPU and "
              f"{wall / n * 1e3:.0f} ms wall per job")
        faults = {"worker SIGKILL": _kill_a_worker(sched),
                  "driver SIGKILL": lambda p: p.send_signal(signal.SIGKILL),
                  "driver SIGTERM": lambda p: p.send_signal(signal.SIGTERM)}
        for name, fault in faults.items():
            out = tmp / name.replace(" ", "-")
            code, wall, cpu, at_fault = run_batch(gonio, plan, out, sched, fault)
            from gonio_cli.batch.plan import file_name_of

            twice, bad = _started_twice(out), _mismatches(out)
            again = len(twice & {file_name_of(k) for k in at_fault})
            time.sleep(2)  # let the scheduler drop a dead driver's tasks (not measured)
            rerun = _rerun(gonio, plan, out, sched)
            print(f"  {name:15s}: exit {code}, {len(at_fault)} of {n} recorded at the fault; "
                  f"{len(twice)} job(s) started twice in the run ({again} recorded before "
                  f"the fault), {bad} output(s) not as "
                  f"journalled; the rerun ran {rerun} of the {n - len(at_fault)} not "
                  f"finished at the fault")
    finally:
        stop_cluster(procs)

