"""Result types of the verification: Metric, ScenarioRecord, LayoutScore, VerificationResult.

Owns: aggregation of per-scenario records into metrics with Monte-Carlo errors.
May import: the foundations.
"""

import math
from dataclasses import KW_ONLY, dataclass

import numpy as np

__all__ = ["Metric", "ScenarioRecord", "LayoutScore", "VerificationResult", "METRICS", "EXTRA_METRICS"]

METRICS = ("rmse", "localisation_error_m", "detection_rate", "false_alarm_rate", "coverage95", "band_width")
EXTRA_METRICS = ("control_coverage95", "damaged_coverage95", "span_detection_rate", "loss_coverage95",
                 "non_converged")


@dataclass(frozen=True)
class Metric:
    """Mean of a per-scenario metric with its Monte-Carlo standard error over ``n`` scenarios."""

    mean: float
    se: float
    n: int = 0

    @classmethod
    def of(cls, values):
        """Mean and standard error of the finite values (NaN when there are none)."""
        values = np.asarray([v for v in values if v is not None and np.isfinite(v)], dtype=float)
        if values.size == 0:
            return cls(float("nan"), float("nan"), 0)
        se = float(values.std(ddof=1) / math.sqrt(values.size)) if values.size > 1 else float("nan")
        return cls(float(values.mean()), se, int(values.size))

    def __iter__(self):  # unpacks as (mean, se)
        return iter((self.mean, self.se))

    def to_dict(self):
        return {"mean": self.mean, "se": self.se, "n": self.n}


@dataclass(frozen=True, kw_only=True)
class ScenarioRecord:
    """What one scenario gave for one layout: the inversion's accuracy and bands, the detector's verdict.

    ``detected`` is set for damaged scenarios, ``false_alarm`` for undamaged controls (1.0 when the
    detector fired, else 0.0); ``localisation_error_m`` and ``loss_covered`` for detected local losses.
    """

    kind: str  # "local", "span" or "control"
    centre_m: float  # centre of the damaged zone [m] (0 for a control)
    rmse: float  # of EI / truth - 1 over the elements
    coverage95: float  # share of the elements whose 95 % band covers the true EI
    band_width: float  # mean width of the 95 % band relative to the nominal EI
    converged: float  # 1.0 when the inversion converged
    statistic: float  # the detector's scan statistic
    threshold: float  # and its threshold
    detected: float | None = None
    false_alarm: float | None = None
    localisation_error_m: float | None = None
    loss_covered: float | None = None  # 1.0 when the 95 % interval of the loss covers the true one

    def to_dict(self):
        out = {"kind": self.kind, "centre_m": self.centre_m, "rmse": self.rmse, "coverage95": self.coverage95,
               "band_width": self.band_width, "converged": self.converged, "statistic": self.statistic,
               "threshold": self.threshold}
        for name in ("false_alarm", "detected", "localisation_error_m", "loss_covered"):
            if getattr(self, name) is not None:
                out[name] = getattr(self, name)
        return out


