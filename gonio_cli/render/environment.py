"""Environment light from prefiltered maps and lobe weights (seed 001 §5, eqs. 7-9).

With the normalised prefiltered maps P_E of ``gonio prefilter`` (docs/conventions.md,
``docs/prefilter.md``: P_E(r) = ∫ L max(0, r·ω)^E dω / ∫ max(0, r·ω)^E dω, and
∫ max(0, r·ω)^E dω = 2π/(E+1)) and the lobe weights of ``gonio lobes fit``
(``docs/lobes.md``), the reflected radiance of seed 001 eqs. 7-9 is

    L_o = K_D π P_1(N)                                         (eq. 9, diffuse)
        + (R·N) Σ_i K_DD,i 2π/(E_i+1) P_Ei(R)                  (eq. 7, directional diffuse)
        + Σ_i K_G,i 2π/(E_i+1) P_Ei(R)                         (eq. 8, gloss)

with R = 2 (N·V) N − V the mirrored view direction (so R·N = N·V) and N the normal. The
weights K come as a table over view angle θv = acos(N·V) (seed 001 §5.2) and are
interpolated linearly in θv; outside the table's range the nearest row is used.

The maps hold linear sRGB. docs/conventions.md turns an RGB radiance into the spectrum
D65(λ) Σ_c rgb_c B_c(λ) (Mallett–Yuksel 2019 basis B_c, D65 with Y = 1). Everything is
linear, so each term is precomputed per table row as a 3 × 3 matrix from map channel c to
XYZ j:

* spectral weights K(λ):  M[c, j] = Σλ K(λ) D65(λ) B_c(λ) cmf_j(λ) / Σ ȳ  (exact);
* XYZ weights K_j (``--channels xyz``, which are the XYZ of the spectral weights under
  equal energy): M[c, j] = K_j · X_j(D65 B_c) / X_j(equal energy), a per-channel product
  (von Kries-like) approximation, exact for a spectrally flat K.

Only the maps whose lobes have a non-zero weight somewhere in the table are read (lazily,
once per :class:`Environment`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import log
from ..envmap import lookup
from ..errors import ArtifactError, InputError
from ..geometry import reflect
from ..imageio import read_image
from ..lobes import lobe_integral, phong_normalisation
from ..lobes.energy import lobe_energy
from ..schemas import Lobes, MAX_MAGNITUDE, PrefilterIndex, read_prefilter_index
from ..spectra import cmf_weights, luminance, rgb_spectral_basis, same_grid
from . import Light

#: Pixels per block of :func:`environment_xyz`, so the lookups' temporaries (4 corners ×
#: 3 channels × lobes) stay in cache: 0.43 s instead of 0.9 s at 512² (8 lobes).
ENV_BLOCK = 8192

#: Two exponents closer than this (relative) are the same lobe: the index stores the
#: exponents of the lobes file as full floats, but a hand-written scene may round them.
EXPONENT_RTOL = 1e-6


@dataclass
class Environment:
    """A prefiltered environment (``gonio prefilter`` OUTDIR, read by :func:`load_environment`).

    Attributes
    ----------
    path : the ``index.json`` read.
    exponents : (k,) float, the exponent of every map, increasing; 1 is the diffuse map.
    files : (k,) paths of the maps (EXR, float linear sRGB, lat-long, docs/conventions.md).
    shapes : (k,) (height, width) the index promises for each map.
    maps : exponent → (H, W, 3) float32 array, filled on first use (:meth:`map`), and
        the float64 stacks of :meth:`stacked`.
    tables : the lobe tables of :func:`gonio_cli.render.env_model.tables_for`, by key.
    sun : the index's ``sun`` (``gonio prefilter --sun``), or None: :func:`sun_light`.
    """

    path: str
    exponents: np.ndarray
    files: list[str]
    shapes: list[tuple[int, int]]
    maps: dict = field(default_factory=dict)
    tables: dict = field(default_factory=dict)
    sun: dict | None = None

    def index_of(self, exponent: float, where: str = "") -> int:
        """Index of the map of ``exponent`` (within :data:`EXPONENT_RTOL`), or an error."""
        k = np.flatnonzero(np.abs(self.exponents - exponent) <= EXPONENT_RTOL * exponent)
        if k.size == 0:
            raise InputError(f"{where}lobe exponent {exponent:g} has no prefiltered map "
                             f"(the environment has {', '.join(f'{e:g}' for e in self.exponents)})",
                             path=self.path,
                             fix="prefilter the map for these lobes: gonio prefilter ENV.exr "
                                 "--lobes LOBES.json -o OUTDIR")
        return int(k[0])

    def has(self, exponent: float) -> bool:
        return bool(np.any(np.abs(self.exponents - exponent) <= EXPONENT_RTOL * exponent))

    def map(self, exponent: float, where: str = "") -> np.ndarray:
        """The (H, W, 3) float32 map of ``exponent``, read and validated on first use."""
        k = self.index_of(exponent, where)
        e = float(self.exponents[k])
        if e not in self.maps:
            self.maps[e] = _read_map(self.files[k], self.shapes[k])
        return self.maps[e]

    def groups(self, exponents, where: str = "") -> list[tuple[float, ...]]:
        """``exponents`` grouped by the size of their maps (one lookup per group)."""
        by_shape: dict[tuple[int, int], list[float]] = {}
        for e in exponents:
            k = self.index_of(e, where)
            by_shape.setdefault(tuple(self.shapes[k]), []).append(float(e))
        return [tuple(g) for g in by_shape.values()]

    def stacked(self, exponents: tuple[float, ...]) -> np.ndarray:
        """The maps of ``exponents`` (all of one size) side by side along the channel axis:
        (H, W, 3 × len), cached, so one bilinear lookup serves every lobe."""
        key = ("stacked",) + tuple(exponents)
        if key not in self.maps:                     # float64: lookup would convert it
            self.maps[key] = np.concatenate([self.map(e) for e in exponents],
                                            axis=2).astype(np.float64)
        return self.maps[key]

    def level(self, i: int) -> np.ndarray:
        """The map of ``exponents[i]`` ((H, W, 3) float32, read on first use): a level of
        the chain the lobes of :mod:`.env_model` mix; maps no lobe uses are never read."""
        return self.map(float(self.exponents[i]))

    @property
    def diffuse(self) -> np.ndarray:
        """P_1, the diffuse map (irradiance / π), looked up with the normal (eq. 9)."""
        return self.map(1.0)


def _read_map(path: str, shape: tuple[int, int]) -> np.ndarray:
    """Read one prefiltered map; refuse a wrong size, an 8-bit image, NaN or negatives."""
    img = read_image(path)
    px = img.pixels
    if not img.is_float:
        raise ArtifactError(f"is {img.format}, not a float (HDR) map", path=path,
                            fix="regenerate it with gonio prefilter")
    if px.shape[:2] != tuple(shape) or px.shape[2] < 3:
        raise ArtifactError(f"is {px.shape[1]} × {px.shape[0]} × {px.shape[2]}, the index says "
                            f"{shape[1]} × {shape[0]} × 3", path=path,
                            fix="regenerate the folder with gonio prefilter")
    px = np.ascontiguousarray(px[:, :, :3], dtype=np.float32)
    bad = ~((px >= 0) & (px <= MAX_MAGNITUDE))          # NaN, inf, negative or huge
    if np.any(bad):
        r, c, _ = np.argwhere(bad)[0]
        raise ArtifactError(f"texel (row {r}, col {c}) is {px[r, c].tolist()} "
                            f"({int(bad.any(axis=2).sum())} bad texels)", path=path,
                            fix="regenerate it with gonio prefilter --fix-invalid")
    return px


def load_environment(index_json_path: str | os.PathLike) -> Environment:
    """Read the ``index.json`` of a prefiltered environment (``docs/prefilter.md``).

    The maps themselves are read on first use (:meth:`Environment.map`), so lobes no
    object uses cost nothing. Missing files, a missing diffuse map (E = 1), duplicate or
    non-positive exponents are refused here, naming the file.
    """
    path = Path(index_json_path)
    index = read_prefilter_index(path)  # types, ranges and unknown keys (docs/schemas/)
    exps, files, shapes = [], [], []
    for k, entry in enumerate(index.maps):
        name = entry["path"]
        f = path.parent / name
        if not f.is_file():
            raise ArtifactError(f"field 'maps[{k}].path': {name} does not exist", path=path,
                                fix=PrefilterIndex.FIX)
        exps.append(float(entry["exponent"]))
        files.append(os.fspath(f))
        shapes.append((entry["height"], entry["width"]))
    order = np.argsort(exps)
    e = np.asarray(exps)[order]
    if np.any(np.diff(e) <= EXPONENT_RTOL * e[1:]):
        raise ArtifactError("field 'maps' lists an exponent twice", path=path,
                            fix=PrefilterIndex.FIX)
    env = Environment(os.fspath(path), e, [files[i] for i in order], [shapes[i] for i in order],
                      sun=index.sun)
    if env.sun is not None:
        for key in ("direction", "irradiance_rgb"):
            if len(env.sun[key]) != 3 or (key == "direction"
                                          and not np.linalg.norm(env.sun[key]) > 0):
                raise ArtifactError(f"field 'sun.{key}' is {env.sun[key]}, not 3 numbers"
                                    + (" of non-zero length" if key == "direction" else ""),
                                    path=path, fix=PrefilterIndex.FIX)
            if key == "irradiance_rgb" and min(env.sun[key]) < 0:
                raise ArtifactError(f"field 'sun.{key}' is {env.sun[key]}: negative",
                                    path=path, fix=PrefilterIndex.FIX)
    if not env.has(1.0):
        raise ArtifactError("has no diffuse map (exponent 1)", path=path,
                            fix="regenerate it with gonio prefilter (which always adds E = 1)")
    return env


def sun_light(environment: Environment, wavelength_nm):
    """The sun split off the map (``gonio prefilter --sun``) as a directional
    :class:`~gonio_cli.render.Light` on the working grid, or None: its linear-sRGB
    irradiance E_rgb becomes the spectrum D65 Σ_c E_c B_c (docs/conventions.md), scaled
    to Σ S ȳ / Σ ȳ = 1 with ``irradiance`` its luminance; it casts shadows whose penumbrae
    are as wide as the sun's ``angular_diameter_deg`` makes them."""
    if environment.sun is None:
        return None
    wl = np.asarray(wavelength_nm, dtype=float)
    spectrum = rgb_spectral_basis(wl) @ np.asarray(environment.sun["irradiance_rgb"], float)
    y = float(luminance(spectrum, wl))
    if not y > 0:
        return None
    d = np.asarray(environment.sun["direction"], dtype=float)
    return Light("directional", spectrum / y, direction=d / np.linalg.norm(d), irradiance=y,
                 name=f"the sun of {Path(environment.path).parent.name}", shadow=True,
                 angular_diameter_deg=float(environment.sun["angular_diameter_deg"]))


