"""The shell examples of README.md and docs/*.md run as written (tests/docs_runner.py),
and the README stays a newcomer's page: short, with its sections, and every link whole.

The chain (README.md's worked example, then docs/tour.md, which goes on from it) runs
first, in order, in one temporary folder holding a copy of sample_data/ (what a fresh
clone's top level offers the examples). Each other docs/*.md file then runs in its own copy
of that folder, so a doc may use what the chain wrote into try/ but nothing another doc
wrote. Every command must exit 0. `make …` lines are not run (CI runs `make test` and
`make demo` itself); blocks marked `<!-- not run: reason -->` are not run either.

The runner itself is tested first: a failing command fails, skipped ones are skipped, and
console prompts, continuation lines and comments are read as a user's shell would.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from docs_runner import (CHAIN, NOT_RUN, SKIPPED_PROGRAMS, extract_blocks, failure_message,
                         prepare_workspace, run_commands, run_markdown, with_chain)
from readme_images import IMAGES

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DOCS = sorted((ROOT / "docs").glob("*.md"))
MARKDOWN = [README, *DOCS]
#: The pages outside the chain: each runs in a copy of the folder the chain wrote.
PAGES = [p for p in DOCS if str(p.relative_to(ROOT)) not in CHAIN]

#: The README is a newcomer's page; the rest lives in docs/ (docs/tour.md goes on from it).
README_MAX_LINES = 200

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


def test_runner_runs_the_chain_first():
    """A page outside the chain gets the whole chain before it; a chain file what precedes it."""
    readme, tour = CHAIN
    assert with_chain(["docs/lobes.md"]) == [readme, tour, "docs/lobes.md"]
    assert with_chain([readme]) == [readme]
    assert with_chain([tour]) == [readme, tour]
    assert with_chain([tour, readme, "docs/fit.md", "docs/fit.md"]) == [
        readme, tour, "docs/fit.md"]


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
def chain_workspace(tmp_path_factory):
    """A folder after the chain's examples (README.md, then docs/tour.md) ran in it, and
    each file's results (a file after a failed one is not run: its results are empty)."""
    root = prepare_workspace(tmp_path_factory.mktemp("docs") / "chain", ROOT)
    results: dict[str, list] = {}
    for name in CHAIN:
        failed = any(failure_message(n, r) for n, r in results.items())
        results[name] = [] if failed else run_markdown(ROOT / name, root)
    return root, results


def _chain_failure(results) -> str | None:
    return next((m for n, r in results.items() if (m := failure_message(n, r))), None)


def test_readme_runs(chain_workspace):
    """The README's worked chain runs and is one: ingest, then fit, then render."""
    root, results = chain_workspace
    message = failure_message("README.md", results["README.md"])
    assert message is None, message
    ran = [r.command.text.split()[:2] for r in results["README.md"] if r.returncode == 0]
    assert ran == [["gonio", "ingest"], ["gonio", "fit"], ["gonio", "render"]]
    assert (root / "try" / "render" / "green.png").stat().st_size > 0


def test_tour_runs(chain_workspace):
    _, results = chain_workspace
    if failure_message("README.md", results["README.md"]):
        pytest.fail("README.md's examples failed; docs/tour.md builds on them")
    message = failure_message("docs/tour.md", results["docs/tour.md"])
    assert message is None, message
    tour = results["docs/tour.md"]
    assert sum(r.returncode == 0 for r in tour) >= 20     # the chain, not an empty file


@pytest.mark.parametrize("path", PAGES, ids=_name)
def test_doc_runs(path, chain_workspace, tmp_path):
    root, chain_results = chain_workspace
    if _chain_failure(chain_results):
        pytest.fail("the chain's examples (README.md, docs/tour.md) failed; the docs build on them")
    cwd = tmp_path / "clone"
    shutil.copytree(root, cwd, symlinks=True)
    message = failure_message(_name(path), run_markdown(path, cwd))
    assert message is None, message


# --- the README: short, with what a newcomer needs ----------------------------------------

def _section(text: str, title: str) -> str:
    """The body of the ``## title…`` section of a Markdown text ("" if there is none)."""
    match = re.search(rf"^## {re.escape(title)}.*?\n(.*?)(?=^## |\Z)", text, re.M | re.S)
    return match.group(1) if match else ""


def test_readme_is_short():
    lines = len(README.read_text(encoding="utf-8").splitlines())
    assert lines <= README_MAX_LINES, (
        f"README.md has {lines} lines (at most {README_MAX_LINES}): move detail to docs/")


def test_readme_keeps_the_two_commands_and_their_timing():
    """`make demo` and `make test` in a shell block, and how long the demo takes, measured."""
    section = _section(README.read_text(encoding="utf-8"), "The two commands")
    commands = [c.text.split("#")[0].strip() for b in extract_blocks(section) for c in b.commands]
    assert commands == ["make demo", "make test"]
    assert re.search(r"The demo \(\d+ s\b.*measured with `/usr/bin/time`", section, re.S)


def test_readme_names_every_command_and_its_doc():
    """The Stages table has a row per gonio subcommand, each linking to its docs page."""
    import typer
    from gonio_cli import cli

    table = _section(README.read_text(encoding="utf-8"), "Stages")
    rows = {m.group(1): m.group(2) for m in re.finditer(r"^\| `gonio (\w+)` \|(.*)$", table, re.M)}
    commands = set(typer.main.get_command(cli.app).commands)
    assert set(rows) == commands
    for name, row in rows.items():
        assert re.search(r"\]\(docs/\w+\.md", row), f"gonio {name}: no link to its docs page"


def test_readme_images_are_shown():
    """Every demo image that tests/readme_images.py keeps up to date is shown on a page
    (the README or the docs page its stage moved to), and the README shows some."""
    shown = "\n".join(p.read_text(encoding="utf-8") for p in MARKDOWN)
    assert [n for n in IMAGES if f"images/{n})" not in shown] == []
    assert re.search(r"!\[[^\]]*\]\(docs/images/", README.read_text(encoding="utf-8"))


def test_architecture_names_every_module():
    """docs/architecture.md's module map has a line for every module of the package (and
    none for a module that is gone), so a split or a new module updates the map."""
    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    named = set(re.findall(r"`(gonio_cli/[\w/]+\.py)`", text))
    modules = {_name(p) for p in (ROOT / "gonio_cli").rglob("*.py")}
    assert sorted(modules - named) == [], "not in docs/architecture.md's module map"
    assert sorted(named - modules) == [], "named in docs/architecture.md but gone"


#: A Markdown link or image: ``[text](target)``.
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")


def _anchors(path: Path) -> set[str]:
    """The heading anchors of a Markdown file, as GitHub spells them."""
    text = re.sub(r"^```.*?^```", "", path.read_text(encoding="utf-8"), flags=re.M | re.S)
    return {re.sub(r"[^\w\- ]", "", h.strip().lower()).replace(" ", "-")
            for h in re.findall(r"^#+ (.*)$", text, re.M)}


@pytest.mark.parametrize("path", MARKDOWN, ids=_name)
def test_links_point_at_files_and_headings_that_exist(path):
    """Text moves between the README and docs/: a link left pointing at it fails here."""
    broken = []
    for target in LINK.findall(path.read_text(encoding="utf-8")):
        if re.match(r"[a-z]+:", target):
            continue                                  # https:, mailto:
        file, _, anchor = target.partition("#")
        linked = (path.parent / file) if file else path
        if not linked.exists():
            broken.append(target)
        elif anchor and linked.suffix == ".md" and anchor not in _anchors(linked):
            broken.append(target)
    assert not broken, f"{_name(path)}: links to nothing: {broken}"


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
