"""Figures of the model and of what sensors can tell about EI: influence lines, informativeness of
each sensor, and the identifiability spectrum with its eigenvectors.
"""

import numpy as np

from .common import axes_or_new, eng_unit, integer_ticks, legend_outside, mark_bridge

__all__ = ["plot_influence_lines", "plot_informativeness", "plot_spectrum", "plot_eigenvectors"]


def plot_influence_lines(lines, *, ax=None, supports=None):
    """Predicted influence lines against the reference-axle position; tilt (µrad) and deflection (mm) on
    separate y axes (the deflection one on the right when both are present)."""
    ax = axes_or_new(ax)
    kinds = list(dict.fromkeys(lines.sensors.kinds))
    axes = {kinds[0]: ax}
    if len(kinds) > 1:
        axes[kinds[1]] = ax.twinx()
    for i, (name, kind, y) in enumerate(zip(lines.sensors.names, lines.sensors.kinds, lines.predictions)):
        scale, unit = eng_unit(kind)
        axes[kind].plot(lines.positions, scale * y, color=f"C{i % 10}", label=f"{name} [{unit}]",
                        linestyle="-" if kind == kinds[0] else "--")
    for kind, a in axes.items():
        a.set_ylabel(("tilt" if kind == "rotation" else "deflection") + f" [{eng_unit(kind)[1]}]")
    if supports is not None:
        mark_bridge(ax, supports)
    ax.axhline(0.0, color="0.3", linewidth=0.6)
    ax.set_xlabel("reference-axle position [m]")
    ax.set_title("Influence lines at nominal EI")
    handles = [h for a in axes.values() for h in a.get_legend_handles_labels()[0]]
    ax.legend(handles, [h.get_label() for h in handles], fontsize=8, loc="best")
    return ax


def plot_informativeness(blocks, *, ax=None, supports=None, log=False, ei=None):
    """Informativeness curves along the bridge.

    In log-EI parameters, or with the nominal ``ei`` [N m^2] per element, each
    curve is shown as the EI standard deviation [%] one sensor alone would
    leave on an element if every other element were known (100 / sqrt(I_jj)
    of log EI; lower is better); otherwise as the diagonal I_jj itself.
    """
    ax = axes_or_new(ax)
    edges = blocks.edges
    percent = blocks.parameterisation == "log_ei" or (ei is not None and blocks.parameterisation == "ei")
    factor = np.asarray(ei, float) if blocks.parameterisation == "ei" and ei is not None else 1.0
    with np.errstate(divide="ignore"):
        curves = 100.0 / (factor * np.sqrt(blocks.curves)) if percent else blocks.curves
    for name, curve in zip(blocks.sensors.names, curves):
        ax.stairs(curve, edges, label=name, linewidth=1.4, baseline=None)
    if log or percent:
        ax.set_yscale("log")
    ax.set_xlabel("position along the bridge x [m]")
    ax.set_ylabel("EI std this sensor alone\nwould leave [%] (lower: better)" if percent else
                  f"Fisher information I_jj\n[{blocks.unit}]")
    ax.set_title(f"Informativeness of each sensor ({blocks.n_crossings} crossing(s))")
    ax.set_xlim(edges[0], edges[-1])
    if supports is not None:
        mark_bridge(ax, supports, blocks.sensors, labels=False)
    if blocks.n_sensors <= 12:
        legend_outside(ax, fontsize=7, title="sensor", title_fontsize=7)
    return ax


def plot_spectrum(ident, *, ax=None):
    """Eigenvalues of the total information (log scale) with the rank threshold."""
    ax = axes_or_new(ax, figsize=(6, 3.6))
    vals = np.maximum(ident.eigenvalues, 1e-300)
    ax.semilogy(np.arange(1, vals.size + 1), vals, "o-", markersize=3)
    ax.axhline(ident.threshold * vals[0], color="C3", linestyle=":",
               label=f"threshold: effective rank {ident.effective_rank}")
    ax.set_xlabel("eigenvalue index")
    ax.set_ylabel("eigenvalue of total information")
    ax.set_title("Identifiability spectrum")
    integer_ticks(ax.xaxis)
    ax.legend(fontsize=8, loc="best")
    return ax


def plot_eigenvectors(ident, *, ax=None, count=2, supports=None):
    """Leading (solid) and trailing (dashed) eigenvectors as fields along the bridge."""
    ax = axes_or_new(ax)
    n = ident.n_elements
    edges = ident.edges if ident.edges is not None else np.arange(n + 1.0)
    for i in range(min(count, ident.eigenvalues.size)):
        ax.stairs(ident.eigenvectors[:n, i], edges, label=f"well informed #{i + 1}", linewidth=1.4, baseline=None)
    for i in range(min(count, ident.eigenvalues.size)):
        ax.stairs(ident.eigenvectors[:n, -1 - i], edges, label=f"poorly informed #{i + 1}",
                  linestyle="--", linewidth=1.2, baseline=None)
    ax.axhline(0.0, color="0.3", linewidth=0.6)
    ax.set_xlabel("position along the bridge x [m]")
    ax.set_ylabel("eigenvector component")
    ax.set_title("Best- and worst-informed directions of EI")
    ax.set_xlim(edges[0], edges[-1])
    if supports is not None:
        mark_bridge(ax, supports)
    ax.legend(fontsize=7, ncol=2, loc="best")
    return ax
