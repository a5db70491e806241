"""The Makefile pipelines as a file graph ("Pipelines"; docs/pipelines.md).

Every test drives GNU make on a copy of the Makefile, ``pipelines/``, ``sample_data/`` and
``pyproject.toml`` in a temporary folder, with ``OUT`` there too. No gonio stage runs: the
copy is "built" once per session with ``make -t demo`` (touch every target in dependency
order), its times are moved an hour into the past, and each test then touches a source
and asks make what it would do: ``make -n -t GOAL`` lists the targets it would remake,
``make -n GOAL`` the commands, ``make -q GOAL`` whether anything is out of date.

make runs with ``VENV=<the project's .venv> STAMP=`` (use that environment as it is), so
nothing is installed and no virtual environment is made; the whole module takes ~2 s.
"""

from __future__ import annotations

import os
import shlex
import shutil
import subprocess
import time
from collections import Counter
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MAKE = shutil.which("make")
COPIED = ("Makefile", "pipelines", "sample_data", "pyproject.toml", "requirements.lock",
          "setup.py", "gonio_cli/halftone/_diffuse.c", "gonio_cli/render/_envlookup.c",
          "gonio_cli/render/_rasterscan.c")

pytestmark = pytest.mark.skipif(
    MAKE is None, reason="`make` is not on PATH: the pipelines are Makefiles (install GNU make)")

INKS = ("red", "green", "blue")
RENDERS = ("render/figure5.png", "render/print-D65.png", "render/print-A.png",
           "render/print-A-unadapted.png", "render/paint_env.png", "render/paint_sparkle.png",
           "render/paint_sky.png")
PRINTS = {"render/print-D65.png", "render/print-A.png", "render/print-A-unadapted.png"}

# Every file `make demo` makes, relative to OUT: the file graph of docs/pipelines.md.
ALL = frozenset(
    [f"rgbink/{i}.{kind}" for i in INKS for kind in
     ("measurement.json", "material.json", "fit.png", "torrance-sparrow.material.json")]
    + ["rgbink/print.png", "rgbink/print.json",
       "carpaint/paint.measurement.json", "carpaint/paint.material.json",
       "carpaint/paint.fit.png", "carpaint/coat.measurement.json",
       "carpaint/coat.material.json", "carpaint/coat.fit.png",
       "lobes/basis.json", "lobes/basis.png", "lobes/paint.lobes.json",
       *(f"lobes/{i}.lobes.json" for i in INKS),
       "sky/index.json", "sky/sun/index.json", "sky/quarry/index.json", "render/sparkle.png",
       *RENDERS, "report/report.md", "demo.txt"])
# Files written by the run that writes another target (two-target rules) and the list.
SECONDARY = frozenset({"rgbink/red.fit.png", "rgbink/green.fit.png", "rgbink/blue.fit.png",
                       "rgbink/print.json", "carpaint/paint.fit.png",
                       "carpaint/coat.fit.png", "lobes/basis.png",
                       "demo.txt"})
ALL_LOBES = {"lobes/basis.json", "lobes/basis.png", "lobes/paint.lobes.json",
             *(f"lobes/{i}.lobes.json" for i in INKS)}
HOUR_NS = 3600 * 10**9


def _environment() -> dict:
    """The test's environment without an enclosing make's flags (``make test`` runs us):
    MAKEFLAGS would pass its -j, -n or command-line variables on to our make."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("MAKEFLAGS", "MFLAGS", "MAKELEVEL", "MAKEOVERRIDES", "GNUMAKEFLAGS")}
    env["LC_ALL"] = "C"
    return env


class Tree:
    """A copy of the pipelines with its own OUT; make runs there with the project's .venv."""

    def __init__(self, root: Path):
        self.root = root
        self.out = root / "out"

    def make(self, *args: str, stamp: str = "", ok=(0,)) -> subprocess.CompletedProcess:
        cmd = [MAKE, "--no-print-directory", "-C", str(self.root), f"VENV={ROOT / '.venv'}",
               f"STAMP={stamp}", f"OUT={self.out}", *args]
        r = subprocess.run(cmd, capture_output=True, text=True, env=_environment(),
                           timeout=60)
        assert r.returncode in ok, f"{shlex.join(cmd)} → {r.returncode}\n{r.stdout}\n{r.stderr}"
        return r

    def rel(self, path: str) -> str:
        p = Path(path)
        return p.relative_to(self.out).as_posix() if p.is_relative_to(self.out) else path

    def plan(self, goal: str = "demo", **kw) -> set[str]:
        """The files ``make GOAL`` would remake (``make -n -t``), relative to OUT."""
        lines = self.make("-n", "-t", goal, **kw).stdout.splitlines()
        return {self.rel(line[len("touch "):]) for line in lines if line.startswith("touch ")}

    def commands(self, *args: str) -> list[list[str]]:
        """The gonio commands of ``make -n ARGS`` as argument lists (``gonio`` dropped)."""
        text = self.make("-n", *args).stdout.replace("\\\n", " ")
        return [argv[1:] for argv in map(shlex.split, text.splitlines())
                if argv and Path(argv[0]).name == "gonio"]

    def up_to_date(self, goal: str = "demo") -> bool:
        return self.make("-q", goal, ok=(0, 1)).returncode == 0

    def target(self, rel: str) -> str:
        return str(self.out / rel)

    def touch(self, rel: str) -> None:
        """An edit: the file (relative to the tree) becomes the newest of all."""
        os.utime(self.root / rel)


