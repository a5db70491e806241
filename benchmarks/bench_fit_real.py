"""make bench: every model's colour error and time on the real measurements, side by side.

The real data are small fixtures of tests/fixtures/real/ (their README names the sources):
the X-Rite MA-T12 matte pigment (12 in-plane geometries) and eight RGL database materials
(Dupuy & Jakob 2018: a white felt, cardboard, a colour-shifting wrap, two architectural
coatings, a leaf, a purple satin, an iridescent film), each sampled as ``gonio ingest
X.bsdf`` samples a file by default (301 configurations: the plane of incidence every 5°
and a ring 1-3° around each mirror direction) plus a check grid out of the plane that no
fit sees (θi 10-70° by 20, θo 10-80° by 10, φo 30-150° by 30: 160 configurations).

For each material and each ``--model`` (``auto`` last), ``gonio fit`` runs as a process and
the table gives its mean CIEDE2000 over the fitted configurations beside the wall time. The
colour error is the one the issue tracker's table used: D65, 10° observer, R = π f, every
configuration (model and data alike) scaled so that the data's Y is 0.5, so a glossy peak
and a dark tail count alike. The ``auto`` table adds the verdict's own figures (pairs
scaled only where Y > 1), the mirror-peak ratios, the error on the out-of-plane check
grid (``gonio eval``), and the summary over materials: median and worst of the means.

``--models auto`` (or a comma list) limits the models; ``--make-fixtures RGL_DIR`` writes
the RGL fixtures from the ``.bsdf`` files (Mitsuba 3).
"""

import json
import sys
import tempfile
from pathlib import Path

from gonio_cli.__main__ import use_blas_threads

use_blas_threads()  # before numpy: as in a gonio process

import numpy as np

from gonio_cli import spectra
from gonio_cli.names import FIT_MODEL_CHOICES

import process

ROOT = Path(__file__).resolve().parent.parent
FIXTURES = ROOT / "tests/fixtures/real"

#: (label, RGL file stem): the fixtures are rgl_<stem>.csv (fit grid) and
#: rgl_<stem>.check.csv (the out-of-plane check grid).
RGL = (("white felt", "acrylic_felt_white_rgb"), ("cardboard", "cardboard_rgb"),
       ("Ibiza Sunset wrap", "cc_ibiza_sunset_rgb"), ("mint coating", "chm_mint_rgb"),
       ("azure coating", "colodur_azure_4e_rgb"), ("maple leaf", "leaf_maple_rgb"),
       ("purple satin", "satin_purple_rgb"), ("ultra pink film", "vch_ultra_pink_rgb"))

#: The check grid out of the plane (module docstring).
CHECK_THETA_I_DEG = (10.0, 30.0, 50.0, 70.0)
CHECK_THETA_O_DEG = tuple(float(t) for t in range(10, 81, 10))
CHECK_PHI_O_DEG = (30.0, 60.0, 90.0, 120.0, 150.0)

GRID = np.arange(380.0, 781.0, 10.0)
HEADER = "# Derived from the RGL material database (Dupuy & Jakob 2018), {src}: {what}\n" \
         "# Mitsuba 3's measured BSDF, linear sRGB BRDF (sr^-1, no cosine), 4 significant " \
         "digits; benchmarks/bench_fit_real.py --make-fixtures.\n"


def fit_grid():
    """(θi, θo, φo) of ``gonio ingest X.bsdf``'s default grid."""
    from gonio_cli.ingest import hemisphere, rgl

    ti = rgl.parse_angles(rgl.DEFAULT_THETA_I_DEG, "--theta-i-deg", True)
    to = rgl.parse_angles(rgl.DEFAULT_THETA_O_DEG, "--theta-o-deg", False)
    return hemisphere.hemisphere_grid(
        ti, to, hemisphere.parse_azimuths(hemisphere.DEFAULT_PHI_O_DEG),
        hemisphere.parse_mirror(hemisphere.DEFAULT_MIRROR_DEG))


def check_grid():
    """(θi, θo, φo) of the out-of-plane check grid, (160,) each."""
    g = np.array([(a, b, c) for a in CHECK_THETA_I_DEG for b in CHECK_THETA_O_DEG
                  for c in CHECK_PHI_O_DEG])
    return g[:, 0], g[:, 1], g[:, 2]


