"""gonio render on bad lobes, prefiltered indexes, materials, lights and options: one line
naming the file and the field, exit 2, no image or report written; and a render whose
shading overflows is an error, never NaN, inf or black texels with exit 0."""

from __future__ import annotations

import pytest
from bad_inputs import (assert_refused, broken, copy_index, make_good, run, scene_text,
                        set_key)


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    return make_good(tmp_path_factory)


def _render(tmp_path, **scene):
    path = tmp_path / "scene.toml"
    path.write_text(scene_text(**scene))
    outs = [tmp_path / "o.png", tmp_path / "o.exr", tmp_path / "o.json"]
    code, err = run("render", path, "-o", outs[0], "--exr", outs[1], "--report", outs[2])
    return code, err, outs


def _weights(key, value):
    return lambda doc: doc[key][0].__setitem__(0, value)


#: case → (change to the lobes file, the field the error must name)
BAD_LOBES = {
    "n_samples a number": (set_key("n_samples", 20), "'n_samples'"),
    "diffuse empty": (set_key("diffuse", []), "'diffuse'"),
    "gloss empty": (set_key("gloss", []), "'gloss'"),
    "negative weight": (lambda d: d["gloss"][0][0].__setitem__(0, -0.5), "'gloss'"),
    "weight 1e300": (_weights("diffuse", 1e300), "'diffuse'"),
    "view angles decrease": (lambda d: d.__setitem__("view_angle_deg",
                                                     d["view_angle_deg"][::-1]),
                             "'view_angle_deg'"),
    "channel kind rgb": (set_key("channel_kind", "rgb"), "'channel_kind'"),
    "channels disagree with kind": (set_key("channels", ["X", "Y", "Z"]), "'channels'"),
    "exponent 0": (lambda d: d["exponents"].__setitem__(0, 0.0), "'exponents'"),
    "errors a list": (set_key("errors", []), "'errors'"),
    "extra field": (set_key("weights", []), "weights"),
}


@pytest.mark.parametrize("case", sorted(BAD_LOBES))
def test_bad_lobes_is_one_line_naming_file_and_field(good, tmp_path, case):
    change, field = BAD_LOBES[case]
    bad = broken(good["lobes"], tmp_path, change)
    code, err, outs = _render(tmp_path, material=good["material"], lobes=bad,
                              index=good["index"])
    assert_refused(code, err, names=(bad.name, field), outputs=outs)


#: case → (change to index.json, the field the error must name)
BAD_INDEXES = {
    "extra field": (set_key("resolution", 8), "resolution"),
    "extra field in a map": (set_key("maps.0.scale", 2.0), "maps[0].scale"),
    "maps empty": (set_key("maps", []), "'maps'"),
    "maps a string": (set_key("maps", "prefiltered_E1.exr"), "'maps'"),
    "exponent negative": (set_key("maps.0.exponent", -1.0), "'maps[0].exponent'"),
    "exponent a string": (set_key("maps.0.exponent", "1"), "'maps[0].exponent'"),
    "width a float": (set_key("maps.0.width", 8.5), "'maps[0].width'"),
    "height zero": (set_key("maps.0.height", 0), "'maps[0].height'"),
    "path missing": (lambda d: d["maps"][0].pop("path"), "'maps[0].path'"),
    "source channels a string": (set_key("source.channels", "rgb"), "'source.channels'"),
}


@pytest.mark.parametrize("case", sorted(BAD_INDEXES))
def test_bad_prefilter_index_is_one_line_naming_file_and_field(good, tmp_path, case):
    change, field = BAD_INDEXES[case]
    index = copy_index(good["index"], tmp_path, change)
    code, err, outs = _render(tmp_path, material=good["material"], lobes=good["lobes"],
                              index=index)
    assert_refused(code, err, names=("index.json", field), outputs=outs)


