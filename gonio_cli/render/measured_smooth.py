"""A smooth measured reference: the in-plane measurement as a smooth, reciprocal BRDF.

Coordinates. Each configuration (ωi, ωo) about the normal N maps to

    θh = angle(N, h),  h = (ωi + ωo)/‖ωi + ωo‖          (seed 000 eq. 1)
    σ  = (θi + θo)/2,  θi, θo the polar angles (unsigned)  (seed 000 eq. 6's angle)

— the two angles seed 000's eq. 5 depends on (D(θh) and E(λ; cos σ)). Both are symmetric
in ωi ↔ ωo (reciprocity holds by construction) and 0 ≤ θh ≤ σ < 90° (θh is the
distance from N to the midpoint of the arc ωi–ωo, which the convexity of the distance
on the hemisphere keeps below the mean distance σ). The in-plane goniometer covers the
whole triangle: a far-side configuration (θo > 0) is at (|θo − θi|/2, (θi + θo)/2), a
light-side one (θo < 0) on the edge θh = σ = (θi + |θo|)/2. Light-side configurations
that meet there (reciprocal pairs, and configurations with the same θi + |θo|) are
averaged in log. Out of the plane the reference therefore *assumes* the BRDF is a
function of (θh, σ), as eq. 5 is; the four-nearest rule of :mod:`.measured` assumed a
symmetry about the mirror direction instead.

Interpolant. A thin-plate spline (scipy.interpolate.RBFInterpolator, with its linear
polynomial) through log f at the merged configurations, smoothed as much as the
measurement's noise allows (:func:`choose_smoothing`), all wavelengths at once, with
each configuration also placed at −θh so that the spline is even in θh: smooth across the
mirror direction, where θh itself has a cone. log f keeps a narrow peak from ringing
below zero; exp makes every value positive. The spline is sampled once per material on a
(θh, σ) grid of :data:`GRID_STEP_DEG` and read per pixel by a cubic B-spline
(scipy.ndimage.map_coordinates, order 3: C² like the spline it samples, so the lookup
adds no kink), one wavelength at a time.

Outside the measured range. A (θh, σ) is in the measured range when it lies inside the
configurations' convex hull (by :data:`HULL_MARGIN_NODES`) and within :data:`MEASURED_RADIUS_DEG` of one of them
(mirror copies included).
Between the configurations' convex hull and that range (gaps of the sweep, and the
grazing region θh > 90° − σ that no in-plane configuration reaches) the spline
interpolates across the gap; beyond the hull, a grid node takes the spline's value at the
nearest point of the hull (the nearest measured direction: no extrapolated trend), which
is continuous there but has a slope break (a crease, outside the measured range only).
:attr:`SmoothMeasured.outside_samples` counts the shaded samples outside the measured
range; the renderer reports it (``measured_outside_samples`` in the run report's
counts), so a render says how much of it is interpolated from afar or clamped.
"""

from __future__ import annotations

import numpy as np

from .. import log
from ..schemas import Measurement

#: Step (degrees) of the (θh, σ) lookup grid: 181² nodes over [0°, 90°]². Between nodes
#: the cubic B-spline's error on the spline it samples is O(h⁴ f''''): measured < 0.1 % of
#: f on the α = 0.3 ink of the tests, below the interpolation's own error by 50×.
GRID_STEP_DEG = 0.5

#: Upper end (degrees) of both grid axes: θh ≤ σ < 90°.
GRID_MAX_DEG = 90.0

#: Floor of f relative to the measurement's largest value before the log: a measured 0
#: (or a dark reading below the noise) would be −∞; 1e-6 of the peak is below what any
#: 8-bit display of the peak shows, so the floor is never seen.
FLOOR_REL = 1e-6

#: Two configurations whose (θh, σ) differ by less than this (degrees) are one point of
#: the spline (merged in log): the spline's system would be singular.
MERGE_TOL_DEG = 1e-6

#: Noise (standard deviation of log f) of a measurement without repeats: 2 %, a
#: spectrometer's reading noise as the sample data's (gonio_cli.synthetic) and seed 000's.
DEFAULT_NOISE_LOG = 0.02

