"""Figure of a logger's estimated noise: the Allan deviation of the quiet data against the fitted model."""

import textwrap

import numpy as np

from ..acquisition.noise import allan_variance_model
from .common import eng_unit, new_figure

__all__ = ["plot_allan_deviation"]


def plot_allan_deviation(result, *, axes=None, attribution=""):
    """Per channel, the Allan deviation of the data (dots) and of the fitted model (line, with its three parts).

    ``result`` is a :class:`~sensorplan.acquisition.noise.NoiseEstimate`;
    ``attribution`` (e.g. the data's licence) is written under the figure.
    Returns the Axes.
    """
    n = len(result.channels)
    if axes is None:
        _, axes = new_figure((6.4 * min(n, 2), 4.2 * ((n + 1) // 2)), (n + 1) // 2, min(n, 2), squeeze=False)
        axes = axes.ravel()
    for ax, c in zip(axes, result.channels):
        scale, unit = eng_unit(c.kind)
        tau, dt = c.allan.tau_s, result.sample_interval
        m = np.round(tau / dt).astype(int)
        ax.loglog(tau, scale * c.allan.data, "o", color="k", markersize=4, label="data (quiet parts)")
        ax.loglog(tau, scale * c.allan.model, "-", color="C0", linewidth=1.6, label="fitted model")
        parts = (("white", dict(white=c.white_std.value)),
                 ("correlated (OU)", dict(white=0.0, correlated=c.correlated_std.value,
                                          correlation_time=c.correlation_time_s.value)),
                 ("random walk", dict(white=0.0, random_walk=c.random_walk.value)))
        for k, (label, kw) in enumerate(parts):
            ax.loglog(tau, scale * np.sqrt(allan_variance_model(m, dt, **kw)), "--", color=f"C{k + 1}",
                      linewidth=0.9, label=label)
        shown = np.concatenate([c.allan.data, c.allan.model]) * scale
        shown = shown[np.isfinite(shown) & (shown > 0)]
        if shown.size:
            ax.set_ylim(0.3 * shown.min(), 2.0 * shown.max())  # a part far below the data would squash the plot
        _plain_ticks(ax.yaxis)
        ax.set_xlabel("averaging time tau [s]")
        ax.set_ylabel(f"Allan deviation [{unit}]")
        ax.set_title(f"{c.name}: white {scale * c.white_std.value:.3g}, OU {scale * c.correlated_std.value:.3g} {unit}"
                     f" / {c.correlation_time_s.value:.2g} s, walk {scale * c.random_walk.value:.2g} {unit}/sqrt(s)",
                     fontsize=8)
        ax.grid(True, which="both", linewidth=0.3, alpha=0.5)
        ax.legend(fontsize=7)
    for ax in axes[n:]:
        ax.set_visible(False)
    if attribution:  # below everything, in the space constrained layout keeps for it
        axes[0].figure.supxlabel("\n".join(textwrap.wrap(attribution, 120)), fontsize=6, color="0.4")
    return axes


def _plain_ticks(axis):
    """Log-axis ticks as plain numbers (5, 10, 20), not 2 x 10^1."""
    from matplotlib.ticker import FuncFormatter

    plain = FuncFormatter(lambda v, _: f"{v:g}")
    axis.set_major_formatter(plain)
    axis.set_minor_formatter(plain)
