"""A batch plan (TOML) → jobs, and the checks of their graph before anything runs.

A plan holds materials, a matrix and plain jobs (docs/batch.md)::

    [[material]]                    # ingest → fit, or an existing material file
    name = "red"
    csv = ["../ink_red.csv"]
    fit = { exclude-theta-i = [70] }

    [matrix]                        # every material × scene × vars value × frame
    scenes = ["scenes/sphere.toml"]
    frames = 4
    orbit = "camera"

    [[job]]                         # any gonio command with its options
    key = "halftone/print"
    command = "halftone"
    inputs = ["../print_image.png"]
    output = "${out}/print.png"
    options = { method = "floyd-steinberg" }

Paths are relative to the plan file; ``${out}`` is the output folder (``-o``). A job's
inputs are its positional inputs, the files it ``needs`` and, for renders of the matrix,
the scene and the material; a job whose input is another job's output waits for it.
:func:`check_graph` refuses duplicate keys or outputs, an input that neither exists nor
is made by a job, and a cycle, naming the plan, the job and the path.
"""

from __future__ import annotations

import itertools
import os
from collections import deque
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Mapping

from ..artifact import read_toml
from ..errors import InputError
from ..names import choices_fix

TOP_KEYS = ("material", "matrix", "job")
MATERIAL_KEYS = ("name", "csv", "ingest", "fit", "material", "render")
MATRIX_KEYS = ("scenes", "frames", "orbit", "vars", "render", "material_var", "needs")
JOB_KEYS = ("key", "command", "inputs", "output", "options", "needs")

#: Commands a plan can name → how a worker runs them (:data:`gonio_cli.batch.jobs.RUNNERS`):
#: gonio's own commands run through its CLI in the worker; ``preview`` assembles a
#: turntable's frames into an animated PNG.
COMMANDS = {"ingest": "gonio", "fit": "gonio", "eval": "gonio", "halftone": "gonio",
            "prefilter": "gonio", "lobes": "gonio", "sparkle": "gonio", "render": "gonio",
            "preview": "preview"}

#: The output folder inside plan strings.
OUT = "${out}"
_VAR = re.compile(r"\$\{([A-Za-z_][A-Za-z0-9_]*)\}")
#: Characters a job key keeps when it becomes a file name (attempt logs).
_NAME_SAFE = re.compile(r"[^A-Za-z0-9._=-]+")


@dataclass(frozen=True)
class Job:
    """One command of a batch.

    ``argv``: the gonio arguments that run (paths absolute); ``template``: the same as the
    plan writes them (``${out}``, plan-relative paths), which with the input hashes and
    gonio's version decides whether an earlier run still stands; ``inputs``/``outputs``:
    absolute paths; ``labels``: what the contact sheet groups by (material, scene, frame).
    """

    key: str
    command: str
    argv: tuple[str, ...]
    template: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    labels: Mapping[str, Any] = field(default_factory=dict)
    #: the inputs no job of the plan makes (the user's files): a change of their
    #: modification time reruns the job, as ``make`` would (:func:`..jobs.up_to_date`)
    sources: tuple[str, ...] = ()

    @property
    def runner(self) -> str:
        return COMMANDS[self.command.split()[0]]

    @property
    def file_name(self) -> str:
        return file_name_of(self.key)


def file_name_of(key: str) -> str:
    """A job key as a file name (attempt logs, receipts): unsafe characters as ``_``."""
    return _NAME_SAFE.sub("_", key)


@dataclass
class Plan:
    """A read plan: its file, the output folder and the jobs in plan order."""

    path: Path
    outdir: Path
    jobs: list[Job]
    materials: list[str] = field(default_factory=list)


class PlanError(InputError):
    """A plan that cannot run: a bad key or value, a missing input, a cycle."""


# ---------------------------------------------------------------------------- reading --

