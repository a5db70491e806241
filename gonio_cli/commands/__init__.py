"""Thin typer shells, one module per stage; each exposes ``register(app)``.

Also what every shell shares:

* :func:`apply_help_style`, applied once by :mod:`gonio_cli.cli` to the whole app, gives
  every command gonio's help layout: whole first sentences as the short help in
  ``gonio --help``, and arguments shown by their metavar (``PHOTO...``) instead of
  typer's type labels (``<list[Path]>``);
* :func:`require_files`, the check of path arguments that names a shell pattern which
  matched nothing (``no files match 'photo_ti*.png'``) instead of a missing file of that
  literal name;
* :func:`plain_coercion`, installed by the command classes here, which turns the command
  line's strings into ``str``, ``int``, ``float``, ``bool`` and ``Path`` values (and lists
  of them) without pydantic, whose import and per-option validators cost ~0.1 s of every
  run.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable

import typer
from typer.core import TyperCommand, TyperGroup
from typer.models import DefaultPlaceholder

from ..errors import GonioError, InputError
from ..makers import make_fix

#: Stage shells in pipeline order (module names = command names); each module has
#: ``register(app)`` and ``EXAMPLE``, and ``gonio --help`` lists the commands in this order.
STAGES = ("ingest", "fit", "eval", "lobes", "halftone", "prefilter", "sparkle", "render", "export",
          "report", "batch")

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


# ------------------------------------------------------------- flags as typed --

#: The command line of the current run (set by :func:`gonio_cli.cli.run`), so that a
#: message names an option as the user typed it (``--width-px`` or its old ``--width``,
#: :func:`as_typed_in`).
_ARGV: list[str] = []


def remember_argv(args: Iterable[str]) -> None:
    """Record the current run's arguments (:func:`as_typed_in` reads them)."""
    _ARGV[:] = [str(a) for a in args]


#: Old spellings of flags that now carry their unit → the spelling shown (``--width`` →
#: ``--width-px``): still accepted, never shown in ``--help`` (tests/test_cli_help.py
#: checks each has a shown spelling with a unit, and that it is this one).
ALIASES = {"--width": "--width-px", "--height": "--height-px",
           "--exclude-theta-i": "--exclude-theta-i-deg",
           "--exclude-theta-o": "--exclude-theta-o-deg", "--theta-i": "--theta-i-deg",
           "--resolution": "--height-px", "--view-angles": "--view-angles-deg",
           "--exposure": "--exposure-stops", "--size": "--size-px"}
HIDDEN_ALIASES = frozenset(ALIASES)


def as_typed_in(text: str) -> str:
    """``text`` (a message of a core, which names options by their shown spelling) with
    each option the user typed by an old spelling (:data:`ALIASES`, and not by its
    shown one) named as typed: ``--width-px: 100000 …`` for ``--width 100000`` becomes
    ``--width: 100000 …``."""
    typed = {a.split("=", 1)[0] for a in _ARGV}
    for alias, shown in ALIASES.items():
        if alias in typed and shown not in typed:
            text = re.sub(rf"(?<![\w-]){re.escape(shown)}(?![\w-])", alias, text)
    return text


def _help_record(param, ctx):
    """``param``'s help row without its :data:`HIDDEN_ALIASES`."""
    shown = [o for o in param.opts if o not in HIDDEN_ALIASES]
    if len(shown) == len(param.opts) or not shown:
        return param.get_help_record(ctx)
    opts, param.opts = param.opts, shown
    try:
        return param.get_help_record(ctx)
    finally:
        param.opts = opts


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
            record = _help_record(param, ctx)
            if record is None or param.param_type_name not in sections:
                continue
            if param.param_type_name == "argument":  # no '<list[Path]>' after the name
                record = (argument_label(param), record[1])
            sections[param.param_type_name].append(record)
        for title, name in (("Arguments", "argument"), ("Options", "option")):
            if sections[name]:
                with formatter.section(title):
                    formatter.write_dl(sections[name])


