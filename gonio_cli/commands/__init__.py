"""Thin typer shells, one module per stage; each exposes ``register(app)``.

Also what every shell shares:

* :func:`apply_help_style`, applied once by :mod:`gonio_cli.cli` to the whole app, gives
  every command gonio's help layout: whole first sentences as the short help in
  ``gonio --help``, and arguments shown by their metavar (``PHOTO...``) instead of
  typer's type labels (``<list[Path]>``);
* :func:`require_files`, the check of path arguments that names a shell pattern which
  matched nothing (``no files match 'photo_ti*.png'``) instead of a missing file of that
  literal name.
"""

from __future__ import annotations

import os
import re
from typing import Iterable

import typer
from typer.core import TyperCommand, TyperGroup

#: Stage shells in pipeline order (module names = command names); each module has
#: ``register(app)`` and ``EXAMPLE``, and ``gonio --help`` lists the commands in this order.
STAGES = ("ingest", "fit", "eval", "lobes", "halftone", "prefilter", "sparkle", "render", "report")

#: Characters that make a shell word a pattern (POSIX sh and bash globbing).
GLOB_CHARACTERS = frozenset("*?[")

#: Words ending in '.' that do not end a sentence in gonio's help texts.
ABBREVIATIONS = frozenset({"eq", "eqs", "e.g", "i.e", "fig", "figs", "cf", "vs", "approx",
                           "no", "sec", "ref", "et al"})


def first_sentence(text: str | None) -> str:
    """The first whole sentence of a help text, on one line.

    A sentence ends at '.', '!' or '?' followed by a space or the end of the first
    paragraph, outside parentheses and not after an abbreviation (``eqs. 1-7``). Text
    without such an end is returned whole with a full stop added, never cut mid-way.
    """
    paragraph = re.split(r"\n\s*\n|\x08", (text or "").strip(), maxsplit=1)[0]
    words = " ".join(paragraph.split())
    depth = 0
    for k, ch in enumerate(words):
        depth += {"(": 1, ")": -1, "[": 1, "]": -1}.get(ch, 0)
        if ch in ".!?" and depth == 0 and (k + 1 == len(words) or words[k + 1] == " "):
            last_word = words[:k].rsplit(" ", 1)[-1].lower()
            if ch == "." and last_word in ABBREVIATIONS:
                continue
            return words[:k + 1]
    return words + "." if words and words[-1] not in ".!?" else words


def short_help(command) -> str:
    """What ``gonio --help`` lists for a (click) command: its ``short_help`` if set,
    else the first whole sentence of its help."""
    return " ".join(command.short_help.split()) if command.short_help else first_sentence(
        command.help)


def argument_label(param) -> str:
    """An argument as help shows it: its metavar (or NAME), ``...`` if it takes several."""
    label = param.metavar or param.name.upper()
    if param.nargs != 1 and not label.endswith(("...", "…")):
        label += "..."
    return label


class _HelpStyle:
    """gonio's help layout for a typer command (mixed into the command classes)."""

    def get_short_help_str(self, limit: int = 45) -> str:  # noqa: ARG002 (never cut)
        return short_help(self)

    def collect_usage_pieces(self, ctx) -> list[str]:
        pieces = [self.options_metavar] if self.options_metavar else []
        for param in self.get_params(ctx):
            if param.param_type_name == "argument":
                label = argument_label(param)
                pieces.append(label if param.required else f"[{label}]")
            else:
                pieces.extend(param.get_usage_pieces(ctx))
        return pieces

    def format_options(self, ctx, formatter) -> None:
        sections: dict[str, list[tuple[str, str]]] = {"argument": [], "option": []}
        for param in self.get_params(ctx):
            record = param.get_help_record(ctx)
            if record is None or param.param_type_name not in sections:
                continue
            if param.param_type_name == "argument":  # no '<list[Path]>' after the name
                record = (argument_label(param), record[1])
            sections[param.param_type_name].append(record)
        for title, name in (("Arguments", "argument"), ("Options", "option")):
            if sections[name]:
                with formatter.section(title):
                    formatter.write_dl(sections[name])


class Command(_HelpStyle, TyperCommand):
    """A gonio subcommand (help layout of :class:`_HelpStyle`)."""


class Group(TyperGroup):
    """The ``gonio`` command group: subcommands (and sub-groups such as ``lobes``) listed
    with whole first sentences."""

    def list_commands(self, ctx) -> list[str]:
        """Stages in pipeline order (:data:`STAGES`), anything else after them."""
        names = list(self.commands)
        return sorted(names, key=lambda n: STAGES.index(n) if n in STAGES else len(STAGES))

    def format_commands(self, ctx, formatter) -> None:
        rows = [(name, short_help(cmd)) for name in self.list_commands(ctx)
                if (cmd := self.get_command(ctx, name)) is not None and not cmd.hidden]
        if rows:
            with formatter.section("Commands"):
                formatter.write_dl(rows)


def apply_help_style(app: typer.Typer) -> None:
    """Give every command of ``app`` (and of its sub-apps) gonio's help layout.

    Sets the class of each registered command that kept typer's default; idempotent, so
    commands registered later (tests) get it on the next call.
    """
    for info in app.registered_commands:
        if info.cls is None or info.cls is TyperCommand:
            info.cls = Command
    for group in app.registered_groups:
        if group.typer_instance is not None:
            apply_help_style(group.typer_instance)


def is_pattern(text: str) -> bool:
    """Does ``text`` hold shell wildcards (``*``, ``?``, ``[``)?"""
    return any(ch in GLOB_CHARACTERS for ch in text)


def require_files(paths: Iterable[str | os.PathLike], *, what: str = "file",
                  missing_fix: str = "check the path") -> None:
    """Refuse a path that is not an existing file, naming the real cause.

    A shell passes a pattern that matches nothing on unchanged (bash without
    ``nullglob``), so ``gonio sparkle photo_ti*.png`` in the wrong folder arrives as the
    literal name ``photo_ti*.png``: that is "no files match", not "no such file".

    Raises
    ------
    InputError
        ``no files match 'photo_ti*.png'``, ``PATH: no such file`` (``no such image
        file`` with ``what="image file"``) or ``PATH: is a folder, not a file``.
    """
    from ..errors import InputError

    for path in paths:
        text = os.fspath(path)
        if os.path.isfile(text):
            continue
        if os.path.isdir(text):
            raise InputError(f"is a folder, not a {what}", path=text,
                             fix=f"name the files inside it, e.g. {text}/*")
        if is_pattern(os.path.basename(text)) or is_pattern(os.path.dirname(text)):
            raise InputError(f"no files match {text!r}",
                             fix="check the folder and the pattern (a pattern that matches "
                                 "nothing reaches gonio as it is)")
        raise InputError(f"no such {what}", path=text, fix=missing_fix)