#: Smoothing values tried (the RBF's λ added to its kernel matrix's diagonal, in the
#: kernel's units: r² log r with r in degrees), a quarter decade apart.
SMOOTHING_CANDIDATES = tuple(10.0 ** np.arange(-1.0, 4.01, 0.25))

#: A (θh, σ) within this distance (degrees) of a measured configuration is in the
#: measured range: two steps of θh at the usual 5° θo spacing (2.5° each), so the gaps
#: of a sweep with its 10° retro-reflection hole, and the region no in-plane
#: configuration reaches (θh > 90° − σ off the edge θh = σ, grazing both ways), are out.
MEASURED_RADIUS_DEG = 5.0

#: Grid nodes between the measured range and the hull's edge (2°): the interpolating cubic
#: B-spline spreads the clamp's slope break inside, decaying by |√3 − 2| = 0.27 a node
#: (its prefilter's pole): 4 nodes in, 0.5 % of it is left.
HULL_MARGIN_NODES = 4

#: Grid nodes this far (degrees) past the edge θh = σ take the spline's continuation
#: instead of the clamp: the cubic B-spline reads 2 nodes (1°) across, and a wider band
#: would let the linear continuation of log f grow.
DIAGONAL_REACH_DEG = 2.0

#: The spline's kernel: C¹ everywhere, smooth away from the configurations, the
#: minimum-bending surface through them (no shape parameter to choose).
KERNEL = "thin_plate_spline"


def noise_log(measurement: Measurement) -> float:
    """The measurement's noise as a standard deviation of log f: the median of
    brdf_std / brdf where repeats were read (``gonio ingest`` keeps their spread), else
    :data:`DEFAULT_NOISE_LOG`."""
    std = measurement.brdf_std
    if std is None:
        return DEFAULT_NOISE_LOG
    brdf = np.asarray(measurement.brdf, float)
    ok = brdf > 0
    return float(np.median(np.asarray(std, float)[ok] / brdf[ok])) if np.any(ok) \
        else DEFAULT_NOISE_LOG


def choose_smoothing(points: np.ndarray, values: np.ndarray, n_own: int,
                     noise: float) -> float:
    """The spline's smoothing λ by Morozov's discrepancy principle: the largest of
    :data:`SMOOTHING_CANDIDATES` whose RMS residual at the configurations (the first
    ``n_own`` rows of ``points`` (m, 2) / ``values`` (m, n_λ), log f) stays within the
    noise ``noise`` (log units). Smoothing less would draw the noise into ripples of the
    sampling's period (2.5° of θh at 5° θo steps: 2–3 px on Figure 5's spheres)."""
    from scipy.interpolate import RBFInterpolator

    best = 0.0
    for lam in SMOOTHING_CANDIDATES:
        fit = RBFInterpolator(points, values, kernel=KERNEL, smoothing=lam)
        res = fit(points[:n_own]) - values[:n_own]
        if np.sqrt(np.mean(res ** 2)) > noise:
            break
        best = lam
    return best


def in_plane_coordinates(theta_i_deg, theta_o_deg) -> tuple[np.ndarray, np.ndarray]:
    """(θh, σ) in degrees (N,) of in-plane configurations (θi ≥ 0, θo signed, degrees):
    θh = |θo − θi|/2, σ = (θi + |θo|)/2 (module docstring)."""
    ti = np.asarray(theta_i_deg, float)
    to = np.asarray(theta_o_deg, float)
    return np.abs(to - ti) / 2.0, (ti + np.abs(to)) / 2.0


