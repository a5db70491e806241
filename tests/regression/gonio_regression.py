"""Regression artifacts of the sample data: one compute function per artifact, shared by
``tests/test_regression.py`` (compare) and ``tests/regression/refresh.py`` (rewrite).

Every artifact is computed in-process from ``sample_data/`` with the settings of the
pipelines (``pipelines/*.mk``), at a small size where the stage has one (renders at
128²). Three kinds, each with its own file format and comparison:

``numbers``  a dict of arrays → ``references/NAME.npz``; each key compared by relative
             error |a − b| / max(|b|, floor · max|b|) (``floor`` keeps near-zero entries,
             e.g. the LP's zero weights, from dividing by ~0), keys and shapes exactly.
``mask``     halftone labels (H, W) (0 bare, 1 R, 2 G, 3 B) → ``references/NAME.png``
             (the RGB mask ``gonio halftone`` writes); compared exactly, and on failure
             the mismatch fraction and the coverage per ink are reported.
``image``    a render's 8-bit sRGB display image → ``references/NAME.png``; compared by
             CIEDE2000 (mean and 99th percentile, colour-science) and SSIM (scikit-image).

Tolerances live in :data:`ARTIFACTS` beside the reason for each (STYLE 12); the README
in this folder explains them and when to refresh.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
SAMPLE = ROOT / "sample_data"
REFERENCES = HERE / "references"
MANIFEST = REFERENCES / "manifest.json"
REFRESH = ".venv/bin/python tests/regression/refresh.py {name}  (or: make refresh-references)"

#: Render size of the small renders (px, square): large enough that every sphere of
#: Figure 5 and the print's dots cover hundreds of pixels, small enough for ~0.2 s each.
RENDER_PX = 128

# --------------------------------------------------------------- stage computations --
# Cached: several artifacts share a stage's output (the renders read the fits), and the
# test session computes each once.

#: Ingest settings of pipelines/rgbink.mk and carpaint.mk: files and options.
INGEST = {
    "red": (["ink_red.csv"], {}),
    "green": (["ink_green.csv"], {"quantity": "ratio-to-white", "white_reflectance": 0.99}),
    "blue": (["ink_blue_a.csv", "ink_blue_b.csv"], {}),
    "paint": (["carpaint_multiangle.csv"], {"quantity": "reflectance-factor"}),
}
#: Seed 000 leaves out the unreliable 70° row of the inks (RGBINK_FIT in rgbink.mk).
FIT_EXCLUDE = {"red": [70.0], "green": [70.0], "blue": [70.0], "paint": []}
INKS = ("red", "green", "blue")
#: The halftone source and the scene files (inputs recorded in the manifest).
PRINT_IMAGE = SAMPLE / "print_image.png"
SKY = SAMPLE / "sky.exr"
SCENES = SAMPLE / "scenes"
#: Lobe settings of pipelines/lobes.mk: LOBE_COUNT lobes out of an 11-lobe basis.
MAX_LOBES = 11
LOBE_COUNT = 8
#: Exponents of the prefilter artifacts: the diffuse map (E = 1, always written), a wide
#: and a narrow lobe of the paint's range; fixed so that this stage is tested alone.
PREFILTER_EXPONENTS = (8.0, 64.0)


@functools.lru_cache(maxsize=None)
def measurement(name: str):
    from gonio_cli import log
    from gonio_cli.ingest import ingest

    files, options = INGEST[name]
    quiet = log.is_quiet()
    log.set_quiet(True)  # the paint's 5 nm → 10 nm note is expected, not news
    try:
        return ingest([SAMPLE / f for f in files], **options)
    finally:
        log.set_quiet(quiet)


@functools.lru_cache(maxsize=None)
def material(name: str, model: str):
    from gonio_cli.fit import fit, to_material
    from gonio_cli.fit.common import prepare
    from gonio_cli.fit.results import FitOptions

    data = prepare(measurement(name), exclude_theta_i_deg=FIT_EXCLUDE[name])
    result = fit(data, model, FitOptions())
    if not result.result.success:
        raise AssertionError(f"the {model} fit of {name} failed: {result.result.message}")
    return to_material(result)


def demo_materials():
    """The four materials lobes.mk chooses the basis over (inks' eq. 5 fits, the paint)."""
    return [material(i, "goniochromatic") for i in INKS] + [material("paint", "cook-torrance")]


@functools.lru_cache(maxsize=None)
def basis():
    from gonio_cli.lobes.basis import select_basis
    from gonio_cli.lobes.samples import sample_set, target_values

    s = sample_set("seed001")
    targets = [target_values(m, s, "xyz")[0] for m in demo_materials()]
    return select_basis(targets, s, MAX_LOBES, solver="nnls")


@functools.lru_cache(maxsize=None)
def halftone_labels(method: str) -> np.ndarray:
    from gonio_cli import halftone
    from gonio_cli.imageio import read_image

    img = read_image(PRINT_IMAGE)
    prepared = halftone.prepare(img.pixels, is_float=img.is_float)
    return halftone.halftone(prepared.coverage, method).labels


@functools.lru_cache(maxsize=None)
def prefiltered_sky() -> dict[float, np.ndarray]:
    from gonio_cli import prefilter
    from gonio_cli.imageio import read_image

    pixels, _ = prefilter.inputs.validate_map(read_image(SKY).pixels, path=str(SKY))
    results = prefilter.prefilter(pixels, PREFILTER_EXPONENTS, check=False, path=str(SKY))
    return {r.exponent: r.pixels for r in results}


def _render(scene_name: str, variables: dict[str, str]) -> np.ndarray:
    """Render ``sample_data/scenes/SCENE.toml`` at RENDER_PX² with this run's fits and
    halftone written where the scene's ``${out}`` points; returns the uint8 display."""
    from gonio_cli.imageio import write_png
    from gonio_cli.render.pipeline import render_scene
    from gonio_cli.render.scene import load_scene
    from gonio_cli.schemas import write_material, write_measurement

    with tempfile.TemporaryDirectory(prefix="gonio-regression-") as tmp:
        ink_dir = Path(tmp) / "rgbink"
        ink_dir.mkdir()
        for ink in INKS:
            write_measurement(ink_dir / f"{ink}.measurement.json", measurement(ink))
            write_material(ink_dir / f"{ink}.material.json", material(ink, "goniochromatic"))
            write_material(ink_dir / f"{ink}.torrance-sparrow.material.json",
                           material(ink, "torrance-sparrow"))
        from gonio_cli.halftone import labels_to_mask

        write_png(ink_dir / "print.png", labels_to_mask(halftone_labels("floyd-steinberg")))
        scene = load_scene(SCENES / f"{scene_name}.toml", variables={"out": tmp, **variables},
                           overrides={"width": RENDER_PX, "height": RENDER_PX})
        return render_scene(scene).display


# -------------------------------------------------------------- artifact functions --

def ingest_numbers(name: str) -> dict[str, np.ndarray]:
    m = measurement(name)
    out = {"wavelength_nm": m.wavelength_nm, "theta_i_deg": m.theta_i_deg,
           "theta_o_deg": m.theta_o_deg, "brdf": m.brdf, "n_repeats": m.n_repeats}
    if m.brdf_std is not None:
        out["brdf_std"] = m.brdf_std
    return out


#: The data errors of a fit compared (keys of its final method's report): what the fit
#: minimises (log_rmse, the default residuals) and the two linear ones.
FIT_ERRORS = ("log_rmse", "rmse_per_sr", "relative_rmse_percent")


def fit_numbers(name: str, model: str) -> dict[str, np.ndarray]:
    """A fit's parameters and its data errors (those of the final method's report)."""
    mat = material(name, model)
    report = mat.fit["methods"][mat.fit["final"]]
    return {"wavelength_nm": mat.wavelength_nm,
            **{k: np.asarray(v, dtype=float) for k, v in mat.params.items()},
            **{k: np.asarray(report[k], dtype=float) for k in FIT_ERRORS}}


def basis_numbers() -> dict[str, np.ndarray]:
    out = {}
    for step in basis().steps:
        out[f"exponents_{step.n_lobes}"] = np.asarray(step.exponents, dtype=float)
        out[f"error_{step.n_lobes}"] = np.asarray(step.error, dtype=float)
    return out


def lobes_numbers(name: str, model: str, samples: str, solver: str) -> dict[str, np.ndarray]:
    """Weights of LOBE_COUNT lobes whose exponents are those of the *stored* lobes-basis
    reference (this artifact tests the weight fit alone, not the basis search again), and
    the fit's L1 and squared error per view angle and channel, Σ_n |M x − b| and
    Σ_n (M x − b)² (the LP minimises the first, NNLS the second)."""
    from gonio_cli.lobes import design_matrix
    from gonio_cli.lobes.samples import parse_view_angles, sample_set, target_values
    from gonio_cli.lobes.solve import fit_weight_table

    mat = material(name, model)
    e = load_numbers("lobes-basis")[f"exponents_{LOBE_COUNT}"]
    s = sample_set(samples, parse_view_angles("0:80:10"))
    t = fit_weight_table(mat, e, s, "spectral", solver)
    b, _ = target_values(mat, s, "spectral")
    M = design_matrix(s.cos_theta_i(), s.cos_rv(), e)
    x = np.concatenate([t.diffuse[:, None], t.directional_diffuse, t.gloss], axis=1)
    r = np.einsum("nk,nkc->nc", M, x[s.view_index]) - b                  # (N, C)
    l1 = np.stack([np.abs(r[s.view_index == k]).sum(axis=0) for k in range(t.view_angle_deg.size)])
    sse = np.stack([(r[s.view_index == k] ** 2).sum(axis=0) for k in range(t.view_angle_deg.size)])
    return {"exponents": t.exponents, "view_angle_deg": t.view_angle_deg,
            "diffuse": t.diffuse, "directional_diffuse": t.directional_diffuse,
            "gloss": t.gloss, "l1": l1, "sse": sse}


def prefilter_numbers(exponent: float) -> dict[str, np.ndarray]:
    return {"pixels": prefiltered_sky()[exponent]}


# ------------------------------------------------------------------ the registry --

@dataclass
class Artifact:
    """One reference: how to compute it, its kind and tolerances, its inputs."""

    name: str
    kind: str                                  # numbers | mask | image
    compute: Callable[[], Any]
    inputs: list[Path]
    why: str                                   # why these tolerances (in failure messages)
    rel_tol: float = 0.0                       # numbers: max relative error
    floor: float = 1e-12                       # numbers: denominator floor, × max|ref|
    de_mean: float = 0.0                       # image: mean CIEDE2000
    de_p99: float = 0.0                        # image: 99th percentile CIEDE2000
    ssim_min: float = 1.0                      # image: minimum SSIM
    depends: list[str] = field(default_factory=list)
    # numbers: per-key (rel_tol, floor) overriding the two above
    key_tol: dict[str, tuple[float, float]] = field(default_factory=dict)
    # numbers: keys stored (for other artifacts or for reading) but never compared, each
    # with the reason (a result the stage does not determine uniquely)
    stored_only: dict[str, str] = field(default_factory=dict)

    def tolerance(self, key: str) -> tuple[float, float] | None:
        """(rel_tol, floor) of a key, or None if it is stored only (a prefix matches)."""
        if any(key.startswith(prefix) for prefix in self.stored_only):
            return None
        return self.key_tol.get(key, (self.rel_tol, self.floor))

    @property
    def path(self) -> Path:
        return REFERENCES / (self.name + (".npz" if self.kind == "numbers" else ".png"))


#: Relative tolerance of a fit's data errors (log_rmse, ...): see FIT_WHY.
DATA_ERROR_TOL = 1e-4
#: (rel_tol, floor) of the LP optimum per view and channel: see LOBES_WHY.
LP_OPTIMUM_TOL = (1e-4, 1e-2)


def _files(*names: str) -> list[Path]:
    return [SAMPLE / n for n in names]


INGEST_WHY = ("ingest is closed-form arithmetic (unit conversion, averaging of repeats, "
              "linear resampling): only float round-off (~1e-16) can differ")
FIT_WHY = ("identifiable parameters (alpha, and rho and c / f0, linear given alpha: one "
           "minimum of a 1-D profile in alpha): least_squares/nlopt stop at xtol/ftol 1e-10 "
           "and log-alpha xtol 1e-8; a BLAS thread count, summation order or optimiser "
           "version can move the stopping point within that region, amplified ~100x into "
           "the spectra by the linear step: 1e-6 is 100x that, far below any real change "
           "(entries below 1e-6 of a spectrum's peak compared absolutely). Data errors "
           "(log_rmse, rmse_per_sr, relative_rmse_percent): at the minimum they are "
           "stationary, so any optimiser that reaches it gives them to ~1e-10; 1e-4 allows "
           "an equally good point and fails a fit whose error rises (leaving the 70 deg row "
           "in the red ink raises log_rmse by 10x)")
PAINT_FIT_WHY = ("the Cook-Torrance paint is compared by its data errors only (rel 1e-4, as "
                 "for the inks): from one multi-angle instrument's aspecular angles at one "
                 "incidence, ks * F(f0) and the roughness m trade against each other per "
                 "wavelength, so another optimiser may find other kd, ks, m, f0 that fit "
                 "equally well; the parameters are stored for reading, not compared")
BASIS_WHY = ("the basis is compared by its seed 001 eq. 4 error per lobe count, not by its "
             "exponents: the error surface is flat along valleys in log E, and other "
             "stopping rules (nlopt xtol 1e-4 ... 3e-3, ftol 1e-5, fewer evaluations) moved "
             "exponents by up to 6 % but eq. 4 by at most 5e-5 relative; 1e-3 is 20x that, "
             "and a basis 10 % worse fails. The exponents are stored (the lobe-weight "
             "artifacts read them) but not compared")
LOBES_WHY = ("the LP optimum is compared per view and channel (l1 = sum |M x - b|), not "
             "the weights: where the LP is degenerate several vertices are optimal and "
             "HiGHS and the exact simplex (or two HiGHS versions) return different ones "
             "with the same L1 (weights 2e-4 apart on the sample red ink). The exact "
             "simplex reaches the optimum to round-off; HiGHS to its absolute feasibility "
             "tolerance (1.2e-7 above it here): l1 within 1e-4 relative, floored at 1e-2 "
             "of the largest l1 (4.6e-7 absolute, 4x HiGHS's gap), so a channel whose L1 "
             "rises by 10 % fails unless its L1 is below 5e-6 (the lobes fit it exactly)")
NNLS_WHY = ("NNLS has one minimum (the design matrix has full column rank, so the problem "
            "is strictly convex): the weights are identifiable and compared, with the "
            "residual sse; Lawson-Hanson is exact up to round-off on the active set and the "
            "paint material carries the fit's 1e-6: 1e-5; weights below 1e-3 of the "
            "largest are compared absolutely (floor) so a zero weight turning 1e-12 is "
            "not a 'relative' infinity")
PREFILTER_WHY = ("the ring convolution is FFT-based (pocketfft, deterministic) and stored "
                 "as float32 (relative 6e-8); the sun is 1e5x the sky, so texels are "
                 "compared relative to max(|ref|, 1e-7 of the brightest): 1e-5")
IMAGE_WHY = ("a render is deterministic given its inputs; the fits feeding it may move "
             "by 1e-6, which can flip an 8-bit level where a value sits on a rounding "
             "edge (one level is ~0.2-0.5 CIEDE2000 in these colours, on a few pixels). "
             "A just noticeable difference is ~1 CIEDE2000: mean <= 0.05 and p99 <= 0.5 "
             "allow the level flips and nothing a viewer could see; SSIM >= 0.995 "
             "catches a moved or blurred structure at unchanged colour")


def _registry() -> dict[str, Artifact]:
    arts: list[Artifact] = []
    for name, (files, _) in INGEST.items():
        arts.append(Artifact(f"ingest-{name}", "numbers", functools.partial(ingest_numbers, name),
                             _files(*files), INGEST_WHY, rel_tol=1e-9))
    fits = [(ink, model) for ink in INKS for model in ("goniochromatic", "torrance-sparrow")]
    data_errors = {k: (DATA_ERROR_TOL, 0.0) for k in FIT_ERRORS}
    for name, model in fits:
        arts.append(Artifact(f"fit-{name}-{model}", "numbers",
                             functools.partial(fit_numbers, name, model),
                             _files(*INGEST[name][0]), FIT_WHY, rel_tol=1e-6, floor=1e-6,
                             key_tol=data_errors))
    arts.append(Artifact("fit-paint-cook-torrance", "numbers",
                         functools.partial(fit_numbers, "paint", "cook-torrance"),
                         _files(*INGEST["paint"][0]), PAINT_FIT_WHY, rel_tol=1e-6, floor=1e-6,
                         key_tol=data_errors,
                         stored_only={k: "not identifiable" for k in ("kd", "ks", "m", "f0")}))
    every_ink = [SAMPLE / f for n in INKS + ("paint",) for f in INGEST[n][0]]
    arts.append(Artifact("lobes-basis", "numbers", basis_numbers, every_ink, BASIS_WHY,
                         rel_tol=1e-3,
                         stored_only={"exponents_": "a flat valley in log E; read by the "
                                                   "lobe-weight artifacts"}))
    lp_weights = {k: "a degenerate LP has several optimal vertices"
                  for k in ("diffuse", "directional_diffuse", "gloss")}
    arts.append(Artifact("lobes-red", "numbers",
                         functools.partial(lobes_numbers, "red", "goniochromatic", "seed001", "lp"),
                         _files("ink_red.csv"), LOBES_WHY, rel_tol=1e-5, floor=1e-3,
                         depends=["lobes-basis"], key_tol={"l1": LP_OPTIMUM_TOL},
                         stored_only={**lp_weights, "sse": "the LP does not minimise it"}))
    arts.append(Artifact("lobes-paint", "numbers",
                         functools.partial(lobes_numbers, "paint", "cook-torrance", "hemisphere",
                                           "nnls"),
                         _files("carpaint_multiangle.csv"), NNLS_WHY, rel_tol=1e-5, floor=1e-3,
                         depends=["lobes-basis"],
                         stored_only={"l1": "NNLS does not minimise it"}))
    mask_why = "the numba kernels are deterministic integer/float loops: exactly equal"
    for method in ("floyd-steinberg", "blue-noise"):
        arts.append(Artifact(f"halftone-{method}", "mask",
                             functools.partial(halftone_labels, method), [PRINT_IMAGE], mask_why))
    for e in (1.0,) + PREFILTER_EXPONENTS:
        arts.append(Artifact(f"prefilter-sky-E{e:g}", "numbers",
                             functools.partial(prefilter_numbers, e), [SKY], PREFILTER_WHY,
                             rel_tol=1e-5, floor=1e-7))
    ink_files = [SAMPLE / f for n in INKS for f in INGEST[n][0]]
    image = dict(de_mean=0.05, de_p99=0.5, ssim_min=0.995)
    arts.append(Artifact("render-figure5-small", "image",
                         functools.partial(_render, "figure5", {}),
                         ink_files + [SCENES / "figure5.toml"], IMAGE_WHY, **image))
    arts.append(Artifact("render-print-small", "image",
                         functools.partial(_render, "print", {"illuminant": "D65"}),
                         ink_files + [PRINT_IMAGE, SCENES / "print.toml", SCENES / "sheet.obj"],
                         IMAGE_WHY, **image))
    return {a.name: a for a in arts}


ARTIFACTS: dict[str, Artifact] = _registry()


# ------------------------------------------------------------------ storage --

def load_numbers(name: str) -> dict[str, np.ndarray]:
    path = ARTIFACTS[name].path
    if not path.is_file():
        raise FileNotFoundError(f"{name}: no reference {path.relative_to(ROOT)}; "
                                f"create it with {REFRESH.format(name=name)}")
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


def labels_from_mask(rgb: np.ndarray) -> np.ndarray:
    """RGB mask (H, W, 3) of 0/1 (or 0/255) → labels (H, W) uint8 (0 bare, 1 R, 2 G, 3 B)."""
    on = np.asarray(rgb)[..., :3] > 0.5 * np.asarray(rgb).max(initial=0)
    if np.any(on.sum(axis=-1) > 1):
        raise ValueError("more than one ink at a pixel: not a halftone mask")
    return np.where(on.any(axis=-1), on.argmax(axis=-1) + 1, 0).astype(np.uint8)


def load(art: Artifact):
    """The stored reference, in the form ``art.compute`` returns."""
    if art.kind == "numbers":
        return load_numbers(art.name)
    from gonio_cli.imageio import read_image

    if not art.path.is_file():
        raise FileNotFoundError(f"{art.name}: no reference {art.path.relative_to(ROOT)}; "
                                f"create it with {REFRESH.format(name=art.name)}")
    pixels = read_image(art.path).pixels[..., :3]
    if art.kind == "mask":
        return labels_from_mask(pixels)
    return np.round(pixels * 255.0).astype(np.uint8)


def save(art: Artifact, value) -> None:
    REFERENCES.mkdir(exist_ok=True)
    if art.kind == "numbers":
        # atomic: temp file in the same folder, then os.replace (STYLE 13)
        fd, tmp = tempfile.mkstemp(dir=REFERENCES, suffix=".npz")
        os.close(fd)
        with open(tmp, "wb") as f:
            np.savez_compressed(f, **value)
        os.chmod(tmp, 0o644)  # mkstemp's 0600 would hide the reference from others
        os.replace(tmp, art.path)
        return
    from gonio_cli.imageio import write_png

    meta = {"schema": "gonio.regression-reference", "artifact": art.name}
    if art.kind == "mask":
        from gonio_cli.halftone import labels_to_mask

        write_png(art.path, labels_to_mask(value), metadata=meta)
    else:
        write_png(art.path, value, metadata=meta)


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def read_manifest() -> dict[str, Any]:
    if not MANIFEST.is_file():
        return {}
    doc = json.loads(MANIFEST.read_text())
    if doc.get("schema") != "gonio.regression-manifest" or doc.get("schema_version") != 1:
        raise ValueError(f"{MANIFEST}: not a gonio.regression-manifest v1")
    return doc["artifacts"]


def write_manifest(entries: dict[str, Any]) -> None:
    from gonio_cli import __version__

    doc = {"schema": "gonio.regression-manifest", "schema_version": 1,
           "gonio_version": __version__, "artifacts": dict(sorted(entries.items()))}
    fd, tmp = tempfile.mkstemp(dir=REFERENCES, suffix=".json")
    with os.fdopen(fd, "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")
    os.chmod(tmp, 0o644)
    os.replace(tmp, MANIFEST)


def manifest_entry(art: Artifact) -> dict[str, Any]:
    return {"file": art.path.name, "kind": art.kind,
            "inputs": {str(p.relative_to(ROOT)): sha256(p) for p in art.inputs},
            "tolerances": tolerance_text(art)}


def changed_inputs(art: Artifact) -> list[str]:
    """Inputs whose sha256 differs from the manifest's (the likely cause of a failure)."""
    entry = read_manifest().get(art.name, {})
    return [p for p, h in entry.get("inputs", {}).items()
            if not (ROOT / p).is_file() or sha256(ROOT / p) != h]


# --------------------------------------------------------------- comparison --

@dataclass
class Check:
    metric: str
    value: float
    tolerance: float
    ok: bool
    detail: str = ""

    def line(self) -> str:
        sign = "<=" if self.metric != "SSIM" else ">="
        verdict = "ok" if self.ok else "FAILS"
        return (f"{self.metric} = {self.value:.3g} ({verdict}: tolerance {sign} "
                f"{self.tolerance:.3g}){' ' + self.detail if self.detail else ''}")


def tolerance_text(art: Artifact) -> str:
    if art.kind == "numbers":
        text = f"relative error <= {art.rel_tol:g} (floor {art.floor:g} x max|ref|)"
        extra = sorted({f"{tol:g}" for tol, _ in art.key_tol.values()})
        if art.key_tol:
            text += f"; {', '.join(sorted(art.key_tol))}: <= {', '.join(extra)}"
        if art.stored_only:
            text += f"; stored, not compared: {', '.join(sorted(art.stored_only))}"
        return text
    if art.kind == "mask":
        return "exactly equal labels"
    return (f"CIEDE2000 mean <= {art.de_mean:g}, p99 <= {art.de_p99:g}; "
            f"SSIM >= {art.ssim_min:g}")


def relative_error(value: np.ndarray, ref: np.ndarray, floor: float) -> np.ndarray:
    """|value − ref| / max(|ref|, floor · max|ref|), elementwise."""
    scale = floor * float(np.max(np.abs(ref), initial=0.0))
    denom = np.maximum(np.abs(ref), scale)
    diff = np.abs(value - ref)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(denom > 0, diff / np.where(denom > 0, denom, 1.0),
                        np.where(diff > 0, np.inf, 0.0))


def compare_numbers(art: Artifact, value: dict, ref: dict) -> list[Check]:
    checks = []
    if set(value) != set(ref):
        checks.append(Check("keys", 1.0, 0.0, False,
                            f"computed {sorted(value)} vs reference {sorted(ref)}"))
    for key in sorted(set(value) & set(ref)):
        a, b = np.asarray(value[key], dtype=float), np.asarray(ref[key], dtype=float)
        if a.shape != b.shape:
            checks.append(Check(f"{key}: shape", 1.0, 0.0, False, f"{a.shape} vs {b.shape}"))
            continue
        tolerance = art.tolerance(key)
        if a.size == 0 or tolerance is None:
            continue
        rel_tol, floor = tolerance
        rel = relative_error(a, b, floor)
        bad_nan = np.isnan(a) != np.isnan(b)
        worst = np.unravel_index(int(np.nanargmax(np.where(np.isnan(rel), -1, rel))), rel.shape)
        err = float(np.nanmax(rel)) if not bad_nan.any() else float("inf")
        detail = f"at index {tuple(int(i) for i in worst)}: {a[worst]:.9g} vs reference {b[worst]:.9g}"
        checks.append(Check(f"{key}: relative error", err, rel_tol, err <= rel_tol, detail))
    return checks


def compare_mask(art: Artifact, value: np.ndarray, ref: np.ndarray) -> list[Check]:
    if value.shape != ref.shape:
        return [Check("shape", 1.0, 0.0, False, f"{value.shape} vs reference {ref.shape}")]
    frac = float(np.mean(value != ref))
    cov = " ".join(f"{ink}={np.mean(value == k):.4f}/{np.mean(ref == k):.4f}"
                   for k, ink in enumerate(("bare", "R", "G", "B")))
    return [Check("mismatched pixel fraction", frac, 0.0, frac == 0.0,
                  f"(coverage computed/reference: {cov})")]


def delta_e_2000(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """CIEDE2000 between two 8-bit sRGB images (D65), per pixel (colour-science)."""
    import colour

    def lab(img):
        rgb = np.asarray(img, dtype=np.float64) / 255.0
        return colour.XYZ_to_Lab(colour.sRGB_to_XYZ(rgb))

    return colour.delta_E(lab(a), lab(b), method="CIE 2000")


def ssim(a: np.ndarray, b: np.ndarray) -> float:
    from skimage.metrics import structural_similarity

    return float(structural_similarity(a, b, channel_axis=-1, data_range=255))


def compare_image(art: Artifact, value: np.ndarray, ref: np.ndarray) -> list[Check]:
    if value.shape != ref.shape:
        return [Check("shape", 1.0, 0.0, False, f"{value.shape} vs reference {ref.shape}")]
    de = delta_e_2000(value, ref)
    mean, p99 = float(de.mean()), float(np.percentile(de, 99))
    s = ssim(value, ref)
    where = np.unravel_index(int(de.argmax()), de.shape)
    return [Check("CIEDE2000 mean", mean, art.de_mean, mean <= art.de_mean),
            Check("CIEDE2000 p99", p99, art.de_p99, p99 <= art.de_p99,
                  f"(max {de.max():.3g} at row, col {tuple(int(i) for i in where)})"),
            Check("SSIM", s, art.ssim_min, s >= art.ssim_min)]


COMPARE = {"numbers": compare_numbers, "mask": compare_mask, "image": compare_image}


def compare(art: Artifact, value, ref) -> list[Check]:
    return COMPARE[art.kind](art, value, ref)


def failure_message(art: Artifact, checks: list[Check]) -> str:
    lines = [f"regression artifact {art.name} ({art.path.relative_to(ROOT)}) shifted:"]
    lines += ["  " + c.line() for c in checks if not c.ok]
    lines.append(f"  why this tolerance: {art.why}")
    changed = changed_inputs(art)
    if changed:
        lines.append(f"  inputs changed since the reference was made: {', '.join(changed)}")
    lines.append(f"  if the change is intended, refresh it: {REFRESH.format(name=art.name)}"
                 " and give the reason in the commit message (tests/regression/README.md)")
    return "\n".join(lines)
