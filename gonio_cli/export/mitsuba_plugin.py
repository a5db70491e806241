"""A gonio material as a Mitsuba 3 BSDF (written by ``gonio export --to mitsuba``).

Copied verbatim as ``gonio_bsdf.py`` into the export folder, beside
``gonio_drjit_brdf.py`` (the Dr.Jit port of gonio's models) and ``bsdf_params.json``
(the material's parameters, its lobes and their sampling weights). Needs only ``mitsuba``
and ``drjit``::

    import mitsuba as mi
    mi.set_variant("llvm_ad_spectral")      # or scalar_spectral, scalar_rgb, llvm_ad_rgb
    import gonio_bsdf                       # from the export folder
    gonio_bsdf.register()                   # <bsdf type="gonio"> in scene files
    scene = mi.load_file("scene.xml")

``eval`` returns f · cos θo in Mitsuba's convention (gonio's BRDF f has no cosine; the
light's direction is Mitsuba's ``wo``). Spectral variants evaluate the spectral
parameters at the wavelengths a path carries (linear interpolation on the material's
grid, held constant beyond its ends); RGB variants sum f over the material's grid with
the weights ``rgb_weights`` (linear sRGB of the reflectance under D65), which is exact for
light of D65's colour.

``sample`` draws one lobe with the probabilities ``lobes[].probability`` (proportional to
an albedo estimate of each lobe, see ``gonio_cli/export/mitsuba.py``) and from it: the
cosine-weighted hemisphere for a diffuse term, the distribution of visible normals for
a GGX or Beckmann lobe (Mitsuba's ``MicrofacetDistribution``, Heitz 2018), reflected. The
pdf is the mixture of every lobe's pdf at the sampled direction, so sample's weight is
eval / pdf exactly.
"""

from __future__ import annotations

import functools
import importlib.util
import json
from pathlib import Path

import drjit as dr
import mitsuba as mi

HERE = Path(__file__).resolve().parent

#: Floor of ωo·m in the reflection Jacobian 1/(4 ωo·m): m is the half vector of two
#: upper-hemisphere directions, so ωo·m > 0 except at ωo = −ωi (never lit and seen).
MIN_DOT = 1e-12

#: The parameter file's schema this plugin reads.
SCHEMA = "gonio.mitsuba-bsdf"
SCHEMA_VERSION = 1


