"""The driver's cost per job of ``gonio batch`` on a large plan of no-op jobs, and the
per-task costs the simulation (:mod:`batch_sim`) takes; used by bench_batch_scale.py.

The plan has the sample's shape (sample_data/batch/turntable.toml) scaled up: M materials
(each an ingest and a fit), 2 scenes, F-frame turntables (a render a frame, a preview a
turntable): M × (2 + 2 (F + 1)) jobs; 100 materials and 48 frames make 10 000. It is read,
checked and dispatched by the unchanged ``gonio batch`` command; the workers (an external
scheduler and workers, as on a cluster) are started with benchmarks/batch_noop.py
preloaded, which makes every job create its outputs empty and do nothing else. So the
driver does all it does for real jobs, the workers all gonio batch adds to a job.
"""

from __future__ import annotations

import os
import shutil
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

import process  # noqa: E402
from batch_faults import run_batch, start_cluster, stop_cluster  # noqa: E402

#: The sample plan's materials: (CSV files, extra lines of the [[material]] table).
SAMPLE_MATERIALS = [(["../ink_red.csv"], ""),
                    (["../ink_green.csv"],
                     'ingest = { quantity = "ratio-to-white", white-reflectance = "0.99" }\n'),
                    (["../ink_blue_a.csv", "../ink_blue_b.csv"], "")]
SCENES = ("sphere", "panel")


def n_jobs(materials: int, frames: int) -> int:
    """Jobs of :func:`scale_plan`'s plan."""
    return materials * (2 + len(SCENES) * (frames + 1))


def shape_for(jobs: int) -> tuple[int, int]:
    """(materials, frames) of a plan of about ``jobs`` jobs, 100 jobs a material at most
    (48 frames): 10 000 → (100, 48); 1 150 → (25, 21); 11 500 → (250, 21)."""
    for per in range(100, 5, -1):
        if jobs % per == 0 and (per - 2) % len(SCENES) == 0:
            return jobs // per, (per - 2) // len(SCENES) - 1
    return max(1, round(jobs / 100)), 48


def scale_plan(folder: Path, materials: int, frames: int, render: str = "") -> Path:
    """The sample plan with ``materials`` materials (the sample's three inks in turn) and
    ``frames``-frame turntables, with its data, under ``folder``; ``render``: a [matrix]
    render table's body (``width = 64, …``), or none."""
    data = folder / "batch"
    if not data.is_dir():
        shutil.copytree(ROOT / "sample_data" / "batch", data)
        for csv in (ROOT / "sample_data").glob("ink_*.csv"):
            shutil.copy(csv, folder / csv.name)
    lines = []
    for k in range(materials):
        csvs, extra = SAMPLE_MATERIALS[k % len(SAMPLE_MATERIALS)]
        lines += ["[[material]]", f'name = "m{k:04d}"', f"csv = {csvs!r}".replace("'", '"'),
                  "fit = { exclude-theta-i = [70] }", extra]
    scenes = ", ".join(f'"scenes/{s}.toml"' for s in SCENES)
    lines += ["[matrix]", f"scenes = [{scenes}]", f"frames = {frames}", 'orbit = "camera"']
    if render:
        lines.append(f"render = {{ {render} }}")
    plan = data / f"scale{materials}x{frames}.toml"
    plan.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return plan


def cpu_s(pid: int) -> float:
    """User + system CPU seconds of a live process (Linux /proc)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def in_process_phases(plan_path: Path, out: Path, profile: bool = False) -> dict[str, float]:
    """CPU seconds of the driver's phases without the cluster, in this process: reading and
    checking the plan, the up-to-date check against ``out``'s journal (every job up to
    date) and the contact sheet. ``profile``: print cProfile's top functions."""
    import cProfile
    import pstats

    from gonio_cli.batch.engine import settle
    from gonio_cli.batch.journal import read_journal
    from gonio_cli.batch.plan import read_plan
    from gonio_cli.batch.sheet import write_sheet

    prof = cProfile.Profile() if profile else None
    times: dict[str, float] = {}
    start = time.process_time()
    if prof:
        prof.enable()
    plan = read_plan(plan_path, out)
    times["read and check the plan"] = time.process_time() - start
    start = time.process_time()
    previous = read_journal(out)
    times["read the journal"] = time.process_time() - start
    start = time.process_time()
    settle(plan, {})
    times["up-to-date check, no records"] = time.process_time() - start
    start = time.process_time()
    done, stale, _ = settle(plan, previous)
    times["up-to-date check"] = time.process_time() - start
    start = time.process_time()
    write_sheet(out, [previous[j.key] for j in plan.jobs], title="no-op")
    times["contact sheet"] = time.process_time() - start
    if prof:
        prof.disable()
        pstats.Stats(prof).sort_stats("tottime").print_stats(25)
    times["jobs up to date"] = len(done)
    return times