class _Reader:
    """Builds jobs from the plan's tables; every message names the plan and the table."""

    def __init__(self, path: Path, outdir: Path):
        self.path, self.outdir, self.base = path, outdir, path.parent
        self.jobs: list[Job] = []
        self.material_render: dict[str, dict] = {}   # [[material]] render = {…}, by name
        self.words: dict[str, str] = {}   # resolve_word's answers: a plan repeats its words
        self.paths: dict[str, str] = {}   # resolve's answers

    def error(self, where: str, message: str, fix: str | None = None) -> PlanError:
        return PlanError(f"{where}: {message}" if where else message, path=self.path, fix=fix)

    def keys(self, table, allowed, where: str) -> None:
        if not isinstance(table, dict):
            raise self.error(where, f"is a {type(table).__name__}, expected a table")
        unknown = sorted(set(table) - set(allowed))
        if unknown:
            raise self.error(where, f"unknown key {unknown[0]!r}",
                             fix=choices_fix(unknown[0], allowed, "use"))

    def strings(self, value, where: str) -> list[str]:
        items = value if isinstance(value, list) else [value]
        if not items or not all(isinstance(v, str) and v for v in items):
            raise self.error(where, f"{value!r} is not a path or a list of paths")
        return items

    def resolve(self, text: str) -> str:
        """A plan path → absolute: ``${out}/…`` in the output folder, else beside the plan."""
        done = self.paths.get(text)
        if done is None:
            if text == OUT or text.startswith(OUT + "/"):
                done = os.path.normpath(os.path.join(self.outdir, text[len(OUT) + 1:]))
            else:
                done = os.path.normpath(os.path.join(self.base, text))
            self.paths[text] = done
        return done

    def resolve_word(self, word: str) -> str:
        """A word of a command as it runs: paths (also ``NAME=PATH`` of a render's --var)
        absolute, anything else as written. Each distinct word is looked at (a ``stat``)
        once per plan."""
        done = self.words.get(word)
        if done is None:
            done = self.words[word] = self._resolve_word(word)
        return done

    def _resolve_word(self, word: str) -> str:
        if _is_path(word, self.base):
            return self.resolve(word)
        name, sep, value = word.partition("=")
        if sep and not word.startswith("-") and _is_path(value, self.base):
            return f"{name}={self.resolve(value)}"
        return word

    def option_words(self, options, where: str, subst: Mapping[str, str]):
        """``{name = value}`` → (template words, outputs as written): true → --name,
        false → --no-name, a list → the option repeated, a table → --name k=v each."""
        self.keys(options, list(options) if isinstance(options, dict) else [], where)
        words: list[str] = []
        outputs: list[str] = []
        for name, value in options.items():
            flag = f"--{name}"
            if isinstance(value, bool):
                words.append(flag if value else f"--no-{name}")
                continue
            if isinstance(value, dict):
                values = [f"{k}={_text(v)}" for k, v in value.items()]
            else:
                values = [_text(v) for v in (value if isinstance(value, list) else [value])]
            for v in values:
                v = _substitute(v, subst)
                if v.startswith(OUT + "/"):
                    outputs.append(v)
                words += [flag, v]
        return words, outputs

    def add(self, key: str, command: str, positional: list[str], output: str | None,
            options: list[str], outputs: list[str], needs: list[str], where: str,
            labels: Mapping[str, Any] | None = None) -> Job:
        if command.split()[0] not in COMMANDS:
            raise self.error(f"{where} command", f"{command!r} is not a command a plan runs",
                             fix=f"use one of {', '.join(COMMANDS)}")
        outs = ([output] if output else []) + outputs
        if not outs:
            raise self.error(where, "has no output", fix='add output = "${out}/NAME"')
        for o in outs:
            if not o.startswith(OUT + "/"):
                raise self.error(f"{where} output", f"{o!r} is not inside the output folder",
                                 fix=f"write it as \"{OUT}/{os.path.basename(o)}\"")
        template = [*command.split(), *positional]
        if output is not None:
            template += ["-o", output]
        template += options
        argv = [self.resolve_word(w) for w in template]
        job = Job(key, command, tuple(argv), tuple(template),
                  tuple(self.resolve(p) for p in [*positional, *needs]),
                  tuple(self.resolve(o) for o in outs), dict(labels or {}))
        self.jobs.append(job)
        return job


def _text(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float) and value.is_integer():
        return str(int(value)) if abs(value) < 1e15 else repr(value)
    return str(value)


def _substitute(text: str, subst: Mapping[str, str]) -> str:
    return _VAR.sub(lambda m: subst.get(m.group(1), m.group(0)), text)


def _is_path(word: str, base: Path) -> bool:
    """A word the plan means as a path: inside the output folder, or a file beside the plan."""
    if word.startswith(OUT + "/"):
        return True
    return not word.startswith("-") and "=" not in word and (base / word).is_file()


def read_plan(path: str | os.PathLike, outdir: str | os.PathLike) -> Plan:
    """Read a plan file into jobs (plan order) and check their graph (:func:`check_graph`).

    Raises
    ------
    PlanError : one line naming the plan file, the table or job, and the fix.
    """
    display = os.fspath(path)
    p = Path(path)
    doc = read_toml(p, "plan", PlanError, display)
    r = _Reader(Path(display), Path(os.path.abspath(outdir)))
    r.base = p.resolve().parent
    r.keys(doc, TOP_KEYS, "")
    materials = _materials(r, doc.get("material", []))
    if "matrix" in doc:
        _matrix(r, doc["matrix"], materials)
    for k, raw in enumerate(_array(r, doc.get("job", []), "job")):
        _plain_job(r, raw, f"[[job]] {k + 1}")
    if not r.jobs:
        raise r.error("", "has no jobs", fix="add [[material]] with a [matrix], or [[job]]")
    made = {o for j in r.jobs for o in j.outputs}
    jobs = [replace(j, sources=tuple(i for i in j.inputs if i not in made)) for j in r.jobs]
    plan = Plan(r.path, r.outdir, jobs, list(materials))
    check_graph(plan)
    return plan


