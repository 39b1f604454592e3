"""Figure of a logger record turned into crossings: each channel with its detected events and fits."""

from .common import eng_unit, new_figure

__all__ = ["plot_crossing_events"]


def plot_crossing_events(result, series, *, axes=None):
    """The logger record per channel with the detected events and the fitted influence lines; returns the Axes."""
    n = len(result.names)
    if axes is None:
        _, axes = new_figure((9, 1.2 + 1.9 * n), n, 1, sharex=True, squeeze=False)
        axes = axes[:, 0]
    for c, (ax, name, kind) in enumerate(zip(axes, result.names, result.kinds)):
        scale, unit = eng_unit(kind)
        ax.plot(series.time, scale * series.values[series.names.index(name)], color="0.6", linewidth=0.5,
                label="record")
        for e in result.events:
            color = "C2" if e.accepted else "C3"
            ax.axvspan(e.t_start, e.t_end, color=color, alpha=0.08)
            if e.fit_time.size:
                ax.plot(e.fit_time, scale * e.fit_values[c], color=color, linewidth=1.1,
                        label=("fit, accepted" if e.accepted else "fit, rejected") if c == 0 else None)
            if c == 0:
                ax.annotate(e.label + ("" if e.accepted else f"\n{e.reason}"), (0.5 * (e.t_start + e.t_end), 1.0),
                            xycoords=("data", "axes fraction"), ha="center", va="bottom", fontsize=7, color=color)
        ax.set_ylabel(f"{name} [{unit}]")
    handles, labels = axes[0].get_legend_handles_labels()
    unique = dict(zip(labels, handles))
    axes[0].legend(unique.values(), unique.keys(), fontsize=7, loc="lower right", ncol=3)
    axes[0].set_title(f"{len(result.events)} event(s), {len(result.accepted)} accepted "
                      "(green: accepted, red: rejected)", pad=22)
    axes[-1].set_xlabel("time [s]")
    return axes
