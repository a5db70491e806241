"""One ``[[object]]`` of a scene file (:mod:`.scene`) → :class:`~.scene_types.SceneObject`:
its mesh and placement, what covers it (a material, three inks with a mask, or a
measurement), its lobes, its sparkle texture (seed 004 eq. 17) and its glints, each key
checked by the scene's :class:`~.scene_check.Checker` (one line naming the file and key)."""

from __future__ import annotations

import os

import numpy as np

from ..schemas import EXPONENT_RANGE, MAX_MAGNITUDE
from .measured import DEFAULT_INTERPOLATION, INTERPOLATIONS
from .scene_check import Checker
from .scene_types import BUILTIN_MESHES, BUILTIN_PREFIX, SceneObject, Substrate
from .texture import DEFAULT_WRAP, WRAP_MODES

OBJECT_KEYS = ("name", "mesh", "translate", "rotate_deg", "scale", "material", "inks",
               "mask", "substrate", "lobes", "measured", "sparkle", "sparkle_color",
               "sparkle_exponent", "sparkle_scale", "wrap", "glint_density", "glint_share",
               "glint_angle_deg", "glint_seed", "interpolation")
#: Keys that belong to an object with a ``sparkle`` texture (seed 004 §6).
SPARKLE_KEYS = ("sparkle_color", "sparkle_exponent", "sparkle_scale")
#: Keys that belong to an object with ``glint_density`` (docs/render.md, "Glints").
GLINT_KEYS = ("glint_share", "glint_angle_deg", "glint_seed")
SUBSTRATE_KEYS = ("kd", "ks", "shininess")

def scene_object(chk: Checker, raw, number: int) -> SceneObject:
    """The ``[[object]]`` table number ``number`` (from 1): its mesh and placement, one of
    material, inks (with mask, substrate and wrap) or measured, its lobes, sparkle texture
    and glints, every key checked."""
    where = f"[[object]] {number}"
    o = chk.table(raw, where)
    chk.keys(o, OBJECT_KEYS, where)
    mesh = _mesh(chk, o, where)
    scale = o.get("scale", 1.0)
    if isinstance(scale, list):
        scale = chk.vector(scale, f"{where} scale")
    else:
        scale = np.full(3, chk.number(scale, f"{where} scale", lo=-MAX_MAGNITUDE,
                                      hi=MAX_MAGNITUDE))
    if np.any(scale == 0.0):
        raise chk.error(f"{where} scale", "is zero: the object would be flat or a point")
    obj = SceneObject(
        number - 1, mesh,
        chk.vector(o.get("translate", [0.0, 0.0, 0.0]), f"{where} translate"),
        chk.vector(o.get("rotate_deg", [0.0, 0.0, 0.0]), f"{where} rotate_deg"),
        scale, name=chk.string(o.get("name", f"object{number}"), f"{where} name"))

    kinds = [k for k in ("material", "inks", "measured") if k in o]
    if len(kinds) != 1:
        raise chk.error(where, ("needs one of" if not kinds else "has more than one of")
                        + " material, inks (with mask) or measured",
                        fix="a plain object names a material, a print names inks and a mask")
    if "material" in o:
        obj.material = chk.file(o["material"], f"{where} material")
    elif "measured" in o:
        obj.measured = chk.file(o["measured"], f"{where} measured")
        obj.interpolation = chk.choice(o.get("interpolation", DEFAULT_INTERPOLATION),
                                       f"{where} interpolation", tuple(INTERPOLATIONS))
    else:
        inks = o["inks"]
        if not isinstance(inks, list) or len(inks) != 3:
            raise chk.error(f"{where} inks", f"{inks!r} is not a list of 3 material paths "
                            "(R, G, B)")
        obj.inks = [chk.file(p, f"{where} inks[{k}]") for k, p in enumerate(inks)]
        obj.mask = chk.file(chk.required(o, "mask", where), f"{where} mask")
        sub = chk.table(o.get("substrate", {}), f"{where} substrate")
        chk.keys(sub, SUBSTRATE_KEYS, f"{where} substrate")
        obj.substrate = Substrate(
            chk.number(sub.get("kd", 0.0), f"{where} substrate.kd", lo=0.0, hi=1.0),
            chk.number(sub.get("ks", 0.0), f"{where} substrate.ks", lo=0.0, hi=1.0),
            chk.number(sub.get("shininess", 1.0), f"{where} substrate.shininess", lo=0.0,
                       hi=EXPONENT_RANGE[1]))
        obj.wrap = chk.choice(o.get("wrap", DEFAULT_WRAP), f"{where} wrap", tuple(WRAP_MODES))
    if "interpolation" in o and obj.measured is None:
        raise chk.error(f"{where} interpolation", "belongs to a measured object")
    for key in ("mask", "substrate", "wrap"):
        if key in o and obj.inks is None:
            raise chk.error(f"{where} {key}", "belongs to a printed object (with inks)")
    if "lobes" in o:
        lobes = o["lobes"]
        if obj.inks is not None:
            if not isinstance(lobes, list) or len(lobes) != 3:
                raise chk.error(f"{where} lobes", "a printed object needs 3 lobes files "
                                "(one per ink)")
            obj.lobes = [chk.file(p, f"{where} lobes[{k}]") for k, p in enumerate(lobes)]
        elif obj.material is not None:
            obj.lobes = chk.file(lobes, f"{where} lobes")
        else:
            raise chk.error(f"{where} lobes", "a measured object has no lobes")
    _sparkle(chk, o, obj, where)
    _glints(chk, o, obj, where)
    return obj


