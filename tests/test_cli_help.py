"""What a newcomer reads: ``gonio`` alone, ``gonio --help`` and every command's ``--help``.

The walk covers EVERY registered command, including sub-commands of groups (``gonio lobes
basis``), so a command added later is held to the same rules; each failure names the
command. The rules: bare ``gonio`` shows the help with status 0; each command's line in
``gonio --help`` is a whole sentence (ends with a full stop, parentheses balanced, not cut
with "..."); usage lines and argument lists show metavars (``PHOTO...``), never typer's
type labels (``<list[Path]>``, ``<path>``) or braces.
"""

from __future__ import annotations

import re

import pytest
import typer.main

from gonio_cli import cli
from gonio_cli.commands import HIDDEN_ALIASES, argument_label, first_sentence


def all_commands():
    """(command path, click command) for every leaf command and group, depth first."""
    found = []

    def walk(prefix, group):
        for name, cmd in group.commands.items():
            path = f"{prefix} {name}".strip()
            found.append((path, cmd))
            if hasattr(cmd, "commands"):
                walk(path, cmd)

    walk("", typer.main.get_command(cli.app))
    return found


COMMANDS = all_commands()
COMMAND_PATHS = [path for path, _ in COMMANDS]

#: typer's type labels after an argument's name, e.g. ``<list[Path]>``, ``<path>``.
TYPE_LABEL = re.compile(r"<(list\[[^\]]*\]|path|file|int|integer|float|str|text|bool)>",
                        re.IGNORECASE)


def commands_section(help_text: str) -> dict[str, str]:
    """The 'Commands:' section of a help page as {name: short help (lines joined)}."""
    rows: dict[str, str] = {}
    lines = help_text.split("Commands:\n", 1)[1].splitlines()
    name = None
    for line in lines:
        if not line.strip():
            break
        m = re.match(r"^  (\S+)\s{2,}(.*)$", line)
        if m:
            name = m.group(1)
            rows[name] = m.group(2).strip()
        elif name is not None and line.startswith("    "):
            rows[name] += " " + line.strip()
        else:
            break
    return rows


def test_every_stage_is_walked():
    assert {"ingest", "fit", "prefilter", "sparkle", "lobes"} <= set(COMMAND_PATHS)
    assert "lobes basis" in COMMAND_PATHS  # the walk goes into groups


def test_bare_gonio_prints_the_help_and_exits_0(run_gonio):
    r = run_gonio()
    assert r.exit_code == 0
    assert r.stdout.startswith("Usage: gonio [OPTIONS] COMMAND [ARGS]...")
    assert "Commands:" in r.stdout and "ingest" in r.stdout
    assert r.stderr == ""
    assert r.stdout == run_gonio("--help").stdout


@pytest.mark.parametrize("path", [p for p, c in COMMANDS if hasattr(c, "commands")])
def test_a_group_alone_prints_its_help_and_exits_0(run_gonio, path):
    r = run_gonio(*path.split())
    assert r.exit_code == 0, f"gonio {path}: exit {r.exit_code}: {r.stderr}"
    assert r.stdout.startswith(f"Usage: gonio {path} "), f"gonio {path}: {r.stdout[:80]}"
    assert r.stderr == ""


def test_a_leaf_command_without_arguments_is_a_one_line_usage_error(run_gonio):
    r = run_gonio("ingest")
    assert r.exit_code == 2 and r.stdout == ""
    assert r.stderr == ("gonio: error: Missing argument 'INPUT.csv'. "
                        "(see 'gonio ingest --help')\n")


def test_gonio_help_lists_every_command_with_a_whole_sentence(run_gonio):
    r = run_gonio("--help")
    assert r.exit_code == 0
    rows = commands_section(r.stdout)
    top = {p for p in COMMAND_PATHS if " " not in p}
    assert set(rows) == top
    for name, text in rows.items():
        assert text.endswith("."), f"gonio --help: the line of {name!r} is cut: {text!r}"
        assert not text.endswith("..."), f"gonio --help: {name!r} is truncated: {text!r}"
        assert text.count("(") == text.count(")"), \
            f"gonio --help: {name!r} has an unbalanced parenthesis: {text!r}"


