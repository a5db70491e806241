"""Benchmark of ``gonio batch``: the sample turntable plan on 2 workers, on 1, and as
separate ``gonio`` processes.

    .venv/bin/python benchmarks/bench_batch.py [--sizes 384,1024] [--repeats 2] [--no-faults]
    .venv/bin/python benchmarks/bench_batch.py --faults [--fault-jobs 280 --fault-size 64]

After the timings (or alone, with ``--faults``) the fault benchmark runs: a 280-job plan
(the sample's inks, 4 materials × 2 scenes × 33-frame turntables at 64², with previews;
benchmarks/batch_faults.py) with a worker SIGKILLed, then the driver SIGKILLed, then
SIGTERMed, mid-run.

The plan is ``sample_data/batch/turntable.toml`` (3 inks ingested and fitted, 2 scenes ×
4 frames each: 24 renders, 6 previews) with its renders at each of ``--sizes`` pixels
square and ssaa 2. For each size, after one untimed run (it fills gonio's caches), whole
processes timed by :mod:`process` (GNU time), best of ``--repeats``:

1. ``gonio batch --workers 2`` into a fresh folder (local cluster start-up included);
2. ``gonio batch --workers 1`` into another;
3. the same 30 gonio commands (3 ingests, 3 fits, 24 renders) as separate processes one
   after the other, as a shell loop or ``make -j1`` runs them.

Prints the wall times, the speed-up of 2 workers over 1 (target ≥ 1.6 on 2 idle cores;
best of each, and each alternated pair's ratio), what two renders at once cost each other
on the machine at that moment (in-process medians: one render alone, then two processes
at once; the speed-up follows their ratio), and the per-job overhead of a separate
process: (3 − the jobs' own time in 2) / 30. At 384² the jobs take ~3 s in all and a
run's fixed cost (~1.3 s: Dask's import and local cluster, each worker's first gonio
import) caps the speed-up; at 1024² the work dominates.

``--faults``: the sample plan with ``--fault-frames`` frames per turntable (16: 96
renders at ``--fault-size`` px, 6 previews, 3 ingests and 3 fits: 108 jobs) on an external
scheduler with two workers (``dask scheduler`` / ``dask worker --nworkers 2``), once
cleanly (the driver's CPU and wall time per job), then with a fault mid-run (a third of
the jobs recorded): a worker SIGKILLed, the driver SIGKILLed, the driver sent SIGTERM.
After each it prints the jobs started again within the run, the outputs whose sha256 is
not the journal's, and the jobs the rerun runs against those not finished at the fault.
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
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


def batch_wall(gonio: str, plan: Path, out: Path, workers: int) -> tuple[float, float, float]:
    """(wall s, peak RSS MB, jobs' own time s) of one ``gonio batch`` into a fresh folder."""
    shutil.rmtree(out, ignore_errors=True)
    wall, rss, _ = process.run_measured([gonio, "-q", "batch", str(plan), "-o", str(out),
                                         "--workers", str(workers)])
    records = [json.loads(line) for line in (out / "manifest.jsonl").open()]
    assert all(r["status"] == "ok" for r in records), "a job failed"
    return wall, rss, sum(r["time_s"] for r in records)


#: One render repeated in one process: (median s of the repeats after the first), printed.
_RENDER_LOOP = """
import statistics, sys, time
from gonio_cli.__main__ import use_blas_threads
use_blas_threads()
from gonio_cli import cli
times = []
for _ in range(6):
    start = time.perf_counter()
    cli.run(sys.argv[1:])
    times.append(time.perf_counter() - start)
print(statistics.median(times[1:]))
"""


def contention(warm: Path, size: int) -> tuple[float, float]:
    """(s alone, s each with two at once) of the plan's sphere render at ``size``² ssaa 2,
    in-process medians: how much two jobs at once slow each other on this machine now (on
    a virtual machine this moves with the host's load, and sets the speed-up)."""
    import subprocess

    scene = warm.parent / f"data{size}" / "batch" / "scenes" / "sphere.toml"
    material = next(warm.glob("*/*.material.json"))

    def start(k: int):
        argv = ["-q", "render", str(scene), "-o", str(warm / f"contention{k}.png"),
                "--width", str(size), "--height", str(size), "--ssaa", "2",
                "--var", f"material={material}"]
        return subprocess.Popen([sys.executable, "-c", _RENDER_LOOP, *argv],
                                stdout=subprocess.PIPE, text=True,
                                env=process.user_environment())

    alone = float(start(0).communicate()[0])
    pair = [start(0), start(1)]
    together = sum(float(p.communicate()[0]) for p in pair) / 2
    return alone, together


def one_size(gonio: str, tmp: Path, size: int, repeats: int) -> None:
    from gonio_cli.batch.plan import read_plan

    plan = copy_plan(tmp / f"data{size}", size)
    batch_wall(gonio, plan, tmp / "warm", 2)  # caches (colour tables, numba) filled first
    runs: dict[int, list[tuple[float, float, float]]] = {1: [], 2: []}
    for _ in range(repeats):  # alternated, so a passing load spike hits both
        for workers in (2, 1):
            runs[workers].append(batch_wall(gonio, plan, tmp / f"out{workers}", workers))
    walls = {w: min(r) for w, r in runs.items()}
    pairs = sorted(one[0] / two[0] for one, two in zip(runs[1], runs[2]))
    jobs = [j for j in read_plan(plan, tmp / f"separate{size}").jobs if j.runner == "gonio"]
    for j in jobs:
        for o in j.outputs:
            Path(o).parent.mkdir(parents=True, exist_ok=True)
    separate = 0.0
    for j in jobs:
        wall, _, _ = process.run_measured([gonio, "-q", *j.argv])
        separate += wall
    job_s = walls[1][2]
    n = len(jobs)
    print(f"\n24 renders at {size}² ssaa 2 (36 jobs: {n} gonio commands, 6 previews; best of "
          f"{repeats}; load {process.load_average()})")
    print(f"  2 workers           {walls[2][0]:6.2f} s  (driver peak RSS {walls[2][1]:.0f} MB)")
    print(f"  1 worker            {walls[1][0]:6.2f} s  (jobs' own time {job_s:.2f} s)")
    print(f"  {n} processes        {separate:6.2f} s  (one after the other)")
    speedup = walls[1][0] / walls[2][0]
    print(f"  speed-up 2 vs 1 worker: {speedup:.2f}x (target >= {TARGET_SPEEDUP}x on 2 idle "
          f"cores): {'met' if speedup >= TARGET_SPEEDUP else 'NOT met'}; alternated pairs "
          f"{', '.join(f'{r:.2f}' for r in pairs)} (median {statistics.median(pairs):.2f}x)")
    alone, together = contention(tmp / "warm", size)
    print(f"  the machine now: one {size}² render {alone * 1e3:.0f} ms alone, "
          f"{together * 1e3:.0f} ms each with two at once ({together / alone:.2f}x; on idle "
          f"cores only what the two share slows them: memory bandwidth and caches), so 2 "
          f"workers can be about {2 * alone / together:.2f}x as fast as 1 on the renders")
    print(f"  per-job overhead of a separate process: {(separate - job_s) / n * 1e3:.0f} ms "
          f"({n} processes {separate:.2f} s against {job_s:.2f} s of work in the workers)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="384,1024",
                        help="render widths and heights (px), comma-separated")
    parser.add_argument("--repeats", type=int, default=2, help="timed runs per worker count")
    parser.add_argument("--faults", action="store_true",
                        help="only the fault benchmark (workers and the driver killed mid-run)")
    parser.add_argument("--no-faults", action="store_true",
                        help="leave the fault benchmark out (it runs after the timings)")
    parser.add_argument("--fault-jobs", type=int, default=280,
                        help="jobs of the fault plan (4 materials x 2 scenes x 33 frames: 280)")
    parser.add_argument("--fault-size", type=int, default=64, help="render size (px)")
    args = parser.parse_args()
    gonio = process.gonio_command()
    if not args.faults:
        timings(gonio, args)
    if not args.no_faults:
        from batch_faults import run_faults

        with tempfile.TemporaryDirectory(prefix="gonio-bench-faults-") as tmp:
            run_faults(gonio, Path(tmp), args.fault_jobs, args.fault_size)


def timings(gonio: str, args) -> None:
    """The sample plan's wall time per worker count and render size."""
    print("gonio batch, the sample turntable plan (sample_data/batch/turntable.toml), whole "
          "processes; the fixed cost of a run (Dask's local cluster ~0.6 s to start and "
          "0.2 s to stop, its import 0.4 s, each worker's first gonio import) weighs on "
          "small renders")
    with tempfile.TemporaryDirectory(prefix="gonio-bench-batch-") as tmp:
        for size in (int(s) for s in args.sizes.split(",")):
            one_size(gonio, Path(tmp), size, args.repeats)


if __name__ == "__main__":
    main()
