"""``gonio batch`` plans: errors before anything runs, and the turntable's orbit maths.

No cluster starts here: a plan error is found while reading the plan, before Dask is
imported (test_batch.py runs batches).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest

from gonio_cli.batch.plan import read_plan
from gonio_cli.render.mesh import rotation_matrix
from gonio_cli.render.scene import load_scene
from gonio_cli.render.turntable import axis_rotation, euler_xyz_deg, orbit

ROOT = Path(__file__).resolve().parents[1]
SAMPLE_PLAN = ROOT / "sample_data" / "batch" / "turntable.toml"


def _write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def _refused(run_gonio, plan: Path, out: Path, *words: str) -> str:
    """gonio batch refuses ``plan`` with one line naming it and the words; nothing written."""
    r = run_gonio("batch", plan, "-o", out)
    assert r.exit_code == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"gonio: error: {plan}: "), r.stderr
    for w in words:
        assert w in lines[0], (w, lines[0])
    assert not out.exists()  # refused before anything ran (the output folder is not made)
    return lines[0]


def test_sample_plan_is_36_jobs_in_graph_order(tmp_path):
    plan = read_plan(SAMPLE_PLAN, tmp_path / "out")
    roles = [j.labels["role"] for j in plan.jobs]
    # 3 inks: ingest + fit; 3 inks x 2 scenes x 4 frames; one preview per turntable
    assert (roles.count("ingest"), roles.count("fit"), roles.count("frame"),
            roles.count("preview")) == (3, 3, 24, 6)
    fit_red = next(j for j in plan.jobs if j.key == "fit/red")
    frame = next(j for j in plan.jobs if j.key == "render/red/panel/frame002")
    assert fit_red.outputs[0] in frame.inputs  # the render waits for the fit
    assert frame.argv[frame.argv.index("--frame") + 1] == "2"
    # paths are relative to the plan, wherever gonio runs from
    assert frame.argv[1] == str(SAMPLE_PLAN.parent / "scenes" / "panel.toml")
    assert os.path.isabs(plan.jobs[0].inputs[0]) and "${out}" not in " ".join(frame.argv)


def test_cycle_is_refused_before_anything_runs(run_gonio, tmp_path):
    plan = _write(tmp_path / "cycle.toml", """
[[job]]
key = "a"
command = "fit"
inputs = ["${out}/b.json"]
output = "${out}/a.json"

[[job]]
key = "b"
command = "fit"
inputs = ["${out}/a.json"]
output = "${out}/b.json"
""")
    line = _refused(run_gonio, plan, tmp_path / "out", "cycle", "a -> b -> a")
    assert "cannot need" in line


def test_missing_input_names_the_job_and_the_file(run_gonio, tmp_path):
    plan = _write(tmp_path / "missing.toml", """
