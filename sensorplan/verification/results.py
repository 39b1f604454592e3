"""Result types of the verification: Metric, LayoutScore, VerificationResult.

Owns: aggregation of per-scenario records into metrics with Monte-Carlo errors.
May import: the foundations.
"""

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Metric", "LayoutScore", "VerificationResult", "METRICS", "EXTRA_METRICS"]

METRICS = ("rmse", "localisation_error_m", "detection_rate", "false_alarm_rate", "coverage95", "band_width")
EXTRA_METRICS = ("control_coverage95",)


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


@dataclass(frozen=True, eq=False)
class LayoutScore:
    """Aggregated metrics of one layout with Monte-Carlo standard errors."""

    layout_m: tuple
    n_scenarios: int
    metrics: dict  # name -> Metric
    records: tuple  # one dict per scenario

    def to_dict(self):
        out = {"layout_m": list(self.layout_m), "n_scenarios": self.n_scenarios}
        for name in METRICS + EXTRA_METRICS:
            metric = self.metrics[name]
            out[name] = metric.mean
            out[name + "_se"] = metric.se
        return out


@dataclass(frozen=True, eq=False)
class VerificationResult:
    """Verification of several layouts on the same scenarios and seeds."""

    layouts: tuple  # LayoutScore
    scenarios: tuple
    n_crossings: int
    seed: int
    severity: float
    length: float
    names: tuple = ()

    def summary(self):
        head = (f"Verification: {sum(s.kind == 'local' for s in self.scenarios)} local losses of "
                f"{100 * self.severity:.0f} % over {self.length:g} m, "
                f"{sum(s.kind == 'span' for s in self.scenarios)} span softenings, "
                f"{sum(s.kind == 'control' for s in self.scenarios)} undamaged controls; "
                f"{self.n_crossings} crossings each; seed {self.seed}")
        lines = [head, f"  {'layout':30s} {'rmse':>13s} {'loc. err [m]':>14s} {'detection':>13s} "
                       f"{'false alarm':>13s} {'coverage95':>13s} {'band width':>13s}"]
        for name, score in zip(self.names or [None] * len(self.layouts), self.layouts):
            label = name or ", ".join(f"{x:g}" for x in score.layout_m)
            cells = [f"{score.metrics[m].mean:6.3f}±{score.metrics[m].se:5.3f}" for m in METRICS]
            lines.append(f"  {label[:30]:30s} " + " ".join(f"{c:>13s}" for c in cells))
        lines.append("  (mean ± Monte-Carlo standard error; rmse and band width relative to EI)")
        return "\n".join(lines)

    def to_dict(self):
        layouts = []
        for name, score in zip(self.names or [None] * len(self.layouts), self.layouts):
            d = score.to_dict()
            if name:
                d["name"] = name
            layouts.append(d)
        return {"layouts": layouts, "n_crossings": self.n_crossings, "seed": self.seed,
                "severity": self.severity, "damage_length_m": self.length}



def _aggregate(layout, records):
    mean_se = Metric.of

    damaged = [r for r in records if r["kind"] != "control"]
    controls = [r for r in records if r["kind"] == "control"]
    metrics = {
        "rmse": mean_se([r["rmse"] for r in records]),
        "localisation_error_m": mean_se([r.get("localisation_error_m") for r in records if r["kind"] == "local"]),
        "detection_rate": mean_se([r["detected"] for r in damaged]),
        "false_alarm_rate": mean_se([r["false_alarm"] for r in controls]),
        "coverage95": mean_se([r["coverage95"] for r in records]),
        "band_width": mean_se([r["band_width"] for r in records]),
        "control_coverage95": mean_se([r["coverage95"] for r in controls]),
    }
    return LayoutScore(tuple(float(x) for x in layout), len(records), metrics, tuple(records))


