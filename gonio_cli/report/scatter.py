"""The error-against-time scatter plot of ``gonio report``'s sections (PNG, matplotlib
imported on first use)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


#: Errors below this are drawn at it on log axes (an exact method's 0 or 1e-16 would
#: stretch the axis over decades of nothing) and marked as such in the legend.
ERROR_FLOOR = 1e-9


def scatter(path: Path, series: dict[str, tuple[list[float], list[float]]], xlabel: str,
             ylabel: str, title: str, logx=True, logy=True,
             point_labels: dict[str, list[str]] | None = None,
             floor: float | None = None) -> None:
    """An error-against-time scatter plot (one marker style per series), PNG.

    ``point_labels``: per series, a text written beside each point (e.g. the ink).
    ``floor``: y values below it are drawn at it with a hollow marker, and the legend
    says "≤ floor (exact)".
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=110)
    markers = "osD^v<>ph*"
    floored_any = False
    for k, (label, (x, y)) in enumerate(series.items()):
        x, y = np.asarray(x, float), np.asarray(y, float)
        floored = np.zeros(y.shape, bool) if floor is None else y < floor
        if floor is not None:
            y = np.maximum(y, floor)
        ok = np.isfinite(x) & np.isfinite(y) & (x > 0) & ((y > 0) | (not logy))
        marker = markers[k % len(markers)]
        (line,) = ax.plot(x[ok & ~floored], y[ok & ~floored], marker, label=label, alpha=0.8)
        if np.any(ok & floored):
            floored_any = True
            ax.plot(x[ok & floored], y[ok & floored], marker, mfc="none",
                    color=line.get_color(), alpha=0.9)
        for xi, yi, text in zip(x[ok], y[ok],
                                np.asarray((point_labels or {}).get(label, []), object)[ok]
                                if (point_labels or {}).get(label) else []):
            ax.annotate(text, (xi, yi), textcoords="offset points", xytext=(4, 3), fontsize=7)
    if floored_any:
        ax.plot([], [], "o", mfc="none", color="0.3", label=f"hollow: ≤{floor:g} (exact), "
                                                            f"drawn at {floor:g}")
    if logx:
        ax.set_xscale("log")
    if logy:
        ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
