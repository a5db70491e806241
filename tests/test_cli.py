"""The gonio shell: version, help, and the one conversion of errors (STYLE 8), quiet mode,
Ctrl-C (one line, exit 130, nothing partial), which libraries light commands import, and
the errors a newcomer meets first (a pattern that matched nothing, an image where a file
of gonio's was expected, an output folder that cannot be written).

Commands that raise are registered for one test on a copy of the app's command list
(monkeypatch restores it), so the real app, with its callback and settings, is exercised.
"""

from __future__ import annotations

import ast
import errno
import io
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import typer.main

import gonio_cli
import gonio_cli.commands
from gonio_cli import artifact, cli, log, outputs
from gonio_cli.errors import InputError, WriteError, num


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


# ----------------------------------------------------------------- progress --

class _Terminal(io.StringIO):
    """A stderr that says it is a terminal."""

    def isatty(self) -> bool:
        return True


@pytest.mark.parametrize("stream, quiet, expected_s, drawn", [
    (_Terminal, False, 10.0, True),   # a long loop on a terminal: the bar
    (_Terminal, True, 10.0, False),   # --quiet
    (io.StringIO, False, 10.0, False),  # redirected (make, a pipe, a log file)
    (_Terminal, False, 0.5, False),   # too short to be worth a bar
])
def test_progress_bar_only_on_a_terminal_and_never_on_stdout(monkeypatch, capsys, stream,
                                                             quiet, expected_s, drawn):
    err = stream()
    monkeypatch.setattr(sys, "stderr", err)
    log.set_quiet(quiet)
    try:
        items = list(log.progress(range(3), "crunching", expected_s=expected_s))
    finally:
        log.set_quiet(False)
    assert items == [0, 1, 2]
    assert ("crunching" in err.getvalue()) is drawn
    assert err.getvalue() == "" or drawn
    assert capsys.readouterr().out == ""


# ------------------------------------------------------------------- Ctrl-C --

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_data"

#: How long a patched step waits for the test's SIGINT: far longer than any start-up, so
#: the interrupt, not the wait, ends it (a run that outlives it fails the test).
WAIT_S = 120


def interrupt(tmp_path, patch: str, *args, entry: bool = False) -> subprocess.CompletedProcess:
    """Run ``gonio ARGS`` in a subprocess whose ``patch`` (Python source run before the
    CLI) makes one step print ``ready`` and wait; send SIGINT once it is ready. ``entry``:
    start from the console entry point (``gonio_cli.__main__``) instead of ``cli.run``."""
    script = tmp_path / "interrupted_gonio.py"
    run = (f"sys.argv = {['gonio'] + [str(a) for a in args]!r}\n"
           "from gonio_cli.__main__ import main\nmain()\n") if entry else (
        "from gonio_cli import cli\n"
        f"sys.exit(cli.run({[str(a) for a in args]!r}))\n")
    # Python installs its SIGINT handler only where SIGINT is not ignored at start, and a
    # shell's background job (CI, `make test &`) starts with it ignored: install it here.
    script.write_text("import signal, sys, time\n"
                      "signal.signal(signal.SIGINT, signal.default_int_handler)\n"
                      + textwrap.dedent(patch) + "\n" + run)
    proc = subprocess.Popen([sys.executable, str(script)], cwd=tmp_path, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        first = proc.stdout.readline()
        if first != "ready\n":  # it ended (or printed) before reaching the patched step
            out, err = proc.communicate(timeout=WAIT_S)
            pytest.fail(f"gonio never reached the patched step: {first}{out}{err}")
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=WAIT_S)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


def wait_in(module: str, name: str, after_call: bool = False) -> str:
    """Patch source: ``module.name`` prints ``ready`` and sleeps (after running, if asked)."""
    return f"""
        import importlib
        _mod = importlib.import_module({module!r})
        _orig = getattr(_mod, {name!r})
        def _wait(*a, **k):
            {"_orig(*a, **k)" if after_call else "pass"}
            print("ready", flush=True)
            time.sleep({WAIT_S})
        setattr(_mod, {name!r}, _wait)
        """


posix_only = pytest.mark.skipif(sys.platform == "win32", reason="SIGINT to a child process")