def direction_coordinates(wi, wo, normal):
    """(θh, σ) in degrees (n,), cos θi and cos θo (n,) of direction pairs (n, 3) about
    unit normals (n, 3); h is eq. 1's half vector (along N when ωo = −ωi: θh = 0)."""
    cos_i = np.einsum("ij,ij->i", normal, wi)
    cos_o = np.einsum("ij,ij->i", normal, wo)
    h = wi + wo
    length = np.linalg.norm(h, axis=1)
    cos_h = np.where(length > 0, np.einsum("ij,ij->i", normal, h) / np.where(length > 0,
                                                                            length, 1.0), 1.0)
    theta_h = np.degrees(np.arccos(np.clip(cos_h, -1.0, 1.0)))
    sigma = 0.5 * np.degrees(np.arccos(np.clip(cos_i, -1.0, 1.0))
                             + np.arccos(np.clip(cos_o, -1.0, 1.0)))
    return theta_h, sigma, cos_i, cos_o


def _hull_clamp(points: np.ndarray, hull_pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(clamped (n, 2), inside (n,)): each point, or the nearest point of the convex hull
    of ``hull_pts`` (m, 2) when it lies outside."""
    from scipy.spatial import ConvexHull, Delaunay

    inside = Delaunay(hull_pts).find_simplex(points) >= 0
    out = points.copy()
    q = points[~inside]
    if q.size:
        hull = ConvexHull(hull_pts)
        best, best_d = np.empty_like(q), np.full(q.shape[0], np.inf)
        for a_i, b_i in hull.simplices:
            a, b = hull_pts[a_i], hull_pts[b_i]
            t = np.clip((q - a) @ (b - a) / np.dot(b - a, b - a), 0.0, 1.0)
            p = a + t[:, None] * (b - a)
            d = np.sum((q - p) ** 2, axis=1)
            closer = d < best_d
            best[closer], best_d[closer] = p[closer], d[closer]
        out[~inside] = best
    return out, inside


def plane_of_incidence(measurement: Measurement, name: str = "") -> Measurement:
    """The rows an in-plane interpolant reads (:meth:`Measurement.in_plane`, φo = 0); a
    measurement with configurations out of the plane gets a warning that names how many
    are left out."""
    kept = measurement.in_plane()
    left = measurement.n_configurations - kept.n_configurations
    if left:
        log.warn(f"{name or 'the measured material'}: rendered from its "
                 f"{kept.n_configurations} configurations in the plane of incidence; the "
                 f"{left} out of the plane are not used (the measured interpolants are "
                 f"in-plane; fit a model to use them all)")
    return kept


class SmoothMeasured:
    """A :class:`~gonio_cli.schemas.Measurement` as a smooth renderable BRDF (module
    docstring): ``evaluate_directions`` as :class:`.measured.MeasuredMaterial`'s.

    Attributes
    ----------
    wavelength_nm : (n_λ,) the measurement's grid.
    points : (m, 2) the spline's configurations (θh, σ) in degrees, mirror copies included.
    outside_samples : int — shaded samples outside the measured range so far.
    """

    def __init__(self, measurement: Measurement, name: str = ""):
        from scipy.interpolate import RBFInterpolator
        from scipy.ndimage import binary_erosion, spline_filter1d

        measurement = plane_of_incidence(measurement, name)
        self.measurement = measurement
        self.name = name
        self.wavelength_nm = measurement.wavelength_nm
        self.outside_samples = 0
        th, sg = in_plane_coordinates(measurement.theta_i_deg, measurement.theta_o_deg)
        brdf = np.asarray(measurement.brdf, float)
        log_f = np.log(np.maximum(brdf, FLOOR_REL * max(brdf.max(), np.finfo(float).tiny)))
        key = np.round(np.stack([th, sg], axis=1) / MERGE_TOL_DEG).astype(np.int64)
        _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
        inverse = inverse.reshape(-1)
        pts = np.stack([th, sg], axis=1)[first]
        vals = np.zeros((first.size, log_f.shape[1]))
        np.add.at(vals, inverse, log_f)
        vals /= np.bincount(inverse, minlength=first.size)[:, None]
        off = pts[:, 0] > MERGE_TOL_DEG
        self.points = np.concatenate([pts, pts[off] * [-1.0, 1.0]])
        values = np.concatenate([vals, vals[off]])
        self.noise_log = noise_log(measurement)
        self.smoothing = choose_smoothing(self.points, values, pts.shape[0], self.noise_log)
        rbf = RBFInterpolator(self.points, values, kernel=KERNEL, smoothing=self.smoothing)
        axis = np.arange(0.0, GRID_MAX_DEG + GRID_STEP_DEG / 2, GRID_STEP_DEG)
        nodes = np.stack(np.meshgrid(axis, axis, indexing="ij"), axis=-1).reshape(-1, 2)
        from scipy.spatial import cKDTree

        clamped, in_hull = _hull_clamp(nodes, self.points)
        # just past the edge θh = σ, which no direction pair crosses (the sphere folds back
        # at it), the spline's own smooth continuation, so the B-spline sees no break there
        past = (nodes[:, 0] > nodes[:, 1]) & (nodes[:, 0] - nodes[:, 1] <= DIAGONAL_REACH_DEG)
        clamped[past] = nodes[past]
        inside = in_hull & (cKDTree(self.points).query(nodes)[0] <= MEASURED_RADIUS_DEG)
        shape = (axis.size, axis.size)
        # short of the clamp's slope break, which the cubic B-spline spreads inside; the
        # grid's own edges (θh = 0: mirror) are no break
        self._inside = binary_erosion(inside.reshape(shape), iterations=HULL_MARGIN_NODES,
                                      border_value=1)
        # B-spline coefficients per wavelength; 'mirror' = even about θh = 0 and σ = 0
        coef = rbf(clamped).reshape(shape + (-1,))
        for axis_k in (0, 1):
            coef = spline_filter1d(coef, order=3, axis=axis_k, mode="mirror")
        self._coef = np.ascontiguousarray(np.moveaxis(coef, -1, 0))  # (n_λ, θh, σ)

    def log_lookup(self, theta_h_deg: np.ndarray, sigma_deg: np.ndarray) -> np.ndarray:
        """log f (n, n_λ) at (θh, σ) (n,) in degrees, from the grid's cubic B-spline."""
        from scipy.ndimage import map_coordinates

        at = np.stack([np.clip(theta_h_deg, 0.0, GRID_MAX_DEG),
                       np.clip(sigma_deg, 0.0, GRID_MAX_DEG)]) / GRID_STEP_DEG
        return np.stack([map_coordinates(c, at, order=3, mode="mirror", prefilter=False)
                         for c in self._coef], axis=1)

    def outside(self, theta_h_deg: np.ndarray, sigma_deg: np.ndarray) -> np.ndarray:
        """(n,) bool: outside the measured range (the hull, at the nearest grid node)."""
        i = np.clip(np.rint(theta_h_deg / GRID_STEP_DEG).astype(np.intp), 0,
                    self._inside.shape[0] - 1)
        j = np.clip(np.rint(sigma_deg / GRID_STEP_DEG).astype(np.intp), 0,
                    self._inside.shape[1] - 1)
        return ~self._inside[i, j]

    def evaluate_directions(self, wi, wo, normal) -> np.ndarray:
        """BRDF (sr⁻¹, no cos θi) at direction pairs (..., 3) about unit normals (..., 3).

        Returns (..., n_λ), positive and finite; 0 where the light or the view is below
        the horizon. Adds the visible samples outside the measured range to
        :attr:`outside_samples`."""
        wi, wo, n = np.broadcast_arrays(np.asarray(wi, float), np.asarray(wo, float),
                                        np.asarray(normal, float))
        shape = wi.shape[:-1]
        wi, wo, n = (a.reshape(-1, 3) for a in (wi, wo, n))
        theta_h, sigma, cos_i, cos_o = direction_coordinates(wi, wo, n)
        visible = (cos_i > 0) & (cos_o > 0)
        f = np.zeros((theta_h.size, self.wavelength_nm.size))
        if np.any(visible):
            th, sg = theta_h[visible], sigma[visible]
            f[visible] = np.exp(self.log_lookup(th, sg))
            self.outside_samples += int(np.count_nonzero(self.outside(th, sg)))
        return f.reshape(shape + (self.wavelength_nm.size,))