[[material]]
name = "red"
csv = ["ink_red_missing.csv"]
""")
    _refused(run_gonio, plan, tmp_path / "out", "job 'ingest/red'",
             str(tmp_path / "ink_red_missing.csv"), "does not exist and no job makes it")


@pytest.mark.parametrize("text, words", [
    ("[[job]]\nkey = 'a'\ncommand = 'frobnicate'\noutput = '${out}/a'\n",
     ["'frobnicate' is not a command", "use one of ingest"]),
    ("[matrix]\nscenes = ['s.toml']\nframs = 4\n",
     ["[matrix]", "unknown key 'frams'", "did you mean 'frames'?"]),
    ("[[material]]\nname = 'red'\nmaterial = 'r.json'\n[matrix]\nscenes = ['s.toml']\n"
     "frames = 4\norbit = 'objekt'\n", ["orbit", "'objekt' is unknown", "did you mean 'object'?"]),
    ("[[job]]\nkey = 'a'\ncommand = 'fit'\noutput = 'a.json'\n",
     ["is not inside the output folder", "${out}/a.json"]),
    ("[[material]]\nname = 'red'\nmaterial = 'r.json'\n[matrix]\nscenes = ['s.toml']\n"
     "render = { frame = 2 }\n", ["'frame' is set by the matrix"]),
    ("[[job]]\nkey = 'a'\ncommand = 'render'\noutput = '${out}/a.png'\n"
     "[[job]]\nkey = 'a'\ncommand = 'render'\noutput = '${out}/b.png'\n",
     ["job 'a' is named twice"]),
    ("[[job\n", ["not valid TOML"]),
])
def test_bad_plans_are_one_line(run_gonio, tmp_path, text, words):
    _refused(run_gonio, _write(tmp_path / "plan.toml", text), tmp_path / "out", *words)


@pytest.mark.parametrize("option, words", [
    (["--jobs-per-task", "0"], "--jobs-per-task 0 is not a number of jobs; give N >= 1"),
    (["--retries", "-1"], "--retries -1 is negative; give N >= 0"),
    (["--workers", "2", "--scheduler", "tcp://x:1"], "--workers and --scheduler exclude"),
])
def test_bad_batch_options_are_one_line_before_the_plan_is_read(run_gonio, tmp_path, option,
                                                                words):
    r = run_gonio("batch", tmp_path / "no-plan.toml", "-o", tmp_path / "out", *option)
    assert r.exit_code == 2 and r.stderr.count("\n") == 1, r.stderr
    assert r.stderr.startswith("gonio: error: ") and words in r.stderr, r.stderr
    assert not (tmp_path / "out").exists()


# ------------------------------------------------------------------- orbit maths --

def test_camera_orbit_turns_the_eye_about_up_through_the_target():
    sc = load_scene(SAMPLE_PLAN.parent / "scenes" / "sphere.toml",
                    variables={"material": str(SAMPLE_PLAN)})  # (not read by load_scene)
    eye = sc.camera.eye.copy()
    assert np.allclose(eye, [0.0, 0.6, 4.0])
    # a quarter turn about +y, right-handed: (x, z) = (0, 4) -> (4, 0); height kept
    q = orbit(sc, 1, 4, "camera")
    assert np.allclose(q.camera.eye, [4.0, 0.6, 0.0], atol=1e-12)
    assert np.allclose(q.camera.up, sc.camera.up) and np.allclose(q.camera.target, 0.0)
    # N steps of 360/N come back to the start; frame 0 is the scene itself
    assert np.allclose(orbit(sc, 4, 4).camera.eye, eye, atol=1e-12)
    assert np.allclose(orbit(sc, 0, 4).camera.eye, eye)
    assert np.allclose(sc.camera.eye, eye)  # the scene given is not changed


def test_object_orbit_turns_objects_the_other_way():
    sc = load_scene(SAMPLE_PLAN.parent / "scenes" / "panel.toml",
                    variables={"material": str(SAMPLE_PLAN)})
    o = sc.objects[0]
    moved = [type(o)(**{**o.__dict__, "translate": np.array([1.0, 0.0, 0.0])})]
    sc2 = type(sc)(**{**sc.__dict__, "objects": moved})
    q = orbit(sc2, 1, 4, "object")
    # -90 deg about +y: (1, 0, 0) -> (0, 0, 1); the camera stays
    assert np.allclose(q.objects[0].translate, [0.0, 0.0, 1.0], atol=1e-12)
    assert np.allclose(q.camera.eye, sc.camera.eye)
    want = axis_rotation([0, 1, 0], -90.0) @ rotation_matrix(o.rotate_deg)
    assert np.allclose(rotation_matrix(q.objects[0].rotate_deg), want, atol=1e-12)


def test_euler_angles_invert_the_mesh_rotation_also_at_gimbal_lock(rng):
    for angles in [*rng.uniform(-180, 180, (50, 3)), (10.0, 90.0, -30.0), (0.0, -90.0, 45.0)]:
        r = rotation_matrix(angles)
        assert np.allclose(rotation_matrix(euler_xyz_deg(r)), r, atol=1e-9), angles
    # Rodrigues against the x, y, z rotations of rotation_matrix
    for k, axis in enumerate(np.eye(3)):
        angles = np.zeros(3)
        angles[k] = 37.0
        assert np.allclose(axis_rotation(axis, 37.0), rotation_matrix(angles), atol=1e-12)


def test_render_turntable_options_are_checked(run_gonio, tmp_path):
    scene = SAMPLE_PLAN.parent / "scenes" / "sphere.toml"
    for args, words in (((" --frame", "1"), "--frame needs --turntable"),
                        (("--turntable", "4", "--frame", "4"), "--frame 4 is outside 0 to 3"),
                        (("--turntable", "0"), "not a number of frames"),
                        (("--turntable", "2", "--orbit", "moon"), "--orbit 'moon' is unknown")):
        args = [a.strip() for a in args]
        r = run_gonio("render", scene, "-o", tmp_path / "a.png", *args)
        assert r.exit_code == 2 and words in r.stderr and len(r.stderr.splitlines()) == 1, \
            r.stderr
    assert not list(tmp_path.iterdir())


def test_plain_job_options_become_gonio_words(tmp_path):
    (tmp_path / "in.csv").write_text("x\n")
    plan = _write(tmp_path / "plan.toml", """
