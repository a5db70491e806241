"""Regenerate gonio's sample data: synthetic goniometer measurements with known truth.

Three structural-colour reflective inks (red, green, blue) as in seed 000, made from its
eq. 5 (:func:`gonio_cli.brdf.goniochromatic`) on the paper's in-plane geometry, and a blue
metallic car paint from seed 004 eq. 11 (:func:`gonio_cli.brdf.cook_torrance`) in the
multi-angle layout of ASTM E2194 instruments. The true parameters and the noise settings
are written to ``truth.json`` beside the CSVs.

Every file is reproduced byte for byte from the fixed seed::

    python sample_data/make_inks.py            # into sample_data/
    python sample_data/make_inks.py --out DIR  # elsewhere (tests compare the bytes)

Files (each exercises a different ingest path):

- ``ink_red.csv``: long layout, comma-delimited, quantity ``brdf``, 3 repeats per
  configuration (so ``brdf_std`` exists).
- ``ink_green.csv``: wide layout, quantity ``ratio-to-white`` (white 0.99), as a European
  instrument exports it: UTF-8 BOM, ``;`` delimiter, decimal commas.
- ``ink_blue_a.csv`` (θi ≤ 40°) and ``ink_blue_b.csv`` (θi ≥ 50°): wide layout,
  tab-delimited, quantity ``brdf``; ingest them together to merge.
- ``carpaint_multiangle.csv``: multi-angle layout (``45as15`` …), quantity
  ``reflectance-factor``, 380–780 nm at 5 nm as in seed 004 (ingest resamples it).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from gonio_cli.brdf import cook_torrance, goniochromatic
from gonio_cli.geometry import in_plane_cosines

#: Seed of every random draw (each data set draws from its own stream (SEED, k)).
SEED = 2024

#: Seed 000's grid: 380–780 nm at 10 nm; seed 004 measured at 5 nm.
WAVELENGTH_NM = np.arange(380.0, 781.0, 10.0)
WAVELENGTH_5NM = np.arange(380.0, 781.0, 5.0)

#: Angles of incidence of seed 000 ("every 10° from 20° to 70° and additionally at 65°").
THETA_I_DEG = (20.0, 30.0, 40.0, 50.0, 60.0, 65.0, 70.0)

#: For θi up to this the goniometer cannot put the detector on the light's side (seed 000,
#: "Limitations"): only θo ≥ 0 is measured.
FAR_SIDE_ONLY_MAX_DEG = 30.0

#: The detector blocks the light within this angle of retro-reflection (θo = −θi).
RETRO_BLOCKED_DEG = 10.0

#: Multiplicative log-normal noise (σ of log value); θi = 70° is the paper's less reliable
#: row (geometrical constraints): more noise and a bias.
NOISE_SIGMA = 0.02
NOISE_SIGMA_70 = 0.08
BIAS_70 = 1.10
CARPAINT_NOISE_SIGMA = 0.01

#: Significant digits written for values (an instrument export, well below the noise).
DIGITS = 6

WHITE_REFLECTANCE = 0.99

#: The inks: roughness α, and ρ(λ), c(λ) shaped like seed 000 Figure 4 (bottom): ρ a
#: smooth band in the ink's colour over a small floor, c larger below the peak (the
#: structural colour shifts to shorter wavelengths at grazing angles).
INKS = {
    "red": {"alpha": 0.18, "peak_nm": 640.0, "width_nm": 45.0, "rho_peak": 0.27,
            "c_low": 0.4, "c_high": 5.6},
    "green": {"alpha": 0.19, "peak_nm": 540.0, "width_nm": 35.0, "rho_peak": 0.24,
              "c_low": 0.3, "c_high": 5.2},
    "blue": {"alpha": 0.20, "peak_nm": 460.0, "width_nm": 32.0, "rho_peak": 0.22,
             "c_low": 0.2, "c_high": 4.6},
}
RHO_FLOOR = 0.02
C_EDGE_OFFSET_NM = 30.0  # c falls from c_high to c_low this far below the peak ...
C_EDGE_WIDTH_NM = 25.0   # ... over about this width (logistic)

#: ASTM E2194 geometries of a multi-angle instrument (light at 45°, and at 15°).
CARPAINT_GEOMETRIES = ("45as-15", "45as15", "45as25", "45as45", "45as75", "45as110",
                       "15as-15", "15as15", "15as45")


def configurations(theta_i_list=THETA_I_DEG) -> tuple[np.ndarray, np.ndarray]:
    """The in-plane sweep: θi and θo (degrees), (n,) each.

    Far side: θo every 10° from 0 to 80 plus every 5° within 15° of the mirror direction
    (up to 85°); light's side: every 10° from −10 to −80 where the goniometer can
    (θi > 30°), skipping θo within 10° of retro-reflection.
    """
    ti_out, to_out = [], []
    for ti in theta_i_list:
        far = set(np.arange(0.0, 81.0, 10.0)) | set(np.arange(ti - 15, ti + 16, 5.0))
        far = {t for t in far if 0 <= t <= 85}
        near = set()
        if ti > FAR_SIDE_ONLY_MAX_DEG:
            near = {t for t in np.arange(-80.0, -9.0, 10.0)
                    if abs(t + ti) >= RETRO_BLOCKED_DEG}
        for to in sorted(near | far):
            ti_out.append(ti)
            to_out.append(float(to))
    return np.array(ti_out), np.array(to_out)


def ink_parameters(ink: dict) -> tuple[np.ndarray, np.ndarray]:
    """ρ(λ) and c(λ) on :data:`WAVELENGTH_NM`, rounded to 6 decimals (the truth as stored)."""
    wl = WAVELENGTH_NM
    band = np.exp(-0.5 * ((wl - ink["peak_nm"]) / ink["width_nm"]) ** 2)
    rho = RHO_FLOOR + (ink["rho_peak"] - RHO_FLOOR) * band
    edge = ink["peak_nm"] - C_EDGE_OFFSET_NM
    c = ink["c_low"] + (ink["c_high"] - ink["c_low"]) / (1 + np.exp((wl - edge)
                                                                     / C_EDGE_WIDTH_NM))
    return np.round(rho, 6), np.round(c, 6)


def noisy(truth: np.ndarray, theta_i: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Multiplicative log-normal noise (median-unbiased), worse and biased at θi = 70°."""
    row70 = (theta_i == 70.0)[..., None]
    sigma = np.where(row70, NOISE_SIGMA_70, NOISE_SIGMA)
    bias = np.where(row70, BIAS_70, 1.0)
    return truth * bias * np.exp(sigma * rng.standard_normal(truth.shape))


