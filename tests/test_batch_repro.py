"""Reproducible artifacts (docs/conventions.md, "Files and errors"; docs/batch.md): the same
plan run into two output folders gives the same bytes in every PNG, EXR and JSON file, apart
from the documented side records; up to date follows content, so a touched file reruns
nothing, and a job that runs again and makes the same bytes reruns nothing after it.

One module-scoped pair of runs of a small plan: a sample ink (ingest, fit), a 2-frame
turntable at 48 px and its preview, a prefilter of the sample sky (EXR maps) and a render
with ``--exr`` that reads the material from another folder of the output.
"""

from __future__ import annotations

import json
import os
import shutil
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_batch import SAMPLE, _batch, _manifest, _ran  # noqa: E402

pytest.importorskip("distributed", reason="gonio[batch] (Dask distributed) is not installed")

#: Files of a batch output that record the run, not its results (docs/batch.md,
#: "Reproducible outputs"): every artifact's side record, the journal, the contact sheet
#: and the batch's own state.
RUN_RECORDS = ("manifest.jsonl", "index.html")

PLAN = """
[[material]]
name = "red"
csv = ["ink_red.csv"]
fit = { exclude-theta-i = [70] }

[matrix]
scenes = ["scenes/sphere.toml"]
frames = 2
render = { width-px = 48, height-px = 48 }

[[job]]
key = "prefilter/sky"
command = "prefilter"
inputs = ["sky.exr"]
output = "${out}/sky"
options = { exponents = "8,64", height-px = 32 }

[[job]]
key = "render/exr"
command = "render"
inputs = ["scenes/sphere.toml"]
output = "${out}/exr/sphere.png"
options = { exr = "${out}/exr/sphere.exr", var = { material = "${out}/red/red.material.json" }, width-px = 48, height-px = 48 }
needs = ["${out}/red/red.material.json"]
"""

#: The plan's jobs: ingest, fit, 2 frames, the preview, prefilter, the EXR render.
N_JOBS = 7


def _is_run_record(rel: str) -> bool:
    return rel.endswith(".run.json") or rel in RUN_RECORDS or rel.startswith(".gonio-batch/")


def _files(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` but the run records, by path relative to it."""
    out = {}
    for path in sorted(folder.rglob("*")):
        rel = path.relative_to(folder).as_posix()
        if path.is_file() and not _is_run_record(rel):
            out[rel] = path.read_bytes()
    return out


@pytest.fixture(scope="module")
def two_runs(tmp_path_factory):
    base = tmp_path_factory.mktemp("repro")
    data = base / "data"
    shutil.copytree(SAMPLE / "batch" / "scenes", data / "scenes")
    for name in ("ink_red.csv", "sky.exr"):
        shutil.copy(SAMPLE / name, data / name)
    plan = data / "plan.toml"
    plan.write_text(PLAN, encoding="utf-8")
    runs = {}
    for name in ("a", "b"):
        done = _batch(plan, base / name, "--workers", "2")
        assert done.returncode == 0, done.stderr
        runs[name] = base / name
    return plan, runs


def test_two_output_folders_hold_the_same_bytes(two_runs):
    _, runs = two_runs
    a, b = _files(runs["a"]), _files(runs["b"])
    assert sorted(a) == sorted(b)
    kinds = {Path(rel).suffix for rel in a}
    assert {".png", ".exr", ".json"} <= kinds
    # 2 frames, the preview, the fit's plot and its thumbnail, the --exr render's PNG
    assert sum(rel.endswith(".png") for rel in a) == 2 + 1 + 2 + 1
    assert sum(rel.endswith(".exr") for rel in a) == 3 + 1            # E = 1, 8, 64; render
    differ = [rel for rel in a if a[rel] != b[rel]]
    assert differ == []
    # the output folders' names are in none of them (paths are relative to each file)
    assert not [rel for rel, data in a.items() if str(runs["a"]).encode() in data]


def test_times_are_in_the_side_records_and_read_back(two_runs):
    from gonio_cli.artifact import read_artifact

    _, runs = two_runs
    out = runs["a"]
    on_disk = json.loads((out / "red" / "red.material.json").read_text())
    assert "created_utc" not in on_disk and "time_s" not in on_disk
    side = json.loads((out / "red" / "red.material.run.json").read_text())
    assert side["schema"] == "gonio.run" and side["artifact"] == "red.material.json"
    assert side["timings"]["time_s"] > 0 and side["created_utc"] and side["host"]
    doc = read_artifact(out / "red" / "red.material.json", "gonio.material", (1, 2))
    assert doc["time_s"] == side["timings"]["time_s"]
    assert all(m["time_s"] > 0 for m in doc["fit"]["methods"].values())
    index = read_artifact(out / "sky" / "index.json", "gonio.prefilter", (2,))
    assert all(m["time_s"] > 0 for m in index["maps"])
    # the journal keeps each job's time and worker
    records = _manifest(out)
    assert all(r["time_s"] > 0 and r["worker"] for r in records.values())


def test_image_headers_hold_relative_paths_and_no_date(two_runs):
    from gonio_cli.imageio import read_image

    _, runs = two_runs
    meta = read_image(runs["a"] / "exr" / "sphere.exr").metadata
    assert "DateTime" not in meta and "render_time_s" not in meta
    paths = [i["path"] for i in json.loads(meta["inputs"])]
    assert "../red/red.material.json" in paths
    settings = json.loads(meta["settings"])
    assert settings["vars"]["material"] == "../red/red.material.json"


def test_touched_inputs_rerun_nothing(two_runs):
    """``touch`` on a user's CSV and on a file a job made: same bytes, nothing runs."""
    plan, runs = two_runs
    out = runs["b"]
    for path in (plan.parent / "ink_red.csv", out / "red" / "red.material.json"):
        st = path.stat()
        os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    done = _batch(plan, out, "--workers", "2")
    assert done.returncode == 0, done.stderr
    assert _ran(_manifest(out)) == set()
    assert f"ran 0 jobs: all {N_JOBS} are up to date" in done.stderr


def test_a_job_that_makes_the_same_bytes_reruns_nothing_after_it(two_runs):
    """A lost measurement: its ingest runs again, writes the very same bytes, so the fit,
    the renders and the previews that read it stand (by content, not by time)."""
    plan, runs = two_runs
    out = runs["a"]
    before = (out / "red" / "red.measurement.json").read_bytes()
    (out / "red" / "red.measurement.json").unlink()
    done = _batch(plan, out, "--workers", "2")
    assert done.returncode == 0, done.stderr
    records = _manifest(out)
    assert _ran(records) == {"ingest/red"}
    assert records["fit/red"]["status"] == "skipped"
    assert (out / "red" / "red.measurement.json").read_bytes() == before
