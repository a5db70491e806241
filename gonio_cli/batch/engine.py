"""Run a plan's jobs on Dask distributed: a local cluster, or one already running.

Jobs whose earlier records still stand are settled here, before any cluster starts (a
rerun with nothing to do starts none); the others are submitted in graph order as futures
that take their upstream futures as arguments, so Dask runs each job when its inputs are
made, on whichever worker is free. A record comes back per job; images stay on disk.

The default cluster is :class:`distributed.LocalCluster` with one single-threaded worker
process per core, on 127.0.0.1 only, without a dashboard unless asked. A worker that dies
mid-job (killed, out of memory) is replaced by its nanny and the scheduler runs its jobs
again, ``retries`` + 1 times at most (the attempt logs of :mod:`.jobs` count them).
"""

from __future__ import annotations

import json
import os
import shutil
from typing import Any, Callable, Mapping

from ..machine import cpu_count
from . import MANIFEST_NAME
from .jobs import ATTEMPTS_DIR, execute, failed_roots, record, up_to_date
from .plan import Plan, check_graph, dependencies

#: Seconds to wait for a scheduler given with ``--scheduler`` (and for its workers).
CONNECT_TIMEOUT_S = 30


def read_manifest(outdir: str | os.PathLike) -> dict[str, dict[str, Any]]:
    """The records of an earlier run in ``outdir`` by key ({} if none or unreadable lines)."""
    path = os.path.join(outdir, MANIFEST_NAME)
    out: dict[str, dict[str, Any]] = {}
    try:
        with open(path, encoding="utf-8") as fh:
            for line in fh:
                try:
                    rec = json.loads(line)
                except json.JSONDecodeError:
                    continue  # a damaged line: that job simply runs again
                if isinstance(rec, dict) and isinstance(rec.get("key"), str):
                    out[rec["key"]] = rec
    except OSError:
        pass
    return out


def write_manifest(outdir: str | os.PathLike, records: list[Mapping[str, Any]]) -> str:
    """``OUTDIR/manifest.jsonl``, one record per line, written atomically."""
    from ..artifact import atomic_path
    from . import MANIFEST_SCHEMA, MANIFEST_SCHEMA_VERSION

    path = os.path.join(outdir, MANIFEST_NAME)
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8") as fh:
        for r in records:
            fh.write(json.dumps({"schema": MANIFEST_SCHEMA,
                                 "schema_version": MANIFEST_SCHEMA_VERSION, **r},
                                sort_keys=False) + "\n")
    return path


def settle(plan: Plan, previous: Mapping[str, Mapping[str, Any]]) -> tuple[dict, list[str]]:
    """({key: record} of the jobs still up to date, keys of the jobs to run), in graph
    order: a job runs if its earlier record does not stand or a job it needs runs."""
    jobs = {j.key: j for j in plan.jobs}
    deps = dependencies(plan)
    done: dict[str, dict] = {}
    stale: list[str] = []
    for key in check_graph(plan):
        job = jobs[key]
        if not any(d in stale for d in deps[key]) and up_to_date(job, previous.get(key)):
            done[key] = {**previous[key], "status": "skipped", "attempts": 0,
                         "labels": dict(job.labels)}
        else:
            stale.append(key)
    return done, stale


def connect(workers: int | None, scheduler: str | None, dashboard: bool, retries: int):
    """A Dask client (and the local cluster it owns, or None)."""
    import importlib.util

    from ..errors import InputError

    missing = InputError("gonio batch needs Dask distributed, which is not installed",
                         fix="pip install 'gonio[batch]'")
    if importlib.util.find_spec("distributed") is None:
        raise missing
    # a local cluster's fork server starts first: its imports overlap this process's
    method = None if scheduler else worker_start_method()
    try:
        import dask
        from distributed import Client, LocalCluster
    except ImportError:
        raise missing from None

    if scheduler:
        if os.path.isfile(scheduler):
            return Client(scheduler_file=scheduler, timeout=CONNECT_TIMEOUT_S), None
        return Client(scheduler, timeout=CONNECT_TIMEOUT_S), None
    # a job whose worker dies is tried again on another, retries + 1 times in all
    config: dict[str, Any] = {"distributed.scheduler.allowed-failures": retries}
    if method:
        config["distributed.worker.multiprocessing-method"] = method
    dask.config.set(config)
    cluster = LocalCluster(n_workers=workers or cpu_count(), threads_per_worker=1,
                           processes=True, host="127.0.0.1",
                           dashboard_address="127.0.0.1:0" if dashboard else None)
    return Client(cluster), cluster


#: Modules a local cluster's fork server imports once, before it forks the workers: Dask,
#: the job runner, gonio's CLI and the render pipeline (what every worker needs first).
WORKER_PRELOAD = ("distributed", "gonio_cli.batch.jobs", "gonio_cli.cli",
                  "gonio_cli.render.pipeline")


