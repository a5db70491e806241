"""Shared by tests/test_bad_*.py: good artifacts made once by the sample pipeline's stages,
copies of them broken on purpose, and the one assertion every bad input must meet.

Each module gets the good artifacts through a module-scoped fixture (``good``); they are
made once per test session (:func:`make_good`, small sizes so it takes a few seconds) in a
folder no test writes into. A test copies a file with :func:`broken`, changing one field,
runs the command and checks :func:`assert_refused`: exit status 2, exactly one stderr line
``gonio: error: …`` naming the file and the field, no traceback or "internal error", and
no output file.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any, Callable

from gonio_cli import cli, log

ROOT = Path(__file__).resolve().parent.parent
SAMPLE = ROOT / "sample_data"

#: The session's good artifacts (one folder), made on first use.
_GOOD: dict[str, Path] = {}

SCENE = """\
[camera]
eye = [0.0, 0.0, 4.0]
target = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_deg = 40.0
width = 12
height = 12

[[object]]
mesh = "builtin:sphere"
material = "{material}"
{extra_object}
{light}
{extra}
[output]
ssaa = 1
"""

LIGHT = """
[[light]]
type = "directional"
direction = [0.0, 0.0, 1.0]
irradiance = {irradiance}
"""


def run(*args) -> tuple[int, str]:
    """``gonio ARGS…`` in-process: (exit status, stderr). stdout is not looked at."""
    import contextlib
    import io

    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = cli.run([str(a) for a in args])
    log.set_quiet(False)
    return code, err.getvalue()


def _ok(*args) -> None:
    code, err = run(*args)
    assert code == 0, f"gonio {' '.join(map(str, args))}: {err}"


def make_good(factory) -> dict[str, Path]:
    """Measurement, material, lobe basis, lobes, prefiltered sky and a render report,
    made by gonio itself from sample_data (the pipeline's own stages, tiny sizes)."""
    if _GOOD:
        return _GOOD
    d = factory.mktemp("good")
    g = {"measurement": d / "red.measurement.json", "material": d / "red.material.json",
         "basis": d / "basis.json", "lobes": d / "red.lobes.json",
         "index": d / "sky" / "index.json", "report": d / "render.json"}
    _ok("ingest", SAMPLE / "ink_red.csv", "-o", g["measurement"])
    _ok("fit", g["measurement"], "-o", g["material"], "--exclude-theta-i", "70")
    _ok("lobes", "basis", g["material"], "--max-lobes", "2", "-o", g["basis"])
    _ok("lobes", "fit", g["material"], "--basis", g["basis"], "--lobes", "2", "-o", g["lobes"])
    _ok("prefilter", SAMPLE / "sky.exr", "--lobes", g["lobes"], "-o", d / "sky",
        "--resolution", "8")
    scene = d / "scene.toml"
    scene.write_text(scene_text(g["material"]))
    _ok("render", scene, "-o", d / "render.png", "--report", g["report"])
    _GOOD.update(g)
    return _GOOD


def scene_text(material, *, irradiance="3.0", lobes=None, index=None, extra="",
               light=True) -> str:
    """A 12 × 12 sphere of ``material`` under one directional light (and the environment
    ``index`` through ``lobes`` if given)."""
    extra_object = f'lobes = "{lobes}"' if lobes else ""
    if index:
        extra += f'\n[environment]\nprefiltered = "{index}"\n'
    return SCENE.format(material=material, extra_object=extra_object, extra=extra,
                        light=LIGHT.format(irradiance=irradiance) if light else "")


def broken(src: Path, folder: Path, change: Callable[[dict], Any], name: str | None = None
           ) -> Path:
    """A copy of the JSON artifact ``src`` in ``folder`` after ``change(doc)`` (which edits
    the document in place); the copy keeps the source's name unless ``name`` is given."""
    doc = json.loads(src.read_text())
    change(doc)
    out = folder / (name or src.name)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(doc))
    return out


def copy_index(good_index: Path, folder: Path, change: Callable[[dict], Any]) -> Path:
    """A copy of a prefiltered folder (maps and index.json) with ``index.json`` changed."""
    out = folder / "sky"
    shutil.copytree(good_index.parent, out)
    return broken(good_index, out, change, "index.json")


def set_key(key: str, value) -> Callable[[dict], None]:
    """A change that sets ``doc[key] = value`` (a dotted key walks into objects/lists)."""
    def change(doc):
        *head, last = key.split(".")
        target = doc
        for k in head:
            target = target[int(k)] if isinstance(target, list) else target[k]
        if isinstance(target, list):
            target[int(last)] = value
        else:
            target[last] = value
    return change


def assert_refused(code: int, err: str, *, names: tuple[str, ...], outputs=()) -> None:
    """Exit 2, one ``gonio: error:`` line on stderr holding each of ``names`` (the file,
    the field), no traceback or internal error, and none of ``outputs`` written."""
    lines = err.strip().splitlines()
    assert code == 2, f"exit {code}: {err}"
    assert len(lines) == 1 and lines[0].startswith("gonio: error: "), err
    assert "Traceback" not in err and "internal error" not in err, err
    for n in names:
        assert n in lines[0], f"{n!r} not named in: {lines[0]}"
    for out in outputs:
        assert not Path(out).exists(), f"{out} was written"


def refused_ingest_line(res, tmp_path, out) -> str:
    """The one line of a refused ``gonio ingest`` run ``res`` that was to write ``out``
    (its ``tmp_path`` prefix removed): exit 2, one ``gonio: error:`` line with a fix
    (``; ``), no traceback, nothing written in ``out``'s folder."""
    lines = res.stderr.strip().splitlines()
    assert res.exit_code == 2, res.stderr
    assert len(lines) == 1, res.stderr
    line = lines[0].replace(str(tmp_path) + "/", "")
    assert line.startswith("gonio: error: "), line
    assert "Traceback" not in res.stderr
    assert "; " in line, f"no fix in: {line}"
    assert not out.exists()
    assert not (out.parent.exists() and any(out.parent.iterdir()))
    return line
