"""Messages that name what the user typed and say the fix (issue 32, item 3).

* an option is named as typed (``--width-px``, or its old spelling ``--width``), never as
  the core's key;
* an unknown name (option value, scene key, artifact field) says which valid one was
  probably meant (difflib), from the one shared place (:func:`gonio_cli.names.pick`,
  :func:`gonio_cli.names.choices_fix`);
* an artifact of the wrong kind, or a missing one, names the command that makes the
  expected file, with the user's file as its input where it is that command's input.
"""

from __future__ import annotations

import json

import pytest
from bad_inputs import SAMPLE, assert_refused, make_good, run, scene_text

from gonio_cli.artifact import check_keys
from gonio_cli.errors import ArtifactError, InputError
from gonio_cli.names import FIT_MODEL_CHOICES, choices_fix, closest, pick


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    return make_good(tmp_path_factory)


# ------------------------------------------------------------- options as typed --

@pytest.mark.parametrize("flag, value, shown", [
    ("--width-px", "100000", "--width-px: 100000 is outside [1, 16384]"),
    ("--width", "100000", "--width: 100000 is outside [1, 16384]"),      # the old spelling
    ("--height-px", "0", "--height-px: 0 is outside [1, 16384]"),
    ("--exposure-stops", "1000", "--exposure-stops: 1000.0 is above"),
])
def test_render_names_the_option_as_typed(good, tmp_path, flag, value, shown):
    scene = tmp_path / "scene.toml"
    scene.write_text(scene_text(good["material"]))
    out = tmp_path / "o.png"
    code, err = run("render", scene, flag, value, "-o", out)
    assert_refused(code, err, names=(str(scene), shown), outputs=[out])


def test_an_option_given_with_equals_is_named_as_typed(good, tmp_path):
    scene = tmp_path / "scene.toml"
    scene.write_text(scene_text(good["material"]))
    code, err = run("render", scene, "--width-px=0", "-o", tmp_path / "o.png")
    assert code == 2 and "--width-px: 0 is outside" in err, err


# ------------------------------------------------------------------ did you mean --

def test_closest_is_difflib_s_best_or_none():
    assert closest("goniochromatc", FIT_MODEL_CHOICES) == "goniochromatic"
    assert closest("materal", ("inks", "material", "measured")) == "material"
    assert closest("phong", FIT_MODEL_CHOICES) is None        # nothing alike: no guess
    assert choices_fix("phong", ("a", "b")) == "use one of a, b"


def test_pick_suggests_and_lists():
    with pytest.raises(InputError) as e:
        pick(FIT_MODEL_CHOICES, "cook-torrence", "--model")
    assert str(e.value).startswith("--model 'cook-torrence' is unknown; did you mean "
                                   "'cook-torrance'? use one of goniochromatic, ")
    assert pick(("brute", "ring"), "auto", "method", extra=("auto",)) == "auto"


@pytest.mark.parametrize("args, needle", [
    (("--model", "goniochromatc"), "--model 'goniochromatc' is unknown; did you mean "
                                   "'goniochromatic'?"),
    (("--optimizer", "nlopt-bobyq"), "did you mean 'nlopt-bobyqa'?"),
    (("--on-failure", "wrte"), "--on-failure 'wrte' is unknown; did you mean 'write'?"),
    (("--step2", "mirorr"), "did you mean 'mirror'?"),
])
def test_fit_options_say_what_was_meant(good, tmp_path, args, needle):
    out = tmp_path / "m.json"
    code, err = run("fit", good["measurement"], "-o", out, *args)
    assert_refused(code, err, names=(needle, "use one of" if "optimizer" not in args[0]
                                     else "takes"), outputs=[out])


def test_render_option_and_scene_key_say_what_was_meant(good, tmp_path):
    scene = tmp_path / "scene.toml"
    scene.write_text(scene_text(good["material"]))
    code, err = run("render", scene, "--tonemap", "filmc", "-o", tmp_path / "o.png")
    assert_refused(code, err, names=("--tonemap 'filmc' is unknown; did you mean 'filmic'?",),
                   outputs=[tmp_path / "o.png"])
    scene.write_text(scene_text(good["material"]).replace("fov_deg", "fov_dg"))
    code, err = run("render", scene, "-o", tmp_path / "o.png")
    assert_refused(code, err, names=(str(scene), "[camera]: unknown key 'fov_dg'; did you "
                                     "mean 'fov_deg'? allowed: eye, "), outputs=[])


