"""Memory estimates before large allocations (gonio_cli.memory and each stage's estimator).

Two kinds of test:

* refusal: with the available memory set small (``GONIO_MEMORY_AVAILABLE``, so no test
  needs a big machine), a render at a high ssaa, a finely tessellated built-in sphere, a
  halftone at a large ``--size`` and a prefilter of a big map end at once with exit
  status 2, one stderr line giving the estimate and the option to change, and nothing
  written;
* accuracy: the estimate against the peak resident memory (``ru_maxrss``) of a real run
  in a subprocess. A run's peak includes the interpreter and its libraries, so the test
  compares *differences* between a small and a larger run of the same command with the
  difference of the estimates; they must agree within a factor 1.5 (the margin
  :data:`gonio_cli.memory.MARGIN` leaves room for it). The sizes are small (each run a
  few hundred MB at most, about a second).
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from gonio_cli import memory

SAMPLE = Path(__file__).resolve().parents[1] / "sample_data"

#: The estimate and the measured growth agree within this factor (the brief of the
#: estimators; MARGIN = 0.8 keeps a run within the machine even at the factor's edge).
FACTOR = 1.5

SCENE = """
[vars]
seg = "48"

[camera]
eye = [0.0, 0.0, 4.0]
target = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_deg = 32.0
width = 64
height = 64

[[object]]
mesh = "builtin:sphere?segments=${seg}"
material = "red.json"

[[light]]
type = "directional"
direction = [-1.0, 1.0, 1.2]
irradiance = 3.0
spectrum = "D65"
"""


@pytest.fixture
def scene(tmp_path) -> Path:
    from gonio_cli.schemas import Material, write_material
    from gonio_cli.spectra import parse_grid

    grid = parse_grid()
    write_material(tmp_path / "red.json", Material(
        "goniochromatic", grid, {"alpha": 0.2, "rho": np.linspace(0.02, 0.3, grid.size),
                                 "c": np.linspace(5.0, 0.4, grid.size)}))
    path = tmp_path / "scene.toml"
    path.write_text(textwrap.dedent(SCENE))
    return path


def refused(r, *needles) -> None:
    assert r.exit_code == 2, r.stderr
    assert r.stderr.count("\n") == 1 and r.stderr.startswith("gonio: error: "), r.stderr
    for needle in needles:
        assert needle in r.stderr, r.stderr


def only_inputs(folder: Path, *names: str) -> None:
    """Nothing but the inputs: no output, no temporary file."""
    assert sorted(p.name for p in folder.iterdir()) == sorted(names)


# ---------------------------------------------------------------- the helper --

@pytest.mark.parametrize("text, n", [("512M", 512 << 20), ("2G", 2 << 30), ("1.5GiB", 3 << 29),
                                     ("100000", 100000), ("64k", 64 << 10)])
def test_parse_bytes(text, n):
    assert memory.parse_bytes(text) == n


def test_a_bad_size_in_the_variable_is_one_line(run_gonio, monkeypatch, tmp_path):
    from gonio_cli.errors import InputError

    with pytest.raises(InputError, match="GONIO_MEMORY_AVAILABLE='lots' is not a size"):
        memory.parse_bytes("lots")


def test_available_reads_the_variable_then_meminfo(monkeypatch):
    monkeypatch.setenv(memory.MEMORY_ENV, "1G")
    assert memory.available_bytes() == (1 << 30, f"set by {memory.MEMORY_ENV}")
    monkeypatch.delenv(memory.MEMORY_ENV)
    have, source = memory.available_bytes()
    if os.path.exists("/proc/meminfo"):
        meminfo = dict(line.split(":", 1) for line in open("/proc/meminfo"))
        expected = int(meminfo["MemAvailable"].split()[0]) * 1024
        # MemAvailable moves while the test runs: same order of magnitude is the claim
        assert source in ("available", "allowed by ulimit -v")
        assert have <= 2 * expected


def test_check_refuses_beyond_the_margin(monkeypatch):
    from gonio_cli.errors import MemoryLimitError

    monkeypatch.setenv(memory.MEMORY_ENV, "1000M")
    assert memory.check(799 << 20, "x", fix="f") == 799 << 20
    with pytest.raises(MemoryLimitError) as info:
        memory.check(801 << 20, "a thing", fix="lower --n", path="in.png")
    assert info.value.format() == ("in.png: a thing needs about 801 MiB, more than 80 % of "
                                   "the 1000 MiB set by GONIO_MEMORY_AVAILABLE; lower --n")


# ---------------------------------------------------------------- refusals --

def test_render_at_a_high_ssaa_is_refused(run_gonio, scene, monkeypatch):
    """The issue's case: a 2048² frame at ssaa 16 (tens of GiB) on any machine."""
    r = run_gonio("render", scene, "-o", scene.parent / "o.png", "--width-px", "2048",
                  "--height-px", "2048", "--ssaa", "16")
    refused(r, "scene.toml: a 2048x2048 render at ssaa 16 needs about",
            "lower --ssaa or --width-px/--height-px")
    only_inputs(scene.parent, "scene.toml", "red.json", "red.run.json")


def test_render_of_a_fine_builtin_sphere_is_refused(run_gonio, scene, monkeypatch):
    """The issue's case: a 64² frame of builtin:sphere?segments=4096 (16.8 M triangles)."""
    monkeypatch.setenv(memory.MEMORY_ENV, "1G")
    r = run_gonio("render", scene, "-o", scene.parent / "o.png", "--var", "seg=4096")
    refused(r, "a 64x64 render of 16.8 M built-in mesh triangles needs about 3.0 GiB",
            "1.0 GiB set by GONIO_MEMORY_AVAILABLE", "lower segments=")
    only_inputs(scene.parent, "scene.toml", "red.json", "red.run.json")