def _output(argv: list[str]) -> str:
    return argv[argv.index("-o") + 1]


def _made_by(tree: Tree, argv: list[str]) -> str:
    """The target a gonio command makes, relative to OUT (prefilter and report write a
    folder; the target is its index file)."""
    out = tree.rel(_output(argv))
    return out + {"prefilter": "/index.json", "report": "/report.md"}.get(argv[0], "")


def assert_remakes(tree: Tree, expected: set[str]) -> list[list[str]]:
    """``make demo`` would remake exactly EXPECTED (+ the list of outputs), by both
    ``make -n -t`` (targets) and ``make -n`` (one gonio command per target that is not a
    secondary output). Returns the commands."""
    assert tree.plan() == set(expected) | {"demo.txt"}
    cmds = tree.commands("demo")
    made = [_made_by(tree, c) for c in cmds]
    assert sorted(made) == sorted(set(expected) - SECONDARY)
    return cmds


def _backdate(root: Path, by_ns: int) -> None:
    for p in sorted(root.rglob("*")):
        if p.is_file():
            st = p.stat()
            os.utime(p, ns=(st.st_atime_ns - by_ns, st.st_mtime_ns - by_ns))


@pytest.fixture(scope="session")
def built(tmp_path_factory):
    """A copy made up to date by ``make -t demo`` (every target touched, none run), an hour
    in the past, with the plan ``make -n -t demo`` gave before it."""
    root = tmp_path_factory.mktemp("pipelines").resolve() / "tree"
    root.mkdir()
    for name in COPIED:
        src = ROOT / name
        if src.is_dir():
            shutil.copytree(src, root / name, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            (root / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, root / name)
    tree = Tree(root)
    fresh_plan = tree.plan()
    for rel in fresh_plan:  # the stages make their folders; make -t does not
        (tree.out / rel).parent.mkdir(parents=True, exist_ok=True)
    tree.make("-t", "demo")
    _backdate(root, HOUR_NS)
    return tree, fresh_plan


@pytest.fixture
def tree(built, tmp_path) -> Tree:
    """A private copy of the built tree (modification times kept) for one test to edit."""
    root = tmp_path.resolve() / "tree"
    shutil.copytree(built[0].root, root)
    return Tree(root)


def test_fresh_plan_is_every_artifact(built):
    assert built[1] == ALL


def test_demo_up_to_date_after_build(tree):
    assert tree.up_to_date("demo")
    for stage in ("rgbink", "carpaint", "lobes", "sky", "render"):
        assert tree.up_to_date(stage), stage
    assert tree.plan() == set()
    assert tree.commands("demo") == []


def test_demo_out_of_date_after_an_edit(tree):
    tree.touch("sample_data/sky.exr")
    assert not tree.up_to_date("demo")
    assert not tree.up_to_date("sky")
    assert tree.up_to_date("rgbink") and tree.up_to_date("lobes")


def test_scene_edit_reruns_only_its_renders(tree):
    """Changing a light (or the camera…) of print.toml re-renders the print, nothing else."""
    tree.touch("sample_data/scenes/print.toml")
    cmds = assert_remakes(tree, PRINTS)
    assert [c[0] for c in cmds] == ["render", "render", "render"]
    assert sorted(Path(_output(c)).name for c in cmds) == ["print-A-unadapted.png",
                                                           "print-A.png", "print-D65.png"]


@pytest.mark.parametrize("source, renders", [
    ("sample_data/scenes/figure5.toml", {"render/figure5.png"}),
    ("sample_data/scenes/paint_env.toml", {"render/paint_env.png"}),
    ("sample_data/scenes/paint_sparkle.toml", {"render/paint_sparkle.png"}),
    ("sample_data/scenes/sheet.obj", PRINTS),
    ("sample_data/scenes/paint_sky.toml", {"render/paint_sky.png"}),
    ("sample_data/scenes/floor.material.json", {"render/paint_sky.png"}),
    ("sample_data/meshes/spot.obj", {"render/paint_sky.png"}),
])
def test_other_scene_inputs_rerun_only_renders(tree, source, renders):
    tree.touch(source)
    assert_remakes(tree, renders)


def test_measurement_edit_reruns_everything_downstream(tree):
    """red's CSV → red's ingest and both fits → the lobe basis (chosen over all four
    materials) → every material's lobe weights → the sky, prefiltered per exponent of the
    paint's lobes → every render reading red, its lobes or the sky. Not: the other inks'
    ingest and fits, the halftone, the car paint's ingest and fit, the sparkle texture, the
    paint with glints (lit through its own model, not the lobes).
    And the report (it reads the inks)."""
    tree.touch("sample_data/ink_red.csv")
    cmds = assert_remakes(tree, {
        "rgbink/red.measurement.json", "rgbink/red.material.json", "rgbink/red.fit.png",
        "rgbink/red.torrance-sparrow.material.json", *ALL_LOBES, "sky/index.json",
        "render/figure5.png", *PRINTS, "render/paint_env.png", "report/report.md"})
    kinds = Counter(" ".join(c[:2]) if c[0] == "lobes" else c[0] for c in cmds)
    assert kinds == {"ingest": 1, "fit": 2, "lobes basis": 1, "lobes fit": 4,
                     "prefilter": 1, "render": 5, "report": 1}
    ingest_fit = [c for c in cmds if c[0] in ("ingest", "fit")]
    assert all("red" in Path(_output(c)).name for c in ingest_fit)


def test_paint_measurement_edit(tree):
    tree.touch("sample_data/carpaint_multiangle.csv")
    assert_remakes(tree, {
        "carpaint/paint.measurement.json", "carpaint/paint.material.json",
        "carpaint/paint.fit.png", *ALL_LOBES, "sky/index.json",
        "render/paint_env.png", "render/paint_sparkle.png"})


@pytest.mark.parametrize("source, remade", [
    ("sample_data/sky.exr", {"sky/index.json", "sky/sun/index.json", "render/paint_env.png",
                             "render/paint_sparkle.png"}),
    ("sample_data/sparkle/photo_ti40.png", {"render/sparkle.png"}),
    ("sample_data/envmaps/quarry_01_1k.hdr", {"sky/quarry/index.json", "render/paint_sky.png"}),
    ("sample_data/coat_paint.csv", {"carpaint/coat.measurement.json",
                                    "carpaint/coat.material.json", "carpaint/coat.fit.png",
                                    "render/paint_sky.png"}),
    ("sample_data/print_image.png", {"rgbink/print.png", "rgbink/print.json", *PRINTS}),
    ("sample_data/ink_blue_b.csv", {
        "rgbink/blue.measurement.json", "rgbink/blue.material.json", "rgbink/blue.fit.png",
        "rgbink/blue.torrance-sparrow.material.json", *ALL_LOBES, "sky/index.json",
        "render/figure5.png", *PRINTS, "render/paint_env.png", "report/report.md"}),
])
def test_other_sources(tree, source, remade):
    tree.touch(source)
    assert_remakes(tree, remade)


def _render_scenes(tree: Tree):
    """(target, scene) of every ``gonio render`` of the demo, the scene loaded with the
    command's own --var values, as gonio render would load it."""
    from gonio_cli.render.scene import load_scene

    found = []
    for argv in tree.commands("-B", "demo"):
        if argv[0] != "render":
            continue
        variables = dict(argv[i + 1].split("=", 1) for i, a in enumerate(argv) if a == "--var")
        found.append((_output(argv), load_scene(tree.root / argv[1], variables=variables)))
    return found


def test_renders_depend_on_every_file_they_read(tree):
    """For each render, each file its scene reads (scene.inputs: the scene, meshes,
    materials, masks, measurements, lobes, the prefiltered index, sparkle texture) is
    inside the copy and made newer makes the render out of date."""
    scenes = _render_scenes(tree)
    assert sorted(tree.rel(t) for t, _ in scenes) == sorted(RENDERS)
    for target, scene in scenes:
        assert len(scene.inputs) >= 2, target
        assert tree.up_to_date(target)
        for path in scene.inputs:
            path = Path(path)
            assert path.is_relative_to(tree.root), f"{target} reads {path} outside the tree"
            st = path.stat()
            os.utime(path)
            assert not tree.up_to_date(target), f"{tree.rel(target)} does not depend on {path}"
            os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))
        assert tree.up_to_date(target)