def _array(r: _Reader, value, name: str) -> list:
    if not isinstance(value, list):
        raise r.error(name, f"is a table, expected [[{name}]] (an array of tables)")
    return value


def _materials(r: _Reader, raw) -> dict[str, str]:
    """Each [[material]]: its ingest and fit jobs (or its file) → {name: material path};
    its own render options (``render = {…}``, over the matrix's) go to ``r.material_render``.
    A fit also draws its plot (``NAME.fit.png``, the contact sheet links it) unless the
    plan gives ``plot`` itself."""
    out: dict[str, str] = {}
    for k, m in enumerate(_array(r, raw, "material")):
        where = f"[[material]] {k + 1}"
        r.keys(m, MATERIAL_KEYS, where)
        name = m.get("name")
        if not isinstance(name, str) or not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9._-]*", name):
            raise r.error(f"{where} name", f"{name!r} is not a name",
                          fix="letters, digits, '.', '_' or '-', e.g. name = \"red\"")
        if name in out:
            raise r.error(f"{where} name", f"{name!r} is named twice")
        if ("csv" in m) == ("material" in m):
            raise r.error(where, "needs either csv (to ingest and fit) or material (a file)")
        subst = {"material": name}
        own = m.get("render", {})
        if not isinstance(own, dict):
            raise r.error(f"{where} render", f"{own!r} is not a table of gonio render options",
                          fix='e.g. render = { exposure-stops = -1 }')
        r.material_render[name] = own
        if "material" in m:
            for key in ("ingest", "fit"):
                if key in m:
                    raise r.error(f"{where} {key}", "belongs to a material made from csv")
            out[name] = r.strings(m["material"], f"{where} material")[0]
            continue
        measurement = f"{OUT}/{name}/{name}.measurement.json"
        material = f"{OUT}/{name}/{name}.material.json"
        labels = {"material": name}
        words, extra = r.option_words(m.get("ingest", {}), f"{where} ingest", subst)
        r.add(f"ingest/{name}", "ingest", r.strings(m["csv"], f"{where} csv"), measurement,
              words, extra, [], where, {**labels, "role": "ingest"})
        fit_options = {"plot": f"{OUT}/{name}/{name}.fit.png", **m.get("fit", {})}
        words, extra = r.option_words(fit_options, f"{where} fit", subst)
        r.add(f"fit/{name}", "fit", [measurement], material, words, extra, [], where,
              {**labels, "role": "fit"})
        out[name] = material
    return out


def _matrix(r: _Reader, m, materials: Mapping[str, str]) -> None:
    """Every material × scene × vars value × frame: one render each, and a preview per
    turntable."""
    where = "[matrix]"
    r.keys(m, MATRIX_KEYS, where)
    if not materials:
        raise r.error(where, "has no [[material]] to render")
    scenes = r.strings(m.get("scenes"), f"{where} scenes") if "scenes" in m else None
    if scenes is None:
        raise r.error(where, "needs scenes = [\"SCENE.toml\", ...]")
    frames = m.get("frames", 0)
    if not isinstance(frames, int) or isinstance(frames, bool) or frames < 0:
        raise r.error(f"{where} frames", f"{frames!r} is not a number of frames",
                      fix="give 0 (no turntable) or N >= 1")
    # lazy: only a plan with a turntable loads the renderer's package (gonio_cli.render)
    from ..render.turntable import ORBITS

    orbit = m.get("orbit", "camera")
    if orbit not in ORBITS:
        raise r.error(f"{where} orbit", f"{orbit!r} is unknown", fix=choices_fix(orbit, ORBITS))
    var = m.get("vars", {})
    r.keys(var, list(var) if isinstance(var, dict) else [], f"{where} vars")
    names = list(var)
    values = [[_text(v) for v in (var[n] if isinstance(var[n], list) else [var[n]])]
              for n in names]
    material_var = m.get("material_var", "material")
    needs = r.strings(m["needs"], f"{where} needs") if "needs" in m else []
    render_opts = m.get("render", {})
    for opts, at in [(render_opts, f"{where} render")] + [
            (o, f"[[material]] {n} render") for n, o in r.material_render.items()]:
        for opt in ("output", "o", "turntable", "frame", "orbit"):
            if opt in opts:
                raise r.error(at, f"{opt!r} is set by the matrix",
                              fix="use frames and orbit in [matrix]; outputs are named for you")
    for scene in scenes:
        stem = Path(scene).stem
        for combo in itertools.product(*values):
            tag = "".join(f"-{n}={v}" for n, v in zip(names, combo))
            for name, material in materials.items():
                subst = {"material": name, "scene": stem}
                words, extra = r.option_words({**render_opts, **r.material_render[name]},
                                              f"{where} render", subst)
                words += [w for n, v in zip(names, combo) for w in ("--var", f"{n}={v}")]
                words += ["--var", f"{material_var}={material}"]
                labels = {"material": name, "scene": stem + tag, "vars": dict(zip(names, combo))}
                base = f"{OUT}/{name}/{stem}{tag}"
                if not frames:
                    r.add(f"render/{name}/{stem}{tag}", "render", [scene], f"{base}.png",
                          words, extra, [material, *needs], where, {**labels, "role": "render"})
                    continue
                pngs = []
                for k in range(frames):
                    png = f"{base}.frame{k:03d}.png"
                    pngs.append(png)
                    r.add(f"render/{name}/{stem}{tag}/frame{k:03d}", "render", [scene], png,
                          [*words, "--turntable", str(frames), "--frame", str(k),
                           "--orbit", orbit], extra, [material, *needs], where,
                          {**labels, "role": "frame", "frame": k})
                r.add(f"preview/{name}/{stem}{tag}", "preview", pngs, f"{base}.png", [], [],
                      [], where, {**labels, "role": "preview", "frames": frames})


