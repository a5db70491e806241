"""The "measured" reference material: a measurement interpolated for rendering.

Seed 000 (Figure 5, Table 1) renders its reference spheres "using filtered averaging of the
measurements based on the four nearest neighbors in projected deviation vector
coordinates" (seed 000 ref. 23, Tongbuasirilai, Unger & Kurt 2017). For an isotropic BRDF
that is symmetric about the projected deviation vector (as seed 000 assumes to fit
in-plane data), we use these coordinates:

* frame: the normal N and the tangent x = −(ωi − (N·ωi) N)/‖·‖, so that the light sits on
  the −x side as on the goniometer (docs/conventions.md); y = N × x. At θi = 0 (x undefined,
  isotropy makes it arbitrary) x is taken along the view's tangent component.
* ωr = 2 (N·ωi) N − ωi, the mirror direction; the **projected deviation vector** is the
  tangent-plane projection of ωo − ωr: d = (d_x, d_y) = ((ωo − ωr)·x, ωo·y).
  In the plane of incidence d_y = 0 and d_x = u = sin θo − sin θi (θo signed).
* coordinates (θi, u): a measured configuration (θi, θo) sits at u = sin θo − sin θi.

Interpolation (the four nearest neighbours): the measured θi values form rows; a query
takes the two rows bracketing its θi (θi outside the measured range takes the nearest row)
and, in each row, the two measured configurations bracketing its u (beyond the row's
range, the end value blends into the value at −u over :data:`MIRROR_TRANSITION_U`, by the
symmetry below); the four values are blended bilinearly: linear in u within each row,
then linear in θi. At a measured configuration this returns the measurement exactly, and
it is continuous everywhere.

Out of the plane (d_y ≠ 0), the symmetry about the deviation vector maps the query to the
in-plane points at the same distance r = ‖d‖ on either side of the mirror direction,
blended by the direction of d: with cos φ = d_x / r,

    f = ½ (1 + cos φ) f(θi, +r) + ½ (1 − cos φ) f(θi, −r),

which is f(θi, d_x) in the plane (cos φ = ±1) and continuous elsewhere.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..schemas import Measurement
from .measured_smooth import SmoothMeasured, plane_of_incidence

#: Two θi closer than this (degrees) are the same row of the measurement (CSV noise).
THETA_ROW_TOL_DEG = 1e-6

#: Width in u of the blend from a row's end value to its mirrored value −u beyond the
#: measured range (≈ 6° of θo near the normal): wide enough to hide the seam, narrow
#: enough that the θi interpolation between rows of different ranges stays on the ends.
MIRROR_TRANSITION_U = 0.1

#: Tangent components shorter than this are "along the normal" (θ < 1e-9 rad), where the
#: azimuth of the frame is undefined and another choice is made (module docstring).
TANGENT_EPS = 1e-9


class MeasuredMaterial:
    """A :class:`~gonio_cli.schemas.Measurement` as a renderable BRDF (module docstring).

    Parameters
    ----------
    measurement : the in-plane measurement (``gonio ingest``), BRDF in sr⁻¹, no cos θi.

    Attributes
    ----------
    wavelength_nm : (n_λ,) the measurement's grid.
    theta_i_deg : (R,) measured rows (increasing); rows : per row (u (k,), brdf (k, n_λ))
        sorted by u.
    """

    def __init__(self, measurement: Measurement, name: str = ""):
        measurement = plane_of_incidence(measurement, name)
        self.measurement = measurement
        self.name = name
        self.wavelength_nm = measurement.wavelength_nm
        ti = measurement.theta_i_deg
        to = measurement.theta_o_deg
        u_all = np.sin(np.radians(to)) - np.sin(np.radians(ti))
        rows = np.unique(np.round(ti / THETA_ROW_TOL_DEG) * THETA_ROW_TOL_DEG)
        self.theta_i_deg = rows
        self.rows: list[tuple[np.ndarray, np.ndarray]] = []
        for r in rows:
            sel = np.abs(ti - r) <= THETA_ROW_TOL_DEG
            u, order = np.unique(u_all[sel], return_index=True)
            if u.size < np.count_nonzero(sel):
                raise InputError(f"measurement {name}: θi = {r:g}° repeats a θo", fix=
                                 "merge the repeats with gonio ingest")
            self.rows.append((u, measurement.brdf[sel][order]))

    # ------------------------------------------------------------------ interpolation --

    def _row(self, k: int, u: np.ndarray) -> np.ndarray:
        """Linear interpolation of row k in u: (n,) → (n, n_λ).

        Beyond the row's measured range, the symmetry about the mirror direction takes
        over: the end value blends into the value at −u (itself clamped to the range)
        over :data:`MIRROR_TRANSITION_U`, so the extension is continuous. (Out of the
        plane ‖d‖ reaches 2 while the far side of a 70° row ends at u = sin 80° − sin 70°
        = 0.045; clamping there would spread the near-mirror value over the sphere.)
        """
        us, values = self.rows[k]
        if us.size == 1:
            return np.broadcast_to(values[0], u.shape + values.shape[1:]).copy()

        def linear(q):
            j = np.clip(np.searchsorted(us, q, side="right") - 1, 0, us.size - 2)
            t = np.clip((q - us[j]) / (us[j + 1] - us[j]), 0.0, 1.0)[:, None]
            return values[j] * (1.0 - t) + values[j + 1] * t

        out = linear(u)
        beyond = np.clip(np.maximum(u - us[-1], us[0] - u) / MIRROR_TRANSITION_U, 0.0, 1.0)
        far = beyond > 0
        if np.any(far):
            w = beyond[far, None]
            out[far] = (1.0 - w) * out[far] + w * linear(-u[far])
        return out

    def evaluate_pdv(self, theta_i_deg: np.ndarray, u: np.ndarray) -> np.ndarray:
        """f at (θi, u) (n,) in-plane coordinates: bilinear in the four neighbours (n, n_λ)."""
        ti = np.asarray(theta_i_deg, dtype=float).reshape(-1)
        u = np.asarray(u, dtype=float).reshape(-1)
        rows = self.theta_i_deg
        out = np.zeros((ti.size, self.wavelength_nm.size))
        if rows.size == 1:
            return self._row(0, u)
        pos = np.interp(ti, rows, np.arange(rows.size, dtype=float))
        k0 = np.minimum(pos.astype(np.intp), rows.size - 2)
        t = pos - k0
        for k in range(rows.size):
            w = np.where(k0 == k, 1.0 - t, 0.0) + np.where(k0 + 1 == k, t, 0.0)
            sel = w > 0
            if np.any(sel):
                out[sel] += w[sel, None] * self._row(k, u[sel])
        return out

    def evaluate_directions(self, wi, wo, normal) -> np.ndarray:
        """BRDF (sr⁻¹, no cos θi) at direction pairs (..., 3) about normals (..., 3).

        Returns (..., n_λ); 0 where the light or the view is below the horizon.
        """
        wi, wo, n = np.broadcast_arrays(np.asarray(wi, float), np.asarray(wo, float),
                                        np.asarray(normal, float))
        shape = wi.shape[:-1]
        wi, wo, n = (a.reshape(-1, 3) for a in (wi, wo, n))
        cos_i = np.einsum("ij,ij->i", n, wi)
        cos_o = np.einsum("ij,ij->i", n, wo)
        wi_t = wi - cos_i[:, None] * n
        wo_t = wo - cos_o[:, None] * n
        len_i = np.linalg.norm(wi_t, axis=1)
        len_o = np.linalg.norm(wo_t, axis=1)
        # x: away from the light's tangent part; at θi ≈ 0 along the view's (d_y = 0)
        x = np.where((len_i > TANGENT_EPS)[:, None], -wi_t / np.maximum(len_i, TANGENT_EPS)[:, None],
                     wo_t / np.maximum(len_o, TANGENT_EPS)[:, None])
        # both along the normal: any tangent will do (then d = 0)
        degenerate = (len_i <= TANGENT_EPS) & (len_o <= TANGENT_EPS)
        if np.any(degenerate):
            helper = np.where(np.abs(n[degenerate, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
            t = helper - np.sum(helper * n[degenerate], axis=1, keepdims=True) * n[degenerate]
            x[degenerate] = t / np.linalg.norm(t, axis=1, keepdims=True)
        y = np.cross(n, x)
        sin_i = np.clip(len_i, 0.0, 1.0)
        d_x = np.einsum("ij,ij->i", wo, x) - sin_i         # (ωo − ωr)·x, ωr·x = sin θi
        d_y = np.einsum("ij,ij->i", wo, y)                  # ωr·y = 0
        theta_i = np.degrees(np.arctan2(len_i, cos_i))
        r = np.hypot(d_x, d_y)
        cos_phi = np.where(r > 0, d_x / np.where(r > 0, r, 1.0), 1.0)
        w_plus = 0.5 * (1.0 + cos_phi)
        f = np.zeros((r.size, self.wavelength_nm.size))
        plus = w_plus > 0
        minus = w_plus < 1
        if np.any(plus):
            f[plus] += w_plus[plus, None] * self.evaluate_pdv(theta_i[plus], r[plus])
        if np.any(minus):
            f[minus] += (1.0 - w_plus[minus, None]) * self.evaluate_pdv(theta_i[minus],
                                                                       -r[minus])
        visible = (cos_i > 0) & (cos_o > 0)
        f[~visible] = 0.0
        return f.reshape(shape + (self.wavelength_nm.size,))


def _smooth(measurement: Measurement, name: str = ""):
    return SmoothMeasured(measurement, name)


#: The interpolations of a measured reference, by the name a scene's ``interpolation``
#: key takes: ``smooth`` (:mod:`.measured_smooth`, thin-plate spline in (θh, σ), the
#: default) and ``four-nearest`` (this module: seed 000's four nearest neighbours in
#: projected-deviation-vector coordinates, piecewise linear, with creases at its rows).
INTERPOLATIONS = {"smooth": _smooth, "four-nearest": MeasuredMaterial}

#: The interpolation of a measured object that names none.
DEFAULT_INTERPOLATION = "smooth"


def measured_material(measurement: Measurement, name: str = "",
                      interpolation: str = DEFAULT_INTERPOLATION):
    """The renderable reference of a measurement (seed 000 Figure 5's leftmost column) by
    one of :data:`INTERPOLATIONS`."""
    if interpolation not in INTERPOLATIONS:
        raise InputError(f"measurement {name}: interpolation {interpolation!r} is unknown",
                         fix="one of " + ", ".join(INTERPOLATIONS))
    return INTERPOLATIONS[interpolation](measurement, name)
