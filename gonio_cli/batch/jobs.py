"""One batch job, run inside a worker process: the idempotence test and the record.

A job calls its stage in the worker (:func:`run_stage`: the command's options read, the
stage's library call and its writes), not a subprocess, so what a stage keeps at module
level (colour tables, compiled kernels, meshes, prefiltered maps) is loaded once per
worker and reused by its next jobs. A bad input ends that job with gonio's one-line
error, taken from the exception; it is a result, not an exception, so Dask never
retries it. The record a job returns is one line of the manifest.

Nothing here imports Dask: the engine (:mod:`.engine`) submits :func:`execute`.
"""

from __future__ import annotations

import contextlib
import functools
import io
import json
import os
import socket
import time
from typing import Any, Callable, Mapping

from .. import __version__, log, outputs
from ..artifact import sha256_file
from ..errors import GonioError
from .journal import ATTEMPTS_DIR, TIMEOUT_DIR, read_receipt, write_receipt
from .plan import Job
from .sheet import image_entry, thumbnail

#: Statuses of a record: ran now; up to date (earlier outputs kept); its command failed;
#: not run because a job it needs failed.
STATUSES = ("ok", "skipped", "failed", "blocked")
#: Statuses whose outputs are valid (a later job may use them; a rerun may keep them).
GOOD = ("ok", "skipped")


def sha256(path: str) -> str | None:
    """Hex SHA-256 of a file, or of a folder (``gonio prefilter -o DIR``): of the list of
    its files' relative paths and hashes; None if it is not there."""
    import hashlib

    try:
        if not os.path.isdir(path):
            return sha256_file(path)
        h = hashlib.sha256()
        for folder, dirs, names in sorted(os.walk(path)):
            dirs.sort()
            for name in sorted(names):
                full = os.path.join(folder, name)
                h.update(f"{os.path.relpath(full, path)}\0{sha256_file(full)}\n".encode())
        return h.hexdigest()
    except OSError:
        return None


def stamp(job: Job) -> str:
    """Hash of what decides a job's outputs besides its input files: its command as the
    plan writes it (relocatable: ``${out}`` and plan-relative paths) and gonio's version."""
    import hashlib

    text = json.dumps({"argv": list(job.template), "gonio_version": __version__})
    return hashlib.sha256(text.encode()).hexdigest()


def mtime_ns(path: str) -> int | None:
    try:
        return os.stat(path).st_mtime_ns
    except OSError:
        return None


def files(paths, sources=()) -> list[dict[str, Any]]:
    """Records of files: path and sha256, and for ``sources`` (the user's own files) the
    modification time too."""
    return [{"path": p, "sha256": sha256(p), **({"mtime_ns": mtime_ns(p)} if p in sources
                                                else {})} for p in paths]


def why_stale(job: Job, previous: Mapping[str, Any] | None,
              inputs: list[dict[str, Any]] | None = None) -> str | None:
    """Why ``previous`` (the job's record of an earlier run) does not stand, in words
    (``gonio batch --dry-run`` prints it), or None if it does: same stamp (command and
    gonio version), same input hashes, every output there with its recorded hash. Content
    decides, never a modification time: a touched but unchanged file (the user's own, or
    one another job rewrote with the same bytes) reruns nothing; the ``mtime_ns`` of the
    user's files is recorded, not compared. ``inputs``: the input records if already made
    (:func:`files`)."""
    if not previous:
        return "no record of an earlier run"
    if previous.get("status") not in GOOD:
        return f"its last run {previous.get('status')}"
    if previous.get("stamp") != stamp(job):
        if previous.get("gonio_version") != __version__:
            return f"gonio version changed ({previous.get('gonio_version')} -> {__version__})"
        return "its command changed"
    old = {i["path"]: i for i in previous.get("inputs", [])}
    if list(old) != list(job.inputs):
        return "its inputs changed (other files)"
    if inputs is None:
        inputs = files(job.inputs, job.sources)
    for i in inputs:
        was = old[i["path"]]
        if i["sha256"] is None:
            return f"input {i['path']} is missing"
        if i["sha256"] != was["sha256"]:
            return f"input {i['path']} changed (sha256)"
    outputs = previous.get("outputs", [])
    if [o["path"] for o in outputs] != list(job.outputs):
        return "its outputs changed (other files)"
    for o in outputs:
        now = sha256(o["path"])
        if now is None:
            return f"output {o['path']} is missing"
        if now != o["sha256"]:
            return f"output {o['path']} changed since it was recorded"
    return None


