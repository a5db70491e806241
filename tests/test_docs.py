"""The shell examples of README.md and docs/*.md run as written (tests/docs_runner.py).

README.md runs first, in a temporary folder holding a copy of sample_data/ (what a fresh
clone's top level offers the examples). Each docs/*.md file then runs in its own copy of
that folder, so a doc may use what the README's chain wrote into try/ but nothing another
doc wrote. Every command must exit 0. `make …` lines are not run (CI runs `make test` and
`make demo` itself); blocks marked `<!-- not run: reason -->` are not run either.

The runner itself is tested first: a failing command fails, skipped ones are skipped, and
console prompts, continuation lines and comments are read as a user's shell would.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from docs_runner import (NOT_RUN, SKIPPED_PROGRAMS, extract_blocks, failure_message,
                         prepare_workspace, run_commands, run_markdown)

ROOT = Path(__file__).resolve().parents[1]
DOCS = sorted((ROOT / "docs").glob("*.md"))
MARKDOWN = [ROOT / "README.md", *DOCS]

#: A path into the demo's output folder (out/…), which belongs to make: an example that
#: writes there breaks the next `make demo`, one that reads from there fails on a clone
#: that has not run it.
MAKE_OUTPUT = re.compile(r"(?<![\w./$-])(\$PWD/|\./)?out(/|\s|$)")


def _name(path: Path) -> str:
    return str(path.relative_to(ROOT))


# --- the runner ---------------------------------------------------------------------------

SAMPLE = """\
# A doc

```sh
echo one > a.txt
# a comment, not a command
cat a.txt \\
    a.txt > b.txt
make demo
```

<!-- not run: an address on the author's cluster -->

```sh
scp b.txt cluster.example:/scratch/
```

```console
$ wc -l b.txt
2 b.txt
$ test -s b.txt
```

```text
gonio fit MEASUREMENT.json -o MATERIAL.json
```

```bash
test "$(cat b.txt)" = "$(printf 'one\\none')"
false
echo never > c.txt
```
"""


def test_runner_reads_blocks():
    blocks = extract_blocks(SAMPLE)
    # text blocks are not shell blocks
    assert [b.language for b in blocks] == ["sh", "sh", "console", "bash"]
    first, marked, console, last = blocks
    assert [c.text for c in first.commands] == ["echo one > a.txt", "cat a.txt a.txt > b.txt",
                                               "make demo"]
    assert [c.line for c in first.commands] == [4, 6, 8]
    assert first.commands[2].skip_reason.startswith("make: ")
    assert marked.skip_reason == "an address on the author's cluster"
    assert marked.commands[0].skip_reason == "not run: an address on the author's cluster"
    assert [c.text for c in console.commands] == ["wc -l b.txt", "test -s b.txt"]
    assert [c.line for c in last.commands] == [28, 29, 30]
    assert "make" in SKIPPED_PROGRAMS


def test_runner_fails_on_a_failing_command(tmp_path):
    """The block's `false` fails the file; the commands after it are not run."""
    doc = tmp_path / "doc.md"
    doc.write_text(SAMPLE, encoding="utf-8")
    results = run_markdown(doc, tmp_path)
    ran = [r for r in results if r.returncode is not None]
    assert [r.returncode for r in ran] == [0, 0, 0, 0, 0, 1]   # the last is `false`
    assert [r.command.text for r in results if r.returncode is None] == [
        "make demo", "scp b.txt cluster.example:/scratch/"]
    assert (tmp_path / "b.txt").read_text() == "one\none\n"
    assert not (tmp_path / "c.txt").exists()
    message = failure_message("doc.md", results)
    assert message.startswith("doc.md:29: `false` exited with status 1")


def test_runner_passes_when_every_command_passes(tmp_path):
    doc = tmp_path / "ok.md"
    doc.write_text(SAMPLE.replace("false\n", ""), encoding="utf-8")
    results = run_markdown(doc, tmp_path)
    assert failure_message("ok.md", results) is None
    assert (tmp_path / "c.txt").read_text() == "never\n"


def test_runner_puts_this_gonio_first_on_path(tmp_path):
    """`gonio` in a doc is the one installed with the interpreter running the tests."""
    (cmd,) = extract_blocks("```sh\ngonio --version > v.txt\n```\n")[0].commands
    (result,) = run_commands([cmd], tmp_path)
    from gonio_cli import __version__
    assert result.returncode == 0, result.stderr
    assert __version__ in (tmp_path / "v.txt").read_text()