# ------------------------------------------------------------------------------ colour --

def rgb_basis(wavelength_nm) -> np.ndarray:
    """D65(λ) B_c(λ): (3, n_λ), the spectrum of unit linear-sRGB radiance per channel c
    (docs/conventions.md; Mallett & Yuksel 2019 basis, D65 scaled so (1, 1, 1) has Y = 1)."""
    return rgb_spectral_basis(wavelength_nm).T


def channel_matrices(weights: np.ndarray, channel_kind: str, wavelength_nm,
                     observer: np.ndarray | None = None) -> np.ndarray:
    """Map channel → XYZ matrices of lobe weights: (..., C) → (..., 3 rgb, 3 xyz).

    ``spectral``: Σλ K(λ) D65 B_c cmf_j / Σ ȳ. ``xyz``: K_j X_j(D65 B_c) / X_j(E) (module
    docstring). ``observer`` (n_λ, C) replaces cmf / Σ ȳ (spectral weights only:
    :func:`gonio_cli.render.kernels.xyz_weights`): the last axis then has C channels.
    """
    cm = cmf_weights(wavelength_nm) if observer is None else observer   # (n_λ, C)
    basis = rgb_basis(wavelength_nm)                         # (3, n_λ)
    k = np.asarray(weights, dtype=float)
    if channel_kind == "spectral":                           # Σλ K B_c cmf_j, one product
        return np.tensordot(k, np.einsum("cl,lj->lcj", basis, cm), axes=(-1, 0))
    if observer is not None:
        raise InputError("lobe weights fitted in XYZ channels have no spectrum, so they "
                         "cannot give a spectral image",
                         fix="fit them with gonio lobes fit --channels spectral (its "
                             "default), or leave out --spectral-exr")
    x_basis = basis @ cm                                     # (3 rgb, 3 xyz)
    x_equal = cm.sum(axis=0)                                 # XYZ of equal energy, Y = 1
    return k[..., None, :] * (x_basis / x_equal)