@pytest.mark.parametrize("change,field", [
    (set_key("alpha", -0.2), "'alpha'"),
    (lambda d: d["rho"].__setitem__(0, 1e300), "'rho'"),
    (lambda d: d.__setitem__("wavelength_nm", d["wavelength_nm"][::-1]), "'wavelength_nm'"),
    (set_key("status", 5), "'status'"),
], ids=["negative alpha", "rho 1e300", "wavelengths decrease", "status 5"])
def test_bad_material_is_one_line(good, tmp_path, change, field):
    bad = broken(good["material"], tmp_path, change)
    code, err, outs = _render(tmp_path, material=bad)
    assert_refused(code, err, names=(bad.name, field), outputs=outs)


@pytest.mark.parametrize("irradiance", ["1e38", "1e31", "-1", "nan"])
def test_light_outside_its_range_is_refused(good, tmp_path, irradiance):
    code, err, outs = _render(tmp_path, material=good["material"], irradiance=irradiance)
    assert_refused(code, err, names=("scene.toml", "irradiance"), outputs=outs)


@pytest.mark.parametrize("stops", ["1e6", "-61", "inf"])
def test_exposure_outside_60_stops_is_refused(good, tmp_path, stops):
    path = tmp_path / "scene.toml"
    path.write_text(scene_text(good["material"]))
    out = tmp_path / "o.png"
    code, err = run("render", path, "-o", out, "--exposure", stops)
    assert_refused(code, err, names=("--exposure",), outputs=[out])


def test_overflowing_shading_is_an_error_not_black_or_nan_texels(good, tmp_path):
    """ρ and the irradiance are each within 1e30, their product is beyond float32: the
    render names the overflow instead of writing NaN, inf or blacked-out texels."""
    hot = broken(good["material"], tmp_path,
                 lambda d: d.__setitem__("rho", [1e29] * len(d["rho"])))
    code, err, outs = _render(tmp_path, material=hot, irradiance="1e29")
    assert_refused(code, err, names=("scene.toml", "overflowed"), outputs=outs)


def test_lobes_on_another_grid_name_the_scene_key_and_file(good, tmp_path):
    def every_other_wavelength(doc):
        doc["channels"] = doc["channels"][::2]
        doc["diffuse"] = [row[::2] for row in doc["diffuse"]]
        for key in ("directional_diffuse", "gloss"):
            doc[key] = [[row[::2] for row in view] for view in doc[key]]

    bad = broken(good["lobes"], tmp_path, every_other_wavelength)
    code, err, outs = _render(tmp_path, material=good["material"], lobes=bad,
                              index=good["index"])
    assert_refused(code, err, names=("scene.toml", "lobes = red.lobes.json", "21-sample grid"),
                   outputs=outs)


@pytest.mark.parametrize("x", ["1e300", "nan"])
def test_mesh_vertex_beyond_the_range_is_refused(good, tmp_path, x):
    obj = tmp_path / "tri.obj"
    obj.write_text(f"v 0 0 0\nv 1 0 0\nv 0 {x} 0\nf 1 2 3\n")
    path = tmp_path / "scene.toml"
    path.write_text(scene_text(good["material"]).replace('"builtin:sphere"', '"tri.obj"'))
    out = tmp_path / "o.png"
    code, err = run("render", path, "-o", out)
    assert_refused(code, err, names=("tri.obj", "vertices"), outputs=[out])


def test_grid_with_a_tiny_step_is_refused_before_allocating(good, tmp_path):
    path = tmp_path / "scene.toml"
    path.write_text(scene_text(good["material"]))
    out = tmp_path / "o.png"
    code, err = run("render", path, "-o", out, "--grid-nm", "380:780:1e-300")
    assert_refused(code, err, names=("--grid-nm", "at most 4001 samples"), outputs=[out])


def test_all_zero_ink_renders_black_without_a_warning(good, tmp_path):
    """ρ = 0 everywhere: an exact zero table (before, 0/0 in the table's error check grew
    it to its largest size with a RuntimeWarning)."""
    import numpy as np

    from gonio_cli.imageio import read_image

    zero = broken(good["material"], tmp_path,
                  lambda d: d.__setitem__("rho", [0.0] * len(d["rho"])))
    code, err, outs = _render(tmp_path, material=zero)
    assert code == 0, err
    assert "warning" not in err, err
    exr = read_image(outs[1]).pixels
    assert np.all(np.isfinite(exr)) and exr.max() == 0.0