[[job]]
key = "fit/x"
command = "fit"
inputs = ["${out}/x.measurement.json"]
output = "${out}/x.material.json"
options = { refine = false, std-weights = true, exclude-theta-i = [60, 70.0], plot = "${out}/x.png" }

[[job]]
key = "ingest/x"
command = "ingest"
inputs = ["in.csv"]
output = "${out}/x.measurement.json"
options = { scale = 0.01 }
""")
    p = read_plan(plan, tmp_path / "out")
    fit, ingest = p.jobs
    out = str(tmp_path / "out")
    assert fit.argv == ("fit", f"{out}/x.measurement.json", "-o", f"{out}/x.material.json",
                        "--no-refine", "--std-weights", "--exclude-theta-i", "60",
                        "--exclude-theta-i", "70", "--plot", f"{out}/x.png")
    assert fit.outputs == (f"{out}/x.material.json", f"{out}/x.png")  # --plot is one too
    assert ingest.argv == ("ingest", str(tmp_path / "in.csv"), "-o",
                           f"{out}/x.measurement.json", "--scale", "0.01")
    # the fit waits for the ingest although the plan lists it first
    from gonio_cli.batch.plan import check_graph

    assert check_graph(p) == ["ingest/x", "fit/x"]


def test_folder_outputs_hash_their_files(tmp_path):
    from gonio_cli.batch.jobs import sha256

    d = tmp_path / "maps"
    (d / "sub").mkdir(parents=True)
    (d / "a.bin").write_bytes(b"1")
    (d / "sub" / "b.bin").write_bytes(b"2")
    first = sha256(str(d))
    assert first is not None and sha256(str(d)) == first
    (d / "sub" / "b.bin").write_bytes(b"3")
    assert sha256(str(d)) != first
    assert sha256(str(tmp_path / "missing")) is None


def test_render_turntable_writes_frames_and_an_animated_preview(run_gonio, tmp_path):
    """``--turntable 3`` = three ``--frame K`` renders; frame 0 is the scene unturned."""
    from PIL import Image

    from gonio_cli.schemas import write_material
    sys.path.insert(0, str(ROOT / "tests"))
    from test_render_reference import ink

    material = tmp_path / "ink.material.json"
    write_material(material, ink(620.0, 0.18))
    scene = SAMPLE_PLAN.parent / "scenes" / "sphere.toml"
    common = (scene, "--var", f"material={material}", "--width", "32", "--height", "32")
    assert run_gonio("render", *common, "-o", tmp_path / "spin.png", "--turntable", "3",
                     "--exr", tmp_path / "spin.exr").exit_code == 0
    assert run_gonio("render", *common, "-o", tmp_path / "still.png").exit_code == 0
    assert run_gonio("render", *common, "-o", tmp_path / "k2.png", "--turntable", "3",
                     "--frame", "2").exit_code == 0

    def pixels(name):
        with Image.open(tmp_path / name) as im:
            return np.asarray(im.convert("RGB"))

    assert np.array_equal(pixels("spin.frame000.png"), pixels("still.png"))
    assert np.array_equal(pixels("spin.frame002.png"), pixels("k2.png"))
    assert not np.array_equal(pixels("spin.frame000.png"), pixels("spin.frame001.png"))
    assert all((tmp_path / f"spin.frame{k:03d}.exr").is_file() for k in range(3))
    with Image.open(tmp_path / "spin.png") as im:
        assert im.n_frames == 3
        for k in range(3):
            im.seek(k)
            assert np.array_equal(np.asarray(im.convert("RGB")), pixels(f"spin.frame{k:03d}.png"))


def test_animated_previews_are_lossless_at_every_compression_level(tmp_path):
    """A preview deflates at level 1 by default (imageio.PREVIEW_COMPRESSION, quick to
    write); any level gives the same frames back, and level 9 a file no larger."""
    from PIL import Image

    from gonio_cli.imageio import write_apng

    rng = np.random.default_rng(2)
    frames = []
    for k in range(3):
        path = tmp_path / f"f{k}.png"
        smooth = np.linspace(0, 255, 64 * 48 * 3).reshape(48, 64, 3)
        Image.fromarray((smooth + rng.integers(0, 8, smooth.shape)).clip(0, 255)
                        .astype(np.uint8)).save(path)
        frames.append(path)
    for level in ("fast", "small"):
        write_apng(tmp_path / f"{level}.png", frames, compression=level)
        with Image.open(tmp_path / f"{level}.png") as im:
            assert im.n_frames == 3
            for k, f in enumerate(frames):
                im.seek(k)
                with Image.open(f) as src:
                    assert np.array_equal(np.asarray(im.convert("RGB")), np.asarray(src))
    assert (tmp_path / "small.png").stat().st_size <= (tmp_path / "fast.png").stat().st_size


def test_help_and_plan_errors_do_not_import_dask(tmp_path):
    """Dask is imported only when a cluster is needed (``gonio --version`` stays light:
    tests/test_cli.py)."""
    import subprocess

    plan = _write(tmp_path / "plan.toml", "[[material]]\nname = 'x'\ncsv = ['none.csv']\n")
    code = ("import sys\nfrom gonio_cli import cli\n"
            f"a = cli.run(['batch', '--help'])\nb = cli.run(['batch', {str(plan)!r}, '-o', "
            f"{str(tmp_path / 'out')!r}])\n"
            "print(a, b, sorted(m for m in ('dask', 'distributed') if m in sys.modules))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert done.stdout.strip().splitlines()[-1] == "0 2 []", done.stdout + done.stderr


def test_matrix_expands_materials_scenes_vars_and_frames(tmp_path):
    for name in ("a.material.json", "b.material.json", "s.toml", "t.toml"):
        (tmp_path / name).write_text("{}")
    plan = _write(tmp_path / "plan.toml", """
