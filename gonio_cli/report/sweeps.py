"""Error-against-time sweeps shared by ``gonio report`` and the benchmark scripts.

Each function measures its points in the calling process (nothing is pasted) and returns
plain rows (dicts of numbers and labels), so the report can tabulate and plot them and a
benchmark can print them. Nothing here writes files except :func:`render_scene_file`'s
caller-given scratch scene (see :mod:`gonio_cli.report`).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Callable, Iterable

import numpy as np

from ..lobes import design_matrix
from ..lobes.basis import select_basis
from ..lobes.samples import sample_set, target_values
from ..lobes.solve import fit_weight_table, fit_weights
from ..lobes.solvers import WEIGHT_SOLVERS
from ..prefilter import brute, inputs as prefilter_inputs, methods as prefilter_methods, \
    prefilter, ring
from ..render import Stats
from ..render.environment import Environment, environment_xyz
from ..render.frame import frame_time
from ..render.pipeline import render_scene
from ..render.scene import load_scene
from ..schemas import Lobes, Material
from ..synthetic import ink_spectra

#: The working grid of the comparison materials (nm), seed 000's 380–780 nm in 10 nm steps.
WL = np.arange(380.0, 781.0, 10.0)


# ------------------------------------------------------------------------------ timing --

def timed(fn: Callable, *args, **kw):
    """(result, seconds) of one call ``fn(*args, **kw)``."""
    t = time.perf_counter()
    out = fn(*args, **kw)
    return out, time.perf_counter() - t


def median_time(fn: Callable[[], object], repeats: int) -> float:
    """Median wall time (s) of ``repeats`` calls of ``fn()``."""
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return float(np.median(times))


# ------------------------------------------------------------------------------- lobes --

def lobe_test_materials() -> dict:
    """The lobe benchmark's materials (seed 001): the three structural-colour inks of seed
    000 (synthetic, as the demo's) and comparison materials (Torrance–Sparrow glossy and
    rough, a Cook–Torrance metallic paint, a Lambertian white), on :data:`WL`."""
    out = {}
    for ink in ("red", "green", "blue"):
        rho, c = ink_spectra(ink, WL)
        out[f"{ink} ink"] = Material("goniochromatic", WL, {"alpha": 0.18, "rho": rho, "c": c})
    flat = np.ones_like(WL)
    out["TS glossy (α 0.05)"] = Material("torrance-sparrow", WL, {"alpha": 0.05, "f0": 0.04 * flat})
    out["TS rough (α 0.4)"] = Material("torrance-sparrow", WL, {"alpha": 0.4, "f0": 0.9 * flat})
    blue = np.exp(-0.5 * ((WL - 470.0) / 50.0) ** 2)
    out["CT paint"] = Material("cook-torrance", WL, {"kd": 0.05 + 0.3 * blue, "ks": 0.6 * flat,
                                                     "m": 0.25 * flat, "f0": 0.2 + 0.5 * blue})
    out["Lambertian"] = Material("cook-torrance", WL, {"kd": 0.8 * flat, "ks": 0 * flat,
                                                       "m": 0.3 * flat, "f0": 0 * flat})
    rho, c = ink_spectra("green", WL)
    out["ink on paper"] = Material("goniochromatic-diffuse", WL,
                                   {"alpha": 0.15, "rho": rho, "c": c, "rho_d": 0.3 * flat})
    out["coated wrap"] = Material("goniochromatic-coat", WL,
                                  {"alpha": 0.1, "rho": rho, "c": c, "rho_d": 0.02 * flat,
                                   "alpha_coat": 0.03, "k_coat": 1.0, "f0_coat": 0.04})
    return out


def lobe_sweep(max_lobes: int = 6, repeats: int = 5, materials: dict | None = None,
               solvers: Iterable[str] | None = None) -> dict:
    """Lobe count against approximation error and weight-fit time (seed 001).

    The basis (exponents per lobe count) comes from one greedy basis search over the
    materials (seed 001 §3.2, eq. 4, XYZ, seed 001's sample set); then, for each lobe count
    and weight solver, the weights of every material at one view angle (dense set, 40°)
    are fitted: relative RMS error (worst material), L1 summed, median fit time (ms).
    Returns ``{"basis": [...], "rows": [...], "basis_time_s": float}``.
    """
    mats = materials if materials is not None else lobe_test_materials()
    s = sample_set("seed001")
    targets = [target_values(m, s, "xyz")[0] for m in mats.values()]
    result, basis_s = timed(select_basis, targets, s, max_lobes)
    basis = [{"lobes": st.n_lobes, "eq4_error": float(st.error), "time_s": float(st.time_s),
              "exponents": [float(e) for e in st.exponents]} for st in result.steps]
    fit_weights(np.eye(3), np.ones((3, 1)), "lp-simplex")  # compile outside the timing
    one = sample_set("dense", [40.0])
    one_targets = [target_values(m, one, "xyz")[0] for m in mats.values()]
    rows = []
    for st in result.steps:
        M = design_matrix(one.cos_theta_i(), one.cos_rv(), st.exponents)
        for solver in (solvers or WEIGHT_SOLVERS):
            fits = [fit_weights(M, B, solver) for B in one_targets]
            ms = 1e3 * float(np.median([median_time(lambda B=B: fit_weights(M, B, solver),
                                                    repeats) for B in one_targets]))
            rows.append({"lobes": st.n_lobes, "weights": int(M.shape[1]), "solver": solver,
                         "l1_sum": float(sum(f.l1 for f in fits)),
                         "rel_rms_worst": float(max(f.rms_relative for f in fits)),
                         "time_ms": ms})
    return {"basis": basis, "rows": rows, "basis_time_s": basis_s,
            "materials": list(mats), "samples": int(one.n_samples)}


def lobe_render_times(basis: list[dict], material, sky: np.ndarray, size: int = 128,
                      repeats: int = 3) -> list[dict]:
    """Render time of environment light per lobe count (seed 001 eqs. 7–9).

    For each basis row: the sky prefiltered at its exponents, the material's weights fitted
    over the hemisphere (``--samples hemisphere``, NNLS, spectral), then the median time of
    the environment term over the ``size`` × ``size`` pixels of an orthographic sphere
    (``gonio_cli.render.environment.environment_xyz``, what ``gonio render`` runs).
    """
    y, x = np.mgrid[1:-1:size * 1j, -1:1:size * 1j]
    inside = x * x + y * y < 1.0
    normals = np.stack([x[inside], y[inside], np.sqrt(1.0 - x[inside] ** 2 - y[inside] ** 2)],
                       axis=-1)
    views = np.broadcast_to([0.0, 0.0, 1.0], normals.shape)
    wl = material.wavelength_nm
    rows = []
    for b in basis:
        maps = prefilter(sky, b["exponents"], check=False)
        env = Environment("memory", np.array([r.exponent for r in maps]), [""] * len(maps),
                          [r.pixels.shape[:2] for r in maps],
                          {float(r.exponent): r.pixels for r in maps})
        table = fit_weight_table(material, b["exponents"],
                                   sample_set("hemisphere", np.arange(0.0, 90.0, 10.0)),
                                   solver="nnls", compare=())
        lobes = Lobes(table.exponents, "spectral", table.channels, table.view_angle_deg,
                      table.diffuse, table.directional_diffuse, table.gloss, {},
                      table.solver, "hemisphere", table.n_samples)
        environment_xyz(env, lobes, normals, views, wl)                 # warm (map stacks)
        t = median_time(lambda: environment_xyz(env, lobes, normals, views, wl), repeats)
        rows.append({"lobes": b["lobes"], "pixels": int(normals.shape[0]),
                     "render_ms": 1e3 * t})
    return rows


# --------------------------------------------------------------------------- prefilter --

def prefilter_errors(out, truth) -> tuple[float, float]:
    """(99th percentile, maximum) of the relative error of a prefiltered map."""
    e = prefilter_methods.relative_errors(np.asarray(out, float), truth)
    return float(np.percentile(e, 99)), float(e.max())


def prefilter_brute_rows(small: np.ndarray, exponents: Iterable[float]) -> list[dict]:
    """``auto`` (ring) beside ``brute`` on a small map, per exponent: both times and the
    relative error of ring against brute (p99, max)."""
    h, w = small.shape[:2]
    prepared = ring.RingInputs(small)
    rows = []
    for e in exponents:
        levels = prefilter_inputs.output_levels(h, w, e)
        (fast, _), t_fast = timed(ring.prefilter_ring, small, e, levels, prepared)
        (truth, _), t_brute = timed(brute.prefilter_brute, small, e, levels)
        p99, mx = prefilter_errors(fast, truth)
        rows.append({"exponent": float(e), "output": f"{w >> levels}×{h >> levels}",
                     "ring_s": t_fast, "brute_s": t_brute, "p99_error": p99,
                     "max_error": mx})
    return rows


def prefilter_ring_rows(m: np.ndarray, exponent: float, prepared=None) -> list[dict]:
    """Error against time of ``ring`` for one exponent on map ``m``: the auto output level
    and one finer, each with working maps 0–3 octaves finer than the output; the reference
    is ring on the full input (equal to brute to float32 round-off)."""
    prepared = prepared if prepared is not None else ring.RingInputs(m)
    h, w = m.shape[:2]
    auto = prefilter_inputs.output_levels(h, w, exponent)
    rows = []
    for levels in sorted({auto, max(0, auto - 1)}, reverse=True):
        ref, _ = ring.prefilter_ring(m, exponent, levels, prepared, working_levels=99)
        for wl in range(0, min(levels, 3) + 1):
            (out, ws), dt = timed(ring.prefilter_ring, m, exponent, levels, prepared,
                                  working_levels=wl)
            p99, mx = prefilter_errors(out, ref)
            rows.append({"exponent": float(exponent), "output": f"{w >> levels}×{h >> levels}",
                         "working": f"{ws[1]}×{ws[0]}",
                         "auto": bool(levels == auto and wl == min(levels, ring.WORKING_LEVELS)),
                         "time_s": dt, "p99_error": p99, "max_error": mx})
    return rows


# ------------------------------------------------------------------------------ render --

def delta_e_2000(xyz_a, xyz_b) -> np.ndarray:
    """CIEDE2000 between two XYZ arrays (..., 3), Lab with the D65 white at Y = 1
    (docs/conventions.md: a white Lambertian lit by E = π shows Y = 1)."""
    import colour

    white = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]
    return np.asarray(colour.delta_E(colour.XYZ_to_Lab(xyz_a, white),
                                     colour.XYZ_to_Lab(xyz_b, white), method="CIE 2000"))


def render_scene_file(path: Path, variables: dict | None = None, *, doc: dict | None = None,
                      **overrides):
    """Load and render one scene file (a template; ``overrides`` as ``gonio render``'s
    width, height, ssaa, spectral; ``doc``: the scene as data, ``path`` then only anchors
    its relative paths). Returns (Frame, Stats, frame time s)."""
    stats = Stats()
    scene = load_scene(path, variables=variables or {}, doc=doc,
                       overrides={k: overrides.get(k) for k in
                                  ("width", "height", "ssaa", "spectral", "exposure",
                                   "tonemap")})
    frame = render_scene(scene, stats)
    return frame, stats, frame_time(stats)
