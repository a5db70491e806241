"""The structure a newcomer can carry on, checked from the source (docs/architecture.md):

* no module over 500 lines and no function over 80, unless docs/architecture.md names it
  under "Exceptions to the size rules" with its reason;
* no circle among the package's module-level imports;
* no import of a gonio module inside a function unless a ``# lazy: …`` comment on the
  line or the line above says what it saves (``benchmarks/bench_startup.py`` measures it).

Each rule is read off the syntax tree of every module, so a new long function or a new
circle fails here with its file and line.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "gonio_cli"
ARCHITECTURE = ROOT / "docs" / "architecture.md"
MAX_MODULE_LINES = 500
MAX_FUNCTION_LINES = 80
LAZY = re.compile(r"#\s*lazy:", re.IGNORECASE)


def modules() -> dict[str, Path]:
    found = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        found[".".join(parts)] = path
    return found


def exceptions() -> set[str]:
    """The backticked names under docs/architecture.md's "Exceptions to the size rules"."""
    text = ARCHITECTURE.read_text(encoding="utf-8")
    match = re.search(r"^## Exceptions to the size rules\n(.*?)(?=^## |\Z)", text, re.M | re.S)
    if not match:
        return set()
    return set(re.findall(r"^- `([^`]+)`", match.group(1), re.M))


def rel(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


def functions(tree: ast.AST):
    """Each function with its dotted name inside the module (``Class.method``)."""
    def walk(node, prefix):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                name = f"{prefix}{child.name}"
                if not isinstance(child, ast.ClassDef):
                    yield name, child
                yield from walk(child, name + ".")
            else:
                yield from walk(child, prefix)
    yield from walk(tree, "")


def test_no_module_over_500_lines():
    allowed = exceptions()
    long = [f"{rel(p)} ({len(p.read_text().splitlines())} lines)" for p in modules().values()
            if len(p.read_text().splitlines()) > MAX_MODULE_LINES and rel(p) not in allowed]
    assert not long, "over 500 lines and not named in docs/architecture.md: " + ", ".join(long)


def test_no_function_over_80_lines():
    allowed = exceptions()
    long = []
    for path in modules().values():
        for name, node in functions(ast.parse(path.read_text())):
            size = node.end_lineno - node.lineno + 1
            if size > MAX_FUNCTION_LINES and f"{rel(path)}::{name}" not in allowed:
                long.append(f"{rel(path)}:{node.lineno} {name} ({size} lines)")
    assert not long, "over 80 lines and not named in docs/architecture.md: " + ", ".join(long)


def test_every_named_exception_still_exists_and_is_still_long():
    """An exception left behind after a split would excuse the next long thing."""
    found = {rel(p): p for p in modules().values()}
    stale = []
    for item in exceptions():
        file, _, name = item.partition("::")
        if file not in found:
            stale.append(item)
            continue
        if not name:
            stale += [item] if len(found[file].read_text().splitlines()) <= MAX_MODULE_LINES else []
            continue
        sizes = {n: f.end_lineno - f.lineno + 1
                 for n, f in functions(ast.parse(found[file].read_text()))}
        if sizes.get(name, 0) <= MAX_FUNCTION_LINES:
            stale.append(item)
    assert not stale, f"named in docs/architecture.md but no longer long or gone: {stale}"


def imported(name: str, path: Path, node: ast.ImportFrom | ast.Import, known) -> set[str]:
    """The gonio modules one import statement loads (``from . import x`` → the submodule)."""
    if isinstance(node, ast.Import):
        return {a.name for a in node.names if a.name in known}
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    if node.level:
        parts = package.split(".")
        base = ".".join(parts[:len(parts) - node.level + 1] + ([node.module] if node.module else []))
    else:
        base = node.module or ""
    out = set()
    for alias in node.names:
        full = f"{base}.{alias.name}"
        out.add(full if full in known else base)
    return {m for m in out if m in known}


def module_level_graph() -> dict[str, set[str]]:
    known = modules()
    graph = {}
    for name, path in known.items():
        deps = set()
        for node in ast.parse(path.read_text()).body:
            if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.dump(node.test):
                continue
            body = node.body if isinstance(node, ast.Try) else [node]
            for stmt in body:
                if isinstance(stmt, (ast.Import, ast.ImportFrom)):
                    deps |= imported(name, path, stmt, known)
        graph[name] = deps - {name}
    return graph


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_no_import_circle():
    assert circles(module_level_graph()) == []


def test_the_circle_finder_finds_a_circle():
    assert circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_gonio_imports_inside_functions_say_what_they_save():
    known = modules()
    bare = []
    for name, path in known.items():
        lines = path.read_text().splitlines()
        for _, fn in functions(ast.parse("\n".join(lines))):
            for node in ast.walk(fn):
                if isinstance(node, (ast.Import, ast.ImportFrom)) and \
                        imported(name, path, node, known):
                    here = lines[node.lineno - 1]
                    above = lines[node.lineno - 2] if node.lineno > 1 else ""
                    if not (LAZY.search(here) or LAZY.search(above)):
                        bare.append(f"{rel(path)}:{node.lineno}")
    bare = sorted(set(bare))
    assert not bare, (f"{len(bare)} imports of gonio modules inside functions without a "
                      f"'# lazy: what it saves' comment: " + ", ".join(bare[:40]))


@pytest.mark.parametrize("source, expected", [
    ("def f():\n" + "    x = 1\n" * 80, 81),
    ("class C:\n    def m(self):\n" + "        x = 1\n" * 79, 80),
])
def test_function_sizes_are_counted_as_a_reader_sees_them(source, expected):
    (name, node), = [(n, f) for n, f in functions(ast.parse(source))]
    assert node.end_lineno - node.lineno + 1 == expected