@dataclass(frozen=True, eq=False)
class LayoutScore:
    """Aggregated metrics of one layout with Monte-Carlo standard errors."""

    layout_m: tuple
    n_scenarios: int
    metrics: dict  # name -> Metric
    records: tuple  # one ScenarioRecord per scenario
    _: KW_ONLY
    detection_limit: float | None = None  # mean known-location power at the Bonferroni level (local scenarios)
    layout_kind: tuple = ()  # kind of each sensor (parallel to layout_m)

    @classmethod
    def from_records(cls, layout, records, *, detection_limit=None, layout_kind=()):
        """Metrics of one layout over its scenarios' records (local losses, span softenings, controls)."""
        mean_se = Metric.of
        local = [r for r in records if r.kind == "local"]
        damaged = [r for r in records if r.kind != "control"]
        controls = [r for r in records if r.kind == "control"]
        metrics = {
            "rmse": mean_se([r.rmse for r in records]),
            # the detector's centre against the truth, over the detected local losses
            "localisation_error_m": mean_se([r.localisation_error_m for r in local]),
            # local losses (what detection_limit measures); span softenings are span_detection_rate
            "detection_rate": mean_se([r.detected for r in local]),
            "false_alarm_rate": mean_se([r.false_alarm for r in controls]),
            "coverage95": mean_se([r.coverage95 for r in records]),
            "band_width": mean_se([r.band_width for r in records]),
            "control_coverage95": mean_se([r.coverage95 for r in controls]),
            "damaged_coverage95": mean_se([r.coverage95 for r in damaged]),
            "span_detection_rate": mean_se([r.detected for r in damaged if r.kind == "span"]),
            # share of the detected local losses whose 95 % loss interval covers the true loss
            "loss_coverage95": mean_se([r.loss_covered for r in local]),
            "non_converged": mean_se([1.0 - r.converged for r in records]),
        }
        return cls(tuple(float(x) for x in layout), len(records), metrics, tuple(records),
                   detection_limit=detection_limit, layout_kind=tuple(layout_kind))

    @property
    def label(self):
        """Positions [m]; in a layout of mixed kinds the deflection sensors marked ``:deflection``."""
        kinds = self.layout_kind or ("rotation",) * len(self.layout_m)
        mixed = len(set(kinds)) > 1
        return ", ".join(f"{x:g}" + (f":{k}" if mixed and k != "rotation" else "")
                         for x, k in zip(self.layout_m, kinds))

    @property
    def detection_ratio(self):
        """detection_rate / detection_limit (None without a limit)."""
        if not self.detection_limit:
            return None
        return self.metrics["detection_rate"].mean / self.detection_limit

    def to_dict(self):
        out = {"layout_m": list(self.layout_m), "layout_kind": list(self.layout_kind), "n_scenarios": self.n_scenarios}
        for name in METRICS + EXTRA_METRICS:  # NaN (no scenario to average) is written as null
            metric = self.metrics[name]
            out[name] = None if math.isnan(metric.mean) else metric.mean
            out[name + "_se"] = None if math.isnan(metric.se) else metric.se
        out["detection_limit"] = self.detection_limit
        out["detection_ratio"] = self.detection_ratio
        return out


@dataclass(frozen=True, eq=False)
class VerificationResult:
    """Verification of several layouts on the same scenarios and seeds."""

    layouts: tuple  # LayoutScore
    scenarios: tuple
    _: KW_ONLY
    n_crossings: int
    seed: int
    severity: float
    length: float
    names: tuple = ()
    false_alarm: float = 0.05
    nuisance: str = "smooth"

    def summary(self):
        head = (f"Verification: {sum(s.kind == 'local' for s in self.scenarios)} local losses of "
                f"{100 * self.severity:.0f} % over {self.length:g} m, "
                f"{sum(s.kind == 'span' for s in self.scenarios)} span softenings, "
                f"{sum(s.kind == 'control' for s in self.scenarios)} undamaged controls; "
                f"{self.n_crossings} crossings each; seed {self.seed}")
        head += f"; detector at a {self.false_alarm:g} false-alarm rate, {self.nuisance} nuisance"
        lines = [head, f"  {'layout':26s} {'rmse':>12s} {'loc. err [m]':>13s} {'detection':>12s} {'limit':>6s} "
                       f"{'false alarm':>12s} {'coverage95':>12s} {'band width':>12s} {'not conv.':>9s}"]
        for name, score in zip(self.names or [None] * len(self.layouts), self.layouts):
            label = name or score.label
            cells = [f"{score.metrics[m].mean:5.3f}±{score.metrics[m].se:5.3f}" for m in METRICS]
            limit = "n/a" if score.detection_limit is None else f"{score.detection_limit:.3f}"
            cells.insert(3, limit)
            cells.append(f"{score.metrics['non_converged'].mean:.3f}")
            widths = (12, 13, 12, 6, 12, 12, 12, 9)
            lines.append(f"  {label[:26]:26s} " + " ".join(f"{c:>{w}s}" for c, w in zip(cells, widths)))
        lines.append("  (mean ± Monte-Carlo standard error; rmse and band width relative to EI; detection over the "
                     "local losses, limit = their known-location power at the Bonferroni level)")
        # only where the limit is worth comparing with (a few detections are expected)
        ratios = [s.detection_ratio for s in self.layouts if s.detection_limit is not None and s.detection_limit >= 0.2]
        if ratios and min(ratios) < 0.8:
            lines.append("  note: detection below 0.8 x its physical limit for some layout: the detector loses power "
                         "to the scan over unknown locations and lengths")
        return "\n".join(lines)

    def to_dict(self):
        layouts = []
        for name, score in zip(self.names or [None] * len(self.layouts), self.layouts):
            d = score.to_dict()
            if name:
                d["name"] = name
            layouts.append(d)
        return {"layouts": layouts, "n_crossings": self.n_crossings, "seed": self.seed,
                "severity": self.severity, "damage_length_m": self.length, "false_alarm": self.false_alarm,
                "nuisance": self.nuisance}
