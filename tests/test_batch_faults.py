"""``gonio batch`` under faults, on an external Dask scheduler with two workers (loopback):
a worker SIGKILLed mid-job, the driver SIGKILLed or sent SIGTERM mid-run, a stuck job
stopped by ``--job-timeout``; and the folder lock and ``--dry-run``.

"Mid-run" is made deterministic with a gate: the plan's job ``gate`` needs a FIFO (named
pipe), and hashing its inputs blocks on it until the test writes to it. So the test knows
that the gate's job is running (its attempt log names its worker) and what else has
finished (the journal), with no sleeps against the clock. The plan (renders at 48 px, as
tests/test_batch.py):

    render/floor/sphere/frame000..003 -> preview/floor/sphere
    frame000, frame001, gate.fifo     -> gate          (blocks until the test opens it)
    gate.png                          -> after
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from batch_gate import DEADLINE_S, attempts as _attempts, fifo_as_file as _fifo_as_file, \
    open_gate as _open_gate, start_cluster as _start_cluster, stop_cluster as _stop_cluster, \
    wait as _wait  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_data"
GONIO = str(Path(sys.executable).with_name("gonio"))
MATERIAL = SAMPLE / "scenes" / "floor.material.json"
SCENE = SAMPLE / "batch" / "scenes" / "sphere.toml"
FRAMES = [f"render/floor/sphere/frame{k:03d}" for k in range(4)]
BEFORE_GATE = set(FRAMES) | {"preview/floor/sphere"}
ALL = BEFORE_GATE | {"gate", "after"}

pytest.importorskip("distributed", reason="gonio[batch] (Dask distributed) is not installed")
if not hasattr(os, "mkfifo"):
    pytest.skip("the gate is a FIFO (POSIX)", allow_module_level=True)


def _plan(folder: Path) -> Path:
    """The plan above in ``folder`` (the FIFO ``gate.fifo`` made beside it)."""
    folder.mkdir(parents=True, exist_ok=True)
    fifo = folder / "gate.fifo"
    os.mkfifo(fifo)
    plan = folder / "faults.toml"
    plan.write_text(f"""
[[material]]
name = "floor"
material = "{MATERIAL}"

[matrix]
scenes = ["{SCENE}"]
frames = 4
render = {{ width = 48, height = 48 }}

[[job]]
key = "gate"
command = "render"
inputs = ["{SCENE}"]
needs = ["{MATERIAL}", "${{out}}/floor/sphere.frame000.png",
         "${{out}}/floor/sphere.frame001.png", "{fifo}"]
output = "${{out}}/gate.png"
options = {{ var = {{ material = "{MATERIAL}" }}, width = 16, height = 16 }}

[[job]]
key = "after"
command = "render"
inputs = ["{SCENE}"]
needs = ["{MATERIAL}", "${{out}}/gate.png"]
output = "${{out}}/after.png"
options = {{ var = {{ material = "{MATERIAL}" }}, width = 16, height = 16 }}
""", encoding="utf-8")
    return plan


def _journal(out: Path) -> dict[str, dict]:
    from gonio_cli.batch.journal import read_journal

    return read_journal(out)


def _mismatches(records: dict[str, dict]) -> list[str]:
    from gonio_cli.artifact import sha256_file

    return [f["path"] for r in records.values() for f in r["outputs"]
            if f["sha256"] != sha256_file(f["path"])]


def _ran(done: subprocess.CompletedProcess, out: Path) -> set[str]:
    assert "Traceback" not in done.stderr, done.stderr
    return {k for k, r in _journal(out).items() if r["status"] in ("ok", "failed")}


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """A Dask scheduler and two single-threaded workers (each with its nanny, which
    restarts it when it dies) on loopback; the scheduler file's path."""
    procs, sched = _start_cluster(tmp_path_factory.mktemp("cluster"))
    try:
        yield sched
    finally:
        _stop_cluster(procs)


