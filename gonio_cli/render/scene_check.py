"""The scene file's one checker: every key's type and range, one error per key that
names the file and the key with its fix (:class:`Checker`), and ``${name}`` variables."""

from __future__ import annotations

import math
import os
import re
from pathlib import Path
from typing import Mapping

import numpy as np

from ..errors import InputError
from ..names import choices_fix
from ..schemas import MAX_MAGNITUDE

#: A vector shorter than this has no direction (light direction, camera up).
MIN_VECTOR_NORM = 1e-12

_VAR = re.compile(r"\$\{([A-Za-z_][A-Za-z0-9_]*)\}")


class Checker:
    """Type checks that name the file and the key in every message."""

    def __init__(self, path: Path, display: str):
        self.path = path
        self.display = display
        self.base = path.parent

    def error(self, where: str, message: str, fix: str | None = None) -> InputError:
        return InputError(f"{where}: {message}" if where else message, path=self.display,
                          fix=fix)

    def table(self, value, where: str) -> dict:
        if not isinstance(value, dict):
            raise self.error(where, f"is a {type_name(value)}, expected a table")
        return value

    def keys(self, table: Mapping, allowed, where: str) -> None:
        unknown = [k for k in table if k not in allowed]
        if unknown:
            raise self.error(where, f"unknown key {unknown[0]!r}",
                             fix=choices_fix(unknown[0], allowed, "allowed:"))

    def required(self, table: Mapping, key: str, where: str):
        if key not in table:
            raise self.error(where, f"missing key {key!r}")
        return table[key]

    def number(self, value, where: str, *, lo=None, hi=None, lo_open=False,
               hi_open=False) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error(where, f"{value!r} is a {type_name(value)}, expected a number")
        x = float(value)
        if not math.isfinite(x):
            raise self.error(where, f"{value!r} is not a finite number")
        if lo is not None and (x < lo or (lo_open and x == lo)):
            raise self.error(where, f"{value!r} is below {'or at ' if lo_open else ''}{lo}")
        if hi is not None and (x > hi or (hi_open and x == hi)):
            raise self.error(where, f"{value!r} is above {'or at ' if hi_open else ''}{hi}")
        return x

    def integer(self, value, where: str, *, lo=None, hi=None) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(where, f"{value!r} is a {type_name(value)}, expected an integer")
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            raise self.error(where, f"{value} is outside [{lo}, {hi}]")
        return int(value)

    def vector(self, value, where: str, n: int = 3, *, nonzero=False) -> np.ndarray:
        if not isinstance(value, list) or len(value) != n:
            raise self.error(where, f"{value!r} is not a list of {n} numbers")
        v = np.array([self.number(x, where, lo=-MAX_MAGNITUDE, hi=MAX_MAGNITUDE)
                      for x in value], dtype=float)
        if nonzero and np.linalg.norm(v) < MIN_VECTOR_NORM:
            raise self.error(where, f"{value!r} has no direction (zero length)")
        return v

    def boolean(self, value, where: str) -> bool:
        if not isinstance(value, bool):
            raise self.error(where, f"{value!r} is a {type_name(value)}, expected true or false")
        return value

    def string(self, value, where: str) -> str:
        if not isinstance(value, str):
            raise self.error(where, f"{value!r} is a {type_name(value)}, expected a string")
        return value

    def choice(self, value, where: str, choices) -> str:
        s = self.string(value, where)
        if s not in choices:
            raise self.error(where, f"{s!r} is unknown", fix=choices_fix(s, choices))
        return s

    def file(self, value, where: str) -> Path:
        s = self.string(value, where)
        p = Path(s)
        p = p if p.is_absolute() else self.base / p
        if not p.is_file():
            raise self.error(where, f"no such file {s!r} (looked for {os.path.normpath(p)})",
                             fix="paths are relative to the scene file")
        return Path(os.path.normpath(p))


def type_name(value) -> str:
    return {bool: "boolean", int: "integer", float: "number", str: "string", list: "list",
            dict: "table"}.get(type(value), type(value).__name__)


def names_used(value) -> list[str]:
    """Every ``${name}`` in the strings of a parsed TOML value, recursively."""
    if isinstance(value, str):
        return _VAR.findall(value)
    if isinstance(value, list):
        return [n for v in value for n in names_used(v)]
    if isinstance(value, dict):
        return [n for v in value.values() for n in names_used(v)]
    return []


def substitute(value, variables: Mapping[str, str], chk: Checker, where: str):
    """Replace ``${name}`` in every string of a parsed TOML value, recursively."""
    if isinstance(value, str):
        def repl(m):
            if m.group(1) not in variables:
                raise chk.error(where, f"${{{m.group(1)}}} is not defined",
                                fix="define it in [vars] or with --var NAME=VALUE")
            return variables[m.group(1)]
        return _VAR.sub(repl, value)
    if isinstance(value, list):
        return [substitute(v, variables, chk, f"{where}[{k}]") for k, v in enumerate(value)]
    if isinstance(value, dict):
        return {k: substitute(v, variables, chk, f"{where}.{k}" if where else k)
                for k, v in value.items()}
    return value