def worker_start_method() -> str | None:
    """``"forkserver"`` where the OS has it (Linux, macOS), with :data:`WORKER_PRELOAD`
    imported once in the server, so each worker starts from a process that has them
    instead of importing them itself (Dask's default, ``spawn``); None elsewhere. The fork
    server is single-threaded, so forking it is safe, unlike forking the driver. It is
    started here, so that its imports run while the caller imports Dask (~0.3 s)."""
    import multiprocessing

    if "forkserver" not in multiprocessing.get_all_start_methods():
        return None
    from multiprocessing import forkserver

    multiprocessing.set_forkserver_preload(list(WORKER_PRELOAD))
    forkserver.ensure_running()
    return "forkserver"


def run_plan(plan: Plan, *, workers: int | None = None, scheduler: str | None = None,
             retries: int = 2, dashboard: bool = False,
             on_start: Callable[[int, str | None], None] | None = None,
             on_record: Callable[[dict], None] | None = None) -> list[dict]:
    """Run the jobs of ``plan`` that are not up to date; return every job's record in
    plan order (also written to ``OUTDIR/manifest.jsonl``).

    ``on_start(n_to_run, dashboard_link)`` is called once the cluster is up (or with 0
    when nothing is to run), ``on_record(record)`` as each job ends.
    """
    from ..artifact import make_folder

    outdir = os.fspath(plan.outdir)
    make_folder(outdir)
    previous = read_manifest(outdir)
    for folder in sorted({os.path.dirname(o) for j in plan.jobs for o in j.outputs}):
        make_folder(folder)
    shutil.rmtree(os.path.join(outdir, ATTEMPTS_DIR), ignore_errors=True)
    records, stale = settle(plan, previous)
    try:
        if stale:
            _submit(plan, stale, records, previous, workers, scheduler, retries, dashboard,
                    on_start, on_record)
        elif on_start is not None:
            on_start(0, None)
    finally:  # also after Ctrl-C: what ran is kept (a job without a record runs next time)
        write_manifest(outdir, [records.get(j.key) or previous[j.key] for j in plan.jobs
                                if j.key in records or j.key in previous])
    return [records[j.key] for j in plan.jobs]


def _submit(plan, stale, records, previous, workers, scheduler, retries, dashboard,
            on_start, on_record) -> None:
    """Run the ``stale`` jobs on Dask, adding each one's record to ``records`` (which
    holds the settled ones) as it ends."""
    jobs = {j.key: j for j in plan.jobs}
    deps = dependencies(plan)
    outdir = os.fspath(plan.outdir)
    client, cluster = connect(workers, scheduler, dashboard, retries)
    from distributed import as_completed

    try:
        if on_start is not None:
            on_start(len(stale), client.dashboard_link if dashboard else None)
        futures: dict[str, Any] = {}
        token = os.urandom(4).hex()
        for key in stale:
            upstream = [futures[d] if d in futures else records[d] for d in deps[key]]
            futures[key] = client.submit(execute, jobs[key], outdir, previous.get(key),
                                         *upstream, key=task_key(jobs[key], token),
                                         pure=False, retries=retries)
        keys = {f.key: k for k, f in futures.items()}
        for future in as_completed(list(futures.values())):
            key = keys[future.key]
            try:
                rec = future.result()
            except Exception as exc:  # the job's worker kept dying, or a lost cluster
                bad = failed_roots([records[d] for d in deps[key] if d in records])
                rec = record(jobs[key], "blocked" if bad else "failed",
                             attempts=_attempts(outdir, jobs[key]),
                             error=(f"not run: {', '.join(bad)} failed" if bad else
                                    " ".join(f"lost its worker: {type(exc).__name__}: "
                                             f"{exc}".split())),
                             **({"failed_roots": bad} if bad else {}))
            records[key] = rec
            if on_record is not None:
                on_record(rec)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def task_key(job, token: str) -> str:
    """The Dask key of ``job``'s task: ``COMMAND-TOKEN-JOBKEY``. Dask groups tasks by the
    key's first word (``dask.utils.key_split``), so every render shares one duration
    estimate, every fit another …; with those, work stealing moves queued renders to an
    idle worker (a job runs where its upstream's small record is, so without them one
    worker was left the last material's renders while the other idled: ~2 s of 13 at
    1024², 2 workers)."""
    return f"{job.command.split()[0]}-{token}-{job.key}"


def _attempts(outdir: str, job) -> int:
    try:
        with open(os.path.join(outdir, ATTEMPTS_DIR, job.file_name + ".log"),
                  encoding="utf-8") as fh:
            return sum(1 for _ in fh)
    except OSError:
        return 0