def test_ingest_quantity_says_what_was_meant(tmp_path):
    out = tmp_path / "m.json"
    code, err = run("ingest", SAMPLE / "ink_red.csv", "--quantity", "reflectance-factr",
                    "-o", out)
    assert_refused(code, err, names=("ink_red.csv", "did you mean 'reflectance-factor'?"),
                   outputs=[out])


def test_artifact_fields_say_what_was_meant():
    with pytest.raises(ArtifactError) as e:
        check_keys({"alpah": 1, "rho": 2}, ("alpha", "rho", "c"), path="m.json")
    assert str(e.value) == ("m.json: unknown field alpah; did you mean 'alpha'? allowed: "
                            "alpha, c, rho")
    with pytest.raises(ArtifactError) as e:
        check_keys({"alpah": 1, "rh": 2, "zzz": 3}, ("alpha", "rho", "c"), where="fit.")
    assert "did you mean fit.alpha for fit.alpah, fit.rho for fit.rh? allowed:" \
        in str(e.value)


def test_a_misspelt_material_field_is_one_line_with_the_guess(good, tmp_path):
    doc = json.loads(good["material"].read_text())
    doc["alpah"] = doc.pop("alpha")
    bad = tmp_path / "red.material.json"
    bad.write_text(json.dumps(doc))
    code, err = run("eval", bad, "--at", good["measurement"], "-o", tmp_path / "e.json")
    assert_refused(code, err, names=(str(bad), "alpah", "did you mean 'alpha'?"),
                   outputs=[tmp_path / "e.json"])


# ------------------------------------------------- the command that makes the file --

def test_a_measurement_where_a_material_is_expected(good, tmp_path):
    m = good["measurement"]
    out = tmp_path / "b.json"
    code, err = run("lobes", "basis", m, "-o", out)
    assert_refused(code, err, names=(
        str(m), "schema is 'gonio.measurement', expected 'gonio.material'",
        f"make a material from it with `gonio fit {m} -o red.material.json`"), outputs=[out])


def test_a_material_where_a_measurement_is_expected(good, tmp_path):
    out = tmp_path / "m.json"
    code, err = run("fit", good["material"], "-o", out)
    assert_refused(code, err, names=(str(good["material"]), "it is a material, not a "
                                     "measurement", "`gonio ingest INPUT.csv -o "),
                   outputs=[out])


def test_the_option_that_gave_the_wrong_file_is_named(good, tmp_path):
    out = tmp_path / "e.json"
    code, err = run("eval", good["material"], "--at", good["material"], "-o", out)
    assert_refused(code, err, names=("(given as --at)", "`gonio ingest "), outputs=[out])
    code, err = run("lobes", "fit", good["material"], "--basis", good["material"], "-o", out)
    assert_refused(code, err, names=("(given as --basis)", "make a lobe basis from it with "
                                     f"`gonio lobes basis {good['material']} -o "),
                   outputs=[out])


def test_a_csv_where_a_measurement_is_expected_gets_the_ingest_command(tmp_path):
    out = tmp_path / "m.json"
    code, err = run("fit", SAMPLE / "ink_red.csv", "-o", out)
    assert_refused(code, err, names=(f"`gonio ingest {SAMPLE / 'ink_red.csv'} -o "
                                     "ink_red.measurement.json`",), outputs=[out])


@pytest.mark.parametrize("command, schema_command", [
    (("fit", "{missing}", "-o", "{out}"), "`gonio ingest INPUT.csv -o {missing}`"),
    (("eval", "{missing}", "--at", "{measurement}", "-o", "{out}"),
     "`gonio fit MEASUREMENT.json -o {missing}`"),
])
def test_a_missing_file_names_the_command_that_makes_it(good, tmp_path, command,
                                                         schema_command):
    names = {"missing": tmp_path / "nope.json", "out": tmp_path / "o.json",
             "measurement": good["measurement"]}
    code, err = run(*[a.format(**names) for a in command])
    assert_refused(code, err, names=("no such file; check the path, or make it with "
                                     + schema_command.format(**names),),
                   outputs=[names["out"]])


