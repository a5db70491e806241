"""make bench: error against run time of every fit method, optimiser and model.

1. The goniochromatic model (seed 000 eq. 5) on synthetic data of known parameters:
   parameter errors against the truth, the data's log-RMSE and the median time of the
   whole fit (one ink: ~130 configurations × 41 wavelengths). Targets: refined fit < 50 ms,
   the paper's two steps < 10 ms (the core, log residuals).
2. Every other model on data made from itself (parameter errors, time).
3. Whole commands as users run them (wall time and peak memory of the process, beside the
   fit's own ``time_s``): every model, and ``--model auto``, on the sample inks and paint
   and on two real measurements (tests/fixtures/real: an X-Rite MA-T12 matte pigment, with
   and without its lamps' gains, and an RGL glossy wrap), with the verdict's colour error
   beside the time; and ``gonio
   --version``, ``gonio ingest``, ``gonio fit --plot``, ``gonio eval``.

4. ``--auto``: only ``gonio fit --model auto`` as a whole process, on the sample inks,
   the MA-T12 pigment and three RGL materials as ``gonio ingest X.bsdf`` samples them
   (301 configurations × 41 wavelengths, tests/fixtures/real/rgl_*_rgb.csv): wall and CPU time (the child's and its
   forked fitters'), peak memory and the load average beside the chosen model and its
   held-out and in-sample colour error; ``--repeats N`` (default 3). Every model on all
   the real files: benchmarks/bench_fit_real.py.

``--quick`` runs fewer cases.
"""

import json
import os
import sys
import tempfile
import time
from pathlib import Path

from gonio_cli.__main__ import use_blas_threads

use_blas_threads()  # before numpy: kernels timed as in a gonio process

from gonio_cli.artifact import read_artifact
from gonio_cli.names import FIT_MODEL_CHOICES
from gonio_cli.fit.sweep import (comparison_sweep, format_comparison, format_rows,
                                  goniochromatic_sweep)

import bench_fit_real
import process

ROOT = Path(__file__).resolve().parent.parent
#: Every ``--model`` of the registry, ``auto`` last.
MODELS = FIT_MODEL_CHOICES

#: (label, input files, ingest options, fit options) of the whole-command table.
DATASETS = (
    ("red ink (sample, eq. 5 + 2 % noise)", ["sample_data/ink_red.csv"], [],
     ["--exclude-theta-i-deg", "70"]),
    ("car paint (sample, 14 ASTM geometries)", ["sample_data/carpaint_multiangle.csv"],
     ["--quantity", "reflectance-factor"], []),
    ("matte pigment (MA-T12, 12 geometries)", ["tests/fixtures/real/ma_t12_clean.csv"],
     ["--quantity", "reflectance-factor", "--grid-nm", "400:700:10"], []),
    # the same without the light-source gains a multi-angle file gets by default
    ("matte pigment, `--sweep-gain off`", ["tests/fixtures/real/ma_t12_clean.csv"],
     ["--quantity", "reflectance-factor", "--grid-nm", "400:700:10"],
     ["--sweep-gain", "off"]),
    ("glossy wrap (RGL, θi 20/40/60°)", ["tests/fixtures/real/rgl_wrap_inplane.csv"], [], []),
)


def commands(tmp: Path, quick: bool) -> None:
    gonio = process.gonio_command()
    print(f"\n## Whole commands (load average before: {process.load_average()})\n")
    red = tmp / "red.json"
    rows = [("gonio --version", [gonio, "--version"]),
            ("gonio ingest (red ink, 15 252 rows)",
             [gonio, "-q", "ingest", str(ROOT / "sample_data/ink_red.csv"), "-o", str(red)]),
            ("gonio fit (red ink, default)",
             [gonio, "-q", "fit", str(red), "-o", str(tmp / "m.json"),
              "--exclude-theta-i-deg", "70"]),
            ("gonio fit --plot",
             [gonio, "-q", "fit", str(red), "-o", str(tmp / "m.json"),
              "--exclude-theta-i-deg", "70", "--plot", str(tmp / "m.png")]),
            ("gonio eval",
             [gonio, "-q", "eval", str(tmp / "m.json"), "--at", str(red), "-o",
              str(tmp / "e.json")])]
    print("| command | wall s (best of 3) | peak memory MB |\n|---|---:|---:|")
    for label, argv in rows:
        runs = [process.run_measured(argv) for _ in range(3)]
        wall, peak, _ = min(runs)
        print(f"| `{label}` | {wall:.2f} | {peak:.0f} |")


