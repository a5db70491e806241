"""Cosine lobes (seed 001): weight-fit error and time per solver and lobe count, and the
time of the basis search.

Materials: the three structural-colour inks of seed 000 (synthetic, as the demo's) and
comparison materials (Torrance–Sparrow glossy and rough, a Cook–Torrance metallic paint,
a Lambertian white). Basis search: seed 001 §4's set at 10°, 40° and 70° view (58
samples), XYZ. One weight fit: the dense set at one view angle (58 samples) × (1 + 2m)
weights × 3 channels (XYZ).
Weight table: the red ink at 9 view angles × 41 wavelengths, every solver (``highs`` is
scipy's ``linprog``, the peer the exact simplex solvers are checked against), error
beside time. Whole process: ``gonio lobes fit`` run as a command (second of two runs, so
numba's disk cache is warm), wall time and peak memory beside the solver's time per view.
Targets: one fit (8 lobes) under 2 ms; the default solver under 2 ms per view angle for
all 41 channels and the whole ``gonio lobes fit`` under 1 s; the basis search under a
minute. Prints Markdown tables; ``--quick`` runs fewer repeats and lobe counts.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

from gonio_cli.__main__ import use_blas_threads

use_blas_threads()  # before numpy: kernels timed as in a gonio process

import numpy as np

from gonio_cli import lobes as L
from gonio_cli.lobes.basis import select_basis
from gonio_cli.lobes.samples import sample_set, target_values
from gonio_cli.lobes.solve import fit_weight_table, fit_weights
from gonio_cli.lobes.solvers import WEIGHT_SOLVERS
from gonio_cli.artifact import read_artifact
from gonio_cli.report.sweeps import lobe_test_materials, median_time

import process

#: The materials and the timer are shared with ``gonio report`` (gonio_cli.report.sweeps).
materials = lobe_test_materials


def main() -> None:
    quick = "--quick" in sys.argv
    repeats = 5 if quick else 25
    max_lobes = 6 if quick else 11
    mats = materials()
    s = sample_set("seed001")
    targets = {name: target_values(m, s, "xyz")[0] for name, m in mats.items()}

    t = time.perf_counter()
    result = select_basis(list(targets.values()), s, max_lobes)
    basis_s = time.perf_counter() - t
    print(f"## Basis search (seed 001 §3.2, eq. 4), {len(mats)} materials, {s.n_samples} "
          f"samples × 3 views, XYZ, nnls inside, nlopt LN_SBPLX\n")
    print("| lobes | eq. 4 error | max | mean | evaluations | time (s) | exponents |")
    print("|---:|---:|---:|---:|---:|---:|---|")
    for st in result.steps:
        print(f"| {st.n_lobes} | {st.error:.4f} | {st.max_error:.4f} | {st.mean_error:.4f} | "
              f"{st.evaluations} | {st.time_s:.2f} | "
              f"{', '.join(f'{e:.3g}' for e in st.exponents)} |")
    errors = [st.error for st in result.steps]
    print(f"\nTotal {basis_s:.1f} s; error non-increasing with lobe count: "
          f"{all(b <= a + 1e-9 for a, b in zip(errors, errors[1:]))}\n")

    fit_weights(np.eye(3), np.ones((3, 1)), "lp-simplex")   # compile (numba) outside the timing
    counts = (1, 3, max_lobes) if quick else tuple(range(1, max_lobes + 1))
    one = sample_set("dense", [40.0])       # one view angle, ~60 samples
    one_targets = [target_values(m, one, "xyz")[0] for m in mats.values()]
    print(f"## One weight fit (seed 001 eqs. 5-6): {one.n_samples} samples (dense set, view "
          f"40°) × 3 channels (XYZ); L1 summed and relative RMS worst over the "
          f"{len(mats)} materials; median time of {repeats}\n")
    print("| lobes | weights | solver | L1 (sum) | rel. RMS (worst) | time (ms) |")
    print("|---:|---:|---|---:|---:|---:|")
    for m in counts:
        if m > len(result.steps):
            continue
        e = result.steps[m - 1].exponents
        M = L.design_matrix(one.cos_theta_i(), one.cos_rv(), e)
        for solver in WEIGHT_SOLVERS:
            fits = [fit_weights(M, B, solver) for B in one_targets]
            ms = 1e3 * np.median([median_time(lambda B=B: fit_weights(M, B, solver), repeats)
                                  for B in one_targets])
            print(f"| {m} | {M.shape[1]} | {solver} | {sum(f.l1 for f in fits):.4g} | "
                  f"{max(f.rms_relative for f in fits):.4g} | {ms:.3f} |")

    mat = mats["red ink"]
    sv = sample_set("seed001", L.DEFAULT_VIEW_ANGLES_DEG)
    e8 = result.steps[min(8, len(result.steps)) - 1].exponents
    print(f"\n## Weight table for the red ink: {sv.view_angle_deg.size} view angles × "
          f"{sv.n_samples // sv.view_angle_deg.size} samples, 41 spectral channels, "
          f"{e8.size} lobes\n")
    print("| solver | rel. RMS (worst view) | time per view (ms) |")
    print("|---|---:|---:|")
    fit_weights(np.eye(3), np.ones((3, 1)), "lp")              # first-call costs outside
    table = fit_weight_table(mat, e8, sv, "spectral", compare=tuple(WEIGHT_SOLVERS))
    for solver, r in table.errors.items():
        print(f"| {solver} | {max(r['rms_relative']):.4f} | {1e3 * np.median(r['time_s']):.2f} |")

    whole_process(mat, e8)


def whole_process(material, exponents) -> None:
    """``gonio lobes fit`` as a user runs it, per solver: the second of two runs."""
    from gonio_cli.schemas import write_material

    gonio = Path(sys.executable).with_name("gonio")
    print(f"\n## Whole process: `gonio lobes fit` (red ink, {exponents.size} lobes, 9 views × "
          "41 wavelengths), second of two runs\n")
    print("| solver | wall s | peak memory MB | solver ms per view (median) | "
          "rel. RMS (worst view) | L1 (sum) |")
    print("|---|---:|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory(prefix="gonio-bench-lobes-") as tmp:
        mat_path, out = Path(tmp) / "red.material.json", Path(tmp) / "red.lobes.json"
        write_material(mat_path, material)
        for solver in ("lp", "lp-simplex", "highs", "nnls"):
            argv = [str(gonio), "-q", "lobes", "fit", str(mat_path), "-o", str(out),
                    "--exponents", ",".join(f"{e:.17g}" for e in exponents),
                    "--solver", solver]
            process.run_measured(argv, check=False)
            wall, peak, code = process.run_measured(argv, check=False)
            if code != 0:
                print(f"| {solver} | exit {code} | | | | |")
                continue
            r = read_artifact(out, "gonio.lobes", (1,))["errors"][solver]   # side record's times
            print(f"| {solver} | {wall:.2f} | {peak:.0f} | {1e3 * np.median(r['time_s']):.2f} | "
                  f"{max(r['rms_relative']):.4f} | {sum(r['l1']):.6g} |")


if __name__ == "__main__":
    main()
