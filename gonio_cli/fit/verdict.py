"""How good a fit is, in the units a user judges colour by, and the verdict it earns.

A fit's relative RMSE says little about what a viewer sees: a glossy peak 2 % off and a
dark tail 300 % off can give the same number. So every fit is also judged by colour: the
model's and the data's reflectance factor R = π f at each measured configuration, as
CIE 1976 L*a*b* under D65 with the 10° observer (what multi-angle instruments report),
compared by CIEDE2000. A glossy configuration can have R ≫ 1 (L* would pass 100 and lose
its meaning), so a pair whose data Y exceeds 1 is scaled, model and data alike, until the
data's Y is 1: the difference then measures colour and relative brightness at that
configuration. Where the measurement has mirror configurations (θo = θi), the ratio of
the model's Y to the data's at each of them says whether the specular peak is right.

Verdict (thresholds :data:`THRESHOLDS`, documented in docs/fit.md):

- ``good``: mean CIEDE2000 ≤ 0.7, worst ≤ 1.5, every mirror peak within 0.75–1.33 × the data;
- ``poor``: the fit ran but misses one of those;
- ``failed``: the fit could not produce trustworthy parameters (a method's own failure).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import spectra
from ..errors import deg
from ..geometry import measurement_directions, reciprocal_configuration, reflect
from .common import FitData, MIRROR_TOL_DEG
from .uncertainty import LEVEL, half_width_text

#: Limits of a ``good`` fit. Mean CIEDE2000 0.7: about half of a just-noticeable
#: difference, the level of an instrument's inter-instrument agreement on a matte sample;
#: worst 1.5: no configuration clearly visibly off; mirror peak within a factor 4/3 (the
#: accuracy a renderer needs for a highlight's brightness to look right).
THRESHOLDS = {"mean_delta_e": 0.7, "worst_delta_e": 1.5,
              "peak_ratio_min": 0.75, "peak_ratio_max": 1.0 / 0.75}

VERDICTS = ("good", "poor", "failed")

#: Colour is computed only on a grid that covers most of the visible: at least 400–700 nm
#: (the range of multi-angle instruments), where the 10° CMFs hold > 99 % of Y.
COLOUR_RANGE_NM = (400.0, 700.0)


@dataclass
class ColourErrors:
    """Colour of the model against the data at the measured configurations."""

    delta_e: np.ndarray               # (N,) CIEDE2000 per configuration
    theta_i_deg: np.ndarray
    theta_o_deg: np.ndarray
    peak_ratio: dict[float, float]    # θi → Y_model / Y_data at θo = θi
    phi_o_deg: np.ndarray | None = None   # (N,) out of the plane, else None

    @property
    def mean(self) -> float:
        return float(np.mean(self.delta_e))

    @property
    def peaks_off(self) -> dict[float, float]:
        """θi → ratio of the mirror peaks outside the ``good`` range of :data:`THRESHOLDS`."""
        lo, hi = THRESHOLDS["peak_ratio_min"], THRESHOLDS["peak_ratio_max"]
        return {t: r for t, r in self.peak_ratio.items() if not lo <= r <= hi}

    @property
    def worst_index(self) -> int:
        return int(np.argmax(self.delta_e))

    def to_dict(self) -> dict[str, Any]:
        k = self.worst_index
        out: dict[str, Any] = {
            "delta_e2000_mean": self.mean, "delta_e2000_worst": float(self.delta_e[k]),
            "worst_colour_configuration": {"theta_i_deg": float(self.theta_i_deg[k]),
                                           "theta_o_deg": float(self.theta_o_deg[k]),
                                           "delta_e2000": float(self.delta_e[k])},
            "colour": "CIEDE2000 of R = pi f, D65, 10 degree observer; pairs with data "
                      "Y > 1 scaled to data Y = 1"}
        if self.phi_o_deg is not None and self.phi_o_deg[k] != 0.0:
            out["worst_colour_configuration"]["phi_o_deg"] = float(self.phi_o_deg[k])
        if self.peak_ratio:
            out["mirror_peak_y_ratio"] = {f"{t:g}": float(r) for t, r in
                                          self.peak_ratio.items()}
        return out


#: Reciprocal pairs (:func:`reciprocity`) are compared only this far from the mirror
#: (|θo − θi| ≥, the same for a configuration and its reverse), where a sweep is smooth
#: enough to interpolate; a reverse configuration that was not measured is interpolated
#: only between measured θo at most this far apart.
RECIPROCITY_MIN_ASPECULAR_DEG = 15.0
RECIPROCITY_MAX_GAP_DEG = 25.0


@dataclass
class Reciprocity:
    """The data's most non-reciprocal pair: f(θi, θo) against f(θi', θo'), the same two
    directions with light and detector swapped (θi' = |θo|, θo' = θi · sign θo in the
    goniometer's signed plane), measured or interpolated along its θo sweep;
    ``uncertainty``: how far two interpolations of the reverse disagree (0 if measured)."""

    theta_i_deg: float
    theta_o_deg: float
    reverse_theta_i_deg: float
    reverse_theta_o_deg: float
    interpolated: bool
    delta_e: float
    uncertainty: float = 0.0
    phi_o_deg: float = 0.0          # both configurations' azimuth (out of plane: φo' = φo)

    def to_dict(self) -> dict[str, Any]:
        return {"theta_i_deg": self.theta_i_deg, "theta_o_deg": self.theta_o_deg,
                **({"phi_o_deg": self.phi_o_deg} if self.phi_o_deg else {}),
                "reverse_theta_i_deg": self.reverse_theta_i_deg,
                "reverse_theta_o_deg": self.reverse_theta_o_deg,
                "reverse_interpolated": self.interpolated, "delta_e2000": self.delta_e,
                "interpolation_delta_e2000": self.uncertainty}

    def sentence(self) -> str:
        how = " (interpolated)" if self.interpolated else ""
        phi = f", phi_o {deg(self.phi_o_deg)}" if self.phi_o_deg else ""
        return (f"the data are not reciprocal: theta_i {deg(self.theta_i_deg)}, theta_o "
                f"{deg(self.theta_o_deg)}{phi} and its reverse theta_i "
                f"{deg(self.reverse_theta_i_deg)}, theta_o {deg(self.reverse_theta_o_deg)}"
                f"{phi}{how} "
                f"differ by CIEDE2000 "
                f"{self.delta_e:.2f}: no BRDF, being reciprocal, can match both (a "
                f"calibration or alignment that differs between the sweeps?)")


def _reverse_value(o: np.ndarray, fs: np.ndarray, target: float):
    """The sweep (θo ascending ``o``, spectra ``fs``) at θo = ``target``: (measured or
    log-quadratic value, log-linear value, interpolated?) — the measured spectrum twice
    where there is one — or None where it is not bracketed by positive readings at most
    :data:`RECIPROCITY_MAX_GAP_DEG` apart."""
    j = int(np.searchsorted(o, target))
    if j < o.size and abs(o[j] - target) < 1e-6:
        return fs[j], fs[j], False
    if not (0 < j < o.size) or o[j] - o[j - 1] > RECIPROCITY_MAX_GAP_DEG:
        return None
    near = [j - 1, j]
    extra = [k for k in (j - 2, j + 1) if 0 <= k < o.size]
    if extra:                                   # the third point nearest the target
        near.append(min(extra, key=lambda k: abs(o[k] - target)))
    if np.any(fs[near] <= 0):
        return None
    logs = np.log(fs[near])
    w = (target - o[j - 1]) / (o[j] - o[j - 1])
    linear = np.exp((1.0 - w) * logs[0] + w * logs[1])
    if len(near) == 2:
        return linear, linear, True
    x = o[near]
    weights = [np.prod([(target - x[m]) / (x[k] - x[m]) for m in range(3) if m != k])
               for k in range(3)]
    return np.exp(sum(wk * lk for wk, lk in zip(weights, logs))), linear, True


def reciprocity(wavelength_nm, theta_i_deg, theta_o_deg, f, phi_o_deg=None
                ) -> Reciprocity | None:
    """The pair of the data whose colours most break reciprocity, f(ωi, ωo) = f(ωo, ωi),
    which every physical BRDF (so every model here) obeys; None where the data hold no
    pair (or colour cannot be judged).

    Each configuration at least :data:`RECIPROCITY_MIN_ASPECULAR_DEG` from the mirror is
    compared with its reverse (θi' = |θo|, θo' = θi · sign θo; out of the plane (θo, θi,
    φo), :func:`gonio_cli.geometry.reciprocal_configuration`; the angle from the mirror
    direction is measured in 3-D there): measured, or interpolated
    in log f along its sweep (same θi and φo) through the two measured θo around it and the next nearest
    (quadratic; exact for a lobe that is Gaussian in θo), its disagreement with the
    log-linear interpolation kept as the estimate's uncertainty. Colour as
    :func:`colour_errors` (R = π f, D65, 10°, a pair scaled so the first's Y is at most 1).
    The pair with the largest difference net of that uncertainty is returned. A gap
    larger than a good fit's mean error means the data cannot be fitted that well by any
    model: light sources calibrated apart (a multi-angle instrument's 15° and 45° lamps),
    or a sample that moved between sweeps.
    """
    wl = np.asarray(wavelength_nm, dtype=float)
    if not covers_colour(wl):
        return None
    ti = np.asarray(theta_i_deg, dtype=float)
    to = np.asarray(theta_o_deg, dtype=float)
    f = np.asarray(f, dtype=float)
    po = np.zeros_like(ti) if phi_o_deg is None else np.asarray(phi_o_deg, dtype=float)
    rev_i, rev_o, _ = reciprocal_configuration(ti, to, po)
    wi, wo = measurement_directions(ti, to, po)
    aspecular = np.where(po == 0, np.abs(to - ti), np.degrees(np.arccos(np.clip(
        np.sum(wo * reflect(wi), axis=-1), -1.0, 1.0))))
    sweeps = {}
    for t, p in set(zip(ti.tolist(), po.tolist())):
        rows = np.flatnonzero((ti == t) & (po == p))
        rows = rows[np.argsort(to[rows], kind="stable")]
        sweeps[(float(t), float(p))] = (to[rows], f[rows])
    forward, best, simple, where = [], [], [], []
    for k in range(ti.size):
        a, b = float(ti[k]), float(to[k])
        if b == 0.0 or aspecular[k] < RECIPROCITY_MIN_ASPECULAR_DEG or abs(b) == a:
            continue
        ri, ro = float(rev_i[k]), float(rev_o[k])
        if (ri, float(po[k])) not in sweeps:
            continue
        values = _reverse_value(*sweeps[(ri, float(po[k]))], ro)
        if values is None:
            continue
        forward.append(f[k])
        best.append(values[0])
        simple.append(values[1])
        where.append((a, b, ri, ro, values[2], float(po[k])))
    if not forward:
        return None
    white = spectra.reflectance_to_xyz(np.ones(wl.size), wl)
    xyz_f, xyz_b, xyz_s = (spectra.reflectance_to_xyz(np.pi * np.asarray(v), wl)
                           for v in (forward, best, simple))
    y = xyz_f[:, 1]
    scale = np.where(y > 1.0, 1.0 / np.where(y > 1.0, y, 1.0), 1.0)[:, None]
    lab_f, lab_b, lab_s = (spectra.xyz_to_lab(v * scale, white) for v in (xyz_f, xyz_b, xyz_s))
    de = spectra.delta_e_2000(lab_f, lab_b)
    spread = spectra.delta_e_2000(lab_b, lab_s)
    net = np.where(np.isfinite(de) & np.isfinite(spread), de - spread, -np.inf)
    if not np.isfinite(net).any():
        return None
    k = int(np.argmax(net))
    return Reciprocity(*where[k][:5], float(de[k]), float(spread[k]), where[k][5])


def covers_colour(wavelength_nm) -> bool:
    """True when the grid spans :data:`COLOUR_RANGE_NM` (colour can be judged)."""
    wl = np.asarray(wavelength_nm, dtype=float)
    return bool(wl.size >= 2 and wl[0] <= COLOUR_RANGE_NM[0] and wl[-1] >= COLOUR_RANGE_NM[1])


def colour_errors(wavelength_nm, theta_i_deg, theta_o_deg, f_data, f_model,
                  phi_o_deg=None) -> ColourErrors:
    """CIEDE2000 (D65, 10°) of π f_model against π f_data per configuration, (N, L) each;
    the mirror configurations (θo = θi, φo = 0) give the peak ratios."""
    wl = np.asarray(wavelength_nm, dtype=float)
    white = spectra.reflectance_to_xyz(np.ones(wl.size), wl)
    xyz_d = spectra.reflectance_to_xyz(np.pi * np.asarray(f_data, dtype=float), wl)
    xyz_m = spectra.reflectance_to_xyz(np.pi * np.asarray(f_model, dtype=float), wl)
    y = xyz_d[:, 1]
    scale = np.where(y > 1.0, 1.0 / np.where(y > 1.0, y, 1.0), 1.0)[:, None]
    de = spectra.delta_e_2000(spectra.xyz_to_lab(xyz_d * scale, white),
                              spectra.xyz_to_lab(xyz_m * scale, white))
    ti = np.asarray(theta_i_deg, dtype=float)
    to = np.asarray(theta_o_deg, dtype=float)
    peak: dict[float, float] = {}
    for t in np.unique(np.round(ti, 6)):
        k = np.where((np.abs(ti - t) < 1e-6) & (np.abs(to - t) <= MIRROR_TOL_DEG)
                     & (True if phi_o_deg is None else np.asarray(phi_o_deg) == 0))[0]
        if k.size and y[k[0]] > 0:
            peak[float(t)] = float(xyz_m[k[0], 1] / y[k[0]])
    return ColourErrors(de, ti, to, peak,
                        None if phi_o_deg is None else np.asarray(phi_o_deg, dtype=float))


def fit_colour_errors(data: FitData, f_model) -> ColourErrors | None:
    """:func:`colour_errors` of a fit on its data; None where the grid misses the visible."""
    if not covers_colour(data.wavelength_nm):
        return None
    return colour_errors(data.wavelength_nm, data.theta_i_deg, data.theta_o_deg, data.y,
                         f_model, data.phi_o_deg)


def verdict(success: bool, colour: ColourErrors | None,
            max_mean_delta_e: float | None = None) -> tuple[str, list[str]]:
    """("good" | "poor" | "failed", the reasons it is not good). ``max_mean_delta_e``
    replaces the mean threshold (``gonio fit --max-error``)."""
    if not success:
        return "failed", ["the fit failed"]
    if colour is None:
        return "poor", [f"colour cannot be judged: the grid does not cover "
                        f"{COLOUR_RANGE_NM[0]:g}-{COLOUR_RANGE_NM[1]:g} nm"]
    limit = THRESHOLDS["mean_delta_e"] if max_mean_delta_e is None else max_mean_delta_e
    reasons = []
    if colour.mean > limit:
        reasons.append(f"mean CIEDE2000 {colour.mean:.2f} > {limit:g}")
    worst = float(colour.delta_e[colour.worst_index])
    if worst > max(THRESHOLDS["worst_delta_e"], limit):
        reasons.append(f"worst CIEDE2000 {worst:.2f} > {max(THRESHOLDS['worst_delta_e'], limit):g}")
    off = colour.peaks_off
    if off:
        reasons.append("mirror peak off at theta_i " + ", ".join(
            f"{t:g} (x{r:.2f})" for t, r in off.items()))
    return ("poor" if reasons else "good"), reasons


def parameters_text(params: dict[str, Any], intervals: dict[str, Any] | None) -> str:
    """"alpha 0.180 ± 0.004 (95 %)": the scalar parameters with their intervals
    (:mod:`.uncertainty`); "" for a model without scalars or a fit without intervals."""
    if not intervals or not intervals.get("available"):
        return ""
    shown = [half_width_text(name, float(params[name]), entry)
             for name, entry in intervals.get("parameters", {}).items()
             if not isinstance(entry["low"], list) and name in params]
    if not shown:
        return ""
    return f"{', '.join(shown)} ({100 * intervals.get('level', LEVEL):g} %)"
