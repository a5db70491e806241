"""``gonio batch`` on Dask, on loopback: the sample plan, reruns, failures, lost workers,
an external scheduler, and the contact sheet in a real browser.

One module-scoped run sequence serves most assertions (a cluster start costs seconds):
the sample plan (renders shrunk to 48 px) with 2 workers, again (nothing to do), after a
change to one CSV, and with another CSV replaced by garbage.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from browser import chromium, headless_flags

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_data"
GONIO = str(Path(sys.executable).with_name("gonio"))
INKS = ("red", "green", "blue")
SCENES = ("sphere", "panel")
N_FRAMES = 4

pytest.importorskip("distributed", reason="gonio[batch] (Dask distributed) is not installed")
sys.path.insert(0, str(Path(__file__).resolve().parent))  # batch_gate


def _copy_plan(folder: Path, extra: str = "") -> Path:
    """The sample plan and its CSVs under ``folder`` (same layout: plan in batch/, CSVs
    beside batch/), renders shrunk to 48 px (the [matrix] is the plan's last table)."""
    shutil.copytree(SAMPLE / "batch", folder / "batch")
    for csv in SAMPLE.glob("ink_*.csv"):
        shutil.copy(csv, folder / csv.name)
    plan = folder / "batch" / "turntable.toml"
    with plan.open("a", encoding="utf-8") as fh:
        fh.write("render = { width = 48, height = 48 }\n" + extra)
    return plan


def _batch(plan: Path, out: Path, *args: str, timeout: float = 240) -> subprocess.CompletedProcess:
    return subprocess.run([GONIO, "batch", str(plan), "-o", str(out), *args],
                          capture_output=True, text=True, timeout=timeout)


def _manifest(out: Path) -> dict[str, dict]:
    lines = (out / "manifest.jsonl").read_text(encoding="utf-8").splitlines()
    records = [json.loads(l) for l in lines]
    assert len({r["key"] for r in records}) == len(records)
    return {r["key"]: r for r in records}


def _ran(records: dict[str, dict]) -> set[str]:
    return {k for k, r in records.items() if r["status"] in ("ok", "failed")}


def _frames(out: Path) -> dict[str, np.ndarray]:
    from PIL import Image

    return {f"{i}/{s}/{k}": np.asarray(Image.open(out / i / f"{s}.frame{k:03d}.png"))
            for i in INKS for s in SCENES for k in range(N_FRAMES)}


def _mismatches(records: dict[str, dict]) -> list[dict]:
    """Files whose sha256 is not the one their record gives (now)."""
    from gonio_cli.artifact import sha256_file

    return [f for r in records.values() for f in r["inputs"] + r["outputs"]
            if f["sha256"] != sha256_file(f["path"])]


def _chain(ink: str) -> set[str]:
    """The keys of one ink's jobs: ingest, fit, 8 renders, 2 previews."""
    return ({f"ingest/{ink}", f"fit/{ink}"}
            | {f"render/{ink}/{s}/frame{k:03d}" for s in SCENES for k in range(N_FRAMES)}
            | {f"preview/{ink}/{s}" for s in SCENES})


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The run sequence on one output folder; each step's process and manifest."""
    base = tmp_path_factory.mktemp("batch")
    plan = _copy_plan(base / "data")
    out = base / "out"
    steps = {}
    steps["first"] = (_batch(plan, out, "--workers", "2"), _manifest(out))
    steps["frames"] = _frames(out)
    steps["first mismatches"] = _mismatches(steps["first"][1])
    steps["again"] = (_batch(plan, out, "--workers", "2"), _manifest(out))
    with (plan.parent.parent / "ink_red.csv").open("a", encoding="utf-8") as fh:
        fh.write("# a note added after the first run\n")
    steps["red changed"] = (_batch(plan, out, "--workers", "2"), _manifest(out))
    blue = plan.parent.parent / "ink_blue_a.csv"
    later = blue.stat().st_mtime_ns + 10**9
    os.utime(blue, ns=(later, later))  # `touch`: the same bytes, a newer time
    steps["blue touched"] = (_batch(plan, out, "--workers", "2"), _manifest(out))
    (plan.parent.parent / "ink_green.csv").write_text("this is,not\na goniometer,file\n")
    steps["green garbage"] = (_batch(plan, out, "--workers", "2"), _manifest(out))
    steps["plan"], steps["out"] = plan, out
    return steps


def test_first_run_writes_24_frames_6_previews_manifest_and_sheet(runs):
    from PIL import Image

    done, records = runs["first"]
    assert done.returncode == 0, done.stderr
    assert "ran 36 of 36 jobs (36 ok" in done.stderr
    out = runs["out"]
    assert len(runs["frames"]) == 24 and all(a.shape == (48, 48, 3)
                                             for a in runs["frames"].values())
    for i in INKS:
        for s in SCENES:
            with Image.open(out / i / f"{s}.png") as im:  # the animated preview
                assert getattr(im, "n_frames", 1) == N_FRAMES and im.size == (48, 48)
                assert im.info["gonio:schema"] == "gonio.turntable"   # its frames, hashed
                assert len(json.loads(im.info["gonio:inputs"])) == N_FRAMES
    assert len(records) == 36 and {r["status"] for r in records.values()} == {"ok"}
    for r in records.values():
        assert r["attempts"] == 1 and r["time_s"] > 0 and r["worker"] and r["error"] is None
    assert runs["first mismatches"] == []  # the files are what the records say
    # one file per job, and each fit's plot beside its material (the sheet links it)
    assert sum(len(r["outputs"]) for r in records.values()) == 36 + len(INKS)
    assert all((out / i / f"{i}.fit.png").is_file() for i in INKS)
    assert len({r["worker"] for r in records.values()}) == 2  # both workers took jobs
    command = records["render/green/panel/frame003"]["command"]
    assert command.startswith("gonio render scenes/panel.toml -o ${out}/green/panel.frame003.png")
    assert (out / "index.html").is_file()


def test_rerun_runs_nothing_and_says_so(runs):
    done, records = runs["again"]
    assert done.returncode == 0, done.stderr
    assert "ran 0 jobs: all 36 are up to date" in done.stderr
    assert _ran(records) == set() and {r["status"] for r in records.values()} == {"skipped"}


def test_changed_csv_reruns_only_its_ink(runs):
    done, records = runs["red changed"]
    assert done.returncode == 0, done.stderr
    # ingest, fit and the 8 renders; the previews' inputs (the frames) came out the same
    # bytes, so they stand (the worker checks again once a job's inputs are made)
    previews = {f"preview/red/{s}" for s in SCENES}
    assert _ran(records) == _chain("red") - previews and len(_chain("red") - previews) == 10
    assert all(records[k]["status"] == "skipped" for k in previews)
    assert "ran 10 of 36 jobs" in done.stderr


def test_touched_csv_reruns_nothing(runs):
    """A user's file with a new modification time and the same bytes reruns nothing: the
    content hash decides (docs/batch.md), as it does for the files jobs make."""
    done, records = runs["blue touched"]
    assert done.returncode == 0, done.stderr
    assert _ran(records) == set() and {r["status"] for r in records.values()} == {"skipped"}
    assert "ran 0 jobs: all 36 are up to date" in done.stderr


def test_garbage_csv_fails_its_ink_only_with_one_line_errors(runs):
    done, records = runs["green garbage"]
    assert done.returncode == 1, done.stderr
    green = records["ingest/green"]
    assert green["status"] == "failed" and "ink_green.csv" in green["error"]
    assert "\n" not in green["error"]
    blocked = {k for k, r in records.items() if r["status"] == "blocked"}
    assert blocked == _chain("green") - {"ingest/green"}
    # each names the cause, not the chain
    assert all(records[k]["error"] == "not run: ingest/green failed" for k in blocked)
    # every other ink's 16 images are there and up to date
    for k in _chain("red") | _chain("blue"):
        assert records[k]["status"] == "skipped", k
    out = runs["out"]
    assert all((out / i / f"{s}.frame{k:03d}.png").is_file()
               for i in ("red", "blue") for s in SCENES for k in range(N_FRAMES))
    # stderr: the summary, each failed job with its error, the jobs not run
    lines = done.stderr.strip().splitlines()
    assert [l for l in lines if l.startswith("gonio: failed: ")] == [
        f"gonio: failed: ingest/green: {green['error']}"]
    not_run = [l for l in lines if l.startswith("gonio: not run")]
    assert len(not_run) == 1 and set(not_run[0].split(": ")[-1].split(", ")) == blocked
    assert "Traceback" not in done.stderr


def test_one_worker_gives_identical_images(runs, tmp_path):
    plan = _copy_plan(tmp_path)
    done = _batch(plan, tmp_path / "out", "--workers", "1")
    assert done.returncode == 0, done.stderr
    one = _frames(tmp_path / "out")
    two = runs["frames"]
    assert one.keys() == two.keys()
    for k in one:
        assert np.array_equal(one[k], two[k]), k
    # the frames of a turntable differ (the camera moved), so equality is not vacuous
    assert not np.array_equal(one["red/sphere/0"], one["red/sphere/1"])


def test_killed_worker_loses_nothing(runs, tmp_path):
    """A local cluster's worker killed (SIGKILL) mid-job: the driver submits the job
    again, it runs on a new worker, the manifest counts two attempts, every output is
    written. The job is held mid-run by a gate (tests/batch_gate.py: it needs a FIFO),
    so the kill lands while it runs on any machine."""
    from batch_gate import attempts, open_gate, wait

    material = runs["out"] / "blue" / "blue.material.json"
    fifo = tmp_path / "gate.fifo"
    os.mkfifo(fifo)
    plan = tmp_path / "slow.toml"
    plan.write_text(f"""
[[material]]
name = "blue"
material = "{material}"

[matrix]
scenes = ["{SAMPLE / 'batch' / 'scenes' / 'sphere.toml'}"]
frames = 3
render = {{ width = 48, height = 48 }}

[[job]]
key = "slow"
command = "render"
inputs = ["{SAMPLE / 'batch' / 'scenes' / 'sphere.toml'}"]
needs = ["{material}", "{fifo}"]
output = "${{out}}/slow.png"
options = {{ var = {{ material = "{material}" }}, width = 48, height = 48 }}

[[job]]
key = "coarse"
command = "render"
inputs = ["{SAMPLE / 'batch' / 'scenes' / 'sphere.toml'}"]
needs = ["{material}"]
output = "${{out}}/coarse.png"
options = {{ var = {{ material = "{material}" }}, width = 16, height = 16, grid-nm = "400:700:20" }}
""")
    out = tmp_path / "out"
    proc = subprocess.Popen([GONIO, "batch", str(plan), "-o", str(out), "--workers", "2"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        pid = int(wait("the job", lambda: attempts(out, "slow"), proc)[0].rsplit(":", 1)[1])
        os.kill(pid, signal.SIGKILL)
        open_gate(out, fifo, starts=2, key="slow")
        _, err = proc.communicate(timeout=240)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    records = _manifest(out)
    assert records["slow"]["status"] == "ok" and records["slow"]["attempts"] == 2
    assert records["slow"]["worker"].rsplit(":", 1)[1] != str(pid)
    assert all(r["status"] == "ok" for r in records.values())
    assert all(r["attempts"] == 1 for k, r in records.items() if k != "slow")
    assert (out / "slow.png").is_file() and (out / "blue" / "sphere.png").is_file()
    # a command's warnings are kept in its record (a coarser grid resamples the material)
    assert records["coarse"]["warnings"] == [
        f"{material}: material resampled from 41 wavelengths onto the render's grid "
        "(16 samples)"]
    assert records["slow"]["warnings"] == [] and "1 job(s) warned (coarse)" in err


def test_external_scheduler_and_worker_give_the_same_outputs(runs, tmp_path):
    from batch_gate import start_cluster, stop_cluster

    plan = _copy_plan(tmp_path)
    procs, sched_file = start_cluster(tmp_path, nworkers=1)
    try:
        address = json.loads(Path(sched_file).read_text())["address"]
        assert re.match(r"tcp://127\.0\.0\.1:\d+$", address)  # loopback, a random port
        done = _batch(plan, tmp_path / "out", "--scheduler", sched_file)
    finally:
        stop_cluster(procs)
    assert done.returncode == 0, done.stderr
    records = _manifest(tmp_path / "out")
    assert len(records) == 36 and all(r["status"] == "ok" for r in records.values())
    one = _frames(tmp_path / "out")
    assert all(np.array_equal(one[k], runs["frames"][k]) for k in one)


def test_contact_sheet_loads_every_thumbnail_in_a_browser(runs, tmp_path):
    browser = chromium()
    out = runs["out"]
    page = (out / "index.html").read_text(encoding="utf-8")
    n_img = page.count("<img ")
    # the last run: 16 images and 4 previews of red and blue, green's jobs failed
    assert n_img == 20 and "ingest/green" in page and "ink_green.csv" in page
    assert "http://" not in page and "https://" not in page  # no external assets
    check = out / "check.html"  # the page plus a counter of decoded images
    check.write_text(page.replace("</body>", """<script>
window.addEventListener('load', function () {
  var all = document.images, ok = 0;
  for (var i = 0; i < all.length; i++) if (all[i].complete && all[i].naturalWidth > 0) ok++;
  document.body.setAttribute('data-loaded', ok + '/' + all.length);
});
</script></body>"""), encoding="utf-8")
    flags = headless_flags(tmp_path / "profile")
    try:
        dom = subprocess.run([browser, *flags, "--dump-dom", check.as_uri()],
                             capture_output=True, text=True, timeout=120).stdout
        shot = subprocess.run([browser, *flags, f"--screenshot={tmp_path / 'sheet.png'}",
                               "--window-size=1000,1400", (out / "index.html").as_uri()],
                              capture_output=True, text=True, timeout=120)
    finally:
        check.unlink()
    assert f'data-loaded="{n_img}/{n_img}"' in dom, dom[-400:]
    assert (tmp_path / "sheet.png").is_file(), shot.stderr[-400:]


def test_task_keys_group_jobs_by_command_for_dask():
    """Dask keeps one duration estimate per key prefix (``key_split``), which its work
    stealing needs to move queued jobs to an idle worker: the prefix of every task of the
    sample plan is its command, whatever the job's own key, and keys stay unique."""
    from dask.utils import key_split

    from gonio_cli.batch.engine import task_key
    from gonio_cli.batch.plan import read_plan

    plan = read_plan(ROOT / "sample_data" / "batch" / "turntable.toml", ROOT / "try" / "k")
    keys = [task_key(j, "0badcafe") for j in plan.jobs]
    assert len(set(keys)) == len(keys)
    assert {key_split(k) for k in keys} == {"ingest", "fit", "render", "preview"}
    assert all(key_split(k) == j.command.split()[0] for k, j in zip(keys, plan.jobs))


def test_task_keys_of_grouped_jobs_stay_unique_and_keep_the_command():
    from dask.utils import key_split

    from gonio_cli.batch.engine import task_key
    from gonio_cli.batch.plan import read_plan

    plan = read_plan(ROOT / "sample_data" / "batch" / "turntable.toml", ROOT / "try" / "k")
    job = plan.jobs[-1]
    one, four = task_key(job, "0badcafe1"), task_key(job, "0badcafe1", 4)
    assert one != four and four.endswith("+3")
    assert key_split(four) == key_split(one) == job.command.split()[0]


def test_jobs_ready_together_share_tasks_while_every_worker_gets_two():
    """engine.chunks: a group of ready jobs of ``len / (2 slots)`` (at most the option's N)
    per task, one command per task; a job submitted again (its task was lost) alone."""
    from gonio_cli.batch.engine import chunks

    go = [(f"r{k}", 1) for k in range(100)]
    groups = chunks(go, ["render"] * 100, slots=2)
    assert [len(g) for g in groups] == [25] * 4
    assert [item for g in groups for item in g] == go  # every job once, in order
    assert [len(g) for g in chunks(go, ["render"] * 100, slots=1)] == [32] * 3 + [4]
    assert [len(g) for g in chunks(go, ["render"] * 100, slots=1, most=1)] == [1] * 100
    # 64 workers: a fit of the 1 150-job plan makes 42 renders ready: one task each
    assert [len(g) for g in chunks(go[:42], ["render"] * 42, slots=64)] == [1] * 42
    mixed = [(f"f{k}", 1) for k in range(8)] + [("again", 2)] + [(f"r{k}", 1) for k in range(8)]
    groups = chunks(mixed, ["fit"] * 8 + ["render"] * 9, slots=1)
    assert [[key[0] for key, _ in g] for g in groups] == [["f"] * 4] * 2 + [["r"] * 4] * 2 + [["a"]]


def test_local_workers_fork_from_a_preloaded_server_where_the_os_has_one():
    """Where the OS has a fork server (Linux, macOS) the local cluster's workers start
    from it, with gonio's job runner and CLI imported there once; elsewhere Dask's
    default start method is kept (None)."""
    import multiprocessing

    from gonio_cli.batch import engine

    method = engine.worker_start_method()
    if "forkserver" in multiprocessing.get_all_start_methods():
        assert method == "forkserver"
        assert {"distributed", "gonio_cli.batch.jobs", "gonio_cli.cli"} <= set(
            engine.WORKER_PRELOAD)
    else:
        assert method is None


def test_a_fit_through_batch_and_through_the_cli_writes_the_same_material(tmp_path):
    """gonio batch calls the stage in its worker (jobs.run_stage: the command's options,
    then fit.run and its writes), not the CLI: the material it writes is the bytes that
    ``gonio ingest`` and ``gonio fit`` with the same options write, with the same status
    and verdict, for a good fit and a poor one; a fit refused by --max-error fails with
    the CLI's own message."""
    shutil.copy(SAMPLE / "ink_green.csv", tmp_path / "ink_green.csv")
    fits = {"green": ["--exclude-theta-i", "70"], "flat": ["--model", "torrance-sparrow"],
            "strict": ["--max-error", "0.01"]}
    text = ""
    for name, options in fits.items():
        table = ", ".join(f'{options[k][2:]} = "{options[k + 1]}"' for k in range(0, len(options), 2))
        text += (f'[[material]]\nname = "{name}"\ncsv = ["ink_green.csv"]\n'
                 f'fit = {{ {table} }}\n')
    (tmp_path / "plan.toml").write_text(text, encoding="utf-8")
    r = _batch(tmp_path / "plan.toml", tmp_path / "a", "--workers", "1")
    assert r.returncode == 1, r.stderr  # the strict fit fails
    records = _manifest(tmp_path / "a")
    for name, options in fits.items():
        folder = tmp_path / "b" / name
        folder.mkdir(parents=True)
        measurement = folder / f"{name}.measurement.json"
        done = subprocess.run([GONIO, "ingest", str(tmp_path / "ink_green.csv"), "-o",
                               str(measurement)], capture_output=True, text=True, timeout=240)
        assert done.returncode == 0, done.stderr
        done = subprocess.run([GONIO, "fit", str(measurement), "-o",
                               str(folder / f"{name}.material.json"), "--plot",
                               str(folder / f"{name}.fit.png"), *options],
                              capture_output=True, text=True, timeout=240)
        rec = records[f"fit/{name}"]
        if name == "strict":
            assert done.returncode == 3 and rec["status"] == "failed"
            line = done.stderr.strip().splitlines()[-1].replace(f"{tmp_path / 'b'}", "OUT")
            assert line == f"gonio: error: {rec['error']}".replace(f"{tmp_path / 'a'}", "OUT")
            assert not (tmp_path / "a" / name / f"{name}.material.json").exists()
            continue
        assert done.returncode == 0 and rec["status"] == "ok", (done.stderr, rec)
        ours = (tmp_path / "a" / name / f"{name}.material.json").read_bytes()
        assert ours == (folder / f"{name}.material.json").read_bytes()
        verdict = json.loads(ours)["status"]
        assert verdict == ("good" if name == "green" else "poor")
        # the CLI's warnings are the record's
        shown = [l.removeprefix("gonio: warning: ") for l in done.stderr.splitlines()
                 if l.startswith("gonio: warning: ")]
        assert rec["warnings"] == shown
