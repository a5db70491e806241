"""The configurations an RGL ``.bsdf`` is evaluated at: a goniometer grid over the
hemisphere and a ring of fine samples around each mirror direction.

A measured table holds the whole hemisphere, so gonio is free to choose where to look.
A coarse grid (every θo of ``--theta-o-deg`` at every azimuth of ``--phi-o-deg``) sees
the broad lobes; on a mirror-like film the light is within a degree or two of the mirror
direction, where a 5° grid has at most one sample. So around the mirror direction
R = (sin θi, 0, cos θi) of every θi, the detector is also placed at the angular distances
d of ``--mirror-deg`` from R, in three directions: along the plane of incidence on both
sides (θo = θi ± d, φo = 0) and across it,
ωo = cos d · R + sin d · (0, 1, 0), i.e. cos θo = cos d cos θi and
tan φo = sin d / (cos d sin θi) (docs/conventions.md, "Out of the plane of incidence";
the BRDFs are isotropic, so the ring's other side, φo < 0, holds the same values).

Every configuration is written in its canonical form
(:func:`gonio_cli.geometry.canonical_azimuth`) and listed once.
"""

from __future__ import annotations

import numpy as np

from ..csvio import ANGLE_DECIMALS
from ..geometry import canonical_azimuth
from ..numbers import NumberList
from .steps import distinct

#: Default azimuths of the coarse grid: the plane of incidence only.
DEFAULT_PHI_O_DEG = "0"

#: Default angular distances (deg) of the mirror ring, used with the default θo grid:
#: 1, 2 and 3° resolve a peak a few degrees wide that the 5° grid steps over; with the
#: default grid, 7 θi × (34 + 9) = 301 configurations, about what a fit takes.
DEFAULT_MIRROR_DEG = "1,2,3"

#: The word that leaves the mirror ring out (``--mirror-deg none``).
NO_MIRROR = "none"

#: Largest distance from the mirror direction of the ring (deg): beyond it the coarse
#: grid is the right tool.
MAX_MIRROR_DEG = 30.0


def parse_azimuths(spec: str, path=None) -> np.ndarray:
    """``--phi-o-deg``: azimuths in [0, 180] degrees (sorted, distinct)."""
    option = NumberList("--phi-o-deg", "0,45,90,135", unit="deg", lo=0.0, hi=180.0)
    values = np.asarray(option.parse(spec, path), dtype=float)
    return distinct(np.round(values, ANGLE_DECIMALS)) + 0.0


def parse_mirror(spec: str, path=None) -> np.ndarray:
    """``--mirror-deg``: distances from the mirror direction in (0, 30] degrees, or
    ``none`` (an empty array)."""
    if str(spec).strip().lower() == NO_MIRROR:
        return np.zeros(0)
    option = NumberList("--mirror-deg", "1,2,3 (or none)", unit="deg", lo=0.0,
                        lo_open=True, hi=MAX_MIRROR_DEG)
    values = np.asarray(option.parse(spec, path), dtype=float)
    return distinct(np.round(values, ANGLE_DECIMALS)) + 0.0


def mirror_ring(theta_i_deg: float, distances_deg) -> tuple[np.ndarray, np.ndarray]:
    """(θo, φo) (3 k,) of the ring around the mirror direction of ``theta_i_deg`` at each
    distance d (module docstring): θo = θi + d and θi − d in the plane (φo = 0), and the
    direction d across it. Detectors at θo ≥ 90° are left out."""
    d = np.asarray(distances_deg, dtype=float)
    ti = np.radians(float(theta_i_deg))
    dr = np.radians(d)
    across_to = np.degrees(np.arccos(np.clip(np.cos(dr) * np.cos(ti), -1.0, 1.0)))
    across_po = np.degrees(np.arctan2(np.sin(dr), np.cos(dr) * np.sin(ti)))
    to = np.concatenate([theta_i_deg + d, theta_i_deg - d, across_to])
    po = np.concatenate([np.zeros(2 * d.size), across_po])
    keep = np.abs(to) < 90.0
    return to[keep], po[keep]


def hemisphere_grid(theta_i_deg, theta_o_deg, phi_o_deg=(0.0,), mirror_deg=()
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(θi, θo, φo) (n,) each: every θo at every φo for every θi, and the mirror ring
    (:func:`mirror_ring`) at the distances ``mirror_deg``, canonical and distinct, sorted by
    θi, then φo, then θo.

    At an azimuth other than 0 and 180° a θo < 0 is the same direction as |θo| at φo ± 180°
    and is taken as |θo| at φo (isotropy); θo = 0 is the normal at any azimuth.
    """
    rows = []
    for ti in np.asarray(theta_i_deg, dtype=float).ravel():
        for po in np.asarray(phi_o_deg, dtype=float).ravel():
            to = np.asarray(theta_o_deg, dtype=float).ravel()
            if 0.0 < po < 180.0:
                to = np.abs(to)
            rows.append(np.stack([np.full(to.size, ti), to, np.full(to.size, po)], axis=-1))
        to, po = mirror_ring(ti, mirror_deg)
        rows.append(np.stack([np.full(to.size, ti), to, po], axis=-1))
    grid = np.concatenate(rows) if rows else np.zeros((0, 3))
    to, po = canonical_azimuth(grid[:, 1], grid[:, 2])
    keys = np.round(np.stack([grid[:, 0], po, to], axis=-1), ANGLE_DECIMALS) + 0.0
    keys = keys[np.lexsort(keys.T[::-1])]        # by θi, φo, θo (np.unique(axis=0) would
    first = np.r_[True, np.any(keys[1:] != keys[:-1], axis=1)]   # import numpy.ma)
    keys = keys[first]
    return keys[:, 0], keys[:, 2], keys[:, 1]