[[material]]
name = "a"
material = "a.material.json"

[[material]]
name = "b"
material = "b.material.json"

[matrix]
scenes = ["s.toml", "t.toml"]
vars = { illuminant = ["D65", "A"], exposure = 1 }
frames = 3
orbit = "object"
""")
    p = read_plan(plan, tmp_path / "out")
    frames = [j for j in p.jobs if j.labels["role"] == "frame"]
    previews = [j for j in p.jobs if j.labels["role"] == "preview"]
    assert len(frames) == 2 * 2 * 2 * 3 and len(previews) == 2 * 2 * 2
    j = next(j for j in frames if j.key == "render/b/t-illuminant=A-exposure=1/frame002")
    assert j.argv == ("render", str(tmp_path / "t.toml"), "-o",
                      str(tmp_path / "out" / "b" / "t-illuminant=A-exposure=1.frame002.png"),
                      "--var", "illuminant=A", "--var", "exposure=1",
                      "--var", f"material={tmp_path / 'b.material.json'}",
                      "--turntable", "3", "--frame", "2", "--orbit", "object")
    assert str(tmp_path / "b.material.json") in j.inputs
    pv = next(p for p in previews if p.key == "preview/b/t-illuminant=A-exposure=1")
    assert pv.inputs == tuple(str(tmp_path / "out" / "b" / f"t-illuminant=A-exposure=1.frame"
                                  f"{k:03d}.png") for k in range(3))


def test_a_material_sets_its_own_render_options_and_fits_draw_their_plot(tmp_path):
    """[[material]] render = {…} goes to that material's renders only, over the matrix's;
    a fit from CSV also writes NAME.fit.png (one more output: the contact sheet links it),
    unless the plan names the plot itself."""
    for name in ("a.csv", "b.csv", "s.toml"):
        (tmp_path / name).write_text("x")
    plan = _write(tmp_path / "plan.toml", """
[[material]]
name = "a"
csv = ["a.csv"]
render = { exposure-stops = -1.5 }

[[material]]
name = "b"
csv = ["b.csv"]
fit = { plot = "${out}/plots/b.png" }

[matrix]
scenes = ["s.toml"]
render = { exposure-stops = 2, ssaa = 1 }
""")
    p = read_plan(plan, tmp_path / "out")
    jobs = {j.key: j for j in p.jobs}

    def option(job, name):
        return job.argv[job.argv.index(name) + 1]

    assert option(jobs["render/a/s"], "--exposure-stops") == "-1.5"
    assert option(jobs["render/b/s"], "--exposure-stops") == "2"
    assert option(jobs["render/a/s"], "--ssaa") == "1"
    assert jobs["fit/a"].outputs == (str(tmp_path / "out/a/a.material.json"),
                                     str(tmp_path / "out/a/a.fit.png"))
    assert option(jobs["fit/b"], "--plot") == str(tmp_path / "out/plots/b.png")


def test_a_material_cannot_set_what_the_matrix_sets(run_gonio, tmp_path):
    (tmp_path / "a.csv").write_text("x")
    (tmp_path / "s.toml").write_text("x")
    plan = _write(tmp_path / "plan.toml", '[[material]]\nname = "a"\ncsv = ["a.csv"]\n'
                  'render = { frame = 2 }\n\n[matrix]\nscenes = ["s.toml"]\n')
    _refused(run_gonio, plan, tmp_path / "out", "[[material]] a render", "'frame'")
