"""Seed 000 Figure 4 for one fit: data and model against θo per θi, their difference,
and the fitted spectra. matplotlib is imported on first use (Agg, no display)."""

from __future__ import annotations

import os

import numpy as np

from ..artifact import atomic_path
from ..geometry import in_plane_cosines
from ..schemas import Material, Measurement

#: θo samples per degree for the model curves (smooth at α = 0.03: lobe ≈ 3° wide).
CURVE_SAMPLES_PER_DEG = 4


def plot_fit(path: str | os.PathLike, measurement: Measurement, material: Material,
             title: str = "", excluded_theta_i_deg=()) -> None:
    """Write a PNG like seed 000 Figure 4 (top, middle, bottom) for ``material``.

    Top: spectrum-averaged BRDF (dots) and the model averaged the same way (curves)
    against θo, one colour per θi (excluded θi drawn hollow). Middle: absolute
    difference. Bottom: the model's spectral parameters against wavelength.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ti_all, to_all = measurement.theta_i_deg, measurement.theta_o_deg
    y_avg = measurement.brdf.mean(axis=1)
    f_avg = material.evaluate(in_plane_cosines(ti_all, to_all)).mean(axis=1)
    fig, axes = plt.subplots(3, 1, figsize=(7.0, 9.0), constrained_layout=True)
    colours = plt.cm.viridis(np.linspace(0.0, 0.9, np.unique(ti_all).size))
    for colour, ti in zip(colours, np.unique(ti_all)):
        rows = ti_all == ti
        order = np.argsort(to_all[rows])
        to = to_all[rows][order]
        hollow = any(abs(ti - t) < 1e-6 for t in excluded_theta_i_deg)
        axes[0].plot(to, y_avg[rows][order], "o", ms=3.5, color=colour,
                     mfc="none" if hollow else colour,
                     label=f"θi = {ti:g}°" + (" (excluded)" if hollow else ""))
        dense = np.linspace(to.min(), to.max(),
                            max(2, int(np.ptp(to) * CURVE_SAMPLES_PER_DEG) + 1))
        curve = material.evaluate(in_plane_cosines(np.full_like(dense, ti), dense)).mean(axis=1)
        axes[0].plot(dense, curve, "-", lw=1.2, color=colour)
        axes[1].plot(to, np.abs(y_avg[rows] - f_avg[rows])[order], "o-", ms=3, lw=0.8,
                     color=colour)
    axes[0].set_ylabel("BRDF, mean over λ (sr⁻¹)")
    axes[0].set_xlabel("θo (°)")
    axes[0].legend(fontsize=7, ncol=2)
    axes[0].set_title(title or f"{material.model} fit")
    axes[1].set_ylabel("|data − fit| (sr⁻¹)")
    axes[1].set_xlabel("θo (°)")
    wl = material.wavelength_nm
    spectral = {k: v for k, v in material.params.items() if np.ndim(v) == 1}
    scalars = ", ".join(f"{k} = {v:.4g}" for k, v in material.params.items() if np.ndim(v) == 0)
    ax = axes[2]
    for i, (name, values) in enumerate(spectral.items()):
        target = ax if i == 0 else ax.twinx() if i == 1 else ax
        target.plot(wl, values, ["-", "--", ":", "-."][i % 4], label=name,
                    color=f"C{i}")
        target.set_ylabel(name if i < 2 else target.get_ylabel())
    ax.set_xlabel("wavelength (nm)")
    ax.set_title(f"spectral parameters ({scalars})" if scalars else "spectral parameters")
    handles = [h for a in fig.axes[2:] for h in a.get_lines()]
    ax.legend(handles, [h.get_label() for h in handles], fontsize=8)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)
