"""Scene files (``gonio_cli.render.scene``): what a valid scene becomes, and every kind of
bad scene refused with one line naming the file and the key (and, from the CLI, exit 2
and nothing written)."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest

from gonio_cli.errors import InputError
from gonio_cli.evaluate import grid_spec
from gonio_cli.render.pipeline import render_scene
from gonio_cli.render.scene import load_scene
from gonio_cli.render.scene_grid import choose_grid
from gonio_cli.schemas import Material, write_material
from gonio_cli.spectra import cmfs, delta_e_2000, parse_grid, xyz_to_lab

GRID = parse_grid()

CAMERA = """
[camera]
eye = [0.0, 0.0, 4.0]
target = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_deg = 35.0
width = 32
height = 24
"""

LIGHT = """
[[light]]
type = "directional"
direction = [1.0, 1.0, 1.0]
irradiance = 3.0
spectrum = "D65"
"""

OBJECT = """
[[object]]
mesh = "builtin:sphere"
material = "red.json"
"""


def write_red(folder: Path) -> Path:
    path = folder / "red.json"
    n = GRID.size
    write_material(path, Material("goniochromatic", GRID,
                                  {"alpha": 0.18, "rho": np.full(n, 0.1), "c": np.full(n, 2.0)}))
    return path


@pytest.fixture
def scene_dir(tmp_path):
    write_red(tmp_path)
    (tmp_path / "print.png").write_bytes(b"")  # existence is all the scene checks
    return tmp_path


def write_scene(folder: Path, text: str, name="scene.toml") -> Path:
    path = folder / name
    path.write_text(textwrap.dedent(text))
    return path


def test_example_of_the_issue_loads(scene_dir):
    sc = load_scene(write_scene(scene_dir, CAMERA + OBJECT + LIGHT))
    assert (sc.camera.width, sc.camera.height, sc.camera.fov_deg) == (32, 24, 35.0)
    assert len(sc.objects) == 1 and sc.objects[0].kind == "material"
    assert sc.objects[0].material == scene_dir / "red.json"
    np.testing.assert_allclose(sc.objects[0].scale, 1.0)
    (light,) = sc.lights
    assert light.kind == "directional" and light.irradiance == 3.0
    np.testing.assert_allclose(light.direction, np.ones(3) / np.sqrt(3))
    # docs/conventions.md: Σ S ȳ / Σ ȳ = 1 on the working grid
    ybar = cmfs(GRID)[:, 1]
    assert light.spectrum.shape == GRID.shape
    assert light.spectrum @ ybar / ybar.sum() == pytest.approx(1.0)
    assert sc.environment is None and sc.output.spectral == "table"
    assert sc.inputs[0] == sc.path and scene_dir / "red.json" in sc.inputs


def test_vars_and_overrides(scene_dir):
    (scene_dir / "m").mkdir()
    write_red(scene_dir / "m")
    text = CAMERA + LIGHT + """
    [vars]
    dir = "."
    [[object]]
    mesh = "builtin:sphere"
    material = "${dir}/red.json"
    [output]
    ssaa = 3
    """
    path = write_scene(scene_dir, text)
    assert load_scene(path).objects[0].material == scene_dir / "red.json"
    sc = load_scene(path, variables={"dir": "m"},
                    overrides={"width": 8, "ssaa": None, "spectral": "exact"})
    assert sc.objects[0].material == scene_dir / "m" / "red.json"
    assert sc.camera.width == 8 and sc.camera.height == 24
    assert sc.output.ssaa == 3 and sc.output.spectral == "exact"


def test_print_object_and_point_light_and_csv_spectrum(scene_dir):
    write_red(scene_dir)
    csv = scene_dir / "lamp.csv"
    w = np.arange(360, 831, 5)
    csv.write_text("wavelength_nm,value\n" + "".join(f"{x},{1 + x / 1000}\n" for x in w))
    text = CAMERA + """
    [[object]]
    mesh = "builtin:plane"
    inks = ["red.json", "red.json", "red.json"]
    mask = "print.png"
    substrate = { ks = 0.02, shininess = 4 }
    rotate_deg = [-60, 0, 0]
    scale = [2, 1, 1]
    [[light]]
    type = "point"
    position = [0, 2, 2]
    intensity = 10
    spectrum = "lamp.csv"
    """
    sc = load_scene(write_scene(scene_dir, text))
    o = sc.objects[0]
    assert o.kind == "print" and o.mask == scene_dir / "print.png" and len(o.inks) == 3
    assert o.substrate.ks == 0.02 and o.substrate.kd == 0.0
    np.testing.assert_allclose(o.scale, [2, 1, 1])
    assert sc.needs_uvs and sc.lights[0].kind == "point"
    ybar = cmfs(GRID)[:, 1]
    assert sc.lights[0].spectrum @ ybar / ybar.sum() == pytest.approx(1.0)
    assert csv in sc.inputs


BAD = [
    # (what is wrong, scene text, substrings of the message)
    ("unknown object key", CAMERA + LIGHT + OBJECT + """
     [[object]]
     mesh = "builtin:sphere"
     materal = "red.json"
     """, ["[[object]] 2", "unknown key 'materal'", "allowed:", "material"]),
    ("unknown top key", CAMERA + LIGHT + OBJECT + "[lights]\nx = 1\n", ["unknown key 'lights'"]),
    ("unknown camera key", CAMERA.replace("fov_deg", "fov") + LIGHT + OBJECT,
     ["[camera]", "unknown key 'fov'"]),
    ("missing camera key", CAMERA.replace("fov_deg = 35.0", "") + LIGHT + OBJECT,
     ["[camera]", "missing key 'fov_deg'"]),
    ("width as a string", CAMERA.replace("width = 32", 'width = "32"') + LIGHT + OBJECT,
     ["[camera] width", "expected an integer"]),
    ("NaN irradiance", CAMERA + OBJECT + LIGHT.replace("3.0", "nan"),
     ["[[light]] 1 irradiance", "not a finite"]),
    ("eye as two numbers", CAMERA.replace("eye = [0.0, 0.0, 4.0]", "eye = [0.0, 4.0]")
     + LIGHT + OBJECT, ["[camera] eye", "list of 3"]),
    ("missing material file", CAMERA + LIGHT + OBJECT.replace("red.json", "blue.json"),
     ["[[object]] 1 material", "no such file 'blue.json'"]),
    ("missing mesh file", CAMERA + LIGHT + OBJECT.replace("builtin:sphere", "cow.obj"),
     ["[[object]] 1 mesh", "no such file 'cow.obj'"]),
    ("unknown builtin", CAMERA + LIGHT + OBJECT.replace("sphere", "torus"),
     ["[[object]] 1 mesh", "builtin:sphere"]),
    ("no material", CAMERA + LIGHT + '[[object]]\nmesh = "builtin:sphere"\n',
     ["[[object]] 1", "needs one of"]),
    ("material and inks", CAMERA + LIGHT + OBJECT + 'inks = ["red.json"]\n',
     ["[[object]] 1", "more than one"]),
    ("two inks", CAMERA + LIGHT + '[[object]]\nmesh = "builtin:plane"\n'
     'inks = ["red.json", "red.json"]\nmask = "print.png"\n', ["[[object]] 1 inks", "3"]),
    ("inks without mask", CAMERA + LIGHT + '[[object]]\nmesh = "builtin:plane"\n'
     'inks = ["red.json", "red.json", "red.json"]\n', ["[[object]] 1", "missing key 'mask'"]),
    ("mask on a plain object", CAMERA + LIGHT + OBJECT + 'mask = "print.png"\n',
     ["[[object]] 1 mask", "printed object"]),
    ("interpolation on a plain object", CAMERA + LIGHT + OBJECT + 'interpolation = "smooth"\n',
     ["[[object]] 1 interpolation", "measured object"]),
    ("unknown interpolation", CAMERA + LIGHT + '[[object]]\nmesh = "builtin:sphere"\n'
     'measured = "red.json"\ninterpolation = "rbf"\n',
     ["[[object]] 1 interpolation", "'rbf'", "smooth, four-nearest"]),
    ("unknown light type", CAMERA + OBJECT + LIGHT.replace('"directional"', '"spot"'),
     ["[[light]] 1 type", "'spot' is unknown", "directional, point"]),
    ("point key on directional", CAMERA + OBJECT + LIGHT + "intensity = 3\n",
     ["[[light]] 1 intensity", "directional"]),
    ("unknown illuminant", CAMERA + OBJECT + LIGHT.replace("D65", "D66"),
     ["[[light]] 1 spectrum", "'D66'"]),
    ("zero direction", CAMERA + OBJECT + LIGHT.replace("[1.0, 1.0, 1.0]", "[0, 0, 0]"),
     ["[[light]] 1 direction", "zero length"]),
    ("no lights", CAMERA + OBJECT, ["no [[light]]"]),
    ("unknown tone map", CAMERA + OBJECT + LIGHT + '[output]\ntonemap = "aces"\n',
     ["[output] tonemap", "clip, reinhard, filmic"]),
    ("ssaa zero", CAMERA + OBJECT + LIGHT + "[output]\nssaa = 0\n", ["[output] ssaa"]),
    ("bad grid", CAMERA + OBJECT + LIGHT + '[output]\ngrid_nm = "780:380:10"\n',
     ["[output] grid_nm"]),
    ("missing environment", CAMERA + OBJECT + '[environment]\nprefiltered = "sky/index.json"\n',
     ["[environment] prefiltered", "no such file"]),
    ("undefined variable", CAMERA + LIGHT + OBJECT.replace("red.json", "${ink}.json"),
     ["${ink} is not defined", "--var"]),
    ("bad TOML", CAMERA + "[[object]\n", ["not valid TOML", "line"]),
    ("fov out of range", CAMERA.replace("35.0", "180.0") + OBJECT + LIGHT,
     ["[camera] fov_deg", "180"]),
    ("up along the view", CAMERA.replace("up = [0.0, 1.0, 0.0]", "up = [0.0, 0.0, 1.0]")
     + OBJECT + LIGHT, ["[camera] up", "parallel"]),
]


@pytest.mark.parametrize("what,text,needles", BAD, ids=[b[0] for b in BAD])
def test_bad_scene_is_one_line_naming_file_and_key(scene_dir, what, text, needles):
    path = write_scene(scene_dir, text)
    with pytest.raises(InputError) as info:
        load_scene(path)
    msg = info.value.format()
    assert "\n" not in msg
    assert msg.startswith(str(path) + ": "), msg
    for needle in needles:
        assert needle in msg, msg


def test_missing_scene_file(tmp_path):
    with pytest.raises(InputError, match="no such scene file"):
        load_scene(tmp_path / "nope.toml")


@pytest.mark.parametrize("what,text,needles", BAD[:8], ids=[b[0] for b in BAD[:8]])
def test_cli_bad_scene_exit_2_one_line_nothing_written(run_gonio, scene_dir, what, text,
                                                        needles):
    path = write_scene(scene_dir, text)
    out, exr, rep = scene_dir / "o.png", scene_dir / "o.exr", scene_dir / "run.json"
    before = set(scene_dir.iterdir())
    r = run_gonio("render", path, "-o", out, "--exr", exr, "--report", rep)
    assert r.exit_code == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"gonio: error: {path}: "), r.stderr
    assert needles[0] in lines[0]
    assert set(scene_dir.iterdir()) == before  # nothing written, no temporary left


def test_cli_bad_var_and_bad_output_name(run_gonio, scene_dir):
    path = write_scene(scene_dir, CAMERA + LIGHT + OBJECT)
    r = run_gonio("render", path, "-o", scene_dir / "o.png", "--var", "novalue")
    assert r.exit_code == 2 and "--var 'novalue'" in r.stderr
    r = run_gonio("render", path, "-o", scene_dir / "o.jpg")
    assert r.exit_code == 2 and "PNG" in r.stderr
    r = run_gonio("render", path, "-o", scene_dir / "o.png", "--spectral", "fast")
    assert r.exit_code == 2 and "--spectral" in r.stderr and "table, exact" in r.stderr
    assert not (scene_dir / "o.png").exists()


SCENES = Path(__file__).resolve().parent.parent / "sample_data" / "scenes"


@pytest.mark.parametrize("name,variables", [
    ("spheres.toml", {}), ("spheres.toml", {"material": "blue.torrance-sparrow"}),
    ("spheres_measured.toml", {"ink": "green"}), ("print.toml", {"illuminant": "A"}),
    ("print.toml", {"model": ".torrance-sparrow"}), ("paint_env.toml", {}),
    ("figure5.toml", {})])
def test_sample_scenes_are_valid(tmp_path, name, variables):
    """The sample scenes parse and name the demo's artifacts (made empty here under a
    stand-in ${out}, so the test does not need ``make demo``)."""
    out = tmp_path / "out"
    files = [f"rgbink/{i}{m}.{k}.json" for i in ("red", "green", "blue")
             for m, k in (("", "material"), (".torrance-sparrow", "material"),
                          ("", "measurement"))]
    files += ["rgbink/print.png", "carpaint/paint.material.json", "lobes/paint.lobes.json",
              "sky/index.json"]
    for f in files:
        (out / f).parent.mkdir(parents=True, exist_ok=True)
        (out / f).write_text("")
    sc = load_scene(SCENES / name, variables={"out": str(out), **variables})
    assert sc.objects and (sc.lights or sc.environment)
    assert all(p.is_file() for p in sc.inputs)
    if name == "print.toml":
        assert sc.objects[0].mask == out / "rgbink/print.png"
        assert sc.objects[0].mesh == str(SCENES / "sheet.obj")
        assert all(("torrance" in str(p)) == ("model" in variables) for p in sc.objects[0].inks)


# ------------------------------------------------------------------- spectral grid --
#
# The working grid: --grid-nm when given; else the scene's grid when every material
# covers it; else the materials' common range on the scene grid's lattice, with one
# warning; materials sharing less than one step are refused.


def write_material_on(path: Path, spec: str, rho=0.1, c=2.0) -> Path:
    grid = parse_grid(spec)
    write_material(path, Material("goniochromatic", grid, {
        "alpha": 0.18, "rho": np.full(grid.size, rho), "c": np.full(grid.size, c)}))
    return path


@pytest.mark.parametrize("ranges, spec", [
    ([("a", 380.0, 780.0)], "380:780:10"),                    # covers: kept, no warning
    ([("a", 360.0, 830.0), ("b", 380.0, 780.0)], "380:780:10"),
    ([("a", 400.0, 700.0)], "400:700:10"),
    ([("a", 400.0, 700.0), ("b", 380.0, 780.0), ("c", 420.0, 780.0)], "420:700:10"),
    ([("a", 405.0, 695.0)], "410:690:10"),                    # on the scene grid's lattice
    ([("a", 370.0, 700.0)], "380:700:10"),                    # short at one end only
])
def test_choose_grid_keeps_or_intersects(ranges, spec):
    grid, note = choose_grid(GRID, ranges, where="s.toml")
    np.testing.assert_allclose(grid, parse_grid(spec), rtol=0, atol=1e-9)
    kept = spec == "380:780:10"
    assert (note is None) == kept
    if not kept:
        assert note.startswith("s.toml: not every material covers the scene's grid 380-780 nm")
        assert f"rendering on their common range {spec} nm" in note and "--grid-nm" in note
        assert "\n" not in note


def test_choose_grid_keeps_the_step_of_the_scene_grid():
    grid, _ = choose_grid(parse_grid("380:780:5"), [("a", 400.0, 700.0)])
    assert grid_spec(grid) == "400:700:5"


@pytest.mark.parametrize("ranges, needle", [
    ([("a", 400.0, 550.0), ("b", 560.0, 700.0)], "the materials share no range"),
    ([("a", 400.0, 555.0), ("b", 550.0, 700.0)],
     "the materials' common range 550-555 nm holds less than one 10 nm step of the scene's "
     "grid 380-780 nm"),
    ([("a", 790.0, 900.0), ("b", 400.0, 950.0)],
     "the materials' common range 790-900 nm holds less than one 10 nm step"),
])
def test_choose_grid_refuses_materials_with_no_common_range(ranges, needle):
    with pytest.raises(InputError) as info:
        choose_grid(GRID, ranges, where="s.toml")
    msg = info.value.format()
    assert msg.startswith("s.toml: ") and needle in msg and "\n" not in msg
    assert "(a " in msg and ", b " in msg and "--grid-nm" in msg


def test_scene_follows_a_400_700_material_with_one_warning(scene_dir, capsys):
    write_material_on(scene_dir / "red.json", "400:700:10")
    path = write_scene(scene_dir, CAMERA + OBJECT + LIGHT)
    capsys.readouterr()
    sc = load_scene(path)
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "rendering on their common range 400:700:10 nm" in err
    np.testing.assert_allclose(sc.grid_nm, parse_grid("400:700:10"))
    assert sc.output.grid_nm == "400:700:10"
    # the light is made on the chosen grid: Σ S ȳ / Σ ȳ = 1 there (docs/conventions.md)
    ybar = cmfs(sc.grid_nm)[:, 1]
    assert sc.lights[0].spectrum.shape == sc.grid_nm.shape
    assert sc.lights[0].spectrum @ ybar / ybar.sum() == pytest.approx(1.0)


def test_explicit_grid_wins_and_is_not_changed(scene_dir, capsys):
    write_material_on(scene_dir / "red.json", "400:700:10")
    path = write_scene(scene_dir, CAMERA + OBJECT + LIGHT)
    capsys.readouterr()
    sc = load_scene(path, overrides={"grid_nm": "450:650:5"})
    assert capsys.readouterr().err == ""
    assert grid_spec(sc.grid_nm) == "450:650:5" and sc.output.grid_nm == "450:650:5"
    # an explicit grid the material does not cover is kept here; the render refuses it
    sc = load_scene(path, overrides={"grid_nm": "380:780:10"})
    assert grid_spec(sc.grid_nm) == "380:780:10"
    with pytest.raises(InputError, match="covers 400-700 nm, not the render's grid 380-780"):
        render_scene(sc)


def test_bad_grid_option_names_the_option(scene_dir):
    path = write_scene(scene_dir, CAMERA + OBJECT + LIGHT)
    with pytest.raises(InputError) as info:
        load_scene(path, overrides={"grid_nm": "700:400:10"})
    assert info.value.format().startswith("--grid-nm '700:400:10': range '700:400:10' needs "
                                          "STEP > 0, START <= STOP")


def test_inks_with_no_common_range_are_refused(scene_dir):
    write_material_on(scene_dir / "r.json", "400:540:10")
    write_material_on(scene_dir / "g.json", "560:700:10")
    text = CAMERA + LIGHT + """
    [[object]]
    mesh = "builtin:plane"
    inks = ["r.json", "g.json", "g.json"]
    mask = "print.png"
    """
    path = write_scene(scene_dir, text)
    with pytest.raises(InputError) as info:
        load_scene(path)
    msg = info.value.format()
    assert msg.startswith(f"{path}: the materials share no range (r.json 400-540 nm, "
                          "g.json 560-700 nm)"), msg


def test_grey_on_400_700_looks_like_grey_on_380_780(scene_dir):
    """A grey material (constant ρ, c = 0) renders nearly the same on 400–700 nm as on
    380–780 nm: each light spectrum is scaled to Σ S ȳ / Σ ȳ = 1 on its own grid, so only
    the CIE 1931 2° CMF mass outside 400–700 nm is lost, which this test measures (< 0.3 %
    of X, Y and Z). A colour shift that small is far below CIEDE2000 1 (a just-noticeable
    difference); the same comparison sees a third of a stop (× 1.25) of brightness."""
    full, inside = parse_grid("380:780:10"), parse_grid("400:700:10")
    lost = 1.0 - cmfs(inside).sum(axis=0) / cmfs(full).sum(axis=0)
    assert np.all(lost < 0.003), lost
    xyz = {}
    for spec in ("380:780:10", "400:700:10"):
        write_material_on(scene_dir / "grey.json", spec, rho=0.3, c=0.0)
        sc = load_scene(write_scene(scene_dir, CAMERA + LIGHT + OBJECT.replace(
            "red.json", "grey.json") + "[output]\nssaa = 1\n"))
        assert grid_spec(sc.grid_nm) == spec
        xyz[spec] = render_scene(sc).xyz
    a, b = xyz["380:780:10"], xyz["400:700:10"]
    lit = a[..., 1] > 1e-3 * a[..., 1].max()
    assert lit.sum() > 100
    white = np.array([0.95047, 1.0, 1.08883]) * a[..., 1].max()   # D65, the brightest Y
    de = delta_e_2000(xyz_to_lab(a[lit], white), xyz_to_lab(b[lit], white))
    assert de.mean() < 1.0 and de.max() < 1.0, (de.mean(), de.max())
    brighter = delta_e_2000(xyz_to_lab(a[lit], white), xyz_to_lab(1.25 * a[lit], white))
    assert brighter.mean() > 1.0, brighter.mean()                 # the test can fail
