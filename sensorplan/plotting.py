"""Figures from result objects.  matplotlib is imported lazily, here only.

Every function takes the result first and ``ax=None`` and returns the Axes
(scikit-learn's Display convention).  :func:`save_figure` writes a PNG
atomically.
"""

import os
import tempfile
from pathlib import Path

import numpy as np

__all__ = ["plot_informativeness", "plot_spectrum", "plot_eigenvectors", "plot_ei_posterior", "plot_fit", "plot_layout",
           "plot_posterior_std", "plot_criterion_curve", "plot_verification", "plot_residual_map",
           "plot_shrinkage", "plot_ei_before_after", "plot_influence_lines", "plot_detectability", "plot_crossing_events", "save_figure",
           "mark_bridge", "new_figure"]


def new_figure(figsize, nrows=1, ncols=1, **kwargs):
    """A new Figure and its Axes, without pyplot: the user's backend and figure list are untouched.

    ``kwargs`` go to :meth:`Figure.subplots` (``sharex``, ``sharey``, ...).
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, layout="constrained")
    return fig, fig.subplots(nrows, ncols, **kwargs)


def _axes(ax, figsize=(8, 3.6)):
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


def plot_informativeness(blocks, *, ax=None, supports=None, log=False, ei=None):
    """Informativeness curves along the bridge.

    In log-EI parameters, or with the nominal ``ei`` [N m^2] per element, each
    curve is shown as the EI standard deviation [%] one sensor alone would
    leave on an element if every other element were known (100 / sqrt(I_jj)
    of log EI; lower is better); otherwise as the diagonal I_jj itself.
    """
    ax = _axes(ax)
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


def plot_ei_posterior(result, *, ax=None, supports=None, truth=None):
    """EI posterior mean with 75 % and 95 % credible bands and the nominal."""
    ax = _axes(ax)
    edges = result.edges
    ci95 = result.credible_interval(0.95)
    ci75 = result.credible_interval(0.75)
    ax.stairs(ci95[:, 1], edges, baseline=ci95[:, 0], fill=True, color="C0", alpha=0.2,
              label="95 % credible")
    ax.stairs(ci75[:, 1], edges, baseline=ci75[:, 0], fill=True, color="C0", alpha=0.35,
              label="75 % credible")
    ax.stairs(result.ei_mean, edges, color="C0", linewidth=1.8, label="posterior mean", baseline=None)
    ax.stairs(result.ei_nominal, edges, color="0.3", linestyle="--", linewidth=1.0, label="nominal", baseline=None)
    if truth is not None:
        truth_edges, truth_values = truth
        ax.stairs(truth_values, truth_edges, color="k", linewidth=1.2, label="truth", baseline=None)
    if supports is not None:
        mark_bridge(ax, supports)
    damage = getattr(result, "damage", None)
    if damage is not None and damage.detected:
        a, b = damage.centre_m - damage.length_m / 2, damage.centre_m + damage.length_m / 2
        lo, hi = damage.loss_ci95
        ax.axvspan(a, b, color="C3", alpha=0.15, label=f"detected loss {100 * damage.loss:.0f} % "
                   f"(95 %: {100 * lo:.0f}-{100 * hi:.0f} %)")
    ax.set_xlim(edges[0], edges[-1])
    ax.set_xlabel("position along the bridge x [m]")
    ax.set_ylabel("EI [N m^2]")
    ax.set_title("Identified flexural rigidity" if damage is None else
                 "Identified flexural rigidity: " + ("local loss DETECTED" if damage.detected else
                                                     f"no local loss detected (false-alarm rate "
                                                     f"{damage.false_alarm_rate:g})"))
    ax.legend(fontsize=7, ncol=3)
    return ax


def plot_fit(result, sensor, *, ax=None, level=0.95, kind=None):
    """Measured readings of one sensor against the fitted model and its predictive band.

    With the sensor's ``kind`` the readings are shown in µrad (tilt) or mm (deflection), else in SI.
    """
    ax = _axes(ax)
    scale, unit = _eng_unit(kind) if kind is not None else (1.0, "rad or m")
    i = result.sensor_names.index(sensor) if isinstance(sensor, str) else int(sensor)
    name = result.sensor_names[i]
    for k, fit in enumerate(result.fits):
        ax.plot(fit.positions, scale * fit.data[i], ".", color="0.5", markersize=2,
                label="data" if k == 0 else None)
    fit = result.fits[0]
    band = fit.predictive_band(level)
    ax.fill_between(fit.positions, scale * band[0, i], scale * band[1, i], color="C1", alpha=0.3,
                    label=f"{int(level * 100)} % predictive")
    ax.plot(fit.positions, scale * fit.model[i], color="C1", linewidth=1.5, label="model")
    ax.set_xlabel("reference-axle position [m]")
    ax.set_ylabel(f"{name} reading [{unit}]")
    ax.set_title(f"Data vs model: {name}")
    ax.legend(fontsize=7)
    return ax


def plot_layout(design, *, ax=None, exclude=()):
    """Bridge elevation: supports, exclusion zones, relaxed weights of the candidates, chosen and fixed sensors."""
    ax = _axes(ax, figsize=(8, 2.8))
    x0, x1 = design.supports_m[0], design.supports_m[-1]
    for i, (a, b) in enumerate(exclude):
        ax.axvspan(a, b, color="0.5", alpha=0.25, hatch="//", linewidth=0, label="excluded" if i == 0 else None)
    ax.plot([x0, x1], [0, 0], color="0.2", linewidth=3, solid_capstyle="butt")
    ax.plot(design.supports_m, np.full(len(design.supports_m), -0.08), "^", color="0.3",
            markersize=12, label="supports")
    width = 0.8 * float(np.min(np.diff(np.unique(design.candidates_m)))) if design.candidates_m.size > 1 else 0.3
    ax.bar(design.candidates_m, 0.5 * design.weights, width=width, bottom=0.05, color="C0", alpha=0.45,
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
    ax.set_ylim(-0.45, 0.7)
    ax.set_yticks([])
    ax.set_xlim(x0 - 0.02 * (x1 - x0), x1 + 0.02 * (x1 - x0))
    ax.set_xlabel("position along the bridge x [m]")
    ax.set_title(f"{design.criterion}-optimal layout of {design.count} {design.kind.replace('+', ' or ')} sensor(s)")
    ax.legend(fontsize=7, ncol=4, loc="upper right")
    return ax


def plot_posterior_std(design, *, ax=None, baseline=None):
    """Posterior standard deviation of log EI (about the relative std of EI) along the bridge."""
    ax = _axes(ax)
    baseline = design.best_baseline() if baseline is None else baseline
    ax.stairs(100 * design.posterior_std["recommended"], design.edges, linewidth=1.8, color="C3",
              label="recommended layout")
    if baseline in design.posterior_std:
        ax.stairs(100 * design.posterior_std[baseline], design.edges, linewidth=1.3, color="C0",
                  linestyle="--", label=f"best baseline ({baseline})")
    mark_bridge(ax, design.supports_m)
    ax.set_xlabel("position along the bridge x [m]")
    ax.set_ylabel("posterior std of EI [%]")
    ax.set_title("What the layout leaves uncertain (prior + data, at nominal EI)")
    ax.legend(fontsize=8)
    return ax


def plot_criterion_curve(design, *, ax=None):
    """Criterion of the best found layout and the relaxation bound versus the number of sensors."""
    ax = _axes(ax, figsize=(6, 3.6))
    points = [c for c in design.curve if not c.failed]
    r = [c.count for c in points]
    ax.plot(r, [c.value for c in points], "o-", label="best layout found")
    ax.plot(r, [c.bound for c in points], "s--", label="relaxation bound")
    for c in design.curve:
        if c.failed:
            ax.axvline(c.count, color="C3", alpha=0.3, linewidth=6, label=f"R = {c.count} infeasible")
    ax.axvline(design.count, color="0.6", linestyle=":")
    ax.set_xlabel("number of sensors R")
    ax.set_ylabel(f"{design.criterion} criterion")
    ax.set_title("Criterion versus number of sensors")
    ax.legend(fontsize=8)
    return ax


def plot_verification(verification, *, axes=None, supports=None):
    """Scan statistic (relative to its threshold) and localisation error versus damage location, per layout."""
    if axes is None:
        _, axes = new_figure((8, 5.6), 2, 1, sharex=True)
    names = verification.names or [s.label for s in verification.layouts]
    for name, score in zip(names, verification.layouts):
        local = [r for r in score.records if r["kind"] == "local"]
        x = [r["centre_m"] for r in local]
        axes[0].plot(x, [r["statistic"] / r["threshold"] for r in local], "o-", markersize=4, label=name)
        axes[1].plot(x, [r.get("localisation_error_m", np.nan) for r in local], "o-", markersize=4, label=name)
    axes[0].axhline(1.0, color="k", linestyle="--", linewidth=0.8)
    axes[0].set_ylabel("scan statistic / threshold\n(> 1: detected)")
    axes[0].set_title(f"Verification: {100 * verification.severity:.0f} % EI loss over "
                      f"{verification.length:g} m, {verification.n_crossings} crossings")
    axes[1].set_ylabel("localisation error [m]\n(detected losses)")
    axes[1].set_xlabel("centre of the damage [m]")
    for ax in axes:
        if supports is not None:
            mark_bridge(ax, supports)
    axes[0].legend(fontsize=7)
    return axes


def plot_residual_map(diagnosis, *, ax=None, sensor_names=None):
    """Mean residual over crossings, in noise standard deviations, per sensor and load position."""
    ax = _axes(ax, figsize=(8, 3.2))
    grid = diagnosis.residual_map.grid_m
    values = diagnosis.residual_map.normalised_mean_residual
    names = list(diagnosis.gap.by_sensor) if sensor_names is None else sensor_names
    lim = max(3.0, float(np.max(np.abs(values))))
    extent = (grid[0], grid[-1] if grid[-1] > grid[0] else grid[0] + 1.0, len(names) - 0.5, -0.5)
    mesh = ax.imshow(values, aspect="auto", cmap="RdBu_r", vmin=-lim, vmax=lim, interpolation="nearest",
                     extent=extent)
    ax.set_yticks(range(len(names)), names)
    ax.set_xlabel("reference-axle position [m]")
    ax.set_title("Systematic residual (mean over crossings / noise std)")
    ax.figure.colorbar(mesh, ax=ax, label="noise std")
    return ax


def plot_shrinkage(diagnosis, *, ax=None):
    """Residual rms after adding each effect (fitted and held out) against the base model."""
    ax = _axes(ax, figsize=(8, 3.6))
    names = [e.name for e in diagnosis.effects]
    fitted = [e.rms_after for e in diagnosis.effects]
    held = [np.nan if e.heldout_rms_after is None else e.heldout_rms_after for e in diagnosis.effects]
    x = np.arange(len(names))
    ax.bar(x - 0.2, fitted, width=0.4, label="fitted")
    ax.bar(x + 0.2, held, width=0.4, label="held out")
    ax.axhline(diagnosis.gap.rms_residual, color="k", linestyle="--", linewidth=1, label="base model")
    ax.axhline(diagnosis.gap.noise_rms, color="C2", linestyle=":", linewidth=1.2, label="noise floor")
    ax.set_xticks(x, [n.replace("_", "\n") for n in names], fontsize=7)
    ax.set_ylabel("residual rms")
    ax.set_title("How far the gap shrinks with each candidate effect")
    ax.legend(fontsize=7)
    return ax


def plot_ei_before_after(diagnosis, *, ax=None, supports=None):
    """Identified EI with the base model and with the selected effects."""
    ax = _axes(ax)
    ax.stairs(diagnosis.ei_base, diagnosis.ei_edges, linewidth=1.5, label="base model", baseline=None)
    label = "with " + ", ".join(diagnosis.causes) if diagnosis.causes else "final model (= base)"
    ax.stairs(diagnosis.ei_final, diagnosis.ei_edges, linewidth=1.5, linestyle="--", label=label, baseline=None)
    if len(diagnosis.ei_final_band) == 2:  # 95 % band of the corrected model, refitted with its hyperparameters
        low, high = diagnosis.ei_final_band
        ax.stairs(high, diagnosis.ei_edges, baseline=low, fill=True, alpha=0.2, color="C1", label="95 % band after")
    if supports is not None:
        mark_bridge(ax, supports)
    ax.set_xlabel("position along the bridge x [m]")
    ax.set_ylabel("EI [N m^2]")
    ax.set_title("Identified EI before and after modelling the gap")
    ax.legend(fontsize=8)
    return ax


def plot_influence_lines(lines, *, ax=None, supports=None):
    """Predicted influence lines against the reference-axle position; tilt (µrad) and deflection (mm) on
    separate y axes (the deflection one on the right when both are present)."""
    ax = _axes(ax)
    kinds = list(dict.fromkeys(lines.sensors.kinds))
    axes = {kinds[0]: ax}
    if len(kinds) > 1:
        axes[kinds[1]] = ax.twinx()
    for i, (name, kind, y) in enumerate(zip(lines.sensors.names, lines.sensors.kinds, lines.predictions)):
        scale, unit = _eng_unit(kind)
        axes[kind].plot(lines.positions, scale * y, color=f"C{i % 10}", label=f"{name} [{unit}]",
                        linestyle="-" if kind == kinds[0] else "--")
    for kind, a in axes.items():
        a.set_ylabel(("tilt" if kind == "rotation" else "deflection") + f" [{_eng_unit(kind)[1]}]")
    if supports is not None:
        mark_bridge(ax, supports)
    ax.axhline(0.0, color="0.3", linewidth=0.6)
    ax.set_xlabel("reference-axle position [m]")
    ax.set_title("Influence lines at nominal EI")
    handles = [h for a in axes.values() for h in a.get_legend_handles_labels()[0]]
    ax.legend(handles, [h.get_label() for h in handles], fontsize=8)
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


def _eng_unit(kind):
    """(scale from SI, unit label) of a reading at the edges: tilt in urad, deflection in mm."""
    return (1e6, "µrad") if kind == "rotation" else (1e3, "mm")


def plot_crossing_events(result, series, *, axes=None):
    """The logger record per channel with the detected events and the fitted influence lines; returns the Axes."""
    n = len(result.names)
    if axes is None:
        _, axes = new_figure((9, 1.2 + 1.9 * n), n, 1, sharex=True, squeeze=False)
        axes = axes[:, 0]
    for c, (ax, name, kind) in enumerate(zip(axes, result.names, result.kinds)):
        scale, unit = _eng_unit(kind)
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