def up_to_date(job: Job, previous: Mapping[str, Any] | None,
               inputs: list[dict[str, Any]] | None = None) -> list[dict] | None:
    """The job's input records if ``previous`` still stands (:func:`why_stale`), else None."""
    if inputs is None and previous and previous.get("status") in GOOD and \
            previous.get("stamp") == stamp(job):
        inputs = files(job.inputs, job.sources)
    return inputs if why_stale(job, previous, inputs) is None else None


def record(job: Job, status: str, **fields) -> dict[str, Any]:
    """A manifest line: key, command, status and whatever ``fields`` adds."""
    out = {"key": job.key, "command": "gonio " + " ".join(job.template), "status": status,
           "stamp": stamp(job), "gonio_version": __version__, "inputs": [], "outputs": [],
           "time_s": 0.0, "worker": None, "attempts": 0, "run": None, "error": None,
           "warnings": [], "labels": dict(job.labels)}
    out.update(fields)
    return out


def failed_roots(upstream) -> list[str]:
    """The failed jobs behind the records ``upstream``: a failed one's key, or what
    blocked a blocked one (so a message names the cause, not the chain)."""
    roots: list[str] = []
    for u in upstream:
        if u.get("status") == "failed":
            roots.append(u["key"])
        elif u.get("status") not in GOOD:
            roots += u.get("failed_roots") or [u["key"]]
    return list(dict.fromkeys(roots))


def note_attempt(outdir: str, job: Job) -> int:
    """Log one start of ``job`` (host:pid) and return how many starts this batch made,
    counting those of workers that died mid-job (the log outlives them). The line is
    written and the file closed, not fsync'ed (which cost a worker ~10 ms per job on a
    busy disk): a killed worker's line is in the system's cache for every later reader
    (on NFS, closing sends it to the server); a crash of the machine ends the batch, and
    the next one clears the logs."""
    folder = os.path.join(outdir, ATTEMPTS_DIR)
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, job.file_name + ".log"), "a+", encoding="utf-8") as fh:
        fh.write(f"{worker_name()}\n")
        fh.flush()
        fh.seek(0)
        return sum(1 for line in fh if line.strip())


def attempt_log(outdir: str, job: Job) -> list[str]:
    """The workers (host:pid) that started ``job`` in this batch, in order."""
    try:
        with open(os.path.join(outdir, ATTEMPTS_DIR, job.file_name + ".log"),
                  encoding="utf-8") as fh:
            return [line.strip() for line in fh if line.strip()]
    except OSError:
        return []


def timed_out(outdir: str, job: Job) -> float | None:
    """The time limit (s) that stopped ``job`` in this batch, or None."""
    try:
        with open(os.path.join(outdir, TIMEOUT_DIR, job.file_name), encoding="utf-8") as fh:
            return float(fh.read().split()[0])
    except (OSError, ValueError, IndexError):
        return None


@contextlib.contextmanager
def time_limit(outdir: str, job: Job, timeout_s: float | None):
    """Stop ``job`` if it runs longer than ``timeout_s`` seconds: a marker file says so,
    then this worker process kills itself (SIGKILL; a Python thread cannot be stopped
    from outside, and a stuck job may be stuck in C or in a system call). Its nanny
    starts a new worker; the job's next start, or the driver, finds the marker and
    reports the job as stopped. Other jobs running in the same worker lose an attempt."""
    if not timeout_s:
        yield
        return
    import signal
    import threading

    def stop() -> None:
        folder = os.path.join(outdir, TIMEOUT_DIR)
        os.makedirs(folder, exist_ok=True)
        with open(os.path.join(folder, job.file_name), "w", encoding="utf-8") as fh:
            fh.write(f"{timeout_s} {worker_name()}\n")
            fh.flush()
            os.fsync(fh.fileno())
        os.kill(os.getpid(), signal.SIGKILL)

    timer = threading.Timer(timeout_s, stop)
    timer.daemon = True
    timer.start()
    try:
        yield
    finally:
        timer.cancel()


def worker_name() -> str:
    return f"{socket.gethostname()}:{os.getpid()}"


# --------------------------------------------------------------------------- runners --

