"""Figures of a design: the recommended layout, the uncertainty it leaves, the criterion against the
number of sensors, what it detects along the bridge and how it verified on synthetic damage.
"""

import numpy as np

from .common import axes_or_new, empty_note, integer_ticks, mark_bridge, new_figure

__all__ = ["plot_layout", "plot_posterior_std", "plot_criterion_curve", "plot_detectability", "plot_verification"]


def plot_layout(design, *, ax=None, exclude=()):
    """Bridge elevation: supports, exclusion zones, relaxed weights of the candidates, chosen and fixed sensors."""
    ax = axes_or_new(ax, figsize=(8, 2.8))
    x0, x1 = design.supports_m[0], design.supports_m[-1]
    for i, (a, b) in enumerate(exclude):
        ax.axvspan(a, b, color="0.5", alpha=0.25, hatch="//", linewidth=0, label="excluded" if i == 0 else None)
    ax.plot([x0, x1], [0, 0], color="0.2", linewidth=3, solid_capstyle="butt")
    ax.plot(design.supports_m, np.full(len(design.supports_m), -0.08), "^", color="0.3",
            markersize=12, label="supports")
    width = 0.8 * float(np.min(np.diff(np.unique(design.candidates_m)))) if design.candidates_m.size > 1 else 0.3
    weights, at = np.asarray(design.weights, dtype=float), np.asarray(design.candidates_m, dtype=float)
    shown = weights > 1e-4  # bars a tiny fraction of a pixel high are not drawn (thousands cost seconds)
    ax.bar(at[shown], 0.5 * weights[shown], width=width, bottom=0.05, color="C0", alpha=0.45,
           label="relaxed weight (x0.5)")
    kinds = design.layout_kind or (design.kind,) * len(design.layout_m)
    for kind, marker in (("rotation", "v"), ("deflection", "D")):  # one marker per kind when mixed
        xs = [x for x, k in zip(design.layout_m, kinds) if k == kind or not design.mixed]
        if xs:
            ax.plot(xs, np.zeros(len(xs)), marker if design.mixed else "v", color="C3", markersize=11 if
                    marker == "v" else 8, label=f"recommended {kind}" if design.mixed else "recommended", zorder=5)
        if not design.mixed:
            break
    if design.fixed_m:
        ax.plot(design.fixed_m, np.zeros(len(design.fixed_m)), "s", color="k", markersize=8,
                label="existing", zorder=5)
    low, previous = False, -np.inf
    for x in sorted(design.layout_m):  # neighbours closer than 6 % of the length alternate rows (no overlap)
        low = (not low) if x - previous < 0.06 * (x1 - x0) else False
        previous = x
        ax.annotate(f"{x:.2f} m", (x, 0.0), xytext=(0, -32 if low else -22), textcoords="offset points",
                    ha="center", fontsize=8, color="C3")
    ax.set_ylim(-0.45, 0.9)  # relaxed weights reach 0.55; the legend sits above them
    ax.set_yticks([])
    ax.set_xlim(x0 - 0.02 * (x1 - x0), x1 + 0.02 * (x1 - x0))
    ax.set_xlabel("position along the bridge x [m]")
    ax.set_title(f"{design.criterion}-optimal layout of {design.count} {design.kind.replace('+', ' or ')} sensor(s)")
    ax.legend(fontsize=7, ncol=4, loc="upper right")
    return ax


def plot_posterior_std(design, *, ax=None, baseline=None):
    """Posterior standard deviation of log EI (about the relative std of EI) along the bridge."""
    ax = axes_or_new(ax)
    baseline = design.best_baseline() if baseline is None else baseline
    # baseline=None: a step line, not an outline closed down to 0 at the bridge ends (which read as an
    # uncertainty of 0 at the end supports)
    ax.stairs(100 * design.posterior_std["recommended"], design.edges, linewidth=1.8, color="C3",
              label="recommended layout", baseline=None)
    if baseline in design.posterior_std:
        ax.stairs(100 * design.posterior_std[baseline], design.edges, linewidth=1.3, color="C0",
                  linestyle="--", label=f"best baseline ({baseline})", baseline=None)
    ax.set_ylim(bottom=0.0)
    mark_bridge(ax, design.supports_m)
    ax.set_xlim(design.edges[0], design.edges[-1])
    ax.set_xlabel("position along the bridge x [m]")
    ax.set_ylabel("posterior std of EI [%]")
    ax.set_title("What the layout leaves uncertain (prior + data, at nominal EI)")
    ax.legend(fontsize=8, loc="best")
    return ax