@functools.lru_cache(maxsize=None)
def _port():
    """The Dr.Jit port of gonio's models, from this folder (``gonio_drjit_brdf.py``)."""
    spec = importlib.util.spec_from_file_location("gonio_drjit_brdf",
                                                  HERE / "gonio_drjit_brdf.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def read_params(path) -> dict:
    """The ``bsdf_params.json`` document, checked for its schema and version."""
    path = Path(path)
    doc = json.loads(path.read_text(encoding="utf-8"))
    if doc.get("schema") != SCHEMA or doc.get("schema_version") != SCHEMA_VERSION:
        raise ValueError(f"{path}: not a {SCHEMA} v{SCHEMA_VERSION} file "
                         f"(schema {doc.get('schema')!r} v{doc.get('schema_version')!r}); "
                         "export it again with gonio export --to mitsuba")
    return doc


class GonioMethods:
    """A fitted gonio material (``bsdf_params.json``), see the module docstring: the
    methods of the BSDF, which :func:`bsdf_class` puts on the active variant's ``mi.BSDF``."""

    def __init__(self, props):
        mi.BSDF.__init__(self, props)
        name = props["params"] if "params" in props else "bsdf_params.json"
        path = Path(name) if Path(name).is_absolute() else HERE / name
        doc = read_params(path)
        self.port = _port()
        self.model = doc["model"]
        self.evaluate = self.port.MODELS[self.model]
        self.scalar = {k: float(v) for k, v in doc["scalar_params"].items()}
        self.tables = {k: [float(x) for x in v] for k, v in doc["spectral_params"].items()}
        wl = doc["wavelength_nm"]
        self.lambda_0, self.step_nm, self.n = float(wl[0]), float(wl[1] - wl[0]), len(wl)
        self.rgb_weights = [[float(x) for x in row] for row in doc["rgb_weights"]]
        self.scalar_variant = mi.variant().startswith("scalar")
        if self.scalar_variant:  # a whole grid at once in the RGB path, gathers else
            self.tables_dr = {k: dr.scalar.ArrayXf(v) for k, v in self.tables.items()}
            self.rgb_weights_dr = [dr.scalar.ArrayXf(row) for row in self.rgb_weights]
        else:
            self.tables_dr = {k: mi.Float(v) for k, v in self.tables.items()}
        self.lobes = []
        for lobe in doc["lobes"]:
            dist = None
            if lobe["kind"] != "diffuse":
                kind = {"ggx": mi.MicrofacetType.GGX,
                        "beckmann": mi.MicrofacetType.Beckmann}[lobe["kind"]]
                dist = mi.MicrofacetDistribution(kind, float(lobe["alpha"]), True)
            self.lobes.append((lobe["kind"], float(lobe["probability"]), dist))
        flags = mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide
        if any(kind == "diffuse" for kind, _, _ in self.lobes):
            flags = flags | mi.BSDFFlags.DiffuseReflection
        self.m_flags = flags
        self.m_components = [flags]

    # ---------------------------------------------------------------- spectra --
    def _at(self, name, wavelengths):
        """Spectral parameter ``name`` at the path's wavelengths (linear on the grid)."""
        out = []
        for k in range(len(wavelengths)):
            t = dr.clip((wavelengths[k] - self.lambda_0) / self.step_nm, 0.0, self.n - 1.0)
            i = dr.minimum(dr.floor(t), self.n - 2.0)
            u = t - i
            if self.scalar_variant:
                a, b = self.tables[name][int(i)], self.tables[name][int(i) + 1]
            else:
                j = mi.UInt32(i)
                a = dr.gather(mi.Float, self.tables_dr[name], j)
                b = dr.gather(mi.Float, self.tables_dr[name], j + 1)
            out.append(a * (1.0 - u) + b * u)
        return mi.UnpolarizedSpectrum(*out)

    def _f(self, si, cos):
        """gonio's f (no cosine) as a Mitsuba spectrum."""
        if mi.is_spectral:
            params = dict(self.scalar)
            params.update({k: self._at(k, si.wavelengths) for k in self.tables})
            return self.evaluate(cos, **params)
        params = dict(self.scalar)
        if self.scalar_variant:                  # f on the whole grid, weighted to RGB
            params.update(self.tables_dr)
            f = self.evaluate(cos, **params)
            return mi.UnpolarizedSpectrum(*(dr.sum(w * f) for w in self.rgb_weights_dr))
        rgb = [0.0, 0.0, 0.0]
        for k in range(self.n):                  # the material's grid, weighted to RGB
            params = dict(self.scalar)
            params.update({name: t[k] for name, t in self.tables.items()})
            f = self.evaluate(cos, **params)
            rgb = [rgb[c] + self.rgb_weights[c][k] * f for c in range(3)]
        return mi.UnpolarizedSpectrum(rgb[0], rgb[1], rgb[2])

    # --------------------------------------------------------------- sampling --
    def _pdf(self, wi, wo):
        pdf = mi.Float(0.0)
        m = dr.normalize(wi + wo)
        for kind, p, dist in self.lobes:
            if dist is None:
                pdf += p * mi.warp.square_to_cosine_hemisphere_pdf(wo)
            else:
                pdf += p * dist.pdf(wi, m) / (4.0 * dr.maximum(dr.dot(wo, m), MIN_DOT))
        return pdf

    def _lit(self, wi, wo):
        return (mi.Frame3f.cos_theta(wi) > 0) & (mi.Frame3f.cos_theta(wo) > 0)

    def eval(self, ctx, si, wo, active=True):
        active = self._lit(si.wi, wo) & active
        f = self._f(si, self.port.cosines(wo, si.wi))
        value = f * mi.Frame3f.cos_theta(wo)
        return dr.select(active, value, 0.0)

    def pdf(self, ctx, si, wo, active=True):
        active = self._lit(si.wi, wo) & active
        return dr.select(active, self._pdf(si.wi, wo), 0.0)

    def eval_pdf(self, ctx, si, wo, active=True):
        return self.eval(ctx, si, wo, active), self.pdf(ctx, si, wo, active)

    def sample(self, ctx, si, sample1, sample2, active=True):
        wi = si.wi
        wo = mi.Vector3f(0.0)
        low = 0.0
        for j, (kind, p, dist) in enumerate(self.lobes):
            last = j == len(self.lobes) - 1       # takes round-off of the sum too
            chosen = (sample1 >= low) & ((sample1 < low + p) | last)
            if dist is None:
                w = mi.warp.square_to_cosine_hemisphere(sample2)
            else:
                m, _ = dist.sample(wi, sample2)
                w = mi.reflect(wi, m)
            wo = dr.select(chosen, w, wo)
            low += p
        active = self._lit(wi, wo) & active
        bs = dr.zeros(mi.BSDFSample3f)
        bs.wo = wo
        bs.pdf = dr.select(active, self._pdf(wi, wo), 0.0)
        bs.eta = 1.0
        bs.sampled_type = mi.UInt32(+mi.BSDFFlags.GlossyReflection)
        bs.sampled_component = mi.UInt32(0)
        active = active & (bs.pdf > 0)
        f = self._f(si, self.port.cosines(wo, wi))
        weight = f * mi.Frame3f.cos_theta(wo) / dr.select(active, bs.pdf, 1.0)
        return bs, dr.select(active, weight, 0.0)

    def traverse(self, callback):
        pass

    def to_string(self):
        return f"GonioBSDF[model={self.model}]"


def bsdf_class():
    """The BSDF class for the active Mitsuba variant (a class per variant: ``mi.BSDF``
    differs between them): :class:`GonioMethods` on ``mi.BSDF`` (copied, as nanobind's
    classes take one base)."""
    methods = {k: v for k, v in vars(GonioMethods).items()
               if k not in ("__dict__", "__weakref__")}
    return type("GonioBSDF", (mi.BSDF,), methods)


def register() -> None:
    """Register ``<bsdf type="gonio">`` for the active variant (after ``mi.set_variant``)."""
    cls = bsdf_class()
    mi.register_bsdf("gonio", lambda props: cls(props))
