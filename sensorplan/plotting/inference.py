"""Figures of an identification: the EI posterior with its credible bands, and the data of one sensor
against the fitted model.
"""

from .common import axes_or_new, eng_unit, mark_bridge

__all__ = ["plot_ei_posterior", "plot_fit"]


def plot_ei_posterior(result, *, ax=None, supports=None, truth=None):
    """EI posterior mean with 75 % and 95 % credible bands and the nominal."""
    ax = axes_or_new(ax)
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
    verdict = getattr(result, "verdict", None)
    if verdict is not None and verdict.location_m is not None:
        a, b = verdict.location_m
        ax.axvspan(a, b, color="C3", alpha=0.15, label=verdict.headline)
    ax.set_xlim(edges[0], edges[-1])
    ax.set_xlabel("position along the bridge x [m]")
    ax.set_ylabel("EI [N m^2]")
    ax.set_title("Identified flexural rigidity" if verdict is None else
                 f"Identified flexural rigidity: {verdict.headline}")
    ax.legend(fontsize=7, ncol=2, loc="best")
    return ax


def plot_fit(result, sensor, *, ax=None, level=0.95, kind=None):
    """Measured readings of one sensor against the fitted model and its predictive band.

    Readings are shown in µrad (tilt) or mm (deflection), by the sensor's ``kind`` (default: the kind the
    result records for it), else in SI.
    """
    ax = axes_or_new(ax)
    i = result.sensor_names.index(sensor) if isinstance(sensor, str) else int(sensor)
    name = result.sensor_names[i]
    kinds = getattr(result, "sensor_kinds", ())
    kind = kind if kind is not None or not kinds else kinds[i]
    scale, unit = eng_unit(kind) if kind is not None else (1.0, "rad or m")
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
    ax.legend(fontsize=7, loc="best")
    return ax