def _num(x: float) -> str:
    return f"{x:.{DIGITS}g}"


def _write(path: Path, header: list[str], rows: list[list[str]], delimiter: str,
           comments: list[str], bom: bool = False) -> None:
    lines = [f"# {c}" for c in comments] + [delimiter.join(header)]
    lines += [delimiter.join(r) for r in rows]
    text = "\n".join(lines) + "\n"
    path.write_bytes((b"\xef\xbb\xbf" if bom else b"") + text.encode("utf-8"))


def _wide_rows(theta_i, theta_o, values, decimal_comma=False) -> list[list[str]]:
    rows = []
    for ti, to, v in zip(theta_i, theta_o, values):
        cells = [_num(ti), _num(to)] + [_num(x) for x in v]
        rows.append([c.replace(".", ",") for c in cells] if decimal_comma else cells)
    return rows


def _comments(name: str, quantity: str, extra: str = "") -> list[str]:
    return [f"gonio sample data (synthetic): {name}; quantity {quantity}{extra}",
            "regenerate with: python sample_data/make_inks.py; truth in truth.json"]


def make_inks(out: Path, truth: dict) -> None:
    """Write the three ink data sets and add their truth to ``truth``."""
    ti, to = configurations()
    cos = in_plane_cosines(ti, to)
    wl = WAVELENGTH_NM
    for k, (name, ink) in enumerate(INKS.items()):
        rho, c = ink_parameters(ink)
        f = goniochromatic(cos, ink["alpha"], rho, c)  # (n_cfg, n_λ), sr⁻¹
        rng = np.random.default_rng((SEED, k))
        entry = {"model": "goniochromatic", "citation": "seed 000 eq. 5",
                 "alpha": ink["alpha"], "rho": rho.tolist(), "c": c.tolist(),
                 "configurations": int(ti.size)}
        if name == "red":
            repeats = 3
            vals = noisy(np.repeat(f[:, None, :], repeats, axis=1), ti[:, None], rng)
            rows = [[_num(a), _num(b), _num(w), _num(x)]
                    for a, b, rep in zip(ti, to, vals) for spec in rep
                    for w, x in zip(wl, spec)]
            _write(out / "ink_red.csv", ["theta_i_deg", "theta_o_deg", "wavelength_nm",
                                         "value"], rows, ",",
                   _comments("red structural-colour ink", "brdf (sr^-1)",
                             f", {repeats} repeats per configuration"))
            entry.update(files=["ink_red.csv"], layout="long", quantity="brdf",
                         repeats=repeats)
        elif name == "green":
            ratio = noisy(f, ti, rng) * np.pi / WHITE_REFLECTANCE
            _write(out / "ink_green.csv", ["theta_i_deg", "theta_o_deg"]
                   + [_num(w) for w in wl], _wide_rows(ti, to, ratio, decimal_comma=True),
                   ";", _comments("green structural-colour ink", "ratio-to-white",
                                  f" (white standard {WHITE_REFLECTANCE})"), bom=True)
            entry.update(files=["ink_green.csv"], layout="wide", quantity="ratio-to-white",
                         white_reflectance=WHITE_REFLECTANCE, repeats=1)
        else:
            vals = noisy(f, ti, rng)
            for suffix, sel in (("a", ti <= 40), ("b", ti >= 50)):
                _write(out / f"ink_blue_{suffix}.csv", ["theta_i_deg", "theta_o_deg"]
                       + [_num(w) for w in wl], _wide_rows(ti[sel], to[sel], vals[sel]),
                       "\t", _comments("blue structural-colour ink", "brdf (sr^-1)",
                                       f", theta_i {'<= 40' if suffix == 'a' else '>= 50'}"
                                       " (merge with the other file)"))
            entry.update(files=["ink_blue_a.csv", "ink_blue_b.csv"], layout="wide",
                         quantity="brdf", repeats=1)
        truth["inks"][name] = entry