def test_a_measurement_as_a_scene_material_names_the_key_and_the_command(good, tmp_path):
    scene = tmp_path / "scene.toml"
    scene.write_text(scene_text(good["measurement"]))
    out = tmp_path / "o.png"
    code, err = run("render", scene, "-o", out)
    assert_refused(code, err, names=(str(scene), "[[object]] 1 material",
                                     "point material at the right file, or make a material "
                                     f"from it with `gonio fit {good['measurement']}"),
                   outputs=[out])


# ------------------------------------------------- figures a user can read (item 6) --

def test_the_fit_verdict_says_what_decides_it_and_the_thresholds(good, tmp_path):
    """The verdict line leads with what decides it (the colour error, its scale and the
    thresholds of a good fit), gives α with its 95 % interval and no relative RMSE. One
    line."""
    out = tmp_path / "red.material.json"
    code, err = run("fit", good["measurement"], "-o", out, "--exclude-theta-i-deg", "70")
    assert code == 0, err
    line = next(x for x in err.splitlines() if "good if" in x)
    assert line.startswith(f"{out}: goniochromatic: colour error CIEDE2000 mean ")
    assert "; good if mean <= 0.7, worst <= 1.5, peaks x0.75-1.33 (CIEDE2000 1 ~ just " \
        "noticeable): " in line
    assert ": good; alpha 0." in line or ": poor (" in line
    assert " ± " in line and line.endswith(" (95 %)")
    assert "rel-RMSE" not in line


def test_the_verdict_line_carries_the_user_s_limit():
    """--max-error replaces the mean threshold; the worst one is at least as large."""
    from types import SimpleNamespace

    from gonio_cli.commands.fit import verdict_line

    result = SimpleNamespace(model="goniochromatic", params={"alpha": 0.18},
                             result=SimpleNamespace(
                                 success=True, errors={"relative_rmse_percent": 588.9}))
    judgement = {"verdict": "poor", "reasons": ["mean CIEDE2000 3.86 > 2"],
                 "thresholds": {"mean_delta_e": 2.0, "worst_delta_e": 1.5,
                                "peak_ratio_min": 0.75, "peak_ratio_max": 4 / 3},
                 "delta_e2000_mean": 3.86, "delta_e2000_worst": 9.1,
                 "worst_colour_configuration": {"theta_i_deg": 50.0, "theta_o_deg": 80.0}}
    line = verdict_line("m.json", result, judgement)
    assert "\n" not in line
    assert "588.9" not in line and "rel-RMSE" not in line
    assert line == ("m.json: goniochromatic: colour error CIEDE2000 mean 3.86, worst 9.10 at "
                    "theta_i 50, theta_o 80; good if mean <= 2, worst <= 2 (CIEDE2000 1 ~ "
                    "just noticeable): poor (mean CIEDE2000 3.86 > 2)")


def test_the_lobes_fit_line_gives_the_scale_of_its_figure(good, tmp_path):
    out = tmp_path / "red.lobes.json"
    code, err = run("lobes", "fit", good["material"], "--basis", good["basis"], "--lobes",
                    "2", "-o", out, "--compare")
    assert code == 0, err
    line = next(x for x in err.splitlines() if x.startswith(f"{out}: 2 lobes"))
    assert ("how far the lobes miss f cos theta_i at the worst view, rel-RMS (0 exact, 1 no "
            "better than no lobes; over the seed001 samples: compare solvers and lobe "
            "counts on them, not sample sets): lp (written) ") in line
    assert "; nnls " in line and "ms/view, median" in line


@pytest.mark.parametrize("typed, shown", [("--exclude-theta-i", "--exclude-theta-i 95:"),
                                          ("--exclude-theta-i-deg", "--exclude-theta-i-deg 95:")])
def test_a_core_s_message_names_the_old_spelling_the_user_typed(good, tmp_path, typed, shown):
    """The fit's core names --exclude-theta-i-deg; a user who typed the old --exclude-theta-i
    reads that (gonio_cli.commands.as_typed_in, applied once where errors are printed)."""
    out = tmp_path / "m.json"
    code, err = run("fit", good["measurement"], "-o", out, typed, "95")
    assert_refused(code, err, names=(str(good["measurement"]), shown), outputs=[out])
    if typed == "--exclude-theta-i":
        assert "--exclude-theta-i-deg" not in err