def worker_costs(sched: str, since: float) -> dict[str, float]:
    """From the scheduler's task stream since ``since`` (epoch s): the median time of a
    no-op job in the worker (gonio's :func:`~gonio_cli.batch.jobs.execute`) and each
    worker's busy time per task (first start to last end over its tasks: the execute
    time and what Dask spends between two tasks of a worker that always has one queued)."""
    import statistics

    from distributed import Client

    with Client(scheduler_file=sched, timeout=60) as client:
        stream = client.get_task_stream(start=since)
    computes: list[float] = []
    spans: dict[str, list[float]] = {}
    for t in stream:
        for ss in t.get("startstops", ()):
            if ss["action"] == "compute":
                computes.append(ss["stop"] - ss["start"])
                span = spans.setdefault(t["worker"], [ss["start"], ss["stop"], 0])
                span[0], span[1] = min(span[0], ss["start"]), max(span[1], ss["stop"])
                span[2] += 1
    per_task = [(b - a) / n for a, b, n in spans.values() if n > 1]
    return {"execute_s": statistics.median(computes) if computes else float("nan"),
            "busy_per_task_s": statistics.median(per_task) if per_task else float("nan"),
            "tasks": len(computes)}


def measure_driver(gonio: str, tmp: Path, jobs: int, workers: int, repeats: int,
                   profile: bool = False, extra: tuple[str, ...] = ()) -> dict[str, float]:
    """Run a no-op plan of ``jobs`` jobs on ``workers`` no-op workers (external
    scheduler), with ``extra`` options of gonio batch: the driver's CPU per job for a full
    run and for a rerun with everything up to date, its fixed cost (a 4-job plan), the
    scheduler's CPU per job and the workers' per-task costs; best of ``repeats``. Prints
    a line each."""
    from distributed import Client

    materials, frames = shape_for(jobs)
    n = n_jobs(materials, frames)
    plan = scale_plan(tmp / "data", materials, frames)
    tiny = scale_plan(tmp / "data", 1, 0)
    procs, sched = start_cluster(tmp, workers, ("--preload", str(HERE / "batch_noop.py")))
    try:
        with Client(scheduler_file=sched, timeout=60) as client:
            client.get_task_stream()  # starts the scheduler's task stream record
        rows: dict[str, list[float]] = {"fixed": [], "run": [], "rerun": [], "wall": [],
                                        "scheduler": []}
        for k in range(repeats):
            out = tmp / f"out{k}"
            code, _, cpu, _ = run_batch(gonio, tiny, tmp / f"tiny{k}", sched, extra=extra)
            rows["fixed"].append(cpu)
            since, sched_cpu = time.time(), cpu_s(procs[0].pid)
            code, wall, cpu, _ = run_batch(gonio, plan, out, sched, extra=extra)
            if code != 0:
                raise SystemExit(f"gonio batch on the no-op plan exited {code}")
            rows["scheduler"].append(cpu_s(procs[0].pid) - sched_cpu)
            rows["run"].append(cpu)
            rows["wall"].append(wall)
            costs = worker_costs(sched, since)
            rows["rerun"].append(run_batch(gonio, plan, out, sched, extra=extra)[2])
        phases = in_process_phases(plan, tmp / "out0", profile)
    finally:
        stop_cluster(procs)
    best = {k: min(v) for k, v in rows.items()}
    fixed = best["fixed"]
    print(f"\nthe driver on {n} no-op jobs ({materials} materials x {len(SCENES)} scenes x "
          f"{frames} frames + previews), external scheduler, {workers} no-op workers, "
          f"{' '.join(extra) or 'default options'}; best of {repeats}; load "
          f"{process.load_average()}")
    print(f"  fixed cost (Python, gonio and Dask imports, connecting; a 4-job plan): "
          f"{fixed:.2f} s CPU")
    for name, label in (("run", "every job runs"), ("rerun", "all up to date (no cluster)")):
        print(f"  {label:30s} {best[name]:6.2f} s CPU: {best[name] / n * 1e3:.2f} ms/job, "
              f"{(best[name] - fixed) / n * 1e3:.2f} ms/job without the fixed cost")
    print(f"  wall time of the run {best['wall']:.1f} s ({best['wall'] / n * 1e3:.1f} ms/job "
          f"with {workers} workers and the driver on this machine's cores); the scheduler "
          f"{best['scheduler'] / n * 1e3:.2f} ms CPU per job; {costs['tasks']} Dask tasks")
    print(f"  in a worker: a task (gonio's execute of its no-op jobs) {costs['execute_s'] * 1e3:.1f}"
          f" ms (median), a worker busy {costs['busy_per_task_s'] * 1e3:.1f} ms per task")
    for name, value in phases.items():
        if name != "jobs up to date":
            print(f"  in-process: {name:29s} {value:6.2f} s CPU ({value / n * 1e3:.2f} ms/job)")
    # what a fresh run does before the cluster (the simulated runs are fresh)
    plan_s = phases["read and check the plan"] + phases["up-to-date check, no records"]
    dispatch = best["run"] - fixed - plan_s - phases["contact sheet"]
    print(f"  dispatching and recording (the run less the fixed cost, the plan and the sheet):"
          f" {dispatch / n * 1e3:.2f} ms/job")
    return {"jobs": n, "fixed_s": fixed, "run_s": best["run"], "rerun_s": best["rerun"],
            "scheduler_per_task_s": best["scheduler"] / n, **costs, "plan_s": plan_s,
            "dispatch_per_job_s": max(dispatch, 0.0) / n}


def fsync_s(folder: Path, repeats: int = 20) -> float:
    """Median wall time of appending a journal line and fsync'ing it, in ``folder``."""
    import statistics

    times = []
    with open(folder / "fsync-probe.jsonl", "a", encoding="utf-8") as fh:
        for _ in range(repeats):
            start = time.perf_counter()
            fh.write("{}\n")
            fh.flush()
            os.fsync(fh.fileno())
            times.append(time.perf_counter() - start)
    return statistics.median(times)
