"""Seed 001 Figures 2 and 3 for a basis search: the exponents chosen for each lobe count
and the error (eq. 4) against lobe count. matplotlib is imported on first use (Agg)."""

from __future__ import annotations

import os

import numpy as np

from ..artifact import atomic_path


def plot_basis(path: str | os.PathLike, result) -> None:
    """Write a PNG: left, eq. 4's error (and its max and mean terms) against the number
    of lobes (seed 001 Fig. 3); right, the exponents of each basis on a log axis (Fig. 2).
    ``result``: :class:`gonio_cli.lobes.BasisResult`."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    counts = [s.n_lobes for s in result.steps]
    fig, (ax_err, ax_exp) = plt.subplots(1, 2, figsize=(10.0, 4.0), constrained_layout=True)
    ax_err.plot(counts, [s.error for s in result.steps], "o-", label="eq. 4: max + mean")
    ax_err.plot(counts, [s.max_error for s in result.steps], "s--", label="max")
    ax_err.plot(counts, [s.mean_error for s in result.steps], "^--", label="mean")
    ax_err.set_xlabel("number of lobes")
    ax_err.set_ylabel("relative RMS error")
    ax_err.set_title("error of the basis (seed 001 Fig. 3)")
    ax_err.legend()
    for s in result.steps:
        ax_exp.plot(np.full(s.exponents.size, s.n_lobes), s.exponents, "o", color="C0")
    ax_exp.set_yscale("log")
    ax_exp.set_xlabel("number of lobes")
    ax_exp.set_ylabel("exponent E")
    ax_exp.set_title("exponents chosen (seed 001 Fig. 2)")
    for ax in (ax_err, ax_exp):
        ax.set_xticks(counts)
        ax.grid(alpha=0.3)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