def make_fixtures(rgl_dir: Path) -> None:
    """Write tests/fixtures/real/rgl_<stem>.csv and .check.csv from the ``.bsdf`` files."""
    from gonio_cli.ingest.rgl import check_bsdf, evaluate_in_plane

    for _, stem in RGL:
        src = rgl_dir / f"{stem}.bsdf"
        kind, _ = check_bsdf(src)
        for suffix, (ti, to, po), what in ((".csv", fit_grid(), "gonio ingest's default grid"),
                                           (".check.csv", check_grid(),
                                            "the out-of-plane check grid")):
            rgb = evaluate_in_plane(src, kind, ti, to, (0, 1, 2), po)
            rows = [f"{a:g},{b:g},{c:g}," + ",".join(f"{v:.4g}" for v in row)
                    for a, b, c, row in zip(ti, to, po, rgb)]
            out = FIXTURES / f"rgl_{stem}{suffix}"
            out.write_text(HEADER.format(src=src.name, what=what)
                           + "theta_i_deg,theta_o_deg,phi_o_deg,r,g,b\n" + "\n".join(rows) + "\n")
            print(f"wrote {out.relative_to(ROOT)} ({ti.size} configurations)")


def spectral_csv(fixture: Path, out: Path) -> Path:
    """An RGB fixture as spectra in gonio's wide layout (380-780 nm by 10), as ``gonio
    ingest`` makes them of an RGB ``.bsdf``: rgb @ the Mallett-Yuksel basis, clipped at 0."""
    table = np.loadtxt(fixture, delimiter=",", comments="#", skiprows=3)
    brdf = np.maximum(table[:, 3:] @ spectra.rgb_reflectance_basis(GRID).T, 0.0)
    head = "theta_i_deg,theta_o_deg,phi_o_deg," + ",".join(f"{w:g}" for w in GRID)
    rows = [",".join(f"{v:g}" for v in t[:3]) + "," + ",".join(f"{v:.6g}" for v in r)
            for t, r in zip(table, brdf)]
    out.write_text(head + "\n" + "\n".join(rows) + "\n")
    return out


def delta_e_at_half(wl, f_data, f_model) -> np.ndarray:
    """CIEDE2000 (D65, 10°) of π f_model against π f_data per configuration, each pair
    scaled so that the data's Y is 0.5."""
    white = spectra.reflectance_to_xyz(np.ones(wl.size), wl)
    xyz_d = spectra.reflectance_to_xyz(np.pi * f_data, wl)
    xyz_m = spectra.reflectance_to_xyz(np.pi * f_model, wl)
    scale = (0.5 / np.maximum(xyz_d[:, 1], 1e-12))[:, None]
    return spectra.delta_e_2000(spectra.xyz_to_lab(xyz_d * scale, white),
                                spectra.xyz_to_lab(xyz_m * scale, white))


def datasets(tmp: Path) -> list[tuple[str, list[str], Path | None]]:
    """(label, ingest argv, check measurement CSV or None) of every real material."""
    out = [("MA-T12 matte pigment", [str(FIXTURES / "ma_t12_clean.csv"), "--quantity",
                                     "reflectance-factor", "--grid-nm", "400:700:10"], None)]
    for label, stem in RGL:
        fit_csv = spectral_csv(FIXTURES / f"rgl_{stem}.csv", tmp / f"{stem}.csv")
        check_csv = spectral_csv(FIXTURES / f"rgl_{stem}.check.csv", tmp / f"{stem}.check.csv")
        out.append((f"RGL {label}", [str(fit_csv)], check_csv))
    return out


def read(path: Path) -> dict:
    return json.loads(path.read_text())


def fit_once(gonio: str, meas: Path, model: str, out: Path) -> dict:
    """One ``gonio fit`` process: wall and CPU time, and the material it wrote (a failed
    or poor fit is written too: ``--on-failure write``)."""
    run = process.run_with_cpu([gonio, "-q", "fit", str(meas), "-o", str(out), "--model",
                                model, "--on-failure", "write"])
    run["material"] = read(out) if out.exists() else None
    return run


