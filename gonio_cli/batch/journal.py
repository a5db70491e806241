"""The batch journal ``OUTDIR/manifest.jsonl``, the worker's receipts and the folder lock.

The journal *is* the manifest: one JSON line per finished job, appended by the driver as
each result arrives and flushed to the disk (``fsync``) before the job is counted and
before any job that needs it is submitted, with the sha256 of the job's inputs and
outputs; the results that arrive together share one ``fsync`` (:meth:`Journal.extend`).
A key may appear on several lines (a rerun, a retry); the last line counts
(:func:`read_journal`). A run that ends in the driver (also by Ctrl-C or SIGTERM)
rewrites it compacted, atomically: one line per job of the plan, in plan order
(:func:`compact`). After a kill of the driver (SIGKILL, power loss) the appended lines
are what the rerun reads; a torn last line is skipped, so that job runs again.

A worker writes a *receipt* (``.gonio-batch/done/JOB.json``) when a job's outputs are in
place, before its result goes back: a second run of the same job in the same batch (Dask
running it again after a worker loss) returns the receipt instead of rewriting outputs
whose record the driver may already have taken, and a rerun adds the receipts of jobs
that ended after their driver died (:func:`recover_receipts`).

The lock (:func:`lock_folder`) keeps a second ``gonio batch`` out of a folder one is
writing into: an advisory ``flock`` on ``.gonio-batch/lock``, which the system releases
when the process holding it ends, however it ends.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
from typing import Any, Iterable, Iterator, Mapping

from . import MANIFEST_NAME, MANIFEST_SCHEMA, MANIFEST_SCHEMA_VERSION
from ..artifact import atomic_path
from ..errors import InputError
from ..folders import folder_error, make_folder
from .plan import file_name_of

#: gonio batch's own folder inside the output folder (attempt logs, receipts, the lock).
STATE_DIR = ".gonio-batch"
#: One log per job of the running batch: a line per start (host:pid).
ATTEMPTS_DIR = f"{STATE_DIR}/attempts"
#: One receipt per job of the running batch whose outputs are in place.
DONE_DIR = f"{STATE_DIR}/done"
#: One marker per job the time limit stopped (``--job-timeout``).
TIMEOUT_DIR = f"{STATE_DIR}/timeout"
LOCK_NAME = f"{STATE_DIR}/lock"
#: Journal versions this gonio reads (v1: the manifest written once at exit, same fields).
READ_VERSIONS = (1, MANIFEST_SCHEMA_VERSION)


def _line(rec: Mapping[str, Any]) -> str:
    return json.dumps({"schema": MANIFEST_SCHEMA, "schema_version": MANIFEST_SCHEMA_VERSION,
                       **rec}) + "\n"


def read_journal(outdir: str | os.PathLike) -> dict[str, dict[str, Any]]:
    """The last record of each job key in ``OUTDIR/manifest.jsonl`` ({} if none). Lines
    that are not records of a version this gonio reads (a torn last line after a kill)
    are skipped: their jobs run again."""
    out: dict[str, dict[str, Any]] = {}
    try:
        with open(os.path.join(outdir, MANIFEST_NAME), encoding="utf-8") as fh:
            for line in fh:
                try:
                    rec = json.loads(line)
                except json.JSONDecodeError:
                    continue
                if isinstance(rec, dict) and isinstance(rec.get("key"), str) and \
                        rec.get("schema_version", 1) in READ_VERSIONS:
                    out[rec["key"]] = rec
    except (OSError, UnicodeDecodeError):
        pass
    return out


class Journal:
    """``OUTDIR/manifest.jsonl`` open for appending: :meth:`append` writes one record and
    returns once it is on the disk."""

    def __init__(self, outdir: str | os.PathLike):
        self.path = os.path.join(outdir, MANIFEST_NAME)
        try:
            self.fh = open(self.path, "a", encoding="utf-8")
        except OSError as exc:
            raise folder_error(os.fspath(outdir), exc) from None

    def append(self, rec: Mapping[str, Any]) -> None:
        """Append ``rec`` as one line, flushed and fsync'ed (a few ms on a local disk)."""
        self.extend([rec])

    def extend(self, recs: Iterable[Mapping[str, Any]]) -> None:
        """Append ``recs``, a line each, with one flush and one ``fsync`` for them all: the
        disk's few ms are paid once for every record that arrived together."""
        self.fh.writelines(_line(r) for r in recs)
        self.fh.flush()
        os.fsync(self.fh.fileno())

    def close(self) -> None:
        self.fh.close()


