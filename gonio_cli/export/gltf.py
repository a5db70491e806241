"""A fitted material as a glTF 2.0 binary (``gonio export --to gltf``) and its report.

:func:`export_gltf` writes

* ``NAME.glb`` — a preview mesh (the unit UV sphere of ``builtin:sphere``,
  :func:`gonio_cli.render.mesh.uv_sphere`, with its normals; no texture, so no texture
  coordinates) and
  one material: glTF 2.0's metallic-roughness PBR with ``KHR_materials_specular``,
  ``KHR_materials_ior`` and, when the fit wants them, ``KHR_materials_clearcoat`` and
  ``KHR_materials_iridescence``
  (none *required*: a viewer without them still shows the core material). The
  parameters are a fit of glTF's own BRDF to the material
  (:mod:`gonio_cli.export.gltf_fit`), rounded to
  :data:`gonio_cli.export.judge.DIGITS` decimals as written;
* ``NAME.glb.report.json`` (``gonio.export-report`` v1) — the written parameters judged
  against the material (:mod:`gonio_cli.export.judge`): per configuration CIEDE2000,
  mean, p95, worst, and the material's own fit error beside it.

Written with pygltflib; both files atomically.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import __version__
from ..errors import InputError
from ..render.mesh import uv_sphere
from . import check_file_output, get_target
from .gltf_brdf import GltfMaterial, gltf_brdf
from .gltf_fit import fit_gltf
from .judge import Fitted, export_judged

#: φ segments of the preview sphere (rings = half): 4 032 triangles, smooth in a viewer.
PREVIEW_SEGMENTS = 64

#: The extensions a written material may use (all ratified; none is required).
EXTENSIONS = ("KHR_materials_specular", "KHR_materials_ior", "KHR_materials_clearcoat",
              "KHR_materials_iridescence")


def _accessor(gltf, blob: bytearray, array: np.ndarray, kind: str, target: int,
              with_bounds: bool = False) -> int:
    """Append ``array`` to the buffer as a buffer view + accessor; returns its index."""
    import pygltflib as g

    offset = len(blob)
    blob += array.tobytes()
    blob += b"\0" * (-len(blob) % 4)                  # each view 4-byte aligned
    gltf.bufferViews.append(g.BufferView(buffer=0, byteOffset=offset,
                                         byteLength=array.nbytes, target=target))
    ctype = g.UNSIGNED_INT if array.dtype == np.uint32 else g.FLOAT
    acc = g.Accessor(bufferView=len(gltf.bufferViews) - 1, componentType=ctype,
                     count=int(array.shape[0]), type=kind)
    if with_bounds:
        acc.min = [float(x) for x in array.min(axis=0)]
        acc.max = [float(x) for x in array.max(axis=0)]
    gltf.accessors.append(acc)
    return len(gltf.accessors) - 1


def _material(m: GltfMaterial):
    import pygltflib as g

    ext = {"KHR_materials_specular": {"specularFactor": m.specular,
                                      "specularColorFactor": list(m.specular_color)},
           "KHR_materials_ior": {"ior": m.ior}}
    if m.clearcoat > 0:
        ext["KHR_materials_clearcoat"] = {"clearcoatFactor": m.clearcoat,
                                          "clearcoatRoughnessFactor": m.clearcoat_roughness}
    if m.iridescence > 0:
        # no thickness texture: the film is iridescenceThicknessMaximum thick; the
        # minimum (used only with a texture) is written equal to it
        ext["KHR_materials_iridescence"] = {
            "iridescenceFactor": m.iridescence, "iridescenceIor": m.iridescence_ior,
            "iridescenceThicknessMinimum": m.iridescence_thickness_nm,
            "iridescenceThicknessMaximum": m.iridescence_thickness_nm}
    pbr = g.PbrMetallicRoughness(baseColorFactor=[*m.base_color, 1.0],
                                 metallicFactor=m.metallic, roughnessFactor=m.roughness)
    return g.Material(name=m.name or None, pbrMetallicRoughness=pbr, extensions=ext), list(ext)


def glb_bytes(m: GltfMaterial, extras: dict | None = None) -> bytes:
    """The ``.glb`` of material ``m`` on the preview sphere (module docstring)."""
    import pygltflib as g

    mesh = uv_sphere(PREVIEW_SEGMENTS)
    pos = np.asarray(mesh.vertices, dtype=np.float32)
    nrm = np.asarray(mesh.normals, dtype=float)
    nrm = (nrm / np.linalg.norm(nrm, axis=1, keepdims=True)).astype(np.float32)
    gltf = g.GLTF2(asset=g.Asset(version="2.0", generator=f"gonio {__version__} export"),
                   scene=0, scenes=[g.Scene(nodes=[0])], nodes=[g.Node(mesh=0, name="preview")])
    blob = bytearray()
    attrs = g.Attributes(
        POSITION=_accessor(gltf, blob, pos, g.VEC3, g.ARRAY_BUFFER, with_bounds=True),
        NORMAL=_accessor(gltf, blob, nrm, g.VEC3, g.ARRAY_BUFFER))
    faces = np.asarray(mesh.faces, dtype=np.uint32).ravel()
    indices = _accessor(gltf, blob, faces, g.SCALAR, g.ELEMENT_ARRAY_BUFFER)
    gltf.meshes = [g.Mesh(name="sphere", primitives=[
        g.Primitive(attributes=attrs, indices=indices, material=0)])]
    material, used = _material(m)
    gltf.materials = [material]
    gltf.extensionsUsed = used
    if extras:
        gltf.asset.extras = extras
    gltf.buffers = [g.Buffer(byteLength=len(blob))]
    gltf.set_binary_blob(bytes(blob))
    return b"".join(gltf.save_to_bytes())


def export_gltf(material, material_path, out, scene_path=None, variables=None
                ) -> tuple[list[Path], dict]:
    """Fit, write and judge: ``out`` (``NAME.glb``) and its report; returns both paths and
    the report's payload.
    ``scene_path``/``variables`` are refused (the target writes a preview, not a scene)."""
    if scene_path is not None or variables:
        raise InputError("--scene: --to gltf writes the material on a preview sphere, "
                         "not a scene", fix="leave out --scene and --var")
    check_file_output(out, get_target("gltf"))
    return export_judged(Fitted("gltf", fit_gltf, gltf_brdf, glb_bytes), material,
                         material_path, out)
