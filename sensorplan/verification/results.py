"""Result types of the verification: Metric, ScenarioRecord, LayoutScore, VerificationResult.

Owns: aggregation of per-scenario records into metrics with Monte-Carlo errors.
May import: the foundations.
"""

import math
from dataclasses import KW_ONLY, dataclass

import numpy as np
from scipy import special

__all__ = ["wilson_interval", "false_alarm_caveat", "Metric", "ScenarioRecord", "LayoutScore", "VerificationResult", "METRICS", "EXTRA_METRICS"]

METRICS = ("rmse", "localisation_error_m", "detection_rate", "false_alarm_rate", "coverage95", "band_width")
EXTRA_METRICS = ("control_coverage95", "damaged_coverage95", "span_detection_rate", "loss_coverage95",
                 "non_converged")
# shares of scenarios (0/1 outcomes): reported with their count and Wilson 95 % interval
RATES = ("detection_rate", "false_alarm_rate", "span_detection_rate", "loss_coverage95", "non_converged")
MIN_CONTROLS = 20  # fewer undamaged controls cannot tell a false-alarm rate from its nominal value


def wilson_interval(count, n, level=0.95):
    """Wilson score interval (lo, hi) of a proportion of ``count`` successes in ``n`` trials.

    Wilson (1927), JASA 22, 209: the set of p whose score test at ``level``
    does not reject ``count`` / ``n``.  Unlike the normal interval mean ± z se
    it never collapses to a point at 0 / n or n / n (1 in 5 gives 0.04-0.62).
    (nan, nan) when ``n`` is 0.
    """
    if n <= 0:
        return (float("nan"), float("nan"))
    z = float(special.ndtri(0.5 + level / 2.0))
    p, z2 = count / n, z * z
    centre = (p + z2 / (2.0 * n)) / (1.0 + z2 / n)
    half = z * math.sqrt(p * (1.0 - p) / n + z2 / (4.0 * n * n)) / (1.0 + z2 / n)
    return (max(0.0, centre - half), min(1.0, centre + half))


