"""Render this folder's scene with Mitsuba 3 (written by ``gonio export --to mitsuba``).

    python render.py [-o image.exr] [--variant llvm_ad_spectral] [--spp 256] [--xyz]

``scene.xml`` is the material (``<bsdf type="gonio">``, ``gonio_bsdf.py``) on the unit
sphere under the lights and camera of the gonio scene it was exported with
(``gonio_scene.toml`` renders the same with ``gonio render``). The EXR holds linear sRGB,
or CIE XYZ with ``--xyz``, before any tone mapping.
"""

from __future__ import annotations

import argparse
import importlib.util
from pathlib import Path

HERE = Path(__file__).resolve().parent

#: Tried in this order when --variant is not given (LLVM is much faster for a Python BSDF;
#: it is used only if a probe compiles, :func:`llvm_works`).
VARIANTS = ("llvm_ad_spectral", "scalar_spectral")

#: A kernel every BSDF needs (a maximum): with an LLVM that Dr.Jit cannot drive (LLVM 15
#: with Dr.Jit 1.5) compiling it aborts the process, so it is tried in a child process.
LLVM_PROBE = ("import drjit as dr, mitsuba as mi; mi.set_variant('llvm_ad_spectral'); "
              "dr.eval(dr.maximum(dr.arange(mi.Float, 8), 1.0))")


def llvm_works() -> bool:
    """Does a Dr.Jit LLVM kernel compile and run here (in a child process)?"""
    import subprocess
    import sys

    try:
        return subprocess.run([sys.executable, "-c", LLVM_PROBE], capture_output=True,
                              timeout=120).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False


def load_scene(variant: str | None = None, spp: int = 256, xyz: bool = False):
    """Set the variant, register the plugin, load ``scene.xml``; return the scene."""
    import mitsuba as mi

    if variant is None:
        llvm = "llvm_ad_spectral" in mi.variants() and llvm_works()
        variant = VARIANTS[0] if llvm else VARIANTS[1]
    mi.set_variant(variant)
    spec = importlib.util.spec_from_file_location("gonio_bsdf", HERE / "gonio_bsdf.py")
    plugin = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(plugin)
    plugin.register()
    return mi.load_file(str(HERE / "scene.xml"), spp=spp,
                        pixel_format="xyz" if xyz else "rgb")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", default=str(HERE / "mitsuba.exr"))
    parser.add_argument("--variant", default=None)
    parser.add_argument("--spp", type=int, default=256)
    parser.add_argument("--xyz", action="store_true")
    args = parser.parse_args()
    import mitsuba as mi

    scene = load_scene(args.variant, args.spp, args.xyz)
    image = mi.render(scene)
    mi.Bitmap(image).write(args.output)
    print(f"{args.output}: {mi.variant()}, {args.spp} spp")


if __name__ == "__main__":
    main()
