"""What every figure shares: a new figure without pyplot, the Axes to draw on, the bridge's marks,
engineering units and the atomic PNG writer.  matplotlib is imported lazily, in :func:`new_figure`.
"""

import os
import tempfile
from pathlib import Path

import numpy as np

__all__ = ["new_figure", "axes_or_new", "mark_bridge", "eng_unit", "empty_note", "integer_ticks",
           "legend_outside", "save_figure"]


def new_figure(figsize, nrows=1, ncols=1, **kwargs):
    """A new Figure and its Axes, without pyplot: the user's backend and figure list are untouched.

    ``kwargs`` go to :meth:`Figure.subplots` (``sharex``, ``sharey``, ...).
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, layout="constrained")
    return fig, fig.subplots(nrows, ncols, **kwargs)


def axes_or_new(ax, figsize=(8, 3.6)):
    """``ax``, or the Axes of a new figure of ``figsize`` when ``ax`` is None."""
    if ax is not None:
        return ax
    return new_figure(figsize)[1]


def mark_bridge(ax, supports, sensors=None, *, labels=True):
    """Dashed lines at the supports and triangles at sensor positions."""
    for x in supports:
        ax.axvline(x, color="0.55", linestyle="--", linewidth=0.8, zorder=0)
    if sensors is not None:
        y0 = ax.get_ylim()[0]
        ax.plot(sensors.positions, np.full(sensors.n_sensors, y0), "^", color="k",
                markersize=7, clip_on=False, zorder=5, label="sensors" if labels else None)
    return ax


def empty_note(ax, text):
    """Say in the middle of ``ax`` why it shows no data (instead of leaving an empty frame)."""
    ax.text(0.5, 0.5, text, transform=ax.transAxes, ha="center", va="center", fontsize=9, color="0.35",
            bbox=dict(boxstyle="round", facecolor="white", edgecolor="0.8"))
    return ax


def integer_ticks(axis):
    """Ticks at whole numbers only on ``axis`` (a count of sensors has no 2.5)."""
    from matplotlib.ticker import MaxNLocator

    axis.set_major_locator(MaxNLocator(integer=True))


def legend_outside(ax, **kwargs):
    """A legend right of ``ax``, off the data (for many curves that would cover it inside)."""
    return ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, **kwargs)


def eng_unit(kind):
    """(scale from SI, unit label) of a reading at the edges: tilt in urad, deflection in mm."""
    return (1e6, "µrad") if kind == "rotation" else (1e3, "mm")


def save_figure(ax_or_fig, path, *, dpi=130):
    """Save the figure of ``ax_or_fig`` as PNG atomically."""
    fig = getattr(ax_or_fig, "figure", ax_or_fig)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=".png", dir=path.parent)
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=dpi, format="png")
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path