@posix_only
def test_ctrl_c_before_writing_says_nothing_was_written(tmp_path):
    out = tmp_path / "out" / "red.json"
    r = interrupt(tmp_path, wait_in("gonio_cli.ingest", "ingest", after_call=True),
                  "ingest", SAMPLE / "ink_red.csv", "-o", out)
    assert r.returncode == 130
    assert r.stderr == "gonio: interrupted; nothing was written\n"
    assert not out.exists() and not out.parent.exists()


@posix_only
def test_ctrl_c_while_writing_leaves_no_partial_or_temporary_file(tmp_path):
    """The interrupt arrives with half of the JSON in the temporary file."""
    patch = f"""
        import pathlib
        _orig = pathlib.Path.write_text
        def _half(self, data, *a, **k):
            _orig(self, data[:len(data) // 2], *a, **k)
            print("ready", flush=True)
            time.sleep({WAIT_S})
        pathlib.Path.write_text = _half
        """
    out = tmp_path / "out" / "red.json"
    r = interrupt(tmp_path, patch, "ingest", SAMPLE / "ink_red.csv", "-o", out)
    assert r.returncode == 130
    assert r.stderr == "gonio: interrupted; nothing was written\n"
    assert list(out.parent.iterdir()) == []  # not the file, not its .tmp


@posix_only
def test_ctrl_c_after_one_output_leaves_none(run_gonio, tmp_path):
    """fit stages the material, then draws the plot: interrupted there, neither is written
    (the outputs are one transaction), and no temporary file is left."""
    measurement = tmp_path / "red.measurement.json"
    assert run_gonio("ingest", SAMPLE / "ink_red.csv", "-o", measurement).exit_code == 0
    patch = f"""
        import types
        _plot = types.ModuleType("gonio_cli.fit.plot")  # stands in for matplotlib's slow draw
        def plot_fit(*a, **k):
            print("ready", flush=True)
            time.sleep({WAIT_S})
        _plot.plot_fit = plot_fit
        sys.modules["gonio_cli.fit.plot"] = _plot
        """
    r = interrupt(tmp_path, patch, "fit", measurement.name, "-o", "red.material.json",
                  "--plot", "red.png")
    assert r.returncode == 130
    assert r.stderr == "gonio: interrupted; nothing was written\n"
    assert not (tmp_path / "red.material.json").exists()
    assert not (tmp_path / "red.png").exists()
    assert not [p.name for p in tmp_path.iterdir() if p.name.startswith(".gonio-tmp-")]


def test_keyboard_interrupt_inside_atomic_path_removes_the_temporary_file(tmp_path):
    target = tmp_path / "a.json"
    target.write_text("old")
    with pytest.raises(KeyboardInterrupt):
        with artifact.atomic_path(target) as tmp:
            tmp.write_text("half")
            raise KeyboardInterrupt
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json"]
    assert target.read_text() == "old"


def test_outputs_are_recorded_for_the_interrupt_message(tmp_path):
    outputs.forget_written()
    artifact.write_json(tmp_path / "a.json", {"x": 1})
    assert outputs.written_files() == [tmp_path / "a.json"]
    outputs.forget_written()
    assert outputs.written_files() == []


# ------------------------------------------------------------------ imports --

#: Heavy imports a command must not pay for unless it uses them. pydantic is typer's
#: option conversion (~0.1 s), replaced for gonio's plain option types
#: (:func:`gonio_cli.commands.plain_coercion`).
HEAVY = {"matplotlib", "numba", "trimesh", "colour", "scipy", "OpenImageIO", "PIL", "pydantic",
         "numpy.ma", "mitsuba", "drjit"}

#: Parts of a library counted on their own in :data:`HEAVY` (numpy.ma: ~10 ms, loaded by
#: the first np.median or plain np.unique).
SUBMODULES = {"numpy.ma"}