def run_stage(job: Job, warnings: list[str]) -> str | None:
    """Run the job's stage in this process; None, or its error on failure.

    The job's words are what a user would type after ``gonio`` (a plan is written in the
    commands' own options, docs/batch.md), so they are read by the command's own options
    (one grammar for the command line and the plan); then the command's function runs:
    the stage's library call (``fit.run.run``, ``render.run.run``, ``ingest.run`` …) and
    its writes, in one outputs transaction (nothing half-written on failure). Its errors
    come back as exceptions and its warnings as values (:func:`gonio_cli.log.collecting`),
    not as lines read off stderr; what it prints for a user is dropped."""
    import click

    # lazy: the driver (and gonio --help) never load the commands' option tables
    from ..commands import as_typed_in, remember_argv

    group = gonio_group()
    remember_argv(job.argv)  # errors name options as the plan wrote them
    outputs.forget_written()
    try:
        with log.collecting(warnings), outputs.transaction() as tx, \
                contextlib.redirect_stdout(io.StringIO()), log.python_warnings(_subject(job)):
            with group.make_context("gonio", list(job.argv)) as ctx:
                group.invoke(ctx)
            tx.commit()
    except GonioError as exc:
        return as_typed_in(exc.format())
    except click.ClickException as exc:  # a bad option in the plan: its words, one line
        return f"{exc.format_message()} (see 'gonio {job.argv[0]} --help')"
    except click.exceptions.Exit as exc:
        return None if exc.exit_code == 0 else f"exit status {exc.exit_code}"
    return None


@functools.lru_cache(maxsize=1)
def gonio_group():
    """The ``gonio`` command group as click builds it from the typer app (once per
    worker: it reads every command's options, ~7 ms)."""
    import typer.main

    from .. import cli  # lazy: a worker loads the commands once, the driver never

    return typer.main.get_command(cli.app)


def _subject(job: Job) -> str | None:
    """The job's first input: what a Python warning inside it is about."""
    return job.inputs[0] if job.inputs else None


def run_preview(job: Job, warnings: list[str]) -> str | None:  # noqa: ARG001
    """Assemble a turntable's frames (the job's inputs, in order) into an animated PNG."""
    # lazy: a worker loads OpenImageIO and the renderer only for a turntable's preview
    from ..imageio import write_apng
    from ..render.output import turntable_metadata  # lazy: (the same)

    frames = list(job.inputs)
    write_apng(job.outputs[0], frames, metadata=turntable_metadata(frames))
    return None


#: How a worker runs each kind of job (:data:`gonio_cli.batch.plan.COMMANDS`).
RUNNERS: dict[str, Callable[[Job, list[str]], str | None]] = {"gonio": run_stage,
                                                               "preview": run_preview}


def make_thumbnails(outdir: str, job: Job) -> dict[str, Any] | None:
    """The contact sheet's small copies of a job's PNG images, made here in the worker
    (in parallel with other jobs) rather than one after another when the sheet is
    written, and what the sheet shows for its first output if that is an image
    (:func:`gonio_cli.batch.sheet.image_entry`: the thumbnail, its size, a frame's
    flags), for the record, so that the driver does not open the image again. A copy
    that cannot be made is made (or reported) by the sheet instead."""
    entry = None
    for k, path in enumerate(job.outputs):
        if str(path).lower().endswith(".png"):
            with contextlib.suppress(OSError, ValueError):
                if k == 0:
                    entry = image_entry(outdir, path, job.labels.get("role") != "preview")
                else:
                    thumbnail(outdir, path)
    return entry


def refused(job: Job, outdir: str, attempts: int, retries: int) -> dict | None:
    """The failed record of a job that must not start again: the time limit stopped it,
    or its workers died in more than ``retries`` + 1 starts (whatever the scheduler's
    own ``allowed-failures``); else None."""
    limit = timed_out(outdir, job)
    if limit is not None:
        return record(job, "failed", attempts=attempts, worker=worker_name(),
                      error=f"stopped after {limit:g} s (--job-timeout {limit:g}); it may "
                            "be stuck, or give it a longer limit")
    if attempts > retries + 1:
        died = attempt_log(outdir, job)[:-1]
        return record(job, "failed", attempts=attempts - 1, worker=worker_name(),
                      error=f"its worker died in each of its {len(died)} attempts (last "
                            f"{died[-1] if died else '?'}; --retries {retries})")
    return None


