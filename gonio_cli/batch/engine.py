"""Run a plan's jobs on Dask distributed: a local cluster, or one already running.

Jobs whose earlier records still stand are settled here, before any cluster starts (a
rerun with nothing to do starts none). The driver then submits, in bulk, every job whose
inputs are made (jobs made ready together share a task while every worker still gets two
or more: :func:`chunks`), and as each result arrives it appends the record to the journal
(:mod:`.journal`, fsync'ed), releases the result and submits the jobs it made ready. A
job's upstream records go to it as plain values, never as Dask futures: a worker that
dies holds nothing another job needs, so Dask never runs a finished job again, and a kill
of anything loses at most the jobs running then. Images stay on disk.

Retries and the time limit hold on any scheduler: a job whose worker died is submitted
again by the driver (a new task) until it has started ``retries`` + 1 times, and the worker
refuses a start beyond that whatever the scheduler's own ``allowed-failures`` did
(:func:`.jobs.refused`); a job running longer than ``timeout_s`` is stopped in its worker
(:func:`.jobs.time_limit`) and reported.

The default cluster is :class:`distributed.LocalCluster` with one single-threaded worker
process per core, on 127.0.0.1 only, without a dashboard unless asked.
"""

from __future__ import annotations

import contextlib
import os
from collections import deque
from typing import Any, Callable, Mapping

from .. import __version__
from ..errors import InputError
from ..folders import make_folder
from ..machine import cpu_count
from .jobs import attempt_log, execute_chunk, failed_roots, files, receipt, record, \
    timed_out, why_stale, worker_version
from .journal import DONE_DIR, Journal, clear_run_state, compact, lock_folder, read_journal, \
    read_receipt, recover_receipts
from .plan import Plan, dependencies

#: Seconds to wait for a scheduler given with ``--scheduler`` (and for its workers).
CONNECT_TIMEOUT_S = 30


def settle(plan: Plan, previous: Mapping[str, Mapping[str, Any]]
           ) -> tuple[dict, list[str], dict[str, str]]:
    """({key: record} of the jobs still up to date, keys of the jobs to run in graph
    order, {key: why it runs}): a job runs if its earlier record does not stand
    (:func:`.jobs.why_stale`) or a job it needs runs. Linear in the number of jobs: a
    file many jobs read (a scene, a material) is hashed once."""
    jobs = {j.key: j for j in plan.jobs}
    deps = dependencies(plan)
    done: dict[str, dict] = {}
    stale: list[str] = []
    why: dict[str, str] = {}
    seen: dict[str, dict[str, Any]] = {}  # path -> its record as files() makes it
    for key in graph_order(deps):
        job = jobs[key]
        upstream = next((d for d in deps[key] if d in why), None)
        reason = f"it needs {upstream}, which runs" if upstream else \
            why_stale(job, previous.get(key), _inputs(job, seen) if key in previous else None)
        if reason is None:
            done[key] = {**previous[key], "status": "skipped", "attempts": 0,
                         "labels": dict(job.labels)}
        else:
            stale.append(key)
            why[key] = reason
    return done, stale, why