def check_lobes(lobes: Lobes, wavelength_nm: np.ndarray) -> None:
    """Refuse lobe weights whose channels the render cannot use (another spectral grid)."""
    if lobes.channel_kind == "spectral":
        if not same_grid(np.asarray(lobes.channels, dtype=float), wavelength_nm):
            raise InputError(f"lobe weights are on a {len(lobes.channels)}-sample grid, the "
                             f"render on {np.size(wavelength_nm)}",
                             fix="fit the lobes on the render's grid (gonio lobes fit)")
    elif lobes.channel_kind != "xyz":
        raise InputError(f"lobe channel kind {lobes.channel_kind!r} is unknown")
    check_lobe_energy(lobes)


#: The most a lobe table may reflect of uniform light (its directional albedo, π K_D +
#: Σ 2π/(E+1) (K_G + K_DD cos θv)): a real surface reflects ≤ 1; seed 001's in-plane fits
#: of a glossy coat hold up to ~40 × the material's albedo at 80° (too wide across the
#: plane: docs/lobes.md), a few units. Beyond 100 a lobe took a weight its samples do not
#: support (a sharp lobe that no sample sees, weighted 1e11: 1e6–1e14 × the albedo), and
#: the render would be that much too bright. (gonio lobes fit checks the same against the
#: material's own albedo when it fits: docs/lobes.md.)
LOBE_ALBEDO_MAX = 100.0