def plot_criterion_curve(design, *, ax=None):
    """Criterion of the best found layout and the relaxation bound versus the number of sensors."""
    ax = axes_or_new(ax, figsize=(6, 3.6))
    points = [c for c in design.curve if not c.failed]
    r = [c.count for c in points]
    ax.plot(r, [c.value for c in points], "o-", label="best layout found")
    ax.plot(r, [c.bound for c in points], "s--", label="relaxation bound")
    for c in design.curve:
        if c.failed:
            ax.axvline(c.count, color="C3", alpha=0.3, linewidth=6, label=f"R = {c.count} infeasible")
    ax.axvline(design.count, color="0.6", linestyle=":")
    integer_ticks(ax.xaxis)
    ax.set_xlabel("number of sensors R")
    ax.set_ylabel(f"{design.criterion} criterion")
    ax.set_title("Criterion versus number of sensors")
    ax.legend(fontsize=8, loc="best")
    return ax


def plot_detectability(result, *, axes=None):
    """Detection power (top) and minimum detectable EI loss (bottom) of a DetectabilityMap; returns two Axes."""
    if axes is None:
        _, axes = new_figure((8, 5.6), 2, 1, sharex=True)
    x = result.centres_m
    axes[0].plot(x, result.power, "o-", markersize=3, linewidth=1.4, label="power")
    axes[0].axhline(0.9, color="C2", linestyle=":", linewidth=1.0, label="0.9 (min detectable loss)")
    axes[0].axhline(result.false_alarm_rate, color="C3", linestyle=":", linewidth=1.0,
                    label=f"false alarm rate {result.false_alarm_rate:g}")
    axes[0].set_ylim(-0.03, 1.03)
    axes[0].set_ylabel("detection power [-]")
    axes[0].set_title(f"Detectability of a {100 * result.severity:g} % EI loss over {result.length_m:g} m "
                      f"({result.n_crossings} crossing(s), nuisance: {result.nuisance})")
    axes[1].plot(x, 100 * result.min_detectable_loss_array, "o-", markersize=3, linewidth=1.4, color="C1")
    axes[1].set_ylim(0.0, 100.0)
    axes[1].set_ylabel("min detectable\nEI loss [%]")
    axes[1].set_xlabel("centre of the damaged zone [m]")
    for i, ax in enumerate(axes):
        mark_bridge(ax, result.supports_m)
        y0 = ax.get_ylim()[0]
        ax.plot(result.sensors_m, np.full(len(result.sensors_m), y0), "^", color="k", markersize=7,
                clip_on=False, zorder=5, label="sensors" if i == 0 else None)
        ax.set_xlim(0.0, float(result.supports_m[-1]))
    axes[0].legend(fontsize=7, loc="best")
    return axes


def plot_verification(verification, *, axes=None, supports=None):
    """Scan statistic (relative to its threshold) and localisation error versus damage location, per layout.

    A panel with nothing to show says why in its middle (no local-loss
    scenario; no loss detected, so no localisation error).
    """
    if axes is None:
        _, axes = new_figure((8, 5.6), 2, 1, sharex=True)
    names = verification.names or [s.label for s in verification.layouts]
    detected = 0
    for name, score in zip(names, verification.layouts):
        local = [r for r in score.records if r.kind == "local"]
        x = [r.centre_m for r in local]
        errors = [np.nan if r.localisation_error_m is None else r.localisation_error_m for r in local]
        detected += int(np.sum(np.isfinite(errors))) if errors else 0
        axes[0].plot(x, [r.statistic / r.threshold for r in local], "o-", markersize=4, label=name)
        axes[1].plot(x, errors, "o-", markersize=4, label=name)
    axes[0].axhline(1.0, color="k", linestyle="--", linewidth=0.8)
    axes[0].set_ylabel("scan statistic / threshold\n(> 1: detected)")
    axes[0].set_title(f"Verification: {100 * verification.severity:.0f} % EI loss over "
                      f"{verification.length:g} m, {verification.n_crossings} crossings")
    axes[1].set_ylabel("localisation error [m]\n(detected losses)")
    axes[1].set_xlabel("centre of the damage [m]")
    if not any(s.kind == "local" for s in verification.scenarios):
        for ax in axes:
            empty_note(ax, "no local-loss scenario verified").set_yticks([])
    elif detected == 0:
        empty_note(axes[1], "no detections: no layout detected any of the local losses\n"
                            "(every scan statistic above is below its threshold)").set_yticks([])
    for ax in axes:
        if supports is not None:
            mark_bridge(ax, supports)
    axes[0].legend(fontsize=7, loc="best", ncol=2 if len(names) > 3 else 1)
    return axes
