"""The batch journal, receipts, retries and reasons, in-process (no cluster starts):
``gonio_cli.batch.journal``, ``jobs.execute``/``why_stale``/``refused`` and
``engine.lost``/``settle``. The same behaviour end to end, with processes killed, is in
tests/test_batch_faults.py."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
from PIL import Image

from gonio_cli.batch import MANIFEST_NAME
from gonio_cli.batch.engine import graph_order, lost, settle
from gonio_cli.batch.jobs import attempt_log, execute, refused, why_stale
from gonio_cli.batch.journal import Journal, clear_run_state, compact, read_journal, recover_receipts, \
    write_receipt
from gonio_cli.batch.plan import Job, Plan


def _preview_job(tmp_path, key: str = "preview/x") -> Job:
    """A preview job (two 4x4 frames -> an animated PNG): runs in-process in ~ms."""
    frames = []
    for k in range(2):
        path = tmp_path / f"f{k}.png"
        Image.fromarray(np.full((4, 4, 3), 40 * (k + 1), np.uint8)).save(path)
        frames.append(str(path))
    out = str(tmp_path / "out" / "x.png")
    os.makedirs(os.path.dirname(out), exist_ok=True)
    return Job(key, "preview", (), ("preview", *frames), tuple(frames), (out,), {},
               sources=tuple(frames))


SETTINGS = {"run": "run1", "retries": 1, "timeout_s": None}


def test_journal_last_line_counts_and_a_torn_line_is_skipped(tmp_path):
    j = Journal(tmp_path)
    j.append({"key": "a", "status": "failed"})
    j.append({"key": "b", "status": "ok"})
    j.append({"key": "a", "status": "ok"})
    j.close()
    with open(tmp_path / MANIFEST_NAME, "a", encoding="utf-8") as fh:
        fh.write('{"key": "b", "status": "fai')  # a kill in the middle of a line
    got = read_journal(tmp_path)
    assert {k: r["status"] for k, r in got.items()} == {"a": "ok", "b": "ok"}
    assert all(r["schema"] == "gonio.batch-manifest" and r["schema_version"] == 2
               for r in got.values())
    compact(tmp_path, [got["b"], got["a"]])
    lines = (tmp_path / MANIFEST_NAME).read_text().splitlines()
    assert [json.loads(l)["key"] for l in lines] == ["b", "a"]


def test_a_second_run_of_a_done_job_returns_its_receipt_and_rewrites_nothing(tmp_path):
    """Dask running a finished job again (its worker was lost after the result went
    back) must not rewrite outputs whose record the driver took."""
    job = _preview_job(tmp_path)
    outdir = str(tmp_path / "out")
    first = execute(job, outdir, None, (), SETTINGS)
    assert first["status"] == "ok" and first["run"] == "run1"
    before = os.stat(job.outputs[0])
    second = execute(job, outdir, None, (), SETTINGS)
    after = os.stat(job.outputs[0])
    assert second == first  # the receipt, as the driver recorded it: not a second attempt
    assert len(attempt_log(outdir, job)) == 1
    assert (after.st_ino, after.st_mtime_ns) == (before.st_ino, before.st_mtime_ns)
    # another batch (another run id, its attempt logs and receipts cleared) runs it again
    clear_run_state(outdir)
    third = execute(job, outdir, None, (), {**SETTINGS, "run": "run2"})
    assert third["status"] == "ok" and os.stat(job.outputs[0]).st_ino != before.st_ino


def test_receipts_of_a_dead_driver_are_recovered_once(tmp_path):
    job = _preview_job(tmp_path)
    outdir = str(tmp_path / "out")
    rec = execute(job, outdir, None, (), SETTINGS)  # wrote its receipt; no driver took it
    journal = read_journal(outdir)
    assert recover_receipts(outdir, journal, [job.key]) == [job.key]
    assert read_journal(outdir)[job.key] == {"schema": "gonio.batch-manifest",
                                             "schema_version": 2, **rec}
    assert recover_receipts(outdir, journal, [job.key]) == []  # already in the journal
    write_receipt(outdir, job.file_name, {**rec, "status": "failed"})
    assert recover_receipts(outdir, {}, [job.key]) == []  # only done jobs count


def test_why_stale_names_the_reason(tmp_path):
    job = _preview_job(tmp_path)
    outdir = str(tmp_path / "out")
    rec = execute(job, outdir, None, (), SETTINGS)
    assert why_stale(job, rec) is None
    assert why_stale(job, None) == "no record of an earlier run"
    assert why_stale(job, {**rec, "status": "failed"}) == "its last run failed"
    other = Job(job.key, "preview", (), ("preview", "--other"), job.inputs, job.outputs, {},
                sources=job.sources)
    assert why_stale(other, rec) == "its command changed"
    assert why_stale(job, {**rec, "gonio_version": "0.0.1", "stamp": "x"}).startswith(
        "gonio version changed (0.0.1 -> ")
    st = os.stat(job.inputs[1])
    os.utime(job.inputs[1], ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    assert why_stale(job, rec) is None        # touched, same bytes: content decides
    Image.fromarray(np.zeros((4, 4, 3), np.uint8)).save(job.inputs[0])
    assert why_stale(job, rec) == f"input {job.inputs[0]} changed (sha256)"
    clear_run_state(outdir)
    rec = execute(job, outdir, None, (), {**SETTINGS, "run": "run2"})
    os.unlink(job.outputs[0])
    assert why_stale(job, rec) == f"output {job.outputs[0]} is missing"


def test_settle_runs_what_changed_and_what_needs_it_in_linear_order(tmp_path):
    job = _preview_job(tmp_path)
    outdir = str(tmp_path / "out")
    rec = execute(job, outdir, None, (), SETTINGS)
    user = Job("user", "preview", (), ("preview", job.outputs[0]), job.outputs,
               (str(tmp_path / "out" / "y.png"),), {})
    plan = Plan(tmp_path / "p.toml", tmp_path / "out", [user, job])
    done, stale, why = settle(plan, {job.key: rec})
    assert list(done) == [job.key] and stale == ["user"]
    assert why == {"user": "no record of an earlier run"}
    os.unlink(job.outputs[0])
    done, stale, why = settle(plan, {job.key: rec})
    assert stale == [job.key, "user"] and why["user"] == f"it needs {job.key}, which runs"
    # a long chain is ordered without quadratic work (each key visited once)
    deps = {f"k{i}": ([f"k{i - 1}"] if i else []) for i in range(20000)}
    assert graph_order(dict(reversed(deps.items()))) == list(deps)


def test_starts_beyond_the_retries_are_refused_and_the_time_limit_is_reported(tmp_path):
    job = _preview_job(tmp_path)
    outdir = str(tmp_path / "out")
    log = tmp_path / "out" / ".gonio-batch" / "attempts" / (job.file_name + ".log")
    log.parent.mkdir(parents=True)
    log.write_text("h:1\nh:2\n")  # two workers died under it
    rec = execute(job, outdir, None, (), SETTINGS)  # --retries 1: a third start is refused
    assert rec["status"] == "failed" and rec["attempts"] == 2
    assert rec["error"].startswith("its worker died in each of its 2 attempts (last h:2; "
                                   "--retries 1)")
    assert not os.path.exists(job.outputs[0])
    assert refused(job, outdir, 2, 1) is None
    stop = tmp_path / "out" / ".gonio-batch" / "timeout" / job.file_name
    stop.parent.mkdir(parents=True)
    stop.write_text("20 h:2\n")
    assert refused(job, outdir, 2, 1)["error"].startswith("stopped after 20 s (--job-timeout 20)")


@pytest.mark.parametrize("starts,submissions,again", [
    (0, 1, True),    # lost before it started (queued on a worker that died)
    (1, 1, True),    # killed once, --retries 1
    (2, 2, False),   # killed twice: the last error is reported
    (0, 4, False),   # never starts: ends after twice the starts allowed
])
def test_lost_submits_again_within_the_retries(tmp_path, starts, submissions, again):
    job = _preview_job(tmp_path)
    outdir = str(tmp_path / "out")
    if starts:
        log = tmp_path / "out" / ".gonio-batch" / "attempts" / (job.file_name + ".log")
        log.parent.mkdir(parents=True)
        log.write_text("".join(f"h:{k}\n" for k in range(starts)))
    rec = lost(job, RuntimeError("KilledWorker"), outdir, SETTINGS, submissions)
    assert (rec is None) == again
    if rec is not None:
        assert rec["status"] == "failed" and rec["attempts"] == starts
        assert rec["error"].startswith(f"lost its worker in each of {starts} attempts "
                                       "(--retries 1); last: RuntimeError: KilledWorker")


def test_a_job_that_ended_inside_a_lost_task_keeps_its_record(tmp_path):
    """A task runs several jobs (engine.chunks): when its worker dies after the first
    ended, that job's receipt is its record (--retries 0 or not), nothing is run again;
    once its output changes, the receipt no longer stands."""
    job = _preview_job(tmp_path)
    outdir = str(tmp_path / "out")
    rec = execute(job, outdir, None, (), SETTINGS)
    assert rec["status"] == "ok"
    write_receipt(outdir, job.file_name, rec)
    for retries in (0, 1):
        got = lost(job, RuntimeError("KilledWorker"), outdir, {**SETTINGS, "retries": retries}, 1)
        assert got == rec
    Image.fromarray(np.zeros((2, 2, 3), np.uint8)).save(job.outputs[0])
    assert lost(job, RuntimeError("KilledWorker"), outdir, {**SETTINGS, "retries": 0}, 1)[
        "status"] == "failed"


def test_signals_held_defers_sigterm_to_the_end_of_the_block():
    """A SIGTERM sent while a record is being journalled runs its handler after the
    block, once; sent from another thread too (the kernel may hand a process's signal to
    any thread, and Python runs the handler in the main thread)."""
    import signal
    import threading

    from gonio_cli.batch.engine import signals_held

    seen: list[str] = []
    old = signal.signal(signal.SIGTERM, lambda signum, frame: seen.append("handler"))
    try:
        with signals_held():
            t = threading.Thread(target=os.kill, args=(os.getpid(), signal.SIGTERM))
            t.start()
            t.join()
            os.kill(os.getpid(), signal.SIGTERM)
            seen.append("block ends")
        seen.append("after")
    finally:
        signal.signal(signal.SIGTERM, old)
    assert seen[0] == "block ends" and seen.count("handler") >= 1 and seen[-1] == "after"
