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
from gonio_cli.commands import argument_label, first_sentence


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