def _sphere_scene(folder: Path) -> Path:
    """The analytic reference's builtin-sphere scene (64², ssaa 1) with its synthetic ink,
    the colour tables already in the session's cache (as after any first render)."""
    from test_render_reference import ink, sphere_scene

    from gonio_cli.schemas import write_material
    from gonio_cli.spectra import colour_tables

    colour_tables()  # fills the cache the subprocess reads (conftest's GONIO_CACHE_DIR)
    write_material(folder / "ink.json", ink(620.0, 0.18))
    return Path(sphere_scene(folder, folder / "ink.json", size=64))


@pytest.mark.parametrize("args, forbidden", [
    (["--version"], HEAVY | {"numpy"}),
    (["--help"], HEAVY | {"numpy"}),
    (["ingest", str(SAMPLE / "ink_red.csv"), "-o", "{tmp}/red.json"], HEAVY),
    (["-q", "render", "{scene}", "-o", "{tmp}/a.png", "--exr", "{tmp}/a.exr"],
     HEAVY - {"OpenImageIO"}),
    (["render", "{scene}", "-o", "{tmp}/a.png", "--ssaa", "x"], HEAVY - {"pydantic"}),
])
def test_light_commands_do_not_import_heavy_libraries(tmp_path, args, forbidden):
    if any("{scene}" in a for a in args):
        scene = _sphere_scene(tmp_path)
        args = [a.replace("{scene}", str(scene)) for a in args]
    args = [a.replace("{tmp}", str(tmp_path)) for a in args]
    code = (f"import sys\nfrom gonio_cli import cli\nSUBMODULES = {sorted(SUBMODULES)!r}\n"
            f"code = cli.run({args!r})\n"
            "print(sorted({m.split('.')[0] for m in sys.modules}\n"
            "             | (set(SUBMODULES) & set(sys.modules))))\n"
            "sys.exit(code)\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       cwd=tmp_path, timeout=WAIT_S)
    bad_value = "x" in args
    assert r.returncode == (2 if bad_value else 0), r.stderr
    loaded = set(ast.literal_eval(r.stdout.strip().splitlines()[-1]))
    assert "gonio_cli" in loaded  # the check can see what was imported
    assert not loaded & forbidden, f"gonio {' '.join(args)} imported {loaded & forbidden}"
    if bad_value:  # the value typer's conversion refuses: typer's own (pydantic) message
        assert "pydantic" in loaded
        assert r.stderr.startswith("gonio: error: Invalid value for '--ssaa'"), r.stderr
    else:
        assert "numpy" in loaded or "numpy" in forbidden


# -------------------------------------------------------------- option values --

#: Command-line texts for each plain option type: numbers as written and as typer also
#: reads them (spaces, underscores, "3.0" as an int), and values it refuses.
OPTION_TEXTS = {
    int: ["3", "-3", "+3", "007", "0", "99999999999999999999", "3.0", " 3", "1_000", "0x10",
          "abc", "", "1e3", "\u0661"],
    float: ["1", "1.5", "-.5", "+2.", "1e3", "1E-3", "-0", "0.1000000000000000055511151231",
            "inf", "nan", " 1", "1_0", "1e", ".", "abc", "", "\u0663"],
    str: ["", "a", "é", " x ", "-"],
    Path: ["", ".", "a b", "/no/such/x", "-", "~/x", "sample_data"],
}


def _converted(param, text, ctx):
    """(value, None) or (None, error message) of one parameter's conversion."""
    import typer._click as click

    try:
        return param.process_value(ctx, text), None
    except click.exceptions.BadParameter as exc:
        return None, exc.format_message()


@pytest.mark.parametrize("kind", list(OPTION_TEXTS))
@pytest.mark.parametrize("many", [False, True])
def test_plain_option_values_equal_typers_own_conversion(kind, many):
    """gonio's conversion of option values (no pydantic) gives typer's values, types and
    error messages: typer's own conversion of the same parameter is the truth."""
    from typing import List, Optional

    annotation = List[kind] if many else Optional[kind]
    default = [] if many else None

    def fn(value=typer.Option(default, "--value")):
        pass

    fn.__annotations__["value"] = annotation  # (this module's annotations are strings)
    app = typer.Typer()
    app.command(cls=gonio_cli.commands.Command)(fn)
    command = typer.main.get_command(app)
    ours = next(p for p in command.params if p.name == "value")
    theirs = next(p for p in typer.main.get_command(_plain_typer_app(fn)).params
                  if p.name == "value")
    assert isinstance(ours._runtime_param, gonio_cli.commands.PlainParam)
    assert theirs._runtime_param is None  # typer's default: its own conversion, on first use
    ctx = command.make_context("x", [], resilient_parsing=True)
    taken = 0
    for text in OPTION_TEXTS[kind]:
        value = (text, "2") if many else text
        got, expected = _converted(ours, value, ctx), _converted(theirs, value, ctx)
        assert got == expected or (  # nan != nan
            kind is float and str(got) == str(expected)), text
        assert type(got[0]) is type(expected[0]), text
        if many and got[0] is not None:
            assert [type(v) for v in got[0]] == [type(v) for v in expected[0]], text
        taken += ours._runtime_param.leaf(text, ours._runtime_param.parameter_info, ours,
                                          ctx) is not gonio_cli.commands._TYPER
    assert taken >= 3  # the fast path is exercised, not only the fall-back to typer


def _plain_typer_app(fn):
    """``fn`` as a command with typer's own classes (its pydantic conversion)."""
    app = typer.Typer()
    app.command()(fn)
    return app


def test_every_gonio_option_is_converted_without_pydantic():
    """Each option of each gonio command gets the plain conversion: a new option of a kind
    it does not handle (choices, bounds, a parser) would quietly bring pydantic back."""
    command = typer.main.get_command(cli.app)
    missing = []

    def walk(group, prefix):
        for param in group.params:
            if not isinstance(param._runtime_param, gonio_cli.commands.PlainParam):
                missing.append(f"{prefix}{param.name}")
        for name, sub in getattr(group, "commands", {}).items():
            walk(sub, f"{prefix}{name} ")

    walk(command, "gonio ")
    assert not missing, missing


# ------------------------------------------------------- errors a newcomer meets --

@pytest.mark.parametrize("make_args", [
    lambda t: ["ingest", t / "photo_ti*.csv", "-o", t / "m.json"],
    lambda t: ["sparkle", t / "photo_ti*.png", "-o", t / "s.png"],
    lambda t: ["fit", t / "*.measurement.json", "-o", t / "m.json"],
    lambda t: ["prefilter", t / "sky*.exr", "--exponents", "8", "-o", t / "sky"],
], ids=["ingest", "sparkle", "fit", "prefilter"])
def test_a_pattern_that_matched_nothing_is_named(run_gonio, tmp_path, make_args):
    args = make_args(tmp_path)
    r = run_gonio(*args)
    assert r.exit_code == 2
    pattern = str(args[1])
    assert r.stderr.startswith(f"gonio: error: no files match '{pattern}'; check the folder"), \
        r.stderr
    assert r.stderr.count("\n") == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_a_missing_file_is_still_no_such_file(run_gonio, tmp_path):
    r = run_gonio("sparkle", tmp_path / "photo.png", "-o", tmp_path / "s.png")
    assert r.exit_code == 2
    assert r.stderr == (f"gonio: error: {tmp_path / 'photo.png'}: no such image file; check "
                        "the path\n")


def test_a_folder_given_as_input_is_named(run_gonio, tmp_path):
    r = run_gonio("ingest", tmp_path, "-o", tmp_path / "m.json")
    assert r.exit_code == 2
    assert r.stderr.startswith(f"gonio: error: {tmp_path}: is a folder, not a file; ")


def test_an_image_given_to_fit_is_not_a_measurement(run_gonio, tmp_path):
    r = run_gonio("fit", SAMPLE / "print_image.png", "-o", tmp_path / "m.json")
    assert r.exit_code == 2
    assert r.stderr == (f"gonio: error: {SAMPLE / 'print_image.png'}: not a gonio.measurement "
                        "file (it is a PNG image); make a measurement with `gonio ingest "
                        "INPUT.csv -o print_image.measurement.json`\n")


def _refuse_mkstemp(monkeypatch, exc):
    def mkstemp(*a, **k):
        raise exc

    monkeypatch.setattr(artifact.tempfile, "mkstemp", mkstemp)


@pytest.mark.parametrize("exc, message", [
    (PermissionError(errno.EACCES, "Permission denied"),
     "cannot write to folder {out}: permission denied; choose another -o or fix the "
     "folder's permissions"),
    (OSError(errno.EROFS, "Read-only file system"),
     "cannot write to folder {out}: Read-only file system; choose another -o"),
    (OSError(errno.ENOSPC, "No space left on device"),
     "cannot write to folder {out}: No space left on device; choose another -o (another "
     "disk) or free some space"),
])
def test_an_unwritable_output_folder_is_named_not_the_temporary_file(
        run_gonio, tmp_path, monkeypatch, exc, message):
    out = tmp_path / "out"
    _refuse_mkstemp(monkeypatch, exc)
    r = run_gonio("ingest", SAMPLE / "ink_red.csv", "-o", out / "red.json")
    assert r.exit_code == 2
    assert r.stderr == "gonio: error: " + message.format(out=out) + "\n"
    assert ".tmp" not in r.stderr


@pytest.mark.skipif(sys.platform == "win32" or os.geteuid() == 0,
                    reason="permission bits do not stop root (or Windows ACLs)")
def test_a_read_only_folder_for_real(run_gonio, tmp_path):
    out = tmp_path / "ro"
    out.mkdir()
    out.chmod(0o555)
    try:
        r = run_gonio("ingest", SAMPLE / "ink_red.csv", "-o", out / "red.json")
        assert r.exit_code == 2
        assert r.stderr.startswith(f"gonio: error: cannot write to folder {out}: permission "
                                   "denied; ")
        assert list(out.iterdir()) == []
    finally:
        out.chmod(0o755)


def test_a_file_in_the_way_of_the_output_folder(run_gonio, tmp_path):
    (tmp_path / "out").write_text("a file, not a folder")
    r = run_gonio("ingest", SAMPLE / "ink_red.csv", "-o", tmp_path / "out" / "sub" / "r.json")
    assert r.exit_code == 2
    assert r.stderr.startswith(f"gonio: error: cannot write to folder {tmp_path / 'out' / 'sub'}"
                               ": a file of that name (or of one of its parents) is in the way")


def test_an_output_that_is_a_folder(run_gonio, tmp_path):
    r = run_gonio("ingest", SAMPLE / "ink_red.csv", "-o", tmp_path)
    assert r.exit_code == 2
    assert r.stderr == (f"gonio: error: {tmp_path}: is a folder; give a file name for the "
                        "output\n")


def test_a_full_disk_while_writing_names_the_folder(tmp_path):
    with pytest.raises(WriteError) as info:
        with artifact.atomic_path(tmp_path / "a.json"):
            raise OSError(errno.ENOSPC, "No space left on device", str(tmp_path / ".a.tmp"))
    assert info.value.format().startswith(f"cannot write to folder {tmp_path}: No space left")
    assert list(tmp_path.iterdir()) == []


def test_an_unwritable_cache_is_only_slower(tmp_path, monkeypatch):
    """WriteError is an OSError, so the cache still treats a failed write as optional."""
    from gonio_cli import cache

    monkeypatch.setenv(cache.CACHE_ENV, str(tmp_path / "cache"))
    _refuse_mkstemp(monkeypatch, PermissionError(errno.EACCES, "Permission denied"))
    data = cache.cached_arrays("x.npz", lambda: {"a": np.arange(3.0)})
    assert data["a"].tolist() == [0.0, 1.0, 2.0]


@pytest.mark.parametrize("value, text", [
    (np.float64("nan"), "nan"), (np.float32(0.5), "0.5"), (np.float32(0.1), "0.1"),
    (np.float64(95.0), "95"), (95.0, "95"), (0.5, "0.5"), (float("inf"), "inf"),
    (np.int64(7), "7"), (1e-20, "1e-20"), (np.bool_(True), "True"), ("abc", "abc"),
])
def test_numbers_in_messages_print_as_numbers(value, text):
    assert num(value) == text


def test_a_numpy_value_in_a_stage_message_prints_as_a_number():
    from gonio_cli import prefilter

    sky = np.ones((4, 8, 3), dtype=np.float32)
    sky[1, 2, 0] = np.nan
    with pytest.raises(InputError) as info:
        prefilter.inputs.validate_map(sky, path="sky.exr")
    assert "texel (row 1, col 2) is nan; 1 texel is NaN" in str(info.value)
    with pytest.raises(InputError) as info:
        prefilter.inputs.validate_exponents(np.array([0.5]))
    assert str(info.value).startswith("exponent 0.5 is outside")


@posix_only
def test_ctrl_c_during_start_up_imports_is_one_line(tmp_path):
    """Interrupted while the entry point still imports the CLI (typer here): the line
    every interrupt gets and status 130, no traceback."""
    res = interrupt(tmp_path, f"""
        class _Slow:
            def find_spec(self, name, path=None, target=None):
                if name == "typer":
                    print("ready", flush=True)
                    time.sleep({WAIT_S})
                return None
        sys.meta_path.insert(0, _Slow())
        """, "--version", entry=True)
    assert res.returncode == 130
    assert res.stderr == "gonio: interrupted; nothing was written\n"


def test_help_before_a_stage_lists_every_stage(run_gonio):
    """``gonio --help render`` is the whole app's help, though a run of one stage builds
    only that stage's command (:func:`gonio_cli.cli._app_for`)."""
    r = run_gonio("--help", "render")
    assert r.exit_code == 0
    listed = r.stdout.split("Commands:")[1]
    assert all(f"  {name} " in listed for name in stage_names())
    assert cli._app_for(["-q", "render", "x.toml"]).registered_commands[0].name == "render"
    assert cli._app_for(["--help", "render"]) is cli.app


# ------------------------------------------------- ingest's split of plain CSV --

#: CSV texts (after the comment lines) on which the one-go split and the csv module must
#: agree: quoting, trailing and missing delimiters, spaces, empty rows, decimal commas.
CSV_TEXTS = [
    "theta_i_deg,theta_o_deg,wavelength_nm,value\n20,0,380,0.5\n20,0,390, 0.25 \n",
    "theta_i_deg,theta_o_deg,wavelength_nm,value,\n20,0,380,0.5,\n,,,,\n20,0,390,0.25,\n",
    "theta_i_deg,theta_o_deg,wavelength_nm,value,\n20,0,380,0.5,7\n",
    "theta_i_deg,theta_o_deg,wavelength_nm,value\n20,0,380\n",
    "theta_i_deg,theta_o_deg,wavelength_nm,value\n20,0,380,0.5,\n20,0,390,0.25\n",
    'theta_i_deg,theta_o_deg,wavelength_nm,value\n20,0,380,"0.5"\n',
    "theta_i_deg;theta_o_deg;380;390\n20;0;0,5;0,25\n20;10;1,5;1e-3\n",
    "geometry\t400\t410\n45as15\t0.5\t0.6\n45as-15\t 0.7\t0.8\n",
    "theta_i_deg,theta_o_deg,wavelength_nm,value\n,,,\n",
    "Name,theta_i_deg,theta_o_deg,400\nA,20,0,0.5\nB,20,0,0.6\n",
]


@pytest.mark.parametrize("text", CSV_TEXTS + [SAMPLE / "ink_red.csv",
                                              SAMPLE / "carpaint_multiangle.csv"])
def test_plain_csv_split_equals_the_csv_module(tmp_path, monkeypatch, text):
    """ingest's split of an unquoted CSV in one go gives the csv module's table (cells,
    their dtype, line numbers, counts) or its error, word for word."""
    from gonio_cli import csvio, csvlayouts

    path = text if isinstance(text, Path) else tmp_path / "x.csv"
    if not isinstance(text, Path):
        path.write_text("# a comment\n\n" + text)

    def read(plain: bool):
        if not plain:
            monkeypatch.setattr(csvio, "_plain_rows", lambda texts, delim: None)
        try:
            t = csvio.read_table(path, is_header=csvlayouts.is_layout_header)
        except InputError as exc:
            return exc.format()
        finally:
            monkeypatch.undo()
        return (t.header, t.header_line, t.cells.dtype, t.cells.tolist(), t.lines.tolist(),
                t.delimiter, t.decimal_comma, t.comment_lines, t.empty_rows, t.preamble_lines)

    assert read(True) == read(False)