def _mesh(chk: Checker, o: dict, where: str) -> str:
    """An object's ``mesh``: ``builtin:NAME`` (one of :data:`BUILTIN_MESHES`, options after
    ``?``) or the absolute path of an OBJ file that exists."""
    mesh = chk.string(chk.required(o, "mesh", where), f"{where} mesh")
    if not mesh.startswith(BUILTIN_PREFIX):
        return os.fspath(chk.file(mesh, f"{where} mesh"))
    if mesh[len(BUILTIN_PREFIX):].partition("?")[0] not in BUILTIN_MESHES:
        raise chk.error(f"{where} mesh", f"{mesh!r} is not a built-in mesh",
                        fix="use " + ", ".join(BUILTIN_PREFIX + m for m in BUILTIN_MESHES)
                        + " or an OBJ file")
    return mesh


def _sparkle(chk: Checker, o: dict, obj: SceneObject, where: str) -> None:
    """An object's sparkle texture and its colour, exponent and scale (seed 004 eq. 17);
    refused on a print, and the sparkle keys without a texture."""
    if "sparkle" in o:
        if obj.inks is not None:
            raise chk.error(f"{where} sparkle", "belongs to a material or measured object, "
                            "not a print", fix="sparkles are for metallic paint")
        obj.sparkle = chk.file(o["sparkle"], f"{where} sparkle")
        if "sparkle_color" in o:
            obj.sparkle_color = chk.vector(o["sparkle_color"], f"{where} sparkle_color")
            if np.any(obj.sparkle_color < 0):
                raise chk.error(f"{where} sparkle_color",
                                f"{obj.sparkle_color.tolist()} has a negative channel")
        obj.sparkle_exponent = chk.number(o.get("sparkle_exponent", 24.0),
                                          f"{where} sparkle_exponent", lo=0.0, lo_open=True,
                                          hi=EXPONENT_RANGE[1])
        obj.sparkle_scale = chk.number(o.get("sparkle_scale", 1.0), f"{where} sparkle_scale",
                                       lo=0.0, lo_open=True, hi=MAX_MAGNITUDE)
    else:
        for key in SPARKLE_KEYS:
            if key in o:
                raise chk.error(f"{where} {key}", "needs a sparkle texture",
                                fix='add sparkle = "SPARKLE.png" (gonio sparkle)')


def _glints(chk: Checker, o: dict, obj: SceneObject, where: str) -> None:
    """``glint_density`` and its keys (docs/render.md, "Glints"): a material object only,
    not beside a sparkle texture (both would draw the same flakes)."""
    if "glint_density" not in o:
        for key in GLINT_KEYS:
            if key in o:
                raise chk.error(f"{where} {key}", "needs glint_density",
                                fix="add glint_density = FLAKES_PER_SQUARE_UNIT")
        return
    if obj.material is None:
        raise chk.error(f"{where} glint_density", "belongs to a material object",
                        fix="glints draw the flake lobe of a fitted cook-torrance paint")
    if obj.sparkle is not None:
        raise chk.error(f"{where} glint_density", "and sparkle both draw the flakes",
                        fix="keep glint_density (glints) or sparkle (seed 004 eq. 17), "
                            "not both")
    obj.glint_density = chk.number(o["glint_density"], f"{where} glint_density", lo=0.0,
                                   lo_open=True, hi=MAX_MAGNITUDE)
    obj.glint_share = chk.number(o.get("glint_share", obj.glint_share),
                                 f"{where} glint_share", lo=0.0, hi=1.0)
    obj.glint_angle_deg = chk.number(o.get("glint_angle_deg", obj.glint_angle_deg),
                                     f"{where} glint_angle_deg", lo=0.0, hi=10.0)
    obj.glint_seed = chk.integer(o.get("glint_seed", 0), f"{where} glint_seed", lo=0,
                                 hi=2 ** 32 - 1)