def test_gonio_help_lists_the_stages_in_pipeline_order(run_gonio):
    names = list(commands_section(run_gonio("--help").stdout))
    stages = [n for n in cli.COMMAND_MODULES if n in names]
    assert names[:len(stages)] == stages


@pytest.mark.parametrize("path", [p for p, c in COMMANDS if hasattr(c, "commands")])
def test_groups_list_their_commands_with_whole_sentences(run_gonio, path):
    r = run_gonio(*path.split(), "--help")
    for name, text in commands_section(r.stdout).items():
        assert text.endswith(".") and text.count("(") == text.count(")"), \
            f"gonio {path} --help: the line of {name!r} is not a whole sentence: {text!r}"


@pytest.mark.parametrize("path", COMMAND_PATHS)
def test_help_of_every_command_shows_metavars_not_types(run_gonio, path):
    r = run_gonio(*path.split(), "--help")
    assert r.exit_code == 0, f"gonio {path} --help: exit {r.exit_code}: {r.stderr}"
    usage = r.stdout.splitlines()[0]
    assert usage.startswith(f"Usage: gonio {path} "), f"gonio {path} --help: {usage!r}"
    assert "{" not in usage and "}" not in usage, \
        f"gonio {path} --help: braces in the usage line: {usage!r}"
    assert "[[" not in usage and "]]" not in usage, \
        f"gonio {path} --help: double brackets in the usage line (set a plain metavar such " \
        f"as FILE.json): {usage!r}"
    label = TYPE_LABEL.search(r.stdout)
    assert label is None, \
        f"gonio {path} --help shows the type label {label.group(0)!r} (give the parameter " \
        "a metavar such as PATH or FILE.csv)"


def test_list_arguments_show_an_ellipsis(run_gonio):
    usage = {p: run_gonio(*p.split(), "--help").stdout.splitlines()[0]
             for p in ("ingest", "sparkle", "fit")}
    assert usage["ingest"] == "Usage: gonio ingest [OPTIONS] INPUT.csv..."
    assert usage["sparkle"] == "Usage: gonio sparkle [OPTIONS] PHOTO..."
    assert usage["fit"] == "Usage: gonio fit [OPTIONS] MEASUREMENT.json"


@pytest.mark.parametrize("text, first", [
    ("Fit a model (seed 000 eqs. 1-7; seed 004 eqs. 9-14). More text.",
     "Fit a model (seed 000 eqs. 1-7; seed 004 eqs. 9-14)."),
    ("Render per eq. 5 of seed 000. Then more.", "Render per eq. 5 of seed 000."),
    ("Prefilter a map for cosine lobes\nover two lines.\n\nSecond paragraph.",
     "Prefilter a map for cosine lobes over two lines."),
    ("No full stop here\n\nParagraph two.", "No full stop here."),
    ("Version 1.5 is read. Next.", "Version 1.5 is read."),
    ("", ""),
])
def test_first_sentence(text, first):
    assert first_sentence(text) == first


class _Param:
    def __init__(self, metavar, nargs, name="inputs"):
        self.metavar, self.nargs, self.name = metavar, nargs, name


@pytest.mark.parametrize("metavar, nargs, label", [
    ("INPUT.csv", -1, "INPUT.csv..."), ("MATERIAL.json...", -1, "MATERIAL.json..."),
    ("ENV.exr", 1, "ENV.exr"), (None, -1, "INPUTS..."), (None, 1, "INPUTS"),
])
def test_argument_label(metavar, nargs, label):
    assert argument_label(_Param(metavar, nargs)) == label


# ------------------------------------------------- each choice listed once (names.py) --