def check_lobe_energy(lobes: Lobes) -> None:
    """Refuse a lobe table that reflects more than :data:`LOBE_ALBEDO_MAX` × the light it
    receives at some view angle (:func:`gonio_cli.lobes.energy.lobe_energy` summed over its
    terms), naming the lobe that carries most of it."""
    terms = lobe_energy(lobes.exponents, lobes.view_angle_deg, lobes.diffuse,
                        lobes.directional_diffuse, lobes.gloss)         # (V, 1 + 2m, C)
    if not np.nanmax(terms.sum(axis=1)) > LOBE_ALBEDO_MAX:
        return
    v, k, c = np.unravel_index(np.nanargmax(terms[:, 1:]), terms[:, 1:].shape)
    i = k % lobes.exponents.size                           # K_DD columns, then K_G ones
    raise InputError(f"the lobe of exponent {lobes.exponents[i]:g} reflects "
                     f"{terms[v, 1 + k, c]:.3g} x the light it receives at view angle "
                     f"{lobes.view_angle_deg[v]:g} deg (a surface reflects at most 1): its "
                     "weight is not supported by the samples it was fitted to",
                     fix="refit with fewer or wider lobes (gonio lobes fit), or leave the "
                         "lobes out: [environment] method = 'model' needs none")


def view_interpolation(cos_theta_v: np.ndarray, view_angle_deg: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rows and weights of linear interpolation in θv = acos(N·V) over the table's views.

    Returns ``i0``, ``i1`` (n,) int and ``t`` (n,) in [0, 1]: weight (1 − t) on row i0 and
    t on row i1; θv outside the table takes its nearest end row.
    """
    views = np.asarray(view_angle_deg, dtype=float)
    theta = np.degrees(np.arccos(np.clip(cos_theta_v, -1.0, 1.0)))
    if views.size == 1:
        z = np.zeros(theta.shape, dtype=np.intp)
        return z, z, np.zeros(theta.shape)
    pos = np.interp(theta, views, np.arange(views.size, dtype=float))
    i0 = np.minimum(pos.astype(np.intp), views.size - 2)
    return i0, i0 + 1, pos - i0


def _mirror_of_view(view: np.ndarray, normal: np.ndarray, cos_v: np.ndarray) -> np.ndarray:
    """R (n, 3), the mirror of V about N (:func:`gonio_cli.geometry.reflect`) where N faces
    V, and −V where it does not (``cos_v`` = clamped N·V = 0: a smooth mesh's shading
    normal turned away at its silhouette, where no mirror direction lies above the
    surface; the clamped cosine of the view interpolation agrees)."""
    return np.where((cos_v > 0.0)[:, None], reflect(view, normal), -view)


def environment_xyz(environment: Environment, lobes: Lobes, normal: np.ndarray,
                    view: np.ndarray, wavelength_nm,
                    observer: np.ndarray | None = None,
                    diffuse_scale: np.ndarray | None = None) -> np.ndarray:
    """XYZ of environment light reflected by a lobe-fitted material, seed 001 eqs. 7-9.

    Parameters
    ----------
    environment : :class:`Environment` (its maps are read on first use).
    lobes : :class:`~gonio_cli.schemas.Lobes` of the material (a table over view angle).
    normal, view : (n, 3) unit N and V (towards the eye).
    wavelength_nm : (n_λ,) the render's grid (for spectral weights).
    observer : (n_λ, C) or None, the channels' weights instead of cmf / Σ ȳ
        (:func:`channel_matrices`); the result then has C channels.
    diffuse_scale : (n,) or None, a factor on the diffuse term (eq. 9) only: the share
        of the irradiance the scene lets through (:mod:`.occlusion`).

    Returns
    -------
    (n, 3) float64 XYZ, radiance units as :func:`gonio_cli.render.shade.shade`.

    Notes
    -----
    In blocks of :data:`ENV_BLOCK` pixels: one bilinear lookup of P_1 at N and one of all
    lobe maps of the same size at R, stacked along the channel axis (:meth:`Environment.stacked`), giving
    Q = [P_1(N), P_E(R)…, (N·V) P_E(R)…] (n, 3 + 6m'); then, per view-angle interval
    [θ_k, θ_k+1] of the table, XYZ = Q M_k + t Q (M_k+1 − M_k) with M_k the stacked
    3 × 3 channel matrices of row k (π K_D; 2π/(E+1) K_G; 2π/(E+1) K_DD): two matrix
    products per interval for all lobes at once. Lobes whose weights are 0 at every
    view angle (m' ≤ m remain) are not looked up.
    """
    wl = np.asarray(wavelength_nm, dtype=float)
    check_lobes(lobes, wl)
    normal = np.asarray(normal, dtype=float)
    view = np.asarray(view, dtype=float)
    n = normal.shape[0]
    channels = 3 if observer is None else np.shape(observer)[1]
    out = np.zeros((n, channels))
    if n == 0:
        return out
    kind = lobes.channel_kind
    v = lobes.view_angle_deg.size
    # the stacked channel matrices (V, K, 3) and, per stack of maps, its exponents
    def channel_matrices_(weights):
        return channel_matrices(weights, kind, wl, observer)

    matrices = [np.pi * channel_matrices_(lobes.diffuse)]
    used = [i for i in range(lobes.exponents.size)
            if np.any(lobes.directional_diffuse[:, i] > 0) or np.any(lobes.gloss[:, i] > 0)]
    exps = [float(lobes.exponents[i]) for i in used]
    groups = environment.groups(exps, where="lobes: ") if used else []
    for group in groups:
        idx = [used[exps.index(e)] for e in group]
        s = lobe_integral(group)[None, :, None, None]
        matrices += [(s * channel_matrices_(lobes.gloss[:, idx])).reshape(v, -1, channels),
                     (s * channel_matrices_(lobes.directional_diffuse[:, idx])
                      ).reshape(v, -1, channels)]                # eqs. 8 and 7
    m = np.concatenate(matrices, axis=1)                         # (V, K, channels)
    m = np.concatenate([m, m[-1:]], axis=0)                      # row V = row V − 1 (t = 0)
    dm = np.diff(m, axis=0)
    diffuse = environment.stacked((1.0,))
    stacks = [environment.stacked(g) for g in groups]
    for start in range(0, n, ENV_BLOCK):
        b = slice(start, start + ENV_BLOCK)
        nb, vb = normal[b], view[b]
        cos_v = np.clip(np.einsum("ij,ij->i", nb, vb), 0.0, 1.0)
        i0, _, t = view_interpolation(cos_v, lobes.view_angle_deg)
        reflected = _mirror_of_view(vb, nb, cos_v)               # R, mirror of V about N
        columns = [lookup(diffuse, nb) * (1.0 if diffuse_scale is None   # P_1(N), eq. 9
                                          else np.asarray(diffuse_scale[b], float)[:, None])]
        for stack in stacks:
            p = lookup(stack, reflected)                         # P_E(R) of every lobe
            columns += [p, cos_v[:, None] * p]
        q = np.concatenate(columns, axis=1)                      # (n_b, K)
        ob = out[b]
        for k in np.unique(i0):
            sel = i0 == k
            qs = q[sel]
            ob[sel] = qs @ m[k] + t[sel, None] * (qs @ dm[k])
    return out


def substrate_environment_xyz(environment: Environment, substrate: dict, normal: np.ndarray,
                              view: np.ndarray, wavelength_nm,
                              observer: np.ndarray | None = None,
                              diffuse_scale: np.ndarray | None = None) -> np.ndarray:
    """The Phong substrate of :mod:`.shade` under the environment: (n, 3) XYZ; its kd
    term times ``diffuse_scale`` (n,) if given (:mod:`.occlusion`).

    f cos θi = spectrum · (kd/π (L·N) + ks (n+2)/(2π) (L·N)(R_L·V)^n) is exactly a diffuse
    lobe K_D = kd/π and a directional-diffuse lobe of exponent n, so eqs. 7 and 9 apply.
    The highlight needs a map of exponent n; without one it is left out with a warning.
    """
    wl = np.asarray(wavelength_nm, dtype=float)
    spectrum = np.broadcast_to(np.asarray(substrate.get("spectrum", 1.0), dtype=float),
                               wl.shape)
    m = channel_matrices(spectrum, "spectral", wl, observer)      # (3, 3)
    kd = float(substrate.get("kd", 0.0))
    ks = float(substrate.get("ks", 0.0))
    n = float(substrate.get("shininess", 1.0))
    out = kd * (lookup(environment.diffuse, normal) @ m)
    if diffuse_scale is not None:
        out *= np.asarray(diffuse_scale, float)[:, None]
    if ks > 0:
        if environment.has(n):
            cos_v = np.clip(np.einsum("ij,ij->i", normal, view), 0.0, 1.0)
            k = ks * phong_normalisation(n) * lobe_integral(n)
            out += (k * cos_v)[:, None] * (lookup(environment.map(n), reflect(view, normal))
                                           @ m)
        else:
            log.warn(f"{environment.path}: no map of exponent {n:g}, the substrate's Phong "
                     "highlight is left out of the environment light")
    return out


__all__ = ["Environment", "load_environment", "sun_light", "environment_xyz", "substrate_environment_xyz",
           "rgb_basis", "channel_matrices", "view_interpolation"]