def test_runner_reports_a_failing_gonio_command(tmp_path):
    """A doc command that gonio refuses (exit 2) fails the doc, naming file and line."""
    doc = tmp_path / "bad.md"
    doc.write_text("Text.\n\n```sh\ngonio fit missing.measurement.json -o x.material.json\n```\n",
                   encoding="utf-8")
    results = run_markdown(doc, tmp_path)
    message = failure_message("bad.md", results)
    assert results[0].returncode == 2
    assert message.startswith("bad.md:4: `gonio fit missing.measurement.json")
    assert "missing.measurement.json" in message


# --- the documents ------------------------------------------------------------------------

@pytest.mark.parametrize("path", MARKDOWN, ids=_name)
def test_not_run_marks_precede_a_shell_block(path):
    """Every `<!-- not run: … -->` mark skips a shell block (a stray mark hides nothing)."""
    text = path.read_text(encoding="utf-8")
    marks = sum(1 for line in text.splitlines() if NOT_RUN.match(line))
    assert marks == sum(1 for b in extract_blocks(text) if b.skip_reason)


@pytest.mark.parametrize("path", MARKDOWN, ids=_name)
def test_examples_stay_out_of_the_demo_output(path):
    """No example that runs reads or writes the demo's out/ (they use try/)."""
    offending = [f"{_name(path)}:{c.line}: {c.text}"
                 for b in extract_blocks(path.read_text(encoding="utf-8"))
                 for c in b.commands if not c.skip_reason and MAKE_OUTPUT.search(c.text)]
    assert not offending, "examples must use try/, not out/:\n" + "\n".join(offending)


def test_make_output_pattern():
    """The out/ check above can fail, and does not mistake --var out=… or try/out."""
    assert MAKE_OUTPUT.search("gonio prefilter sky.exr -o out/sky")
    assert MAKE_OUTPUT.search("gonio render s.toml -o x.png --var out=$PWD/out/")
    assert not MAKE_OUTPUT.search("gonio render s.toml -o x.png --var out=$PWD/try")
    assert MAKE_OUTPUT.search("gonio render s.toml -o x.png --var out=$PWD/out")
    assert not MAKE_OUTPUT.search("gonio report -o try/report-out/ --var x=try/out/")


@pytest.fixture(scope="module")
def readme_workspace(tmp_path_factory):
    """A folder after README.md's examples ran in it, and their results."""
    root = prepare_workspace(tmp_path_factory.mktemp("docs") / "readme", ROOT)
    return root, run_markdown(ROOT / "README.md", root)


def test_readme_runs(readme_workspace):
    _, results = readme_workspace
    message = failure_message("README.md", results)
    assert message is None, message
    assert sum(r.returncode == 0 for r in results) >= 20     # the chain, not an empty file


@pytest.mark.parametrize("path", DOCS, ids=_name)
def test_doc_runs(path, readme_workspace, tmp_path):
    root, readme_results = readme_workspace
    if failure_message("README.md", readme_results):
        pytest.fail("README.md's examples failed; the docs build on them")
    cwd = tmp_path / "clone"
    shutil.copytree(root, cwd, symlinks=True)
    message = failure_message(_name(path), run_markdown(path, cwd))
    assert message is None, message


#: What a user's clone cannot follow: paths into the project's working folders outside the
#: repository, and internal issue numbers.
INTERNAL = re.compile(r"\.\./shared|/work/|[Ii]ssue\s*#?\d+|(?<![\w&/])#\d+\b")


@pytest.mark.parametrize("path", MARKDOWN, ids=_name)
def test_docs_point_only_inside_the_clone(path):
    text = path.read_text(encoding="utf-8")
    found = [f"{_name(path)}:{n}: {line.strip()}" for n, line in enumerate(text.splitlines(), 1)
             if INTERNAL.search(line)]
    assert not found, "\n".join(found)


def test_internal_pattern():
    assert INTERNAL.search("see ../shared/CONVENTIONS.md")
    assert INTERNAL.search("fixed in issue 7") and INTERNAL.search("(#12)")
    assert not INTERNAL.search("seed 000 eq. 5, Figure 7, `&#8203;`, docs/conventions.md")