def test_halftone_at_a_large_size_is_refused(run_gonio, tmp_path, monkeypatch):
    monkeypatch.setenv(memory.MEMORY_ENV, "256M")
    image = tmp_path / "photo.png"
    shutil.copy(SAMPLE / "print_image.png", image)
    r = run_gonio("halftone", image, "-o", tmp_path / "m.png", "--size", "8000x8000",
                  "--report", tmp_path / "m.json")
    refused(r, "photo.png: a 8000x8000 halftone needs about 1.9 GiB", "lower --size")
    only_inputs(tmp_path, "photo.png")


def test_prefilter_of_a_big_map_is_refused(run_gonio, tmp_path, monkeypatch):
    monkeypatch.setenv(memory.MEMORY_ENV, "1M")
    sky = tmp_path / "sky.exr"
    shutil.copy(SAMPLE / "sky.exr", sky)
    r = run_gonio("prefilter", sky, "--exponents", "8,64", "-o", tmp_path / "maps")
    refused(r, "sky.exr: prefiltering a", "into 3 maps needs about",
            "give a smaller map (or fewer --exponents)")
    only_inputs(tmp_path, "sky.exr")


# ---------------------------------------------------------------- accuracy --

def peak_bytes(args: list[str], cwd: Path) -> int:
    """Peak resident memory (bytes) of ``gonio ARGS`` run in a fresh interpreter."""
    code = ("import resource, subprocess, sys\n"
            f"r = subprocess.run([sys.executable, '-m', 'gonio_cli', *{args!r}])\n"
            "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, r.returncode)\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True,
                         text=True, check=True, timeout=240)
    kib, rc = out.stdout.split()
    assert rc == "0", out.stderr
    return int(kib) * 1024  # Linux reports KiB


def assert_close(measured: float, estimated: float) -> None:
    ratio = estimated / measured
    assert 1 / FACTOR <= ratio <= FACTOR, (f"estimate {estimated / 2**20:.0f} MiB, "
                                           f"measured {measured / 2**20:.0f} MiB")


linux_only = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="ru_maxrss in KiB (Linux)")


@linux_only
def test_sphere_estimate_matches_the_measured_peak(scene):
    """builtin:sphere at 256 and 1536 segments (0.13 M and 4.7 M triangles), 64² frame."""
    from gonio_cli.render.budget import memory_estimate
    from gonio_cli.render.scene import load_scene

    runs = {}
    for seg in (256, 1536):
        args = ["-q", "render", "scene.toml", "-o", "o.png", "--var", f"seg={seg}", "--ssaa", "1"]
        est = memory_estimate(load_scene(scene, variables={"seg": str(seg)},
                                         overrides={"ssaa": 1}))
        runs[seg] = (peak_bytes(args, scene.parent), est)
    assert_close(runs[1536][0] - runs[256][0], runs[1536][1] - runs[256][1])


@linux_only
def test_halftone_estimate_matches_the_measured_peak(tmp_path):
    from gonio_cli.halftone import memory_estimate

    image = tmp_path / "photo.png"
    shutil.copy(SAMPLE / "print_image.png", image)
    runs = {}
    for n in (512, 3072):
        args = ["-q", "halftone", "photo.png", "-o", "m.png", "--size", f"{n}x{n}",
                "--report", "m.json"]
        runs[n] = (peak_bytes(args, tmp_path), memory_estimate(n, n))
    assert_close(runs[3072][0] - runs[512][0], runs[3072][1] - runs[512][1])


@linux_only
def test_prefilter_estimate_matches_the_measured_peak(tmp_path):
    from gonio_cli.imageio import write_exr
    from gonio_cli.prefilter import memory_estimate

    rng = np.random.default_rng(7)
    runs = {}
    for w in (512, 2048):
        write_exr(tmp_path / f"sky{w}.exr",
                  (rng.random((w // 2, w, 3)) + 0.1).astype(np.float32), {})
        args = ["-q", "prefilter", f"sky{w}.exr", "--exponents", "8,64", "-o", f"maps{w}"]
        runs[w] = (peak_bytes(args, tmp_path), memory_estimate(w // 2, w, 3))
        index = json.loads((tmp_path / f"maps{w}" / "index.json").read_text())
        assert len(index["maps"]) == 3
    assert_close(runs[2048][0] - runs[512][0], runs[2048][1] - runs[512][1])


@linux_only
def test_render_buffer_estimate_matches_the_measured_peak(scene):
    """A plane filling a 256² frame (every sample covered, the case the estimate
    assumes) at ssaa 1 and 8 (65 k and 4.2 M samples)."""
    from gonio_cli.render.budget import memory_estimate
    from gonio_cli.render.scene import load_scene

    text = scene.read_text().replace("builtin:sphere?segments=${seg}", "builtin:plane")
    scene.write_text(text.replace("fov_deg = 32.0", "fov_deg = 20.0"))  # 4 tan 10° < 1
    runs = {}
    for ssaa in (1, 8):
        args = ["-q", "render", "scene.toml", "-o", "o.png", "--width", "256", "--height",
                "256", "--ssaa", str(ssaa)]
        sc = load_scene(scene, overrides={"ssaa": ssaa, "width": 256, "height": 256})
        runs[ssaa] = (peak_bytes(args, scene.parent), memory_estimate(sc))
    assert_close(runs[8][0] - runs[1][0], runs[8][1] - runs[1][1])