def test_environment_only_for_scenes_that_need_one(tree):
    """Building a render alone from scratch (``make -n -B``) prefilters the sky only when
    its scene has an [environment] (not for figure5 or the prints), and fits lobes only
    when an object of it names lobes (paint_sky's are the materials' own)."""
    needs = {}
    for target, scene in _render_scenes(tree):
        kinds = {c[0] for c in tree.commands("-B", target)}
        assert "render" in kinds
        needs[tree.rel(target)] = scene.environment is not None
        assert ("prefilter" in kinds) == needs[tree.rel(target)], tree.rel(target)
        lobes = any(o.lobes is not None for o in scene.objects)
        assert ("lobes" in kinds) == lobes, tree.rel(target)
    assert needs["render/figure5.png"] is False and needs["render/paint_env.png"] is True
    # An edit of the prefiltered sky reaches only the renders under it.
    tree.touch("out/sky/index.json")
    assert_remakes(tree, {"render/paint_env.png"})
    tree.touch("out/sky/sun/index.json")          # (paint_env.png is still out of date)
    assert_remakes(tree, {"render/paint_env.png", "render/paint_sparkle.png"})


def test_stamp_is_order_only(tree):
    """With STAMP= nothing is installed; with a stamp, a newer pyproject.toml plans the
    reinstall (the stamp) and nothing else: stages take it as order-only."""
    assert not any("pip" in line for line in tree.make("-n", "-B", "demo").stdout.splitlines())
    stamp = tree.root / "installed.stamp"
    stamp.touch()
    assert tree.plan(stamp=str(stamp)) == set()
    tree.touch("pyproject.toml")
    assert tree.plan(stamp=str(stamp)) == {str(stamp)}
    assert tree.make("-q", "demo", stamp=str(stamp), ok=(0, 1)).returncode == 1
    # new pins reinstall too, and rerun nothing else
    stamp.touch()
    assert tree.plan(stamp=str(stamp)) == set()
    tree.touch("requirements.lock")
    assert tree.plan(stamp=str(stamp)) == {str(stamp)}
    # so does a change to the C kernel that pip compiles at install
    stamp.touch()
    time.sleep(0.05)  # past the file system's clock tick (~4 ms): the edit is newer
    tree.touch("gonio_cli/halftone/_diffuse.c")
    assert tree.plan(stamp=str(stamp)) == {str(stamp)}
    stamp.touch()
    time.sleep(0.05)
    tree.touch("gonio_cli/render/_envlookup.c")
    assert tree.plan(stamp=str(stamp)) == {str(stamp)}


def test_ink_options_come_from_inks_toml(tree):
    """The demo's ingest and fit options are sample_data/inks.toml's (gonio report and
    tests/test_fit.py read the same file): editing it changes the commands and remakes
    every ink."""
    from gonio_cli.samples import demo_inks

    inks = {i.name: i for i in demo_inks(tree.root / "sample_data")}
    commands = tree.commands("-B", "rgbink")
    for name, ink in inks.items():
        argv = next(a for a in commands if a[0] == "ingest"
                    and _output(a) == tree.target(f"rgbink/{name}.measurement.json"))
        flags = argv[argv.index("-o") + 2:]
        expected = [x for k, v in ink.ingest.items()
                    for x in ("--" + k.replace("_", "-"), f"{v:g}" if isinstance(v, float)
                              else str(v))]
        assert flags == expected + ["--summary"]
        assert argv[1:argv.index("-o")] == [str(p.relative_to(tree.root)) for p in ink.files]
    fits = [a for a in commands if a[0] == "fit"]
    assert len(fits) == 6 and all(a[-2:] == ["--exclude-theta-i-deg", "70"] for a in fits)
    tree.touch("sample_data/inks.toml")
    assert {f"rgbink/{i}.measurement.json" for i in inks} <= tree.plan("rgbink")