def compact(outdir: str | os.PathLike, records: Iterable[Mapping[str, Any]]) -> str:
    """Rewrite the journal atomically as ``records`` (one line each, in order)."""
    path = os.path.join(outdir, MANIFEST_NAME)
    with atomic_path(path, immediate=True) as tmp, open(tmp, "w", encoding="utf-8") as fh:
        fh.writelines(_line(r) for r in records)
        fh.flush()
        os.fsync(fh.fileno())
    return path


# ------------------------------------------------------------------------ receipts --

def receipt_path(outdir: str, file_name: str) -> str:
    return os.path.join(outdir, DONE_DIR, file_name + ".json")


def write_receipt(outdir: str, file_name: str, rec: Mapping[str, Any]) -> None:
    """The record of a job whose outputs are in place, written atomically (worker side)."""
    with atomic_path(receipt_path(outdir, file_name), immediate=True) as tmp:
        tmp.write_text(json.dumps(dict(rec)), encoding="utf-8")


def read_receipt(outdir: str, file_name: str) -> dict[str, Any] | None:
    try:
        with open(receipt_path(outdir, file_name), encoding="utf-8") as fh:
            rec = json.load(fh)
    except (OSError, ValueError):
        return None
    return rec if isinstance(rec, dict) and isinstance(rec.get("key"), str) else None


def recover_receipts(outdir: str, journal: dict[str, dict[str, Any]],
                     keys: Iterable[str]) -> list[str]:
    """Append to the journal (and to ``journal``, by key) the receipts of an earlier
    batch for jobs of ``keys`` that its driver did not record (it was killed while they
    ran); return their keys. The rerun still checks their hashes before trusting them."""
    folder = os.path.join(outdir, DONE_DIR)
    if not os.path.isdir(folder):
        return []
    found = []
    for key in keys:
        rec = read_receipt(outdir, file_name_of(key))
        if rec is None or rec.get("key") != key or rec.get("status") != "ok":
            continue
        old = journal.get(key)
        if old is None or old.get("run") != rec.get("run"):
            found.append(rec)
    if found:
        j = Journal(outdir)
        try:
            j.extend(found)
        finally:
            j.close()
        journal.update((rec["key"], rec) for rec in found)
    return [r["key"] for r in found]


def clear_run_state(outdir: str) -> None:
    """Remove the attempt logs, receipts and time-limit markers of an earlier batch."""
    import shutil

    for sub in (ATTEMPTS_DIR, DONE_DIR, TIMEOUT_DIR):
        shutil.rmtree(os.path.join(outdir, sub), ignore_errors=True)


# ---------------------------------------------------------------------------- lock --

@contextlib.contextmanager
def lock_folder(outdir: str | os.PathLike) -> Iterator[str]:
    """Hold ``OUTDIR/.gonio-batch/lock`` while the block runs.

    Raises
    ------
    InputError : another process holds it (its host:pid named, with the fix).
    """
    path = os.path.join(outdir, LOCK_NAME)
    make_folder(os.path.dirname(path))
    try:
        import fcntl
    except ImportError:  # no flock (Windows): no lock
        yield path
        return
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise folder_error(os.path.dirname(path), exc) from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = os.pread(fd, 200, 0).decode("utf-8", "replace").strip() or "unknown"
            raise InputError(f"another gonio batch ({holder}) is writing into {outdir}",
                             path=path, fix="wait for it to end or give another -o (the "
                                            "lock goes when that process ends)") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{socket.gethostname()}:{os.getpid()}\n".encode(), 0)
        yield path
    finally:
        os.close(fd)  # closing releases the flock