def check_error(gonio: str, material_path: Path, check_csv: Path, tmp: Path) -> float:
    """Mean CIEDE2000 (data Y = 0.5) of the material on the out-of-plane check grid."""
    cm, ev = tmp / "check.json", tmp / "check.eval.json"
    process.run_measured([gonio, "-q", "ingest", str(check_csv), "-o", str(cm)])
    process.run_measured([gonio, "-q", "eval", str(material_path), "--at", str(cm), "-o",
                          str(ev)])
    data, model = read(cm), read(ev)
    return float(np.mean(delta_e_at_half(np.asarray(data["wavelength_nm"]),
                                         np.asarray(data["brdf"]),
                                         np.asarray(model["brdf"], float))))


def peak_text(material: dict) -> str:
    ratios = list(material["fit"].get("verdict", {}).get("mirror_peak_y_ratio", {}).values())
    return f"{min(ratios):.2f}-{max(ratios):.2f}" if ratios else "-"


def run_material(gonio: str, label: str, argv: list[str], check: Path | None, models,
                 tmp: Path) -> dict:
    """Every model on one material: {model: (mean ΔE at Y 0.5, wall s, run)}."""
    meas_path = tmp / "meas.json"
    process.run_measured([gonio, "-q", "ingest", *argv, "-o", str(meas_path)])
    meas = read(meas_path)
    row = {}
    for model in models:
        mat = tmp / f"{model}.material.json"
        run = fit_once(gonio, meas_path, model, mat)
        if run["material"] is None:
            row[model] = (float("nan"), run["wall_s"], run)
            continue
        ev = tmp / "eval.json"
        process.run_measured([gonio, "-q", "eval", str(mat), "--at", str(meas_path), "-o",
                              str(ev)])
        de = delta_e_at_half(np.asarray(meas["wavelength_nm"], float),
                             np.asarray(meas["brdf"], float),
                             np.asarray(read(ev)["brdf"], float))
        run["check"] = check_error(gonio, mat, check, tmp) if check is not None else None
        row[model] = (float(np.mean(de)), run["wall_s"], run)
    return row


def print_models(table: dict, models) -> None:
    print("\n## Every model on the real data: mean CIEDE2000 (each configuration at data "
          "Y = 0.5) / wall s of `gonio fit`\n")
    print("| material | " + " | ".join(models) + " |\n|---|" + "---:|" * len(models))
    for label, row in table.items():
        print(f"| {label} | " + " | ".join(
            f"{row[m][0]:.2f} / {row[m][1]:.1f}" for m in models) + " |")


def print_auto(table: dict) -> None:
    print("\n## `gonio fit --model auto` on the real data\n")
    print("| material | chosen | verdict | mean (Y 0.5) | verdict mean / worst | "
          "out of plane (check grid) | mirror peak | wall s | CPU s |\n"
          "|---|---|---|---:|---|---:|---|---:|---:|")
    means, walls = [], []
    for label, row in table.items():
        mean, wall, run = row["auto"]
        m = run["material"]
        if m is None:
            print(f"| {label} | failed | | | | | | {wall:.1f} | |")
            continue
        v = m["fit"].get("verdict", {})
        check = f"{run['check']:.2f}" if run.get("check") is not None else "-"
        print(f"| {label} | {m['model']} | {m['status']} | {mean:.2f} | "
              f"{v.get('delta_e2000_mean', float('nan')):.2f} / "
              f"{v.get('delta_e2000_worst', float('nan')):.2f} | {check} | {peak_text(m)} | "
              f"{wall:.1f} | {run['cpu_s']:.1f} |")
        means.append(mean)
        walls.append(wall)
    if means:
        print(f"\nOver the {len(means)} materials: median {np.median(means):.2f}, worst "
              f"{max(means):.2f} (mean CIEDE2000 at data Y = 0.5); wall time "
              f"{min(walls):.1f}-{max(walls):.1f} s (load {process.load_average()}).")


def main() -> None:
    if "--make-fixtures" in sys.argv:
        make_fixtures(Path(sys.argv[sys.argv.index("--make-fixtures") + 1]))
        return
    models = list(FIT_MODEL_CHOICES)
    if "--models" in sys.argv:
        models = sys.argv[sys.argv.index("--models") + 1].split(",")
    gonio = process.gonio_command()
    table = {}
    with tempfile.TemporaryDirectory(prefix="gonio-bench-real-") as tmp:
        tmp = Path(tmp)
        for label, argv, check in datasets(tmp):
            table[label] = run_material(gonio, label, argv, check, models, tmp)
    print_models(table, models)
    if "auto" in models:
        print_auto(table)


if __name__ == "__main__":
    main()