@dataclass(frozen=True)
class Metric:
    """Mean of a per-scenario metric with its Monte-Carlo standard error over ``n`` scenarios.

    A rate (the share of scenarios where something happened: detection, false
    alarm) also carries its ``count`` of such scenarios and the Wilson 95 %
    interval ``ci95`` (:func:`wilson_interval`); both are None otherwise.
    """

    mean: float
    se: float
    n: int = 0
    count: int | None = None
    ci95: tuple | None = None

    @classmethod
    def of(cls, values):
        """Mean and standard error of the finite values (NaN when there are none)."""
        values = np.asarray([v for v in values if v is not None and np.isfinite(v)], dtype=float)
        if values.size == 0:
            return cls(float("nan"), float("nan"), 0)
        se = float(values.std(ddof=1) / math.sqrt(values.size)) if values.size > 1 else float("nan")
        return cls(float(values.mean()), se, int(values.size))

    @classmethod
    def rate(cls, outcomes):
        """The share of the 0/1 ``outcomes`` (None entries skipped), with its count and Wilson interval."""
        metric = cls.of(outcomes)
        count = int(round(metric.mean * metric.n)) if metric.n else 0
        return cls(metric.mean, metric.se, metric.n, count, wilson_interval(count, metric.n))

    @property
    def is_rate(self):
        return self.count is not None

    def __iter__(self):  # unpacks as (mean, se)
        return iter((self.mean, self.se))

    def text(self, *, digits=2, empty="no scenarios"):
        """The metric as a reader should see it: "0.20 (1/5; 95 % 0.04-0.62)" for a rate, "0.066 ± 0.006"
        otherwise; ``empty`` when no scenario gave a value."""
        if self.n == 0:
            return empty
        if self.is_rate:
            lo, hi = self.ci95
            return f"{self.mean:.{digits}f} ({self.count}/{self.n}; 95 % {lo:.{digits}f}-{hi:.{digits}f})"
        if math.isnan(self.se):
            return f"{self.mean:.{digits + 1}f}"
        return f"{self.mean:.{digits + 1}f} ± {self.se:.{digits + 1}f}"

    def to_dict(self):
        out = {"mean": self.mean, "se": self.se, "n": self.n}
        if self.is_rate:
            out.update(count=self.count, ci95=None if self.n == 0 else list(self.ci95))
        return out


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
    verdict: str | None = None  # status of the one verdict an owner would have read on these data

    def to_dict(self):
        out = {"kind": self.kind, "centre_m": self.centre_m, "rmse": self.rmse, "coverage95": self.coverage95,
               "band_width": self.band_width, "converged": self.converged, "statistic": self.statistic,
               "threshold": self.threshold}
        for name in ("false_alarm", "detected", "localisation_error_m", "loss_covered", "verdict"):
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
        mean_se, rate = Metric.of, Metric.rate
        local = [r for r in records if r.kind == "local"]
        damaged = [r for r in records if r.kind != "control"]
        controls = [r for r in records if r.kind == "control"]
        metrics = {
            "rmse": mean_se([r.rmse for r in records]),
            # the detector's centre against the truth, over the detected local losses
            "localisation_error_m": mean_se([r.localisation_error_m for r in local]),
            # local losses (what detection_limit measures); span softenings are span_detection_rate
            "detection_rate": rate([r.detected for r in local]),
            "false_alarm_rate": rate([r.false_alarm for r in controls]),
            "coverage95": mean_se([r.coverage95 for r in records]),
            "band_width": mean_se([r.band_width for r in records]),
            "control_coverage95": mean_se([r.coverage95 for r in controls]),
            "damaged_coverage95": mean_se([r.coverage95 for r in damaged]),
            "span_detection_rate": rate([r.detected for r in damaged if r.kind == "span"]),
            # share of the detected local losses whose 95 % loss interval covers the true loss
            "loss_coverage95": rate([r.loss_covered for r in local]),
            "non_converged": rate([1.0 - r.converged for r in records]),
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
            out[name + "_n"] = metric.n
            if metric.is_rate:
                out[name + "_count"] = metric.count
                out[name + "_ci95"] = None if metric.n == 0 else list(metric.ci95)
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
        widths = (12, 13, 22, 6, 22, 12, 12, 9)
        titles = ("rmse", "loc. err [m]", "detection", "limit", "false alarm", "coverage95", "band width",
                  "not conv.")
        lines = [head, f"  {'layout':26s} " + " ".join(f"{t:>{w}s}" for t, w in zip(titles, widths))]
        for label, score in zip(self.labels, self.layouts):
            m = score.metrics
            cells = [_pm(m["rmse"]), _pm(m["localisation_error_m"], empty="no detections"),
                     _rate(m["detection_rate"]),
                     "n/a" if score.detection_limit is None else f"{score.detection_limit:.3f}",
                     _rate(m["false_alarm_rate"]), _pm(m["coverage95"]), _pm(m["band_width"]),
                     f"{m['non_converged'].count}/{m['non_converged'].n}"]
            lines.append(f"  {label[:26]:26s} " + " ".join(f"{c:>{w}s}" for c, w in zip(cells, widths)))
        lines.append("  (detection and false alarm: share of the scenarios with its count and Wilson 95 % interval; "
                     "other columns mean ± Monte-Carlo standard error; rmse and band width relative to EI; detection "
                     "over the local losses, limit = their known-location power at the Bonferroni level)")
        lines += [f"  caveat: {c}" for c in self.false_alarm_caveats()]
        lines += [f"  verdicts of {label[:26]}: {text}" for label, text in zip(self.labels, self._verdict_texts())]
        # only where the limit is worth comparing with (a few detections are expected)
        ratios = [s.detection_ratio for s in self.layouts if s.detection_limit is not None and s.detection_limit >= 0.2]
        if ratios and min(ratios) < 0.8:
            lines.append("  note: detection below 0.8 x its physical limit for some layout: the detector loses power "
                         "to the scan over unknown locations and lengths")
        return "\n".join(lines)

    @property
    def labels(self):
        """The layouts' names, or their positions when unnamed."""
        return [name or score.label for name, score in zip(self.names or [None] * len(self.layouts), self.layouts)]

    def verdicts(self):
        """Per layout, the statuses of the verdict (:mod:`sensorplan.verdict`) an owner would have read on each
        scenario's data: ``{label: {"damaged": {status: count}, "controls": {status: count}}}``."""
        out = {}
        for label, score in zip(self.labels, self.layouts):
            counts: dict = {"damaged": {}, "controls": {}}
            for record in score.records:
                if record.verdict is not None:
                    group = counts["controls" if record.kind == "control" else "damaged"]
                    group[record.verdict] = group.get(record.verdict, 0) + 1
            out[label] = counts
        return out

    def _verdict_texts(self):
        texts = []
        for counts in self.verdicts().values():
            parts = [f"{group} " + ", ".join(f"{status} {n}" for status, n in sorted(c.items()))
                     for group, c in counts.items() if c]
            texts.append("; ".join(parts) or "none recorded")
        return texts

    def false_alarm_caveats(self):
        """One sentence per distinct caveat on the layouts' false-alarm rates (:func:`false_alarm_caveat`),
        naming the layouts it applies to unless it applies to all."""
        by_text = {}
        for label, score in zip(self.labels, self.layouts):
            text = false_alarm_caveat(score.metrics["false_alarm_rate"], self.false_alarm)
            if text is not None:
                by_text.setdefault(text, []).append(label)
        return [text if len(labels) == len(self.layouts) else f"{' / '.join(labels)}: {text}"
                for text, labels in by_text.items()]

    def to_dict(self):
        layouts = []
        for name, score in zip(self.names or [None] * len(self.layouts), self.layouts):
            d = score.to_dict()
            if name:
                d["name"] = name
            d["false_alarm_caveat"] = false_alarm_caveat(score.metrics["false_alarm_rate"], self.false_alarm)
            layouts.append(d)
        return {"layouts": layouts, "verdict": self.verdicts(), "n_crossings": self.n_crossings, "seed": self.seed,
                "severity": self.severity, "damage_length_m": self.length, "false_alarm": self.false_alarm,
                "nuisance": self.nuisance}


def false_alarm_caveat(metric, nominal):
    """A sentence when a false-alarm rate (a rate :class:`Metric` over the controls) says little, else None.

    It says little when it rests on fewer than MIN_CONTROLS controls or its
    95 % interval reaches above three times the ``nominal`` rate: the nominal
    rate then lies in the interval and cannot be told from it.  When the
    interval lies wholly above the nominal rate, the sentence says that the
    detector fires more often than calibrated instead.
    """
    if metric.n == 0:
        return "no undamaged controls: the false-alarm rate was not measured"
    lo, hi = metric.ci95
    head = (f"{metric.n} control{'s' if metric.n != 1 else ''}: a false-alarm rate of {metric.mean:.2f}, "
            f"95 % interval {lo:.2f}-{hi:.2f}")
    if lo > nominal:
        return f"{head}, above the nominal {nominal:g}: the detector fires on undamaged bridges more often than calibrated"
    if metric.n < MIN_CONTROLS or hi > 3.0 * nominal:
        return f"{head}, cannot be told from the nominal {nominal:g} (more controls would narrow it)"
    return None


def _pm(metric, *, empty="n/a"):
    """A summary cell: mean±se (the mean alone from one scenario), ``empty`` without any."""
    if metric.n == 0:
        return empty
    return f"{metric.mean:5.3f}" if math.isnan(metric.se) else f"{metric.mean:5.3f}±{metric.se:5.3f}"


def _rate(metric):
    """A summary cell of a rate: "0.20 (1/5; 0.04-0.62)"."""
    if metric.n == 0:
        return "no scenarios"
    lo, hi = metric.ci95
    return f"{metric.mean:.2f} ({metric.count}/{metric.n}; {lo:.2f}-{hi:.2f})"
