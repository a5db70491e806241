"""The pinned dependency set (requirements.lock) covers pyproject.toml's dependencies.

`make demo`, `make test` and CI install exactly the pins, so a fresh machine runs what the
tests were run with. A dependency added to pyproject.toml without `make lock` would be
installed unpinned (or not satisfy its range): this test names it.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

ROOT = Path(__file__).resolve().parent.parent


def _pins(text: str) -> dict[str, set[str]]:
    """{canonical name: {versions}} of a uv/pip-compile lock (markers may fork a name)."""
    pins: dict[str, set[str]] = {}
    for line in text.splitlines():
        m = re.match(r"^([A-Za-z0-9._-]+)==([^\s;]+)", line)
        if m:
            pins.setdefault(canonicalize_name(m.group(1)), set()).add(m.group(2))
    return pins


def _requirements() -> list[Requirement]:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    reqs = [Requirement(r) for r in project["dependencies"]]
    for extra in project.get("optional-dependencies", {}).values():
        reqs += [Requirement(r) for r in extra]
    return reqs


def test_every_dependency_is_pinned_within_its_range():
    pins = _pins((ROOT / "requirements.lock").read_text())
    assert pins, "requirements.lock has no pins"
    for req in _requirements():
        name = canonicalize_name(req.name)
        assert name in pins, f"{req.name} is in pyproject.toml but not pinned: run make lock"
        for version in pins[name]:
            assert req.specifier.contains(version, prereleases=True), (
                f"{req.name}=={version} in requirements.lock is outside {req.specifier}: "
                "run make lock")


def test_build_tools_are_pinned():
    # pip and the build backend are installed from the pins too (Makefile PIP_CONSTRAINT).
    pins = _pins((ROOT / "requirements.lock").read_text())
    assert {"pip", "setuptools"} <= set(pins)


def test_pin_reader_sees_a_missing_pin():
    pins = _pins("numpy==2.4.6 ; python_full_version < '3.12'\n    # via scipy\nscipy==1.17.1\n")
    assert pins == {"numpy": {"2.4.6"}, "scipy": {"1.17.1"}}
    assert "nlopt" not in pins