# ------------------------------------------------------------------ option values --
#
# typer 0.29 converts every option value with a pydantic ``TypeAdapter`` built on first
# use: importing pydantic and building the adapters takes ~0.1 s, a fifth of a render.
# gonio's options are plain ``str``, ``int``, ``float``, ``bool`` and ``Path`` (or lists
# of them) without typer's ``min``/``max``/``parser``/choices, so the value a command
# receives is what the conversion below gives. It is installed in typer's per-parameter
# slot (``_TyperParameter._runtime_param``, an internal of the pinned typer): anything it
# does not recognise, and every value that is not a plain number or path (" 3", "1_000",
# "0x10", …), goes to typer's own conversion, so accepted values and error messages are
# typer's. tests/test_cli.py checks both against typer's conversion and that a render
# never imports pydantic (which would show this slot moved in a newer typer).

try:  # typer internals: without them, typer converts every value itself (slower, same)
    from typer._coercion import RuntimeParam, build_runtime_param
except ImportError:  # pragma: no cover (another typer)
    RuntimeParam = build_runtime_param = None  # type: ignore[assignment,misc]

#: Decimal integers and floats exactly as written (ASCII digits; no spaces, underscores,
#: hex): for these ``int()``/``float()`` give what typer's pydantic conversion gives.
_INT_TEXT = re.compile(r"[+-]?[0-9]+", re.ASCII)
_FLOAT_TEXT = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?", re.ASCII)

#: Returned by a leaf conversion for a value it leaves to typer.
_TYPER = object()


def _plain_str(value, parameter_info, param, ctx):
    return value if type(value) is str else _TYPER


def _plain_int(value, parameter_info, param, ctx):
    if type(value) is int:
        return value
    return int(value) if type(value) is str and _INT_TEXT.fullmatch(value) else _TYPER


def _plain_float(value, parameter_info, param, ctx):
    if type(value) is float:
        return value
    return float(value) if type(value) is str and _FLOAT_TEXT.fullmatch(value) else _TYPER


def _plain_bool(value, parameter_info, param, ctx):
    return value if type(value) is bool else _TYPER


def _plain_path(value, parameter_info, param, ctx):
    if not isinstance(value, (str, Path)):
        return _TYPER
    from typer._param_types import coerce_cli_path  # typer's checks (exists, dir_okay, …)

    return coerce_cli_path(Path(value), parameter_info, path_type=Path, param=param, ctx=ctx)


#: The leaf types converted here, by annotation.
PLAIN_TYPES: dict[Any, Callable] = {str: _plain_str, int: _plain_int, float: _plain_float,
                                    bool: _plain_bool, Path: _plain_path}

#: typer parameter settings that need typer's own conversion when set (not None/False).
_TYPER_ONLY_SETTINGS = ("parser", "click_type", "min", "max", "clamp", "formats", "path_type",
                        "resolve_path")


if RuntimeParam is not None:
    @dataclass(frozen=True)
    class PlainParam(RuntimeParam):
        """typer's conversion contract for one parameter, done by :data:`PLAIN_TYPES`
        (``leaf``) for a single value or each item of a list (``many``); a value it does
        not take goes to typer's own conversion of ``descriptor``."""

        leaf: Callable = _plain_str
        many: bool = False
        descriptor: Any = None

        def _coerce_value(self, value, param, ctx):
            info = self.parameter_info
            if self.many:
                items = value if isinstance(value, (list, tuple)) else [value]
                out = [self.leaf(item, info, param, ctx) for item in items]
                if not any(item is _TYPER for item in out):
                    return out
            else:
                out = self.leaf(value, info, param, ctx)
                if out is not _TYPER:
                    return out
            return build_runtime_param(self.descriptor)._coerce_value(value, param, ctx)


def plain_runtime_param(descriptor) -> Any:
    """The :class:`PlainParam` for a typer type descriptor, or None where typer's own
    conversion is needed (other types, files, choices, bounds, parsers)."""
    if RuntimeParam is None or descriptor is None or descriptor.file_annotation is not None:
        return None
    info = descriptor.parameter_info
    if any(getattr(info, name, None) not in (None, False) for name in _TYPER_ONLY_SETTINGS):
        return None
    annotation, many = descriptor.annotation, False
    if getattr(annotation, "__origin__", None) is list:
        (annotation,), many = annotation.__args__, True
    leaf = PLAIN_TYPES.get(annotation)
    if leaf is None or descriptor.choices is not None:
        return None
    return PlainParam(parameter_info=info, annotation=descriptor.annotation, leaf=leaf,
                      many=many, descriptor=descriptor)


