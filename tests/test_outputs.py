"""Outputs as one transaction per command (gonio_cli.outputs): outputs that collide with
each other or with an input, outputs that are not regular files, a failure or a kill
between two outputs, and the temporary files a killed run leaves.

Every refusal: exit status 2, one stderr line naming the option and the file, nothing
written or changed, no temporary file left.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from gonio_cli import outputs

SAMPLE = Path(__file__).resolve().parents[1] / "sample_data"
IMAGE = SAMPLE / "print_image.png"

posix_only = pytest.mark.skipif(sys.platform == "win32", reason="FIFOs, signals, /dev/null")


def snapshot(folder: Path) -> dict:
    """Every entry of ``folder`` with its bytes (None for what is not a regular file)."""
    return {p.name: (p.read_bytes() if p.is_file() and not p.is_fifo() else None)
            for p in folder.iterdir()}


def temporaries(folder: Path) -> list[str]:
    return [p.name for p in folder.iterdir() if p.name.startswith(outputs.TMP_PREFIX)]


def refused(r, *needles) -> None:
    assert r.exit_code == 2, r.stderr
    assert r.stderr.count("\n") == 1 and r.stderr.startswith("gonio: error: "), r.stderr
    for needle in needles:
        assert needle in r.stderr, r.stderr


@pytest.fixture
def image(tmp_path) -> Path:
    path = tmp_path / "photo.png"
    shutil.copy(IMAGE, path)
    return path


# ---------------------------------------------------------------- collisions --

def test_report_equal_to_output_is_refused_before_work(run_gonio, image, tmp_path):
    before = snapshot(tmp_path)
    out = tmp_path / "print.png"
    r = run_gonio("halftone", image, "-o", out, "--report", out)
    refused(r, f"--report {out} is the same file as -o {out}", "choose another --report")
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("link", ["same path", "symlink", "hard link", "dot path"])
def test_output_that_is_the_input_is_refused(run_gonio, image, tmp_path, link):
    target = {"same path": lambda: image,
              "dot path": lambda: tmp_path / "." / image.name}[link]() \
        if link in ("same path", "dot path") else tmp_path / "alias.png"
    if link == "symlink":
        target.symlink_to(image)
    elif link == "hard link":
        os.link(image, target)
    before = snapshot(tmp_path)
    r = run_gonio("halftone", image, "-o", target)
    refused(r, f"-o {target} is the input {image}", "choose another -o")
    assert snapshot(tmp_path) == before


def test_sparkle_output_equal_to_a_photo(run_gonio, tmp_path):
    photos = sorted((SAMPLE / "sparkle").glob("photo_ti*.png"))[:2]
    for p in photos:
        shutil.copy(p, tmp_path / p.name)
    photos = [tmp_path / p.name for p in photos]
    before = snapshot(tmp_path)
    r = run_gonio("sparkle", *photos, "--theta-i", "10,20", "-o", photos[1])
    refused(r, f"-o {photos[1]} is the input {photos[1]}")
    assert snapshot(tmp_path) == before


def test_fit_output_equal_to_the_measurement_and_plot_equal_to_output(run_gonio, tmp_path):
    meas = tmp_path / "red.measurement.json"
    assert run_gonio("ingest", SAMPLE / "ink_red.csv", "-o", meas).exit_code == 0
    before = snapshot(tmp_path)
    refused(run_gonio("fit", meas, "-o", meas), f"-o {meas} is the input {meas}")
    out = tmp_path / "red.material.json"
    refused(run_gonio("fit", meas, "-o", out, "--plot", out),
            f"--plot {out} is the same file as -o {out}")
    assert snapshot(tmp_path) == before


def test_render_output_equal_to_a_file_the_scene_reads(run_gonio, tmp_path):
    """The scene's material is an input known only once the scene is read: still refused
    before the render."""
    from test_render_cli import SCENE
    from gonio_cli.schemas import Material, write_material
    from gonio_cli.spectra import parse_grid

    grid = parse_grid()
    write_material(tmp_path / "red.json", Material(
        "goniochromatic", grid, {"alpha": 0.2, "rho": np.linspace(0.02, 0.3, grid.size),
                                 "c": np.linspace(5.0, 0.4, grid.size)}))
    scene = tmp_path / "scene.toml"
    scene.write_text(textwrap.dedent(SCENE))
    before = snapshot(tmp_path)
    refused(run_gonio("render", scene, "-o", tmp_path / "o.png", "--report", scene),
            f"--report {scene} is the input {scene}")
    refused(run_gonio("render", scene, "-o", tmp_path / "o.png", "--report",
                      tmp_path / "red.json"), "--report", "red.json is the input")
    refused(run_gonio("render", scene, "-o", tmp_path / "o.png", "--exr", tmp_path / "o.exr",
                      "--gamut-warning", tmp_path / "o.png"),
            "--gamut-warning", "is the same file as -o")
    assert snapshot(tmp_path) == before


# ---------------------------------------------------------------- not regular files --

@posix_only
def test_output_that_is_a_fifo_is_refused_and_left_alone(run_gonio, image, tmp_path):
    fifo = tmp_path / "pipe.png"
    os.mkfifo(fifo)
    r = run_gonio("halftone", image, "-o", fifo)
    refused(r, f"-o {fifo} is a FIFO (named pipe), not a regular file")
    assert fifo.is_fifo() and temporaries(tmp_path) == []


@posix_only
def test_output_that_is_a_device_is_refused(run_gonio, tmp_path):
    r = run_gonio("ingest", SAMPLE / "ink_red.csv", "-o", "/dev/null")
    refused(r, "-o /dev/null is a character device, not a regular file")
    assert os.path.exists("/dev/null") and not os.path.isfile("/dev/null")


def test_output_that_is_read_only_is_refused_and_kept(run_gonio, image, tmp_path):
    out = tmp_path / "keep.png"
    out.write_bytes(b"precious")
    out.chmod(0o444)
    try:
        r = run_gonio("halftone", image, "-o", out)
        refused(r, f"-o {out} is read-only", "chmod u+w")
        assert out.read_bytes() == b"precious"
    finally:
        out.chmod(0o644)
    assert temporaries(tmp_path) == []


def test_folder_output_that_is_a_file(run_gonio, tmp_path):
    sky = tmp_path / "sky.exr"
    shutil.copy(SAMPLE / "sky.exr", sky)
    r = run_gonio("prefilter", sky, "--exponents", "8", "-o", sky)
    refused(r, str(sky))
    assert sky.read_bytes() == (SAMPLE / "sky.exr").read_bytes()


# ---------------------------------------------------------------- half-made sets --

def test_a_failure_after_the_first_output_leaves_none(run_gonio, image, tmp_path,
                                                      monkeypatch):
    """The mask is staged, then the report cannot be written: neither appears."""
    from gonio_cli import artifact
    from gonio_cli.errors import WriteError

    def fail(path, doc):
        raise WriteError("the disk is full (simulated)", path=path)

    monkeypatch.setattr(artifact, "write_json", fail)
    out, rep = tmp_path / "print.png", tmp_path / "print.json"
    r = run_gonio("halftone", image, "-o", out, "--split", "--report", rep)
    refused(r, "print.json: the disk is full")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["photo.png"]


def test_the_set_is_complete_on_success(run_gonio, image, tmp_path):
    out, rep = tmp_path / "print.png", tmp_path / "print.json"
    r = run_gonio("halftone", image, "-o", out, "--split", "--report", rep, "--size", "64x48")
    assert r.exit_code == 0, r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "photo.png", "print.blue.png", "print.green.png", "print.json", "print.png",
        "print.red.png", "print.run.json"]                # the report's side record


# ---------------------------------------------------------------- killed runs --

def _dead_pid() -> int:
    """The pid of a process that has ended (and been reaped)."""
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_stale_temporaries_of_dead_processes_are_removed_live_ones_kept(run_gonio, tmp_path):
    dead = f"{outputs.TMP_PREFIX}{_dead_pid()}-abcd1234-red.json"
    live_proc = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        live = f"{outputs.TMP_PREFIX}{live_proc.pid}-efgh5678-red.json"
        folder = f"{outputs.TMP_PREFIX}{_dead_pid()}-ijkl9012-report"
        unrelated = ".red.json.x1.tmp"          # not ours: never touched
        for name in (dead, live, unrelated):
            (tmp_path / name).write_text("{half")
        (tmp_path / folder).mkdir()
        (tmp_path / folder / "report.md").write_text("half")
        outputs._cleaned.clear()
        r = run_gonio("ingest", SAMPLE / "ink_red.csv", "-o", tmp_path / "red.json")
        assert r.exit_code == 0, r.stderr
        assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
            [live, unrelated, "red.json", "red.run.json"])
    finally:
        live_proc.kill()
        live_proc.wait()


@posix_only
def test_sigkill_mid_write_then_a_second_run_cleans_up(run_gonio, image, tmp_path):
    """A real gonio halftone is killed (SIGKILL, no handler runs) while writing its
    report, the mask already staged: no output appears, and the next run writing into
    the folder removes both temporary files."""
    script = tmp_path / "killed_gonio.py"
    out = tmp_path / "print.png"
    script.write_text(textwrap.dedent(f"""
        import sys, time
        from gonio_cli import artifact
        def slow(path, doc):
            with artifact.atomic_path(path) as tmp:
                tmp.write_text('{{"half": ')
                print("ready", flush=True)
                time.sleep(60)
        artifact.write_json = slow
        from gonio_cli import cli
        sys.exit(cli.run({["halftone", str(image), "-o", str(out), "--report",
                           str(tmp_path / "print.json")]!r}))
        """))
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline() == "ready\n"
        assert len(temporaries(tmp_path)) == 2          # the staged mask, the half report
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == -signal.SIGKILL
    assert not out.exists() and not (tmp_path / "print.json").exists()
    outputs._cleaned.clear()
    r = run_gonio("halftone", image, "-o", tmp_path / "other.png", "--size", "32x32")
    assert r.exit_code == 0, r.stderr
    assert temporaries(tmp_path) == []
    assert not out.exists()


# ---------------------------------------------------------------- the pieces --

def test_same_file_sees_links_and_dots(tmp_path):
    a = tmp_path / "a"
    a.write_text("x")
    os.link(a, tmp_path / "b")
    (tmp_path / "c").symlink_to(a)
    assert outputs.same_file(a, tmp_path / "b")
    assert outputs.same_file(a, tmp_path / "c")
    assert outputs.same_file(a, tmp_path / "sub" / ".." / "a")
    assert not outputs.same_file(a, tmp_path / "d")


def test_a_transaction_left_without_commit_removes_what_it_staged(tmp_path):
    from gonio_cli.artifact import write_json

    with outputs.transaction() as tx:
        outputs.declare({"-o": tmp_path / "a.json"})
        write_json(tmp_path / "a.json", {"x": 1})
        assert temporaries(tmp_path) and not (tmp_path / "a.json").exists()
        write_json(tmp_path / "scratch.json", {"x": 0})   # not declared: written at once
        assert (tmp_path / "scratch.json").exists()
        assert tx.files
    assert [p.name for p in tmp_path.iterdir()] == ["scratch.json"]
    with outputs.transaction() as tx:
        outputs.declare({"-o": tmp_path / "a.json", "--report": tmp_path / "b.json"})
        write_json(tmp_path / "a.json", {"x": 1})
        write_json(tmp_path / "b.json", {"x": 2})
        tx.commit()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "b.json", "scratch.json"]


# ---------------------------------------------------------------- every command --

@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """A measurement and its material (made once for the module)."""
    from gonio_cli import cli, log

    folder = tmp_path_factory.mktemp("fitted")
    meas, mat = folder / "red.measurement.json", folder / "red.material.json"
    assert cli.run(["-q", "ingest", str(SAMPLE / "ink_red.csv"), "-o", str(meas)]) == 0
    assert cli.run(["-q", "fit", str(meas), "-o", str(mat)]) == 0
    log.set_quiet(False)
    return meas, mat


@pytest.mark.parametrize("case", ["lobes basis -o", "lobes basis --plot", "lobes fit -o",
                                  "ingest -o", "report -o holds an input", "prefilter -o"])
def test_every_command_refuses_outputs_that_collide(run_gonio, fitted, tmp_path, case):
    meas, mat = fitted
    work = tmp_path / "work"
    work.mkdir()
    m, d = work / mat.name, work / meas.name
    shutil.copy(mat, m)
    shutil.copy(meas, d)
    sky = work / "sky.exr"
    shutil.copy(SAMPLE / "sky.exr", sky)
    csv = work / "ink.csv"
    shutil.copy(SAMPLE / "ink_red.csv", csv)
    args, needles = {
        "lobes basis -o": (["lobes", "basis", m, "-o", m], [f"-o {m} is the input {m}"]),
        "lobes basis --plot": (["lobes", "basis", m, "-o", work / "b.json", "--plot",
                                work / "b.json"], ["--plot", "is the same file as -o"]),
        "lobes fit -o": (["lobes", "fit", m, "--exponents", "1,10", "-o", m],
                         [f"-o {m} is the input {m}"]),
        "ingest -o": (["ingest", csv, "-o", csv], ["is both an input and the output"]),
        "report -o holds an input": (["report", d, "--sections", "fit", "-o", work],
                                     [f"-o {work} holds the input {d}",
                                      "replacing the folder would delete"]),
        "prefilter -o": (["prefilter", sky, "--exponents", "8", "-o", sky], [str(sky)]),
    }[case]
    before = snapshot(work)
    refused(run_gonio(*args), *needles)
    assert snapshot(work) == before