def models_on_data(tmp: Path, quick: bool) -> None:
    gonio = process.gonio_command()
    print("\n## Every model on sample and real data: `gonio fit` as a process\n")
    print("Colour: the verdict's mean / worst CIEDE2000 (D65, 10°, R = π f) at the measured "
          "configurations; peak: model/data Y at the mirror configurations (range over θi).\n")
    print("| data | model | verdict | CIEDE2000 mean / worst | peak | fit time_s | "
          "wall s | peak MB |\n|---|---|---|---:|---|---:|---:|---:|")
    for label, files, ingest_opts, fit_opts in (DATASETS[:1] + DATASETS[-1:] if quick
                                                else DATASETS):
        meas = tmp / "meas.json"
        process.run_measured([gonio, "-q", "ingest", *[str(ROOT / f) for f in files], "-o",
                              str(meas), *ingest_opts])
        for model in (("goniochromatic", "goniochromatic-coat", "auto") if quick else MODELS):
            out = tmp / "mat.json"
            wall, peak, code = process.run_measured(
                [gonio, "-q", "fit", str(meas), "-o", str(out), "--model", model,
                 "--on-failure", "write", *fit_opts], check=False)
            if code != 0:
                print(f"| {label} | {model} | exit {code} | | | | {wall:.2f} | {peak:.0f} |")
                continue
            doc = read_artifact(out, "gonio.material", (1, 2))   # times: its side record
            v = doc["fit"].get("verdict", {})
            ratios = list(v.get("mirror_peak_y_ratio", {}).values())
            peak_txt = f"{min(ratios):.2f}–{max(ratios):.2f}" if ratios else "–"
            name = model if model != "auto" else f"auto → {doc['model']}"
            print(f"| {label} | {name} | {doc['status']} | "
                  f"{v.get('delta_e2000_mean', float('nan')):.2f} / "
                  f"{v.get('delta_e2000_worst', float('nan')):.2f} | {peak_txt} | "
                  f"{doc['time_s']:.3f} | {wall:.2f} | {peak:.0f} |")


# ------------------------------------------------------- --model auto as users run it --

#: RGL materials for the ``--auto`` table (their fixtures: :mod:`bench_fit_real`): a matte
#: paper, a satin fabric, a colour-shifting wrap.
RGL_FIXTURES = (("RGL cardboard (matte)", "cardboard_rgb"),
                ("RGL purple satin", "satin_purple_rgb"),
                ("RGL Ibiza Sunset wrap (colour shift)", "cc_ibiza_sunset_rgb"))


def auto_on_data(tmp: Path, repeats: int = 3) -> None:
    """``gonio fit --model auto`` as a whole process on the sample inks, the MA-T12
    pigment and the RGL fixtures: wall and CPU time (the best of ``repeats`` by wall),
    peak memory, the load average, and the chosen model with its held-out and in-sample
    colour error."""
    gonio = process.gonio_command()
    data = [("red ink (sample)", ["sample_data/ink_red.csv"], []),
            ("green ink (sample)", ["sample_data/ink_green.csv"], []),
            ("blue ink (sample, two files)", ["sample_data/ink_blue_a.csv",
                                              "sample_data/ink_blue_b.csv"], []),
            ("MA-T12 matte pigment (12 geometries)", ["tests/fixtures/real/ma_t12_clean.csv"],
             ["--quantity", "reflectance-factor", "--grid-nm", "400:700:10"])]
    data += [(label, [bench_fit_real.spectral_csv(bench_fit_real.FIXTURES / f"rgl_{stem}.csv",
                                                  tmp / f"{stem}.csv")], [])
             for label, stem in RGL_FIXTURES]
    print(f"\n## `gonio fit --model auto`, whole process (load average before: "
          f"{process.load_average()}; {os.cpu_count()} cores)\n")
    print("| data | configurations × wavelengths | chosen | held out / in sample "
          "CIEDE2000 | wall s | CPU s | peak MB | load |\n|---|---|---|---|---:|---:|---:|---|")
    for label, files, opts in data:
        meas, mat = tmp / "auto.measurement.json", tmp / "auto.material.json"
        process.run_measured([gonio, "-q", "ingest", *[str(ROOT / f) for f in files], "-o",
                              str(meas), *opts])
        runs = [process.run_with_cpu([gonio, "-q", "fit", str(meas), "-o", str(mat), "--model",
                              "auto"]) for _ in range(repeats)]
        best = min(runs, key=lambda r: r["wall_s"])
        doc = json.loads(mat.read_text())
        chosen = next(c for c in doc["fit"]["auto"]["candidates"] if c["model"] == doc["model"])
        n = json.loads(meas.read_text())
        shape = f"{len(n['theta_i_deg'])} × {len(n['wavelength_nm'])}"
        print(f"| {label} | {shape} | {doc['model']} | "
              f"{chosen['held_out_delta_e2000_mean']:.3f} / "
              f"{doc['fit']['verdict'].get('delta_e2000_mean', float('nan')):.3f} | "
              f"{best['wall_s']:.2f} | {best['cpu_s']:.2f} | {best['maxrss_kib'] / 1024:.0f} | "
              f"{process.load_average()} |")


def main() -> None:
    if "--auto" in sys.argv:
        with tempfile.TemporaryDirectory(prefix="gonio-bench-auto-") as tmp:
            repeats = (int(sys.argv[sys.argv.index("--repeats") + 1])
                       if "--repeats" in sys.argv else 3)
            auto_on_data(Path(tmp), repeats)
        return
    quick = "--quick" in sys.argv
    t = time.perf_counter()
    rows = goniochromatic_sweep(alphas=(0.19,) if quick else (0.03, 0.19, 0.5),
                                inks=("red",) if quick else ("red", "green", "blue"),
                                repeats=3 if quick else 7)
    print("## gonio fit: goniochromatic (seed 000 eq. 5), synthetic data, 2 % noise\n")
    print(format_rows(rows))
    print("\n## Comparison models on their own synthetic data (2 % noise, θi 20–70°, 41 wavelengths)\n")
    print(format_comparison(comparison_sweep(repeats=3 if quick else 7)))
    with tempfile.TemporaryDirectory(prefix="gonio-bench-fit-") as tmp:
        commands(Path(tmp), quick)
        models_on_data(Path(tmp), quick)
    print(f"\n({time.perf_counter() - t:.1f} s for the benchmark)")


if __name__ == "__main__":
    main()
