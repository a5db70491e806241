"""``gonio batch``: the thin shell over :mod:`gonio_cli.batch` (Dask imported on first use)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from .. import log
from ..errors import InputError

HELP = """Run a plan of gonio jobs on Dask: locally on every core, or on a cluster.

A plan (TOML, docs/batch.md) names materials (CSV files to ingest and fit), a matrix of
materials x scenes x --var values x turntable frames, and plain jobs; a job whose input is
another job's output waits for it. Jobs run inside the workers through gonio's own code.
A job whose outputs exist with the same input hashes, parameters and gonio version is
skipped. OUTDIR/manifest.jsonl is a journal: a record per job appended as it ends, so a
kill of the driver or a worker loses at most the jobs running then. Also writes
OUTDIR/index.html (a contact sheet). A failing job is reported with its one-line error
and the others still run; the exit status is then 1. Ctrl-C and SIGTERM keep every
record (exit 130, 143).

\b
Example:
  gonio batch sample_data/batch/turntable.toml -o out/batch
  gonio batch plan.toml -o out/batch --workers 4 --retries 3 --job-timeout 600
  gonio batch plan.toml -o out/batch --dry-run
  gonio batch plan.toml -o out/batch --scheduler tcp://10.0.0.5:8786
"""


def batch(
    plan: Path = typer.Argument(..., metavar="PLAN.toml", show_default=False,
                                help="The plan; paths in it are relative to it."),
    output: Path = typer.Option(..., "--output", "-o", metavar="OUTDIR",
                                help="The output folder (${out} in the plan)."),
    workers: Optional[int] = typer.Option(
        None, "--workers", "-w", metavar="N",
        help="Worker processes of the local cluster [default: one per core]."),
    scheduler: Optional[str] = typer.Option(
        None, "--scheduler", metavar="ADDRESS|FILE",
        help="Use a running Dask scheduler (tcp://host:8786 or a scheduler file) instead "
             "of a local cluster."),
    retries: int = typer.Option(2, "--retries", metavar="N",
                                help="Times a job is run again after its worker dies, on "
                                     "any scheduler (bad input is never retried)."),
    job_timeout: Optional[float] = typer.Option(
        None, "--job-timeout", metavar="SECONDS",
        help="Stop a job that runs longer (its worker process is restarted) and report "
             "it [default: no limit]."),
    jobs_per_task: int = typer.Option(
        32, "--jobs-per-task", metavar="N",
        help="Most jobs one Dask task runs: jobs ready together are grouped while every "
             "worker still gets two tasks; 1 sends each job alone."),
    dry_run: bool = typer.Option(False, "--dry-run",
                                 help="Print the jobs that would run and why; run nothing."),
    dashboard: bool = typer.Option(False, "--dashboard",
                                   help="Serve the Dask dashboard (on 127.0.0.1)."),
) -> None:
    import sys
    import time

    # lazy: gonio --help and the other commands do not load the batch core (gonio_cli.batch) (benchmarks/bench_startup.py)
    from ..batch.plan import read_plan

    start = time.perf_counter()
    _check_options(workers, scheduler, retries, job_timeout, jobs_per_task, output)
    p = read_plan(plan, output)  # every plan error before anything runs
    if dry_run:
        _dry_run(p, output)
        return
    # lazy: gonio --help and the other commands do not load the batch core (gonio_cli.batch) (benchmarks/bench_startup.py)
    from ..batch.sheet import write_sheet

    records = _run(p, output, dict(workers=workers, scheduler=scheduler, retries=retries,
                                   timeout_s=job_timeout, dashboard=dashboard,
                                   jobs_per_task=jobs_per_task))
    sheet = write_sheet(output, records, title=f"gonio batch: {plan.name}")
    counts = {s: sum(r["status"] == s for r in records) for s in ("ok", "skipped", "failed", "blocked")}
    ran = counts["ok"] + counts["failed"]
    total = time.perf_counter() - start
    what = (f"ran 0 jobs: all {len(records)} are up to date" if not ran and not counts["blocked"]
            else f"ran {ran} of {len(records)} jobs ({counts['ok']} ok, {counts['failed']} "
                 f"failed, {counts['blocked']} not run, {counts['skipped']} up to date)")
    log.info(f"gonio batch: {what} in {total:.1f} s; {output}/manifest.jsonl, {sheet}")
    warned = [r["key"] for r in records if r["status"] == "ok" and r.get("warnings")]
    if warned:
        log.warn(f"{len(warned)} job(s) warned ({', '.join(warned[:3])}"
                 f"{', ...' if len(warned) > 3 else ''}): their warnings are in "
                 f"{output}/manifest.jsonl")
    failed = [r for r in records if r["status"] == "failed"]
    blocked = [r["key"] for r in records if r["status"] == "blocked"]
    for r in failed:  # shown with --quiet too, like every error
        print(f"gonio: failed: {r['key']}: {r['error']}", file=sys.stderr)
    if blocked:
        print(f"gonio: not run, as a job they need failed: {', '.join(blocked)}",
              file=sys.stderr)
    if failed or blocked:
        raise typer.Exit(1)


def _check_options(workers, scheduler, retries, job_timeout, jobs_per_task, output) -> None:
    """One line on the first option that cannot be used."""
    if workers is not None and scheduler is not None:
        raise InputError("--workers and --scheduler exclude each other",
                         fix="a running cluster has its own workers; give one of them")
    if workers is not None and workers < 1:
        raise InputError(f"--workers {workers} is not a number of processes", fix="give N >= 1")
    if retries < 0:
        raise InputError(f"--retries {retries} is negative", fix="give N >= 0")
    if job_timeout is not None and not job_timeout > 0:
        raise InputError(f"--job-timeout {job_timeout:g} is not a time",
                         fix="give SECONDS > 0, or leave it out for no limit")
    if jobs_per_task < 1:
        raise InputError(f"--jobs-per-task {jobs_per_task} is not a number of jobs",
                         fix="give N >= 1 (1: every job its own task)")
    if output.exists() and not output.is_dir():
        raise InputError(f"-o {output} is a file", fix="name a folder")


def _dry_run(p, output: Path) -> None:
    """Print each job that would run and why (stdout), and a summary; run nothing."""
    # lazy: gonio --help and the other commands do not load the batch core (gonio_cli.batch) (benchmarks/bench_startup.py)
    from ..batch.engine import dry_run

    stale, n_done = dry_run(p)
    for key, why in stale:
        print(f"would run {key}: {why}")
    log.info(f"gonio batch --dry-run: would run {len(stale)} of {len(p.jobs)} jobs "
             f"({n_done} up to date in {output}); nothing was run")


class _Stopped(KeyboardInterrupt):
    """SIGTERM, handled as Ctrl-C is."""


def _run(p, output: Path, options: dict) -> list[dict]:
    """Run the plan with a progress display; Ctrl-C or SIGTERM: one line saying what was
    kept, exit 130 or 143 (128 + the signal)."""
    import signal
    import sys
    import threading

    # lazy: gonio --help and the other commands do not load the batch core (gonio_cli.batch) (benchmarks/bench_startup.py)
    from ..batch.engine import run_plan

    bar = _Progress()

    def started(n: int, link: str | None) -> None:
        if link:
            log.info(f"gonio batch: dashboard at {link}")
        bar.start(n)

    def term(signum, frame):  # noqa: ARG001
        raise _Stopped()

    main = threading.current_thread() is threading.main_thread()
    old = signal.signal(signal.SIGTERM, term) if main else None
    try:
        return run_plan(p, **options, on_start=started, on_record=bar.update)
    except KeyboardInterrupt as exc:
        bar.stop()
        name, code = ("SIGTERM", 143) if isinstance(exc, _Stopped) else ("Ctrl-C", 130)
        print(f"gonio batch: stopped by {name} after {bar.done} of {bar.n} jobs ended; their "
              f"records are in {output}/manifest.jsonl and a rerun runs only the rest",
              file=sys.stderr)
        raise typer.Exit(code) from None
    finally:
        if main:
            signal.signal(signal.SIGTERM, old)
        bar.stop()


class _Progress:
    """One bar over the jobs to run (done, running, failed) on stderr when it is a
    terminal; else a line every tenth of the jobs (at least every job); nothing with
    --quiet."""

    def __init__(self):
        self.bar = self.task = None
        self.done = self.failed = 0
        self.n = 0
        self.every = 0  # a line per this many jobs (0: none)

    def start(self, n: int) -> None:
        import sys
        import time

        self.n = n
        self.t0 = time.perf_counter()
        if not n or log.is_quiet():
            return
        if not sys.stderr.isatty():
            self.every = max(1, -(-n // 10))
            return
        from rich.console import Console
        from rich.progress import Progress

        self.bar = Progress(console=Console(file=sys.stderr), transient=True)
        self.bar.start()
        self.task = self.bar.add_task(self._text(), total=n)

    def _text(self) -> str:
        return f"jobs: {self.done} done, {self.n - self.done} running or waiting, {self.failed} failed"

    def update(self, rec: dict) -> None:
        import sys
        import time

        self.done += 1
        self.failed += rec["status"] in ("failed", "blocked")
        if self.bar is not None:
            self.bar.update(self.task, advance=1, description=self._text())
        elif self.every and (self.done % self.every == 0 or self.done == self.n):
            print(f"gonio batch: {self.done} of {self.n} jobs done ({self.failed} failed) "
                  f"in {time.perf_counter() - self.t0:.1f} s", file=sys.stderr, flush=True)

    def stop(self) -> None:
        if self.bar is not None:
            self.bar.stop()
            self.bar = None


EXAMPLE = "gonio batch sample_data/batch/turntable.toml -o out/batch"

SHORT_HELP = "Run a plan of jobs on Dask, locally or on a cluster, with a contact sheet."


def register(app: typer.Typer) -> None:
    """Attach ``gonio batch`` to the app."""
    app.command("batch", help=HELP, short_help=SHORT_HELP)(batch)
