"""Figures from result objects.  matplotlib is imported lazily, here only.

Every function takes the result first and ``ax=None`` and returns the Axes
(scikit-learn's Display convention).  :func:`save_figure` writes a PNG
atomically.
"""

import os
import tempfile
from pathlib import Path

import numpy as np

__all__ = ["plot_informativeness", "plot_spectrum", "plot_eigenvectors", "save_figure",
           "mark_bridge"]


def _pyplot():
    import matplotlib

    if matplotlib.get_backend().lower() not in {"agg", "module://matplotlib_inline.backend_inline"}:
        matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _axes(ax, figsize=(8, 3.6)):
    if ax is not None:
        return ax
    plt = _pyplot()
    _, ax = plt.subplots(figsize=figsize, layout="constrained")
    return ax


def mark_bridge(ax, supports, sensors=None, *, labels=True):
    """Dashed lines at the supports and triangles at sensor positions."""
    for x in supports:
        ax.axvline(x, color="0.55", linestyle="--", linewidth=0.8, zorder=0)
    if sensors is not None:
        y0 = ax.get_ylim()[0]
        ax.plot(sensors.positions, np.full(sensors.n_sensors, y0), "^", color="k",
                markersize=7, clip_on=False, zorder=5, label="sensors" if labels else None)
    return ax


def plot_informativeness(blocks, *, ax=None, supports=None, log=False):
    """Informativeness curves (diag of I^(i) per element) along the bridge."""
    ax = _axes(ax)
    edges = blocks.edges
    for name, curve in zip(blocks.sensors.names, blocks.curves):
        ax.stairs(curve, edges, label=name, linewidth=1.4)
    if log:
        ax.set_yscale("log")
    ax.set_xlabel("position along the bridge x [m]")
    ax.set_ylabel(f"Fisher information I_jj\n[{blocks.unit}]")
    ax.set_title(f"Informativeness curves ({blocks.parameterisation}, "
                 f"{blocks.n_crossings} crossing(s))")
    ax.set_xlim(edges[0], edges[-1])
    if supports is not None:
        mark_bridge(ax, supports, blocks.sensors, labels=False)
    if blocks.n_sensors <= 12:
        ax.legend(fontsize=7, ncol=min(blocks.n_sensors, 6))
    return ax


def plot_spectrum(ident, *, ax=None):
    """Eigenvalues of the total information (log scale) with the rank threshold."""
    ax = _axes(ax, figsize=(6, 3.6))
    vals = np.maximum(ident.eigenvalues, 1e-300)
    ax.semilogy(np.arange(1, vals.size + 1), vals, "o-", markersize=3)
    ax.axhline(ident.threshold * vals[0], color="C3", linestyle=":",
               label=f"threshold: effective rank {ident.effective_rank}")
    ax.set_xlabel("eigenvalue index")
    ax.set_ylabel("eigenvalue of total information")
    ax.set_title("Identifiability spectrum")
    ax.legend(fontsize=8)
    return ax


def plot_eigenvectors(ident, *, ax=None, count=2, supports=None):
    """Leading (solid) and trailing (dashed) eigenvectors as fields along the bridge."""
    ax = _axes(ax)
    n = ident.n_elements
    edges = ident.edges if ident.edges is not None else np.arange(n + 1.0)
    for i in range(min(count, ident.eigenvalues.size)):
        ax.stairs(ident.eigenvectors[:n, i], edges, label=f"well informed #{i + 1}", linewidth=1.4)
    for i in range(min(count, ident.eigenvalues.size)):
        ax.stairs(ident.eigenvectors[:n, -1 - i], edges, label=f"poorly informed #{i + 1}",
                  linestyle="--", linewidth=1.2)
    ax.axhline(0.0, color="0.3", linewidth=0.6)
    ax.set_xlabel("position along the bridge x [m]")
    ax.set_ylabel("eigenvector component")
    ax.set_title("Best- and worst-informed directions of EI")
    if supports is not None:
        mark_bridge(ax, supports)
    ax.legend(fontsize=7, ncol=2)
    return ax


def save_figure(ax_or_fig, path, *, dpi=130):
    """Save the figure of ``ax_or_fig`` as PNG atomically and close it."""
    plt = _pyplot()
    fig = getattr(ax_or_fig, "figure", ax_or_fig)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=".png", dir=path.parent)
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=dpi, format="png")
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
        plt.close(fig)
    return path
