"""Seed 000 Figure 4 for one fit: data and model against θo per θi, their difference,
and the fitted spectra. matplotlib is imported on first use (Agg, no display).

The data panels follow the measurement's layout (:func:`curve_groups`): a goniometer's
θo sweeps and a multi-angle instrument's few aspecular geometries per θi are drawn
against θo, one curve per θi (seed 000 Figure 4); a layout with about one configuration
per θi (mirror-only data, θo = θi) is drawn against θi, one curve per aspecular angle
θi − θo, so that it shows as curves rather than one dot per θi.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..artifact import atomic_path
from ..geometry import in_plane_cosines
from ..schemas import Material, Measurement

#: Samples per degree for the model curves (smooth at α = 0.03: lobe ≈ 3° wide).
CURVE_SAMPLES_PER_DEG = 4

#: Two angles closer than this (deg) are the same angle when configurations are grouped
#: (ingest writes angles as read, so float noise in a CSV must not split a group).
ANGLE_TOL_DEG = 1e-6

#: x-axis of each layout of :func:`curve_groups`: label of the axis and of a curve.
LAYOUTS = {
    "theta_o": ("θo (°)", "θi = {key:g}°"),
    "theta_i": ("θi (°)", "θi − θo = {key:g}°"),
}


@dataclass
class CurveGroup:
    """Configurations drawn as one curve: ``key`` is θi (layout ``theta_o``) or the
    aspecular angle θi − θo (layout ``theta_i``), in degrees; ``rows`` index the
    measurement's configurations, sorted along the x-axis."""

    key: float
    rows: np.ndarray


def _group_keys(values: np.ndarray) -> np.ndarray:
    """Angles (n,) → group keys (n,): equal within :data:`ANGLE_TOL_DEG`."""
    return np.round(np.asarray(values, dtype=float) / ANGLE_TOL_DEG) * ANGLE_TOL_DEG


def curve_groups(theta_i_deg, theta_o_deg) -> tuple[str, list[CurveGroup]]:
    """How to draw in-plane configurations (n,) as curves: ``(layout, groups)``.

    Grouping by θi (curves against θo, seed 000 Figure 4: layout ``"theta_o"``) or by
    aspecular angle θi − θo (curves against θi: layout ``"theta_i"``); whichever gives
    more configurations per curve, θi on a tie. A goniometer sweep (tens of θo per θi) and
    a multi-angle instrument (a few aspecular geometries per θi) keep seed 000's axes;
    mirror-only data (θo = θi at every θi) becomes one curve over θi.

    >>> layout, groups = curve_groups([20, 40, 60], [20, 40, 60])
    >>> layout, [(g.key, g.rows.tolist()) for g in groups]
    ('theta_i', [(0.0, [0, 1, 2])])
    """
    ti = np.asarray(theta_i_deg, dtype=float)
    to = np.asarray(theta_o_deg, dtype=float)
    by_ti, by_aspecular = _group_keys(ti), _group_keys(ti - to)
    n_ti, n_asp = np.unique(by_ti).size, np.unique(by_aspecular).size
    layout, keys, x = (("theta_o", by_ti, to) if n_ti <= n_asp else
                       ("theta_i", by_aspecular, ti))
    groups = []
    for key in np.unique(keys):
        rows = np.flatnonzero(keys == key)
        groups.append(CurveGroup(float(key), rows[np.argsort(x[rows], kind="stable")]))
    return layout, groups


def model_curve(material: Material, layout: str, key: float, x_min: float, x_max: float):
    """The model's spectrum-averaged BRDF along one curve of :func:`curve_groups`:
    ``(x, f)`` each (k,), x in degrees from ``x_min`` to ``x_max``; for one point (k = 1)
    the model at that configuration."""
    n = max(1, int(round((x_max - x_min) * CURVE_SAMPLES_PER_DEG)) + 1)
    x = np.linspace(x_min, x_max, n) if n > 1 else np.array([x_min], dtype=float)
    ti, to = (np.full_like(x, key), x) if layout == "theta_o" else (x, x - key)
    return x, material.evaluate(in_plane_cosines(ti, to)).mean(axis=1)


def in_plane_rows(measurement: Measurement) -> tuple[np.ndarray, str]:
    """(boolean rows, title note): the configurations in the plane of incidence (φo = 0),
    the ones :func:`plot_fit` draws, and the note naming how many out of plane it leaves
    out ("" when none)."""
    plane = measurement.azimuths_deg == 0
    n_out = int((~plane).sum())
    return plane, (f"\n(in-plane configurations only: {n_out} out of plane not shown)"
                   if n_out else "")


