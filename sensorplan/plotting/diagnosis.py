"""Figures of a sim-to-real gap diagnosis: where the model and the data disagree, how far each candidate
effect shrinks the gap, and the identified EI before and after modelling it.
"""

import numpy as np

from .common import axes_or_new, empty_note, legend_outside, mark_bridge

__all__ = ["plot_residual_map", "plot_shrinkage", "plot_ei_before_after"]


def plot_residual_map(diagnosis, *, ax=None, sensor_names=None):
    """Mean residual over crossings, in noise standard deviations, per sensor and load position."""
    ax = axes_or_new(ax, figsize=(8, 3.2))
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
    """Residual rms after adding each effect (fitted and held out) against the base model.

    In units of the noise rms (1 is the noise floor): the residuals of tilt
    and deflection sensors share no physical unit, their ratio to the noise
    does.  In SI (rad or m) when the noise rms is 0.
    """
    ax = axes_or_new(ax, figsize=(8, 3.6))
    noise = diagnosis.gap.noise_rms
    scale, unit = (1.0 / noise, "noise rms") if noise > 0 else (1.0, "rad or m")
    names = [e.name for e in diagnosis.effects]
    fitted = [scale * e.rms_after for e in diagnosis.effects]
    held = [np.nan if e.heldout_rms_after is None else scale * e.heldout_rms_after for e in diagnosis.effects]
    x = np.arange(len(names))
    ax.bar(x - 0.2, fitted, width=0.4, label="fitted")
    ax.bar(x + 0.2, held, width=0.4, label="held out")
    ax.axhline(scale * diagnosis.gap.rms_residual, color="k", linestyle="--", linewidth=1, label="base model")
    ax.axhline(scale * noise, color="C2", linestyle=":", linewidth=1.2, label="noise floor")
    ax.set_xticks(x, [n.replace("_", "\n") for n in names], fontsize=7)
    ax.set_ylabel(f"residual rms [{unit}]")
    ax.set_title("How far the gap shrinks with each candidate effect")
    legend_outside(ax, fontsize=7)
    if not names:
        empty_note(ax, "no candidate effect was fitted")
    return ax


def plot_ei_before_after(diagnosis, *, ax=None, supports=None):
    """Identified EI with the base model and with the selected effects."""
    ax = axes_or_new(ax)
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
    ax.legend(fontsize=8, loc="best")
    return ax
