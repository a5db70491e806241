"""Benchmark of ``gonio batch`` at scale: the driver's time per job on a 10 000-job plan of
no-op jobs, and a simulation of large plans on 64 and 256 workers from costs measured in
the same run.

    .venv/bin/python benchmarks/bench_batch_scale.py [--jobs 10000] [--workers 2]
        [--repeats 2] [--size 384] [--profile]

1. Job costs: the sample plan (sample_data/batch/turntable.toml, renders at ``--size``²
   ssaa 2) on one worker; the median ``time_s`` of its ingests, fits, renders and
   previews, and the contact sheet's time per job on those images.
2. The driver (benchmarks/batch_scale.py): ``gonio batch`` on a plan of ``--jobs`` no-op
   jobs (the sample's shape scaled up; workers preloaded with benchmarks/batch_noop.py)
   on an external scheduler with ``--workers`` workers: its CPU per job for a full run
   and for a rerun with everything up to date, less its fixed cost (imports,
   connecting); the scheduler's CPU per job; a worker's time per no-op task. Twice: with
   the default grouping of ready jobs into tasks (the target), and with
   ``--jobs-per-task 1``, which the simulation's costs per task come from (at 64 workers
   the engine sends each job of these plans alone).
3. The simulation (benchmarks/batch_sim.py) of the sample's shape at 1 150 jobs on 64
   workers and 11 500 on 256, with those costs: efficiency = the jobs' own time /
   (workers × makespan), target ≥ 0.9 at 64 workers; then each overhead alone, which
   says what limits it. Three sets of costs: this machine's jobs; the issue's job costs
   (ingest 0.19 s, fit 0.23 s, render 0.55 s) with this machine's overheads; the same
   with a worker's busy time per task (the scheduler's round trip included) in place of
   its own time, an upper bound.
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import batch_scale  # noqa: E402
import batch_sim  # noqa: E402
import process  # noqa: E402
from bench_batch import copy_plan  # noqa: E402

TARGET_MS_PER_JOB = 1.0
TARGET_EFFICIENCY = 0.9
#: (jobs, workers) simulated: the issue's two cases.
CASES = ((1150, 64), (11500, 256))
#: The overheads of :class:`batch_sim.Costs`, as measured here.
COST_FIELDS = ("worker_task_s", "worker_image_s", "driver_job_s", "driver_batch_s",
               "scheduler_task_s", "plan_per_job_s", "sheet_per_job_s")
#: The issue's figures (s), for comparison with this machine's.
ISSUE_JOB_S = {"ingest": 0.19, "fit": 0.23, "frame": 0.55, "render": 0.55, "preview": 0.1}


def job_costs(gonio: str, tmp: Path, size: int) -> tuple[dict[str, float], float, float]:
    """({role: median s}, the contact sheet's s per job, a frame's image for the sheet in
    its worker, median s) of the sample plan at ``size``²."""
    import time

    from gonio_cli.batch.sheet import image_entry, write_sheet

    plan = copy_plan(tmp / "sample", size)
    out = tmp / "sample-out"
    process.run_measured([gonio, "-q", "batch", str(plan), "-o", str(out), "--workers", "1"])
    records = [json.loads(line) for line in (out / "manifest.jsonl").open()]
    by_role: dict[str, list[float]] = {}
    for r in records:
        by_role.setdefault(r["labels"]["role"], []).append(r["time_s"])
    write_sheet(out, records, title="sample")  # its imports (numpy, PIL) first, untimed
    start = time.process_time()
    write_sheet(out, records, title="sample")
    sheet = (time.process_time() - start) / len(records)
    roles = {role: statistics.median(t) for role, t in by_role.items()}
    roles.setdefault("render", roles.get("frame", ISSUE_JOB_S["render"]))
    images = []
    for r in records:
        if r["labels"]["role"] == "frame":
            start = time.perf_counter()
            image_entry(str(out), r["outputs"][0]["path"])
            images.append(time.perf_counter() - start)
    return roles, sheet, statistics.median(images)


def simulate_cases(costs: batch_sim.Costs, title: str) -> float:
    """Print the simulated efficiencies; return the first case's (1 150 jobs, 64)."""
    from gonio_cli.batch.plan import dependencies, read_plan

    first = None
    print(f"\nsimulated ({title})")
    tmp = Path(tempfile.mkdtemp(prefix="gonio-bench-sim-"))
    try:
        for jobs, workers in CASES:
            materials, frames = batch_scale.shape_for(jobs)
            plan = read_plan(batch_scale.scale_plan(tmp, materials, frames), tmp / "out")
            deps = dependencies(plan)
            roles = {j.key: j.labels["role"] for j in plan.jobs}
            runs = {o: batch_sim.simulate(deps, roles, costs, workers, o)
                    for o in ("submission", "critical-path")}
            r = runs["submission"]
            first = r.efficiency if first is None else first
            ideal = batch_sim.simulate(deps, roles, batch_sim.Costs(costs.job_s), workers)
            print(f"  {jobs} jobs on {workers} workers: efficiency {r.efficiency:.3f} "
                  f"(makespan {r.makespan_s:.2f} s, work {r.work_s:.0f} s, critical path "
                  f"{r.critical_path_s:.2f} s); critical path first "
                  f"{runs['critical-path'].efficiency:.3f}; the graph alone "
                  f"{ideal.efficiency:.3f}")
            alone = []
            for name in COST_FIELDS:
                one = batch_sim.Costs(costs.job_s, **{name: getattr(costs, name)})
                e = batch_sim.simulate(deps, roles, one, workers).efficiency
                alone.append(f"{name} {e - ideal.efficiency:+.3f}")
            print(f"    each overhead alone, in efficiency: {', '.join(alone)}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return first


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=int, default=10000, help="jobs of the no-op plan")
    parser.add_argument("--workers", type=int, default=2, help="no-op worker processes")
    parser.add_argument("--repeats", type=int, default=2, help="runs of the no-op plan")
    parser.add_argument("--size", type=int, default=384, help="the sample's render size (px)")
    parser.add_argument("--profile", action="store_true",
                        help="print cProfile's top functions of the driver's in-process phases")
    args = parser.parse_args()
    gonio = process.gonio_command()
    with tempfile.TemporaryDirectory(prefix="gonio-bench-scale-") as tmp:
        job_s, sheet_s, image_s = job_costs(gonio, Path(tmp), args.size)
        print(f"job costs, the sample plan at {args.size}² ssaa 2 on 1 worker (median s): "
              + ", ".join(f"{k} {v:.3f}" for k, v in sorted(job_s.items()))
              + f"; a frame's thumbnail and flags in its worker {image_s * 1e3:.1f} ms; the "
                f"contact sheet {sheet_s * 1e3:.2f} ms per job in the driver; load "
                f"{process.load_average()}")
        grouped = batch_scale.measure_driver(gonio, Path(tmp) / "noop", args.jobs, args.workers,
                                             args.repeats, args.profile)
        # one task per job: what the engine does at 64 workers on the simulated plans
        # (no ready group is 2 x 64 jobs long there, engine.chunks), so the costs per
        # task of the simulation come from this run
        d = batch_scale.measure_driver(gonio, Path(tmp) / "alone", args.jobs, args.workers,
                                       args.repeats, extra=("--jobs-per-task", "1"))
        fsync = batch_scale.fsync_s(Path(tmp))
    for label, m in (("default", grouped), ("--jobs-per-task 1", d)):
        per_job = (m["run_s"] - m["fixed_s"]) / m["jobs"] * 1e3
        print(f"  driver, {label}: {per_job:.2f} ms CPU per job without the fixed cost "
              f"(target <= {TARGET_MS_PER_JOB} ms): "
              f"{'met' if per_job <= TARGET_MS_PER_JOB else 'NOT met'}")
    print(f"  an fsync of the journal {fsync * 1e3:.1f} ms")
    # a worker's own time per task: gonio's execute of a no-op (the scheduler's part of
    # the gap between two tasks is its own server in the model); the busy time per task
    # (that gap included, on cores the driver and scheduler share) is an upper bound
    costs = batch_sim.Costs(job_s, worker_task_s=d["execute_s"], worker_image_s=image_s,
                            driver_job_s=d["dispatch_per_job_s"], driver_batch_s=fsync,
                            scheduler_task_s=d["scheduler_per_task_s"],
                            plan_per_job_s=d["plan_s"] / d["jobs"], sheet_per_job_s=sheet_s)
    issue = batch_sim.Costs(ISSUE_JOB_S, **{k: getattr(costs, k) for k in COST_FIELDS})
    effs = [simulate_cases(costs, "this machine's job costs and overheads"),
            simulate_cases(issue, "the issue's job costs, this machine's overheads")]
    upper = dict(worker_task_s=d["busy_per_task_s"])
    bound = simulate_cases(batch_sim.Costs(ISSUE_JOB_S, **{
        k: upper.get(k, getattr(costs, k)) for k in COST_FIELDS}),
        "the issue's job costs; a worker's busy time per task, not its own time")
    # the target is the issue's: its job costs, the overheads measured here
    print(f"\nefficiency at 64 workers on 1 150 jobs, the issue's job costs: {effs[1]:.3f} "
          f"(target >= {TARGET_EFFICIENCY}: {'met' if effs[1] >= TARGET_EFFICIENCY else 'NOT met'}"
          f"); {bound:.3f} with the upper bound of a worker's overhead; {effs[0]:.3f} with this "
          f"machine's jobs")


if __name__ == "__main__":
    main()