def _registries():
    """(command path, flag, the names the shell shows, the core registry's keys): the
    cores are imported here, never by the shells' help."""
    from gonio_cli import fit, imageio, names, prefilter, report, sparkle
    from gonio_cli.halftone import run as halftone_run
    from gonio_cli.fit import common, gains, goniochromatic
    from gonio_cli.halftone import METHODS, coverage
    from gonio_cli.lobes import basis, samples, solvers
    from gonio_cli.render import shade, scene, tonemap

    assert scene.SPECTRAL_MODES is names.SPECTRAL_PATHS is shade.SPECTRAL_PATHS
    return [
        ("fit", "--model", names.FIT_MODEL_CHOICES, tuple(fit.FITTERS) + (fit.AUTO,)),
        ("fit", "--step2", names.STEP2_NAMES, goniochromatic.STEP2_MODES),
        ("fit", "--residuals", names.RESIDUAL_NAMES, common.RESIDUALS),
        ("fit", "--sweep-gain", names.SWEEP_GAIN_NAMES, gains.CHOICES),
        ("eval", "--sweep-gain", names.SWEEP_GAIN_NAMES, gains.CHOICES),
        ("fit", "--optimizer", names.OPTIMIZER_NAMES,
         tuple(dict.fromkeys(k for v in fit.OPTIMIZERS_BY_MODEL.values() for k in v))),
        ("render", "--spectral", names.SPECTRAL_PATHS, shade.SPECTRAL_PATHS),
        ("render", "--tonemap", names.TONEMAP_NAMES, tuple(tonemap.TONEMAPS)),
        ("render", "--adapt", names.ADAPTATION_NAMES, tuple(tonemap.ADAPTATIONS)),
        ("render", "--exr-space", names.EXR_SPACE_NAMES, tuple(tonemap.EXR_SPACES)),
        ("render", "--exr-adapt", names.ADAPTATION_NAMES, tuple(tonemap.ADAPTATIONS)),
        ("halftone", "--method", names.HALFTONE_METHOD_NAMES, tuple(METHODS)),
        ("halftone", "--gamut", names.GAMUT_NAMES, tuple(coverage.GAMUT_MAPPERS)),
        ("halftone", "--input-encoding", names.INPUT_ENCODING_NAMES, coverage.INPUT_ENCODINGS),
        ("halftone", "--compress", names.COMPRESSION_NAMES, tuple(imageio.COMPRESSION)),
        ("halftone", "--mask-format", names.MASK_FORMAT_NAMES,
         tuple(halftone_run.MASK_WRITERS)),
        ("lobes basis", "--samples", names.SAMPLE_SET_NAMES + ("FILE.csv",),
         tuple(samples.SAMPLE_SETS) + ("FILE.csv",)),
        ("lobes fit", "--samples", names.SAMPLE_SET_NAMES + ("FILE.csv",),
         tuple(samples.SAMPLE_SETS) + ("FILE.csv",)),
        ("lobes basis", "--channels", names.CHANNEL_NAMES, tuple(samples.CHANNELS)),
        ("lobes fit", "--channels", names.CHANNEL_NAMES, tuple(samples.CHANNELS)),
        ("lobes basis", "--solver", names.BASIS_SOLVER_NAMES, tuple(basis.BASIS_SOLVERS)),
        ("lobes fit", "--solver", names.WEIGHT_SOLVER_NAMES, tuple(solvers.WEIGHT_SOLVERS)),
        ("prefilter", "--method", (names.PREFILTER_AUTO,) + names.PREFILTER_METHOD_NAMES,
         ("auto",) + tuple(prefilter.METHODS)),
        ("sparkle", "--rule", names.SPARKLE_RULE_NAMES, tuple(sparkle.SEGMENTATION_RULES)),
        ("report", "--sections", names.REPORT_SECTION_NAMES, report.SECTION_NAMES),
    ]


#: Choice metavars that name no core registry: the shell's own two-way switches, and
#: "a value or a file" forms.
NOT_REGISTRIES = {("fit", "--on-failure"), ("render", "--orbit"),
                  ("ingest", "--white-reflectance"), ("ingest", "--theta-i-deg"),
                  ("ingest", "--theta-o-deg"), ("ingest", "--phi-o-deg"),
                  ("ingest", "--mirror-deg"), ("lobes fit", "--view-angles"),
                  ("batch", "--scheduler")}