def receipt(job: Job, outdir: str, run) -> dict[str, Any] | None:
    """The record ``job`` left when it ended in this batch (``run``), if its outputs are
    still what it says: the job is done, whatever became of its task."""
    done = read_receipt(outdir, job.file_name)
    if done is not None and done.get("run") == run and all(
            sha256(o["path"]) == o["sha256"] for o in done.get("outputs", [])):
        return done
    return None


def execute(job: Job, outdir: str, previous: Mapping[str, Any] | None,
            upstream: tuple = (), settings: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Run one job in a worker and return its manifest record.

    ``upstream``: the records of the jobs that make its inputs; a failed one blocks this
    job. ``settings``: ``run`` (the batch's id), ``retries`` and ``timeout_s`` (seconds
    or None). A job whose earlier record still stands (:func:`up_to_date`) is skipped; a
    job already done in this batch (its receipt there, its outputs unchanged: Dask
    running it again after a worker loss) is not run again, so outputs whose record the
    driver took are never rewritten.
    """
    settings = dict(settings or {})
    run = settings.get("run")
    done = receipt(job, outdir, run)
    if done is not None:  # it ended already (Dask ran its task again): not an attempt
        return done
    attempts = note_attempt(outdir, job)
    want = settings.get("gonio_version")
    if want and want != __version__:
        return record(job, "failed", attempts=attempts, worker=worker_name(), run=run,
                      error=f"worker {worker_name()} runs gonio {__version__}, the driver "
                            f"{want}; install the same gonio on every worker")
    stop = refused(job, outdir, attempts, int(settings.get("retries", 0)))
    if stop is not None:
        return {**stop, "run": run}
    failed = failed_roots(upstream)
    if failed:
        return record(job, "blocked", attempts=attempts, worker=worker_name(), run=run,
                      error=f"not run: {', '.join(failed)} failed", failed_roots=failed)
    with time_limit(outdir, job, settings.get("timeout_s")):
        rec = _run(job, outdir, previous, attempts, run)
    if rec["status"] == "ok":
        write_receipt(outdir, job.file_name, rec)
    return rec


def execute_chunk(jobs: list[Job], outdir: str, previous: list, upstream: list,
                  settings: Mapping[str, Any] | None = None) -> bytes:
    """:func:`execute`'s records of ``jobs``, one after another, pickled as one list: what
    the engine submits (:func:`..engine.chunks`). Dask sends a dict back as a frame per
    value (a record has ~15), one bytes object as one frame, which saves the driver ~0.1
    ms per job (benchmarks/bench_batch_scale.py). Each job's receipt is written as it
    ends, so a task lost half-way loses none of the jobs it finished."""
    import pickle

    records = [execute(job, outdir, prev, up, settings)
               for job, prev, up in zip(jobs, previous, upstream)]
    return pickle.dumps(records, protocol=pickle.HIGHEST_PROTOCOL)


def _run(job: Job, outdir: str, previous, attempts: int, run) -> dict[str, Any]:
    """Hash the inputs, skip the job if its record stands, else run it; its record."""
    inputs = files(job.inputs, job.sources)  # hashed once: to judge, then to record
    if up_to_date(job, previous, inputs) is not None:
        return {**previous, "status": "skipped", "attempts": attempts, "run": run,
                "labels": dict(job.labels)}
    start = time.perf_counter()
    warnings: list[str] = []
    try:
        error = RUNNERS[job.runner](job, warnings)
    except Exception as exc:  # a bug in a runner: one line in the record, not a retry loop
        error = exc.format() if isinstance(exc, GonioError) else \
            f"internal error: {type(exc).__name__}: {exc}"
    time_s = time.perf_counter() - start
    outputs = files(job.outputs)
    if error is None and any(o["sha256"] is None for o in outputs):
        missing = next(o["path"] for o in outputs if o["sha256"] is None)
        error = f"{missing}: the command did not write it"
    image = make_thumbnails(outdir, job) if error is None else None
    return record(job, "failed" if error else "ok", inputs=inputs,
                  outputs=outputs if not error else [], time_s=time_s, run=run,
                  worker=worker_name(), attempts=attempts, error=error, warnings=warnings,
                  **({"image": image} if image else {}))


def worker_version() -> str:
    """gonio's version in this process (the driver asks each worker: they must match)."""
    return __version__