def _plain_job(r: _Reader, raw, where: str) -> None:
    r.keys(raw, JOB_KEYS, where)
    key, command = raw.get("key"), raw.get("command")
    if not isinstance(key, str) or not key:
        raise r.error(f"{where} key", "is missing", fix='add key = "a unique name"')
    if not isinstance(command, str) or not command:
        raise r.error(f"{where} command", "is missing", fix=f"use one of {', '.join(COMMANDS)}")
    inputs = r.strings(raw["inputs"], f"{where} inputs") if "inputs" in raw else []
    needs = r.strings(raw["needs"], f"{where} needs") if "needs" in raw else []
    output = r.strings(raw["output"], f"{where} output")[0] if "output" in raw else None
    words, extra = r.option_words(raw.get("options", {}), f"{where} options", {})
    r.add(key, command, inputs, output, words, extra, needs, f"{where} ({key})",
          {"role": command.split()[0]})


# -------------------------------------------------------------------------- the graph --

def dependencies(plan: Plan) -> dict[str, list[str]]:
    """{job key: keys of the jobs that make its inputs}, in plan order."""
    made_by = {o: j.key for j in plan.jobs for o in j.outputs}
    return {j.key: list(dict.fromkeys(made_by[i] for i in j.inputs if i in made_by))
            for j in plan.jobs}


def check_graph(plan: Plan) -> list[str]:
    """Refuse what would fail before anything runs; return the keys in a runnable order.

    Raises
    ------
    PlanError : a key or an output used twice, an input that neither exists nor is made
        by a job, or a cycle (named by its keys).
    """
    seen: dict[str, Job] = {}
    made_by: dict[str, str] = {}
    for j in plan.jobs:
        if j.key in seen:
            raise PlanError(f"job {j.key!r} is named twice", path=plan.path,
                            fix="give each job its own key")
        seen[j.key] = j
        for o in j.outputs:
            if o in made_by:
                raise PlanError(f"jobs {made_by[o]!r} and {j.key!r} both write {o}",
                                path=plan.path, fix="give each job its own output")
            made_by[o] = j.key
    for j in plan.jobs:
        for i in j.inputs:
            if i not in made_by and not os.path.exists(i):
                raise PlanError(f"job {j.key!r}: input {i} does not exist and no job makes it",
                                path=plan.path,
                                fix="check the path (relative to the plan) or add the job "
                                    "that writes it")
    deps = dependencies(plan)
    order: list[str] = []
    waiting = {k: set(d) for k, d in deps.items()}
    ready = deque(k for k, d in waiting.items() if not d)
    users: dict[str, list[str]] = {}
    for k, d in deps.items():
        for x in d:
            users.setdefault(x, []).append(k)
    while ready:
        k = ready.popleft()
        order.append(k)
        for u in users.get(k, []):
            waiting[u].discard(k)
            if not waiting[u]:
                ready.append(u)
    if len(order) < len(plan.jobs):
        placed = set(order)
        stuck = [k for k in deps if k not in placed]
        cycle = _find_cycle(stuck, deps)
        raise PlanError(f"the jobs form a cycle: {' -> '.join(cycle)}", path=plan.path,
                        fix="a job cannot need, even through others, what it writes")
    return order


def _find_cycle(stuck: list[str], deps: Mapping[str, list[str]]) -> list[str]:
    """One cycle among ``stuck`` (each has a dependency in it), as keys k0 -> … -> k0."""
    path, k = [], stuck[0]
    while k not in path:
        path.append(k)
        k = next(d for d in deps[k] if d in stuck)
    return path[path.index(k):] + [k]