def _inputs(job, seen: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """:func:`.jobs.files` of ``job``'s inputs, each path looked at once per ``seen``."""
    for p in job.inputs:
        if p not in seen:
            seen[p] = files([p], (p,))[0]  # with its modification time, used or not
    return [seen[p] if p in job.sources else {"path": p, "sha256": seen[p]["sha256"]}
            for p in job.inputs]


def graph_order(deps: Mapping[str, list[str]]) -> list[str]:
    """The keys of an acyclic ``deps`` ({key: keys it needs}) in a runnable order, plan
    order among the ready ones (Kahn's algorithm)."""
    waiting = {k: len(d) for k, d in deps.items()}
    users: dict[str, list[str]] = {}
    for k, d in deps.items():
        for x in d:
            users.setdefault(x, []).append(k)
    ready = deque(k for k, n in waiting.items() if n == 0)
    order: list[str] = []
    while ready:
        k = ready.popleft()
        order.append(k)
        for u in users.get(k, ()):
            waiting[u] -= 1
            if waiting[u] == 0:
                ready.append(u)
    return order


def dry_run(plan: Plan) -> tuple[list[tuple[str, str]], int]:
    """([(key, why it would run)], number of jobs up to date), touching nothing."""
    outdir = os.fspath(plan.outdir)
    previous = read_journal(outdir)
    if os.path.isdir(os.path.join(outdir, DONE_DIR)):  # what a rerun would recover
        for j in plan.jobs:
            rec = read_receipt(outdir, j.file_name)
            if rec and rec.get("status") == "ok" and rec.get("run") != \
                    previous.get(j.key, {}).get("run"):
                previous[j.key] = rec
    done, stale, why = settle(plan, previous)
    return [(k, why[k]) for k in stale], len(done)


def connect(workers: int | None, scheduler: str | None, dashboard: bool):
    """A Dask client (and the local cluster it owns, or None)."""
    import importlib.util

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
        client = Client(scheduler_file=scheduler, timeout=CONNECT_TIMEOUT_S) \
            if os.path.isfile(scheduler) else Client(scheduler, timeout=CONNECT_TIMEOUT_S)
        check_versions(client, scheduler)
        return client, None
    # a job whose worker dies is submitted again by the driver (:func:`lost`), as on any
    # scheduler: Dask itself gives up at once, so the attempts are counted in one place
    config: dict[str, Any] = {"distributed.scheduler.allowed-failures": 0}
    if method:
        config["distributed.worker.multiprocessing-method"] = method
    dask.config.set(config)
    import logging

    # a worker lost (killed, stopped by --job-timeout) is reported in its job's record
    # and on one line at the end; Dask's own log lines about it would come first
    for name in ("distributed.scheduler", "distributed.nanny"):
        logging.getLogger(name).setLevel(logging.CRITICAL)
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


def check_versions(client, scheduler: str) -> None:
    """Refuse workers whose gonio is not the driver's version (their outputs would not
    be what the records say); a worker that joins later is checked by each job
    (:func:`.jobs.execute`)."""
    try:
        versions = client.run(worker_version)
    except Exception as exc:  # a worker without gonio: it cannot unpickle the function
        client.close()
        raise InputError(f"the workers of {scheduler} cannot run gonio ({type(exc).__name__}: "
                         f"{exc})", fix="install this gonio on every worker (pip install "
                                        "'gonio[batch]')") from None
    other = {a: v for a, v in versions.items() if v != __version__}
    if other:
        client.close()
        address, version = next(iter(sorted(other.items())))
        raise InputError(f"worker {address} of {scheduler} runs gonio {version}, this driver "
                         f"{__version__} ({len(other)} of {len(versions)} workers differ)",
                         fix="install the same gonio on the driver and every worker")


def run_plan(plan: Plan, *, workers: int | None = None, scheduler: str | None = None,
             retries: int = 2, timeout_s: float | None = None, dashboard: bool = False,
             jobs_per_task: int = 32,
             on_start: Callable[[int, str | None], None] | None = None,
             on_record: Callable[[dict], None] | None = None) -> list[dict]:
    """Run the jobs of ``plan`` that are not up to date; return every job's record in
    plan order. Each record is appended to ``OUTDIR/manifest.jsonl`` as its job ends;
    the journal is compacted when the run ends here (normally, by an error or by an
    interrupt: what ran is kept, a job without a record runs next time).

    ``retries``: starts of a job after its worker died; ``timeout_s``: seconds a job may
    run (None: no limit); ``jobs_per_task``: the most jobs one Dask task runs
    (:func:`chunks`). ``on_start(n_to_run, dashboard_link)`` is called once the
    cluster is up (or with 0 when nothing is to run), ``on_record(record)`` as each job
    ends.

    Raises
    ------
    InputError : another batch holds the output folder's lock; a worker's gonio version
        is not the driver's.
    """
    outdir = os.fspath(plan.outdir)
    make_folder(outdir)
    with lock_folder(outdir):
        previous = read_journal(outdir)
        recover_receipts(outdir, previous, [j.key for j in plan.jobs])
        for folder in sorted({os.path.dirname(o) for j in plan.jobs for o in j.outputs}):
            make_folder(folder)
        clear_run_state(outdir)
        records, stale, _ = settle(plan, previous)
        try:
            if stale:
                settings = {"run": os.urandom(6).hex(), "retries": retries,
                            "timeout_s": timeout_s, "gonio_version": __version__,
                            "jobs_per_task": jobs_per_task}
                _submit(plan, stale, records, previous, settings,
                        (workers, scheduler, dashboard), on_start, on_record)
            elif on_start is not None:
                on_start(0, None)
        finally:
            compact(outdir, [records.get(j.key) or previous[j.key] for j in plan.jobs
                             if j.key in records or j.key in previous])
    return [records[j.key] for j in plan.jobs]


def _submit(plan, stale, records, previous, settings, cluster_args, on_start,
            on_record) -> None:
    """Run the ``stale`` jobs on Dask, adding each one's record to ``records`` (which
    holds the settled ones) and to the journal as it ends.

    The driver works in batches: it takes every result that has arrived (one gather),
    journals their records with one ``fsync`` (:meth:`.journal.Journal.extend`) before it
    counts them, and submits every job they made ready in one ``client.map``. So its
    cost per job falls as results come faster (a driver under load takes more at once),
    and no job is submitted before the records it needs are on the disk."""
    from distributed import as_completed

    jobs = {j.key: j for j in plan.jobs}
    deps = dependencies(plan)
    outdir = os.fspath(plan.outdir)
    waiting, users = _waits(stale, deps)
    client, cluster = connect(*cluster_args)
    journal = Journal(outdir)
    pending = as_completed()
    running: dict[str, list[tuple[str, int]]] = {}  # task key -> [(job key, submissions)]

    def submit(go: list[tuple[str, int]]) -> None:
        """Submit the jobs ``go`` ((key, submission number)) in one call, in tasks of
        :func:`chunks` (a job submitted again after a loss goes alone)."""
        slots = max(1, sum(client.nthreads().values()))
        groups = chunks(go, [jobs[k].command.split()[0] for k, _ in go], slots,
                        settings["jobs_per_task"])
        if not groups:
            return
        futures = client.map(
            execute_chunk, [[jobs[k] for k, _ in g] for g in groups], [outdir] * len(groups),
            [[previous.get(k) for k, _ in g] for g in groups],
            [[tuple(records[d] for d in deps[k]) for k, _ in g] for g in groups],
            [settings] * len(groups),
            key=[task_key(jobs[g[0][0]], f"{settings['run']}{g[0][1]}", len(g)) for g in groups],
            pure=False, retries=0)
        for g, f in zip(groups, futures):
            running[f.key] = g
        pending.update(futures)

    def finish(done: list[dict]) -> list[tuple[str, int]]:
        """Journal and count the records ``done`` and those of the jobs they block;
        return the jobs they made ready to run."""
        go = []
        while done:
            with signals_held():  # a record is in the journal and counted, or neither
                journal.extend(done)
                for rec in done:
                    records[rec["key"]] = rec
                    if on_record is not None:
                        on_record(rec)
            ready = [u for rec in done for u in users.get(rec["key"], ())
                     if _count_down(waiting, u)]
            done = []
            for key in ready:
                bad = failed_roots([records[d] for d in deps[key]])
                if bad:  # a job it needs failed: not run, recorded in the next round
                    done.append(record(jobs[key], "blocked", run=settings["run"], failed_roots=bad,
                                       error=f"not run: {', '.join(bad)} failed"))
                else:
                    go.append((key, 1))
        return go

    try:
        if on_start is not None:
            on_start(len(stale), client.dashboard_link if cluster_args[2] else None)
        submit([(k, 1) for k in stale if waiting[k] == 0])
        while not pending.is_empty():
            done, again = _results(_gather(client, pending.next_batch()), running, jobs,
                                   outdir, settings)
            submit(again + finish(done))
    finally:
        journal.close()
        client.close()
        if cluster is not None:
            cluster.close()


def _results(arrived, running, jobs, outdir: str, settings) -> tuple[list[dict], list]:
    """(records, [(job key, submission number)] to submit again) of the tasks that
    ``arrived`` ([(future, its records or the exception it ended in)]): each job of a
    lost task gets its receipt, another start or its failed record (:func:`lost`)."""
    done, again = [], []
    for future, result in arrived:
        group = running.pop(future.key)
        if not isinstance(result, BaseException):
            done += result
            continue
        for key, n in group:
            rec = lost(jobs[key], result, outdir, settings, n)
            if rec is None:
                again.append((key, n + 1))
            else:
                done.append(rec)
    return done, again


def _count_down(waiting: dict[str, int], key: str) -> bool:
    """One job ``key`` waits for has ended: True if that was the last."""
    waiting[key] -= 1
    return waiting[key] == 0


def _gather(client, futures: list) -> list[tuple[Any, Any]]:
    """[(future, its record or the exception it ended in)], fetched in one call, and the
    futures released (their results are recorded: Dask may forget them). A batch with a
    failed task (its worker died) is fetched one by one."""
    import pickle

    try:
        out = list(zip(futures, client.gather(futures)))
    except Exception:  # noqa: BLE001  (which one failed, and why, is asked below)
        out = []
        for f in futures:
            try:
                out.append((f, f.result()))
            except Exception as exc:  # its worker died (or the cluster went)
                out.append((f, exc))
    for f in futures:
        f.release()
    return [(f, pickle.loads(r) if isinstance(r, bytes) else r) for f, r in out]


@contextlib.contextmanager
def signals_held():
    """Hold Ctrl-C and SIGTERM back (main thread) while the block runs: a signal that
    comes meanwhile is noted and raised again after it. (Blocking them in this thread
    alone is not enough: the kernel then hands a process's signal to another thread,
    Dask's, and Python still runs the handler here, mid-block.)"""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []
    old = {s: signal.signal(s, lambda signum, frame: caught.append(signum))  # noqa: ARG005
           for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, handler in old.items():
            signal.signal(s, signal.SIG_DFL if handler is None else handler)  # None: set in C
        for s in caught:
            signal.raise_signal(s)


def _waits(stale: list[str], deps: Mapping[str, list[str]]):
    """({key: how many jobs of ``stale`` it waits for}, {key: the stale jobs that need it})."""
    todo = set(stale)
    waiting = {k: sum(d in todo for d in deps[k]) for k in stale}
    users: dict[str, list[str]] = {}
    for k in stale:
        for d in deps[k]:
            if d in todo:
                users.setdefault(d, []).append(k)
    return waiting, users


def lost(job, exc: BaseException, outdir: str, settings: Mapping[str, Any],
         submissions: int) -> dict | None:
    """The record of a job whose task ended in an exception (its worker died and the
    scheduler gave up, the cluster went): its receipt if it had ended (a task runs
    several jobs, :func:`chunks`), else None to submit it again: fewer than
    ``retries`` + 1 starts so far and not stopped by the time limit. A task can be lost
    before it starts (queued on a worker that died): it is submitted again too, up to
    twice the starts allowed in all, so a task that can never start ends."""
    done = receipt(job, outdir, settings["run"])  # it ended before its task was lost
    if done is not None:
        return done
    starts = len(attempt_log(outdir, job))
    limit = timed_out(outdir, job)
    common = {"attempts": starts, "run": settings["run"]}
    if limit is not None:
        return record(job, "failed", **common,
                      error=f"stopped after {limit:g} s (--job-timeout {limit:g}); it may "
                            "be stuck, or give it a longer limit")
    allowed = settings["retries"] + 1
    if starts < allowed and submissions < 2 * allowed:
        return None
    return record(job, "failed", **common,
                  error=" ".join(f"lost its worker in each of {starts} attempts (--retries "
                                 f"{settings['retries']}); last: {type(exc).__name__}: "
                                 f"{exc}".split()))


def task_key(job, token: str, size: int = 1) -> str:
    """The Dask key of the task that runs ``job`` (and ``size`` - 1 jobs after it):
    ``COMMAND-TOKEN-JOBKEY`` (``+N`` for N more jobs). Dask groups tasks by the key's
    first word (``dask.utils.key_split``), so every render shares one duration estimate,
    every fit another …; with those, work stealing moves queued renders to an idle worker
    (without them one worker was left the last material's renders while the other idled:
    ~2 s of 13 at 1024², 2 workers). ``token``: the batch's id and the submission's number
    (a job submitted again is a new task)."""
    more = f"+{size - 1}" if size > 1 else ""
    return f"{job.command.split()[0]}-{token}-{job.key}{more}"


def chunks(go: list[tuple[str, int]], commands: list[str], slots: int, most: int = 32
           ) -> list[list[tuple[str, int]]]:
    """The jobs ``go`` made ready together, in tasks: each command's jobs in turn, in
    groups of ``len / (2 slots)`` (at most ``most``), so that every worker
    thread still gets two tasks or more while a long plan pays Dask's cost per task
    (~1 ms of the driver's CPU, as much of the scheduler's) once per group rather than
    per job. A job submitted again (its task was lost) goes alone, so that a job that
    kills its worker takes no other job down with it next time."""
    alone = [[item] for item in go if item[1] > 1]
    by_command: dict[str, list[tuple[str, int]]] = {}
    for item, command in zip(go, commands):
        if item[1] == 1:
            by_command.setdefault(command, []).append(item)
    groups = []
    for items in by_command.values():
        size = min(most, max(1, len(items) // (2 * slots)))
        groups += [items[k:k + size] for k in range(0, len(items), size)]
    return groups + alone
