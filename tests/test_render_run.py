"""``gonio render`` as a library call (gonio_cli.render.run): the same files as the
command, from plain Python, with a scene path or a loaded Scene; bad options as the
command's one-line errors."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from gonio_cli.errors import InputError
from gonio_cli.imageio import read_image
from gonio_cli.render.options import RenderOptions, frame_files, frame_name
from gonio_cli.render.run import run
from gonio_cli.render.scene import load_scene
from gonio_cli.schemas import write_material
from test_render_reference import ink, sphere_scene


@pytest.fixture
def scene(tmp_path) -> Path:
    write_material(tmp_path / "ink.json", ink(620.0, 0.18))
    return Path(sphere_scene(tmp_path, tmp_path / "ink.json", size=24))


def test_run_writes_what_the_command_writes(run_gonio, scene, tmp_path):
    done = run(scene, RenderOptions(output=tmp_path / "lib.png", exr=tmp_path / "lib.exr",
                                    report=tmp_path / "lib.json", ssaa=2))
    r = run_gonio("render", scene, "-o", tmp_path / "cli.png", "--exr", tmp_path / "cli.exr",
                  "--ssaa", "2")
    assert r.exit_code == 0, r.stderr
    [frame] = done.frames
    assert frame.index is None and done.preview is None
    assert frame.files["-o"] == tmp_path / "lib.png" and frame.files["--gamut-warning"] is None
    assert (frame.width, frame.height) == (24, 24) and frame.total_s > 0
    assert "scene" in frame.stats.time_s and "shade" in frame.stats.time_s
    assert (tmp_path / "lib.png").read_bytes() == (tmp_path / "cli.png").read_bytes()
    np.testing.assert_array_equal(read_image(tmp_path / "lib.exr").pixels,
                                  read_image(tmp_path / "cli.exr").pixels)
    report = json.loads((tmp_path / "lib.json").read_text())
    assert report["outputs"]["png"] == "lib.png"                 # beside the report


def test_run_renders_a_loaded_scene_as_it_is(scene, tmp_path):
    loaded = load_scene(scene, overrides={"width": 16, "height": 8})
    done = run(loaded, RenderOptions(output=tmp_path / "a.png"))
    assert (done.frames[0].width, done.frames[0].height) == (16, 8)
    assert "scene" not in done.frames[0].stats.time_s          # nothing was loaded
    assert read_image(tmp_path / "a.png").pixels.shape[:2] == (8, 16)
    with pytest.raises(ValueError, match="rendered as it is"):
        run(loaded, RenderOptions(output=tmp_path / "b.png", ssaa=2))


def test_run_a_whole_turntable(scene, tmp_path):
    options = RenderOptions(output=tmp_path / "t.png", turntable=3, orbit="object")
    assert [k for k, _ in frame_files(options)] == [0, 1, 2]
    done = run(scene, options)
    assert [f.index for f in done.frames] == [0, 1, 2]
    assert [f.files["-o"] for f in done.frames] == [frame_name(tmp_path / "t.png", k)
                                                    for k in range(3)]
    assert done.preview == tmp_path / "t.png" and (tmp_path / "t.png").exists()


@pytest.mark.parametrize("options, message", [
    ({"output": "a.jpg"}, "-o a.jpg: the image is written as PNG"),
    ({"exr": "a.png"}, "--exr a.png: not an .exr name"),
    ({"frame": 1}, "--frame needs --turntable N"),
    ({"turntable": 2, "frame": 2}, "--frame 2 is outside 0 to 1"),
    ({"tonemap": "nope"}, "--tonemap 'nope' is unknown"),
])
def test_bad_options_are_the_commands_errors(scene, tmp_path, options, message):
    options = {"output": "a.png", **options}
    options = {k: tmp_path / v if isinstance(v, str) and "." in v else v
               for k, v in options.items()}
    with pytest.raises(InputError) as err:
        run(scene, RenderOptions(**options))
    assert message.replace("a.", f"{tmp_path}/a.") in str(err.value)
    assert not list(tmp_path.glob("a.*"))
