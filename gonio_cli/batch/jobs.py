"""One batch job, run inside a worker process: the idempotence test and the record.

A job runs through gonio's own CLI in the worker (:func:`run_gonio`), not a subprocess,
so what a stage keeps at module level (colour tables, compiled kernels, meshes,
prefiltered maps) is loaded once per worker and reused by its next jobs; what belongs to
one run (the list of files written, ``--quiet``) is reset by :func:`gonio_cli.cli.run`.
A bad input ends that job with gonio's one-line error; it is a result, not an exception,
so Dask never retries it. The record a job returns is one line of the manifest.

Nothing here imports Dask: the engine (:mod:`.engine`) submits :func:`execute`.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import socket
import time
from typing import Any, Callable, Mapping

from .. import __version__
from .plan import Job

#: Statuses of a record: ran now; up to date (earlier outputs kept); its command failed;
#: not run because a job it needs failed.
STATUSES = ("ok", "skipped", "failed", "blocked")
#: Statuses whose outputs are valid (a later job may use them; a rerun may keep them).
GOOD = ("ok", "skipped")
#: Folder of the output folder holding each job's attempt log (one line per start).
ATTEMPTS_DIR = ".gonio-batch/attempts"


def sha256(path: str) -> str | None:
    """Hex SHA-256 of a file, or of a folder (``gonio prefilter -o DIR``): of the list of
    its files' relative paths and hashes; None if it is not there."""
    import hashlib

    from ..artifact import sha256_file

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


def up_to_date(job: Job, previous: Mapping[str, Any] | None,
               inputs: list[dict[str, Any]] | None = None) -> list[dict] | None:
    """The job's input records if ``previous`` (its record of an earlier run) still
    stands: same stamp, same input hashes and, for the user's own files
    (``job.sources``), the same modification times (``touch`` reruns, as with make; a
    file another job rewrites with the same bytes does not), every output there with its
    recorded hash; else None. ``inputs``: the input records if already made (:func:`files`)."""
    if not previous or previous.get("status") not in GOOD or previous.get("stamp") != stamp(job):
        return None
    if inputs is None:
        inputs = files(job.inputs, job.sources)
    if [(i["path"], i["sha256"], i.get("mtime_ns")) for i in inputs] != \
            [(i["path"], i["sha256"], i.get("mtime_ns")) for i in previous.get("inputs", [])]:
        return None
    outputs = previous.get("outputs", [])
    if [o["path"] for o in outputs] != list(job.outputs) or any(
            o["sha256"] is None or sha256(o["path"]) != o["sha256"] for o in outputs):
        return None
    return inputs


def record(job: Job, status: str, **fields) -> dict[str, Any]:
    """A manifest line: key, command, status and whatever ``fields`` adds."""
    out = {"key": job.key, "command": "gonio " + " ".join(job.template), "status": status,
           "stamp": stamp(job), "gonio_version": __version__, "inputs": [], "outputs": [],
           "time_s": 0.0, "worker": None, "attempts": 0, "error": None, "warnings": [],
           "labels": dict(job.labels)}
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
    counting those of workers that died mid-job (the log outlives them)."""
    folder = os.path.join(outdir, ATTEMPTS_DIR)
    os.makedirs(folder, exist_ok=True)
    path = os.path.join(folder, job.file_name + ".log")
    with open(path, "a", encoding="utf-8") as fh:
        fh.write(f"{worker_name()}\n")
    with open(path, encoding="utf-8") as fh:
        return sum(1 for _ in fh)


def worker_name() -> str:
    return f"{socket.gethostname()}:{os.getpid()}"


# --------------------------------------------------------------------------- runners --

#: What a command's warnings start with on stderr (:func:`gonio_cli.log.warn`).
WARNING_PREFIX = "gonio: warning: "


def run_gonio(job: Job, warnings: list[str]) -> str | None:
    """Run ``gonio ARGV`` in this process; None, or the error line on failure. The
    command's warnings are appended to ``warnings``; its other output is dropped."""
    from .. import cli

    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = cli.run(list(job.argv))
    lines = err.getvalue().splitlines()
    warnings += [l[len(WARNING_PREFIX):] for l in lines if l.startswith(WARNING_PREFIX)]
    if code == 0:
        return None
    lines = [l for l in lines if l.startswith("gonio: ") and not l.startswith(WARNING_PREFIX)]
    text = lines[-1] if lines else f"exit status {code}"
    for prefix in ("gonio: error: ", "gonio: "):
        if text.startswith(prefix):
            return text[len(prefix):]
    return text


def run_preview(job: Job, warnings: list[str]) -> str | None:  # noqa: ARG001
    """Assemble a turntable's frames (the job's inputs, in order) into an animated PNG."""
    from ..imageio import write_apng
    from ..render.pipeline import turntable_metadata

    frames = list(job.inputs)
    write_apng(job.outputs[0], frames, metadata=turntable_metadata(frames))
    return None


#: How a worker runs each kind of job (:data:`gonio_cli.batch.plan.COMMANDS`).
RUNNERS: dict[str, Callable[[Job, list[str]], str | None]] = {"gonio": run_gonio, "preview": run_preview}


def make_thumbnails(outdir: str, outputs) -> None:
    """The contact sheet's small copies of a job's PNG images, made here in the worker
    (in parallel with other jobs) rather than one after another when the sheet is
    written; the sheet reuses them (:func:`gonio_cli.batch.sheet.thumbnail`). A copy
    that cannot be made is made (or reported) by the sheet instead."""
    from .sheet import thumbnail

    for path in outputs:
        if str(path).lower().endswith(".png"):
            with contextlib.suppress(OSError, ValueError):
                thumbnail(outdir, path)


def execute(job: Job, outdir: str, previous: Mapping[str, Any] | None,
            *upstream: Mapping[str, Any]) -> dict[str, Any]:
    """Run one job in a worker and return its manifest record.

    ``upstream``: the records of the jobs that make its inputs (Dask passes the results
    of the futures it was given); a failed one blocks this job. A job whose earlier
    record still stands (:func:`up_to_date`) is skipped.
    """
    attempts = note_attempt(outdir, job)
    failed = failed_roots(upstream)
    if failed:
        return record(job, "blocked", attempts=attempts, worker=worker_name(),
                      error=f"not run: {', '.join(failed)} failed", failed_roots=failed)
    inputs = files(job.inputs, job.sources)  # hashed once: to judge, then to record
    if up_to_date(job, previous, inputs) is not None:
        return {**previous, "status": "skipped", "attempts": attempts, "labels": dict(job.labels)}
    start = time.perf_counter()
    warnings: list[str] = []
    try:
        error = RUNNERS[job.runner](job, warnings)
    except Exception as exc:  # a bug in a runner: one line in the record, not a retry loop
        from ..errors import GonioError

        error = exc.format() if isinstance(exc, GonioError) else \
            f"internal error: {type(exc).__name__}: {exc}"
    time_s = time.perf_counter() - start
    outputs = files(job.outputs)
    if error is None and any(o["sha256"] is None for o in outputs):
        missing = next(o["path"] for o in outputs if o["sha256"] is None)
        error = f"{missing}: the command did not write it"
    if error is None:
        make_thumbnails(outdir, job.outputs)
    return record(job, "failed" if error else "ok", inputs=inputs,
                  outputs=outputs if not error else [], time_s=time_s,
                  worker=worker_name(), attempts=attempts, error=error, warnings=warnings)
