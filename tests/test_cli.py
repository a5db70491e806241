"""The gonio shell: version, help, and the one conversion of errors (STYLE 8), quiet mode.

Commands that raise are registered for one test on a copy of the app's command list
(monkeypatch restores it), so the real app, with its callback and settings, is exercised.
"""

from __future__ import annotations


import pytest
import typer.main

import gonio_cli
import gonio_cli.commands
from gonio_cli import cli, log
from gonio_cli.errors import InputError


@pytest.fixture
def add_command(monkeypatch):
    """Register ``fn`` as ``gonio NAME`` for this test only."""
    monkeypatch.setattr(cli.app, "registered_commands", list(cli.app.registered_commands))
    monkeypatch.delenv("GONIO_DEBUG", raising=False)

    def _add(name, fn):
        cli.app.command(name)(fn)

    return _add


def test_version(run_gonio):
    r = run_gonio("--version")
    assert r.exit_code == 0
    assert r.stdout == f"gonio {gonio_cli.__version__}\n"
    assert r.stderr == ""


def stage_names() -> set[str]:
    """Every registered subcommand (a stage module whose shell is not written yet
    registers nothing and is not a subcommand)."""
    return set(typer.main.get_command(cli.app).commands)


def test_help_shows_an_example_for_every_subcommand(run_gonio):
    r = run_gonio("--help")
    assert r.exit_code == 0
    names = stage_names()
    assert {"ingest", "fit"} <= names
    examples = [line.split() for line in r.stdout.splitlines()
                if line.strip().startswith("gonio ")]
    for name in names:
        assert any(words[1] == name for words in examples), f"no example of gonio {name}"
    assert "--version" in r.stdout and "--quiet" in r.stdout


def test_unknown_subcommand_fails(run_gonio):
    r = run_gonio("frobnicate")
    assert r.exit_code != 0
    assert "frobnicate" in r.stderr and r.stdout == ""


def test_gonio_error_in_a_command_is_one_line_and_exit_2(run_gonio, add_command):
    def boom():
        raise InputError("theta_i_deg=95 is outside [0, 90)", path="red.csv", row=42,
                         fix="fix the angle\nor drop the row")

    add_command("boom", boom)
    r = run_gonio("boom")
    assert r.exit_code == 2
    assert r.stderr == ("gonio: error: red.csv:42: theta_i_deg=95 is outside [0, 90); "
                        "fix the angle or drop the row\n")
    assert r.stdout == ""


def test_missing_file_in_a_command_is_one_line_and_exit_2(run_gonio, add_command, tmp_path):
    missing = tmp_path / "nope.csv"
    add_command("read", lambda: missing.read_text())
    r = run_gonio("read")
    assert r.exit_code == 2
    assert r.stderr.startswith(f"gonio: error: {missing}: ")
    assert r.stderr.count("\n") == 1


def test_a_bug_is_one_line_internal_error_with_exit_1(run_gonio, add_command):
    def bug():
        return {}["missing"]

    add_command("bug", bug)
    r = run_gonio("bug")
    assert r.exit_code == 1
    assert r.stderr.startswith("gonio: internal error: KeyError: ")
    assert "GONIO_DEBUG=1" in r.stderr and r.stderr.count("\n") == 1
    assert "Traceback" not in r.stderr


def test_gonio_debug_shows_the_traceback_of_a_bug(add_command, monkeypatch):
    add_command("bug", lambda: {}["missing"])
    monkeypatch.setenv("GONIO_DEBUG", "1")
    with pytest.raises(KeyError):
        cli.run(["bug"])


@pytest.mark.parametrize("args, shown", [(["warn"], True), (["--quiet", "warn"], False),
                                         (["-q", "warn"], False)])
def test_quiet_silences_warnings(run_gonio, add_command, args, shown):
    add_command("warn", lambda: log.warn("resampled 1 nm\n input onto the 10 nm grid"))
    r = run_gonio(*args)
    assert r.exit_code == 0
    expected = "gonio: warning: resampled 1 nm input onto the 10 nm grid\n" if shown else ""
    assert r.stderr == expected


def test_quiet_does_not_leak_into_the_next_run(add_command, capsys):
    add_command("warn", lambda: log.warn("careful"))
    assert cli.run(["--quiet", "warn"]) == 0
    assert cli.run(["warn"]) == 0
    assert capsys.readouterr().err == "gonio: warning: careful\n"


@pytest.mark.parametrize("args, needle", [
    (["fit"], "Missing argument"),
    (["fit", "m.json"], "Missing option '--output'"),
    (["fit", "m.json", "-o", "x.json", "--alpha", "abc"], "Invalid value for '--alpha'"),
    (["nosuch"], "No such command 'nosuch'"),
])
def test_usage_errors_are_one_line_with_exit_2(run_gonio, args, needle):
    r = run_gonio(*args)
    assert r.exit_code == 2
    assert r.stderr.count("\n") == 1 and r.stderr.startswith("gonio: error:")
    assert needle in r.stderr and "--help" in r.stderr