def carpaint_parameters() -> dict[str, np.ndarray]:
    """Cook–Torrance kd, ks, m, F0 (seed 004 eq. 11) of a blue metallic paint on the 5 nm
    grid: a blue diffuse base, aluminium flakes (F0 ≈ 0.9) with a faint blue tint."""
    wl = WAVELENGTH_5NM
    kd = 0.02 + 0.12 * np.exp(-0.5 * ((wl - 460.0) / 45.0) ** 2)
    ks = 0.07 + 0.02 * np.exp(-0.5 * ((wl - 470.0) / 80.0) ** 2)
    m = 0.30 + 0.02 * (wl - 580.0) / 200.0
    f0 = 0.90 - 0.02 * (wl - 380.0) / 400.0
    return {k: np.round(v, 6) for k, v in (("kd", kd), ("ks", ks), ("m", m), ("f0", f0))}


def make_carpaint(out: Path, truth: dict) -> None:
    """Write ``carpaint_multiangle.csv`` (reflectance factor R = π f) and its truth."""
    from gonio_cli.csvlayouts import aspecular_angles

    ti, to = np.array([aspecular_angles(g) for g in CARPAINT_GEOMETRIES]).T
    p = carpaint_parameters()
    f = cook_torrance(in_plane_cosines(ti, to), p["kd"], p["ks"], p["m"], p["f0"])
    rng = np.random.default_rng((SEED, len(INKS)))
    r = np.pi * f * np.exp(CARPAINT_NOISE_SIGMA * rng.standard_normal(f.shape))
    rows = [[g] + [_num(x) for x in v] for g, v in zip(CARPAINT_GEOMETRIES, r)]
    _write(out / "carpaint_multiangle.csv", ["geometry"] + [_num(w) for w in WAVELENGTH_5NM],
           rows, ",", _comments("blue metallic car paint, multi-angle instrument",
                                "reflectance-factor", ", 380-780 nm at 5 nm"))
    truth["carpaint"] = {"model": "cook-torrance", "citation": "seed 004 eqs. 9-12",
                         "files": ["carpaint_multiangle.csv"], "layout": "multi-angle",
                         "quantity": "reflectance-factor", "geometries": list(CARPAINT_GEOMETRIES),
                         "wavelength_nm": WAVELENGTH_5NM.tolist(),
                         **{k: v.tolist() for k, v in p.items()},
                         "noise": {"kind": "multiplicative log-normal, median-unbiased",
                                   "sigma_log": CARPAINT_NOISE_SIGMA}}


def main(out: Path) -> None:
    """Write every sample file and ``truth.json`` into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    truth = {"generator": "sample_data/make_inks.py", "seed": SEED,
             "wavelength_nm": WAVELENGTH_NM.tolist(),
             "geometry": {"theta_i_deg": list(THETA_I_DEG),
                          "far_side_only_max_theta_i_deg": FAR_SIDE_ONLY_MAX_DEG,
                          "retro_blocked_deg": RETRO_BLOCKED_DEG},
             "noise": {"kind": "multiplicative log-normal, median-unbiased",
                       "sigma_log": NOISE_SIGMA,
                       "theta_i_70": {"sigma_log": NOISE_SIGMA_70, "bias": BIAS_70}},
             "inks": {}}
    make_inks(out, truth)
    make_carpaint(out, truth)
    (out / "truth.json").write_text(json.dumps(truth, indent=1) + "\n", encoding="utf-8")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent,
                        help="folder to write into (default: this script's folder)")
    main(parser.parse_args().out)