def _start(plan: Path, out: Path, *args: str) -> subprocess.Popen:
    return subprocess.Popen([GONIO, "batch", str(plan), "-o", str(out), *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _batch(plan: Path, out: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([GONIO, "batch", str(plan), "-o", str(out), *args],
                          capture_output=True, text=True, timeout=DEADLINE_S * 2)


def test_worker_killed_mid_job_loses_nothing_and_reruns_nothing(cluster, tmp_path):
    """SIGKILL of the worker running the gate's job, with --retries 1 on the external
    scheduler: the job succeeds on its second start (the journal counts two attempts),
    no finished job runs again (one that finished on the killed worker unreported may be
    run again by Dask: that run returns its receipt and writes nothing), every
    output's sha256 is the journal's, and a rerun runs nothing."""
    plan = _plan(tmp_path / "data")
    fifo, out = tmp_path / "data" / "gate.fifo", tmp_path / "out"
    proc = _start(plan, out, "--scheduler", cluster, "--retries", "1")
    try:
        worker = _wait("the gate's job", lambda: _attempts(out, "gate"), proc)[0]
        pid = int(worker.rsplit(":", 1)[1])
        os.kill(pid, signal.SIGKILL)
        _open_gate(out, fifo, starts=2)
        _, err = proc.communicate(timeout=DEADLINE_S)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    records = _journal(out)
    assert set(records) == ALL and all(r["status"] == "ok" for r in records.values())
    gate = records["gate"]
    assert gate["attempts"] == 2 and gate["worker"] != worker
    # no other job started twice: one that finished on the killed worker just before the
    # kill, its result not yet sent, is run again by Dask, and that run returns the job's
    # receipt without starting it (its outputs committed once: the hashes below are the
    # first start's)
    for k in ALL - {"gate"}:
        starts = _attempts(out, k)
        assert len(starts) == 1 and records[k]["attempts"] == 1, (k, starts)
    assert _mismatches(records) == []
    _fifo_as_file(fifo, gate)
    again = _batch(plan, out, "--workers", "1")
    assert again.returncode == 0, again.stderr
    assert "ran 0 jobs: all 7 are up to date" in again.stderr


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM], ids=["SIGKILL", "SIGTERM"])
def test_driver_stopped_mid_run_keeps_what_finished(cluster, tmp_path, sig):
    """The driver killed (SIGKILL) or stopped (SIGTERM) while the gate's job runs: the
    journal holds the five jobs that had finished, and the rerun runs only what had not
    (the gate's job, which ended in its worker after the driver was gone, is taken from
    its receipt once its hashes check)."""
    plan = _plan(tmp_path / "data")
    fifo, out = tmp_path / "data" / "gate.fifo", tmp_path / "out"
    proc = _start(plan, out, "--scheduler", cluster)
    try:
        _wait("five records and the gate's job running",
              lambda: set(_journal(out)) >= BEFORE_GATE and _attempts(out, "gate"), proc)
        os.kill(proc.pid, sig)
        _, err = proc.communicate(timeout=DEADLINE_S)
    finally:
        if proc.poll() is None:
            proc.kill()
    records = _journal(out)
    assert set(records) == BEFORE_GATE and all(r["status"] == "ok" for r in records.values())
    assert _mismatches(records) == []
    if sig == signal.SIGTERM:
        assert proc.returncode == 143
        lines = [l for l in err.splitlines() if l.startswith("gonio")]
        assert lines[-1].startswith("gonio batch: stopped by SIGTERM after 5 of 7 jobs "
                                    "ended"), err
        assert "Traceback" not in err
        # the journal was compacted: one line per recorded job
        assert len((out / "manifest.jsonl").read_text().splitlines()) == 5
    else:
        assert proc.returncode == -signal.SIGKILL
    # the gate's job is still waiting in its worker: let it end there, driverless
    _open_gate(out, fifo, starts=1)
    receipt = _wait("the gate's receipt", lambda: (out / ".gonio-batch" / "done" /
                                                   "gate.json").is_file())
    assert receipt
    _fifo_as_file(fifo, json.loads((out / ".gonio-batch" / "done" / "gate.json").read_text()))
    dry = _batch(plan, out, "--dry-run")
    assert dry.stdout.splitlines() == ["would run after: no record of an earlier run"], dry
    again = _batch(plan, out, "--scheduler", cluster)
    assert again.returncode == 0, again.stderr
    assert _ran(again, out) == {"after"}
    records = _journal(out)
    assert records["gate"]["status"] == "skipped" and _mismatches(records) == []


def test_job_timeout_stops_a_stuck_job_and_reports_it(cluster, tmp_path):
    """The gate is never opened: --job-timeout stops its job (its worker restarts), the
    job is failed with the limit in its error, the job that needs it is not run, the
    others complete; exit 1."""
    plan = _plan(tmp_path / "data")
    out = tmp_path / "out"
    # the limit only has to exceed a 48-px render (well under a second); it is generous
    # so that a loaded machine does not stop a healthy job
    done = _batch(plan, out, "--scheduler", cluster, "--job-timeout", "20")
    assert done.returncode == 1, done.stderr
    records = _journal(out)
    gate = records["gate"]
    assert gate["status"] == "failed" and gate["error"].startswith(
        "stopped after 20 s (--job-timeout 20)")
    assert records["after"]["status"] == "blocked"
    assert all(records[k]["status"] == "ok" for k in BEFORE_GATE)
    assert f"gonio: failed: gate: {gate['error']}" in done.stderr.splitlines()
    assert "Traceback" not in done.stderr


def test_second_batch_into_a_locked_folder_is_one_line_error(tmp_path):
    from gonio_cli.batch.journal import lock_folder

    plan = _plan(tmp_path / "data")
    out = tmp_path / "out"
    with lock_folder(out) as lock:
        done = _batch(plan, out, "--workers", "1")
    assert done.returncode == 2
    assert done.stderr.strip() == (
        f"gonio: error: {lock}: another gonio batch ({os.uname().nodename}:{os.getpid()}) "
        f"is writing into {out}; wait for it to end or give another -o (the lock goes "
        "when that process ends)")
    assert not (out / "manifest.jsonl").exists()