def _option(path: str, flag: str):
    cmd = dict(COMMANDS)[path]
    (param,) = [p for p in cmd.params if flag in p.opts]
    return param


def test_every_registry_s_keys_are_its_names_and_each_help_shows_them(run_gonio):
    for path, flag, shown, keys in _registries():
        assert shown == keys, (path, flag)
        param = _option(path, flag)
        help_text = run_gonio(*path.split(), "--help").stdout
        if param.metavar not in ("LIST",):
            assert param.metavar == "|".join(keys), (path, flag, param.metavar)
            assert f"{flag} {param.metavar}" in help_text.replace("\n", " "), (path, flag)
        else:   # a comma-separated subset: the help lists the names
            assert ",".join(keys) in help_text, (path, flag)


def test_every_choice_option_is_checked_against_a_registry():
    # a choice option added later (a metavar listing names with "|") must join the table
    # above or be named here as no registry's
    checked = {(path, flag) for path, flag, _, _ in _registries()}
    for path, cmd in COMMANDS:
        for p in getattr(cmd, "params", []):
            if p.metavar and "|" in p.metavar:
                key = next(((path, o) for o in p.opts if (path, o) in checked | NOT_REGISTRIES),
                           None)
                assert key is not None, (path, p.opts, p.metavar)


def test_each_fitter_s_optimizers_are_its_names_default_first():
    from gonio_cli import fit, names
    from gonio_cli.fit.results import FitOptions

    assert tuple(fit.FITTERS) == names.FIT_MODEL_NAMES
    for model in names.FIT_MODEL_NAMES:
        assert tuple(fit.OPTIMIZERS_BY_MODEL[model]) == names.OPTIMIZERS_BY_MODEL[model], model
    assert FitOptions().optimizer is None      # None: each fitter's first
    from gonio_cli.commands import fit as shell

    assert shell.DEFAULT_MODEL in names.FIT_MODEL_NAMES


# ------------------------------------------------------------------ flags carry units --

#: A metavar that says the value's unit, and the suffix the flag's shown name then ends in.
UNIT_METAVARS = {"DEG": "-deg", "DEG,...": "-deg", "PX": "-px", "WxH": "-px", "MM": "-mm",
                 "S": "-s", "STOPS": "-stops"}


def test_a_flag_with_a_unit_says_it_in_its_name():
    for path, cmd in COMMANDS:
        for p in getattr(cmd, "params", []):
            suffix = UNIT_METAVARS.get(p.metavar or "")
            if suffix is None or p.param_type_name != "option":
                continue
            shown = [o for o in p.opts if o not in HIDDEN_ALIASES]
            assert shown and all(o.endswith(suffix) for o in shown if o.startswith("--")), \
                (path, p.opts)


@pytest.mark.parametrize("path, new, old", [
    ("render", "--width-px", "--width"), ("render", "--height-px", "--height"),
    ("render", "--exposure-stops", "--exposure"),
    ("fit", "--exclude-theta-i-deg", "--exclude-theta-i"),
    ("fit", "--exclude-theta-o-deg", "--exclude-theta-o"),
    ("sparkle", "--theta-i-deg", "--theta-i"), ("prefilter", "--height-px", "--resolution"),
    ("lobes fit", "--view-angles-deg", "--view-angles"),
    ("halftone", "--size-px", "--size")])
def test_old_spellings_are_hidden_aliases(run_gonio, path, new, old):
    from gonio_cli.commands import ALIASES

    assert ALIASES[old] == new
    param = _option(path, new)
    assert old in param.opts                     # still parsed, to the same parameter
    text = run_gonio(*path.split(), "--help").stdout
    assert re.search(rf"{re.escape(new)}\b", text)
    assert not re.search(rf"{re.escape(old)}(?![\w-])", text), (path, old)