def plot_fit(path: str | os.PathLike, measurement: Measurement, material: Material,
             title: str = "", excluded_theta_i_deg=(), gains=None) -> None:
    """Write a PNG like seed 000 Figure 4 (top, middle, bottom) for ``material``.

    Top: spectrum-averaged BRDF (dots) and the model averaged the same way (curves),
    one colour per curve of :func:`curve_groups` (against θo per θi, or against θi per
    aspecular angle for mirror-only data); configurations at an excluded θi are drawn
    hollow. Middle: absolute difference. Bottom: the model's spectral parameters against
    wavelength. A curve of one configuration is drawn as the model's value (a bar).
    ``gains`` (:class:`~gonio_cli.fit.gains.SweepGains`): the model drawn against the data
    is g(θi) f, as the verdict judges it (curves against θo only).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plane, left_out = in_plane_rows(measurement)
    ti_all, to_all = measurement.theta_i_deg[plane], measurement.theta_o_deg[plane]
    y_avg = measurement.brdf[plane].mean(axis=1)
    f_avg = material.evaluate(in_plane_cosines(ti_all, to_all)).mean(axis=1)
    layout, groups = curve_groups(ti_all, to_all)
    gained = gains is not None and layout == "theta_o" and gains.covers(ti_all)
    if gained:
        f_avg = f_avg * gains.per_configuration(ti_all)
    x_all = to_all if layout == "theta_o" else ti_all
    x_label, curve_label = LAYOUTS[layout]
    excluded = np.zeros(ti_all.shape, dtype=bool)
    for t in excluded_theta_i_deg:
        excluded |= np.abs(ti_all - t) < 1e-6
    fig, axes = plt.subplots(3, 1, figsize=(7.0, 9.0), constrained_layout=True)
    colours = plt.cm.viridis(np.linspace(0.0, 0.9, len(groups)))
    for colour, g in zip(colours, groups):
        x, rows = x_all[g.rows], g.rows
        label = curve_label.format(key=g.key)
        if layout == "theta_i" and abs(g.key) < ANGLE_TOL_DEG:
            label = "θo = θi (mirror)"
        if layout == "theta_o" and excluded[rows].all():
            label += " (excluded)"
        for hollow in (False, True):
            pick = excluded[rows] == hollow
            if pick.any():
                axes[0].plot(x[pick], y_avg[rows][pick], "o", ms=3.5, color=colour,
                             mfc="none" if hollow else colour,
                             label=None if hollow and (~excluded[rows]).any() else label)
        xs, curve = model_curve(material, layout, g.key, x.min(), x.max())
        if gained:
            curve = curve * gains.per_configuration([g.key])[0]
        if xs.size > 1:
            axes[0].plot(xs, curve, "-", lw=1.2, color=colour)
        else:
            axes[0].plot(xs, curve, "_", ms=12, mew=1.5, color=colour)
        axes[1].plot(x, np.abs(y_avg[rows] - f_avg[rows]), "o-", ms=3, lw=0.8, color=colour)
    if layout == "theta_i" and excluded.any():
        axes[0].plot([], [], "o", ms=3.5, color="grey", mfc="none", label="excluded θi")
    axes[0].set_ylabel("BRDF, mean over λ (sr⁻¹)")
    axes[0].set_xlabel(x_label)
    axes[0].legend(fontsize=7, ncol=2)
    axes[0].set_title((title or f"{material.model} fit") + left_out)
    axes[1].set_ylabel("|data − fit| (sr⁻¹)")
    axes[1].set_xlabel(x_label)
    wl = material.wavelength_nm
    spectral = {k: v for k, v in material.params.items() if np.ndim(v) == 1}
    parts = [f"{k} = {v:.4g}" for k, v in material.params.items() if np.ndim(v) == 0]
    # three scalars a line, so a many-lobe model's title stays inside the figure
    scalars = "\n".join(", ".join(parts[i:i + 3]) for i in range(0, len(parts), 3))
    ax = axes[2]
    for i, (name, values) in enumerate(spectral.items()):
        target = ax if i == 0 else ax.twinx() if i == 1 else ax
        target.plot(wl, values, ["-", "--", ":", "-."][i % 4], label=name,
                    color=f"C{i}")
        target.set_ylabel(name if i < 2 else target.get_ylabel())
    ax.set_xlabel("wavelength (nm)")
    ax.set_title(f"spectral parameters\n{scalars}" if scalars else "spectral parameters",
                 fontsize=9)
    handles = [h for a in fig.axes[2:] for h in a.get_lines()]
    ax.legend(handles, [h.get_label() for h in handles], fontsize=8)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)
