"""Benchmark of ``gonio batch``: the sample turntable plan on 2 workers, on 1, and as
separate ``gonio`` processes.

    .venv/bin/python benchmarks/bench_batch.py [--size PX]

The plan is ``sample_data/batch/turntable.toml`` (3 inks ingested and fitted, 2 scenes ×
4 frames each: 24 renders, 6 previews) with its renders at ``--size`` pixels square and
ssaa 2 (default 384: large enough that the jobs, not the cluster's start-up, take most of
the time). One run of each, whole processes timed by :mod:`process` (GNU time):

1. ``gonio batch --workers 2`` into a fresh folder (local cluster start-up included);
2. ``gonio batch --workers 1`` into another;
3. the same 30 gonio commands (3 ingests, 3 fits, 24 renders) as separate processes one
   after the other, as a shell loop or ``make -j1`` runs them.

Prints the wall times, the speed-up of 2 workers over 1 (target ≥ 1.6 on 2 idle cores)
and the per-job overhead of a separate process: (3 − the jobs' own time in 2) / 30.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))

import process  # noqa: E402  (benchmarks/process.py: whole-process wall time and memory)

TARGET_SPEEDUP = 1.6


def copy_plan(folder: Path, size: int) -> Path:
    """The sample plan and its CSVs under ``folder``, renders at ``size`` px, ssaa 2."""
    shutil.copytree(ROOT / "sample_data" / "batch", folder / "batch")
    for csv in (ROOT / "sample_data").glob("ink_*.csv"):
        shutil.copy(csv, folder / csv.name)
    plan = folder / "batch" / "turntable.toml"
    with plan.open("a", encoding="utf-8") as fh:  # the [matrix] is the plan's last table
        fh.write(f"render = {{ width = {size}, height = {size}, ssaa = 2 }}\n")
    return plan


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=384, help="render width and height (px)")
    args = parser.parse_args()
    from gonio_cli.batch.plan import read_plan

    gonio = process.gonio_command()
    with tempfile.TemporaryDirectory(prefix="gonio-bench-batch-") as tmp:
        tmp = Path(tmp)
        plan = copy_plan(tmp / "data", args.size)
        walls = {}
        for workers in (2, 1):
            out = tmp / f"out{workers}"
            wall, rss, _ = process.run_measured([gonio, "-q", "batch", str(plan), "-o", str(out),
                                                 "--workers", str(workers)])
            records = [json.loads(l) for l in (out / "manifest.jsonl").open()]
            assert all(r["status"] == "ok" for r in records), "a job failed"
            walls[workers] = (wall, rss, sum(r["time_s"] for r in records))
        jobs = [j for j in read_plan(plan, tmp / "separate").jobs if j.runner == "gonio"]
        for j in jobs:
            for o in j.outputs:
                Path(o).parent.mkdir(parents=True, exist_ok=True)
        separate = 0.0
        for j in jobs:
            wall, _, _ = process.run_measured([gonio, "-q", *j.argv])
            separate += wall
    job_s = walls[1][2]
    n = len(jobs)
    print(f"gonio batch, sample turntable plan: 36 jobs ({n} gonio commands: 24 renders at "
          f"{args.size}² ssaa 2, 3 fits, 3 ingests; 6 previews); load {process.load_average()}")
    print(f"  2 workers           {walls[2][0]:6.2f} s  (driver peak RSS {walls[2][1]:.0f} MB)")
    print(f"  1 worker            {walls[1][0]:6.2f} s  (jobs' own time {job_s:.2f} s)")
    print(f"  {n} processes        {separate:6.2f} s  (one after the other)")
    speedup = walls[1][0] / walls[2][0]
    print(f"  speed-up 2 vs 1 worker: {speedup:.2f}x (target >= {TARGET_SPEEDUP}x on 2 idle "
          f"cores): {'met' if speedup >= TARGET_SPEEDUP else 'NOT met'}")
    print(f"  per-job overhead of a separate process: {(separate - job_s) / n * 1e3:.0f} ms "
          f"({n} processes {separate:.2f} s against {job_s:.2f} s of work in the workers)")


if __name__ == "__main__":
    main()