def plain_coercion(params) -> None:
    """Give each typer parameter in ``params`` the conversion of :func:`plain_runtime_param`
    where it applies (idempotent; parameters of other kinds are left alone)."""
    for param in params:
        if getattr(param, "_runtime_param", False) is None:
            plain = plain_runtime_param(getattr(param, "type_descriptor", None))
            if plain is not None:
                param._runtime_param = plain


class _PlainValues:
    """Option values converted by :func:`plain_coercion` (mixed into the command classes):
    the declared parameters and click's ``--help``, made on demand."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        plain_coercion(self.params)

    def get_help_option(self, ctx):
        option = super().get_help_option(ctx)
        plain_coercion([option] if option is not None else [])
        return option


class Command(_PlainValues, _HelpStyle, TyperCommand):
    """A gonio subcommand (help layout of :class:`_HelpStyle`, values converted by
    :func:`plain_coercion`)."""


class Group(_PlainValues, TyperGroup):
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


class SubGroup(_PlainValues, TyperGroup):
    """A group under ``gonio`` (``gonio lobes``): typer's, values converted by
    :func:`plain_coercion`."""


def _default_class(cls, default: type) -> bool:
    """Is ``cls`` typer's default command or group class (unset, or a typer placeholder)?"""
    return cls is None or cls is default or isinstance(cls, DefaultPlaceholder)


def apply_help_style(app: typer.Typer) -> None:
    """Give every command of ``app`` (and of its sub-apps) gonio's help layout.

    Sets the class of each registered command that kept typer's default; idempotent, so
    commands registered later (tests) get it on the next call.
    """
    for info in app.registered_commands:
        if _default_class(info.cls, TyperCommand):
            info.cls = Command
    for group in app.registered_groups:
        if group.typer_instance is not None:
            if all(_default_class(c, TyperGroup)
                   for c in (group.cls, group.typer_instance.info.cls)):
                group.cls = SubGroup
            apply_help_style(group.typer_instance)


def is_pattern(text: str) -> bool:
    """Does ``text`` hold shell wildcards (``*``, ``?``, ``[``)?"""
    return any(ch in GLOB_CHARACTERS for ch in text)


def read_as(option: str, read: Callable[[Any], Any], path) -> Any:
    """``read(path)`` for the file given as ``option`` (``--at``, ``--basis``): an error
    about that file names the option too (``b.json: schema is … (given as --basis)``)."""
    try:
        return read(path)
    except GonioError as exc:
        if exc.path == os.fspath(path) and option not in exc.message:
            exc.message = f"{exc.message} (given as {option})"
        raise


def require_files(paths: Iterable[str | os.PathLike], *, what: str = "file",
                  missing_fix: str = "check the path", schema: str | None = None) -> None:
    """Refuse a path that is not an existing file, naming the real cause.

    A shell passes a pattern that matches nothing on unchanged (bash without
    ``nullglob``), so ``gonio sparkle photo_ti*.png`` in the wrong folder arrives as the
    literal name ``photo_ti*.png``: that is "no files match", not "no such file".

    Raises
    ------
    InputError
        ``no files match 'photo_ti*.png'``, ``PATH: no such file`` (``no such image
        file`` with ``what="image file"``) or ``PATH: is a folder, not a file``. With the
        ``schema`` of the artifact expected, the fix of a missing file is the command that
        makes it (:func:`gonio_cli.makers.make_fix`), not ``missing_fix``.
    """
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
        if schema is not None:
            missing_fix = make_fix(schema, text, missing=True)
        raise InputError(f"no such {what}", path=text, fix=missing_fix)


def parse_vars(items: Iterable[str]) -> dict[str, str]:
    """``--var NAME=VALUE`` options as a dict (scene variables: render, export)."""
    variables = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name:
            raise InputError(f"--var {item!r} is not NAME=VALUE", fix="e.g. --var ink=green")
        variables[name] = value
    return variables
