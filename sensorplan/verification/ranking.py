"""Rank verified layouts by what verification measures, and say when a baseline beats the optimum.

The ranking orders layouts by their detection rate of the local losses
(higher first), then by their detection limit (the known-location power,
free of Monte-Carlo error), then by localisation error (lower first), then
by how close coverage95 is to 0.95.  A layout "verifies better" than the
reference (the recommended layout) when it ranks above it; the differences
are reported with paired Monte-Carlo standard errors (every layout sees the
same scenarios and noise seeds), so a reader can tell a real difference
from scenario noise.

Owns: VerificationRanking, rank_layouts.  May import: the foundations.
"""

import math
from dataclasses import KW_ONLY, dataclass

import numpy as np

__all__ = ["RankedLayout", "VerificationRanking", "rank_layouts"]

_ORDER = "detection rate, then detection limit, localisation error, coverage95 closest to 0.95"


def _mean(metric):
    return None if math.isnan(metric.mean) else metric.mean


@dataclass(frozen=True)
class RankedLayout:
    """One layout's place in the ranking, its verification metrics and criterion value."""

    name: str
    rank: int
    _: KW_ONLY
    detection_rate: float | None
    detection_rate_se: float | None
    detection_limit: float | None
    localisation_error_m: float | None
    coverage95: float | None
    criterion: float | None = None
    better_on: tuple = ()  # metrics on which it beats the reference
    detection_rate_diff: float | None = None  # minus the reference's, paired over the same scenarios
    detection_rate_diff_se: float | None = None
    detection_rate_count: int | None = None  # detected local losses out of detection_rate_n
    detection_rate_n: int = 0
    detection_rate_ci95: tuple | None = None  # Wilson 95 % interval of the detection rate

    def detection_text(self):
        """The detection rate as "0.50 (3/6; 95 % 0.19-0.81)": with its count and Wilson 95 % interval."""
        if self.detection_rate is None:
            return "no scenarios"
        if self.detection_rate_ci95 is None:  # a metric built without its counts
            return f"{self.detection_rate:.2f}"
        lo, hi = self.detection_rate_ci95
        return f"{self.detection_rate:.2f} ({self.detection_rate_count}/{self.detection_rate_n}; 95 % {lo:.2f}-{hi:.2f})"

    def to_dict(self):
        return {"name": self.name, "rank": self.rank, "detection_rate": self.detection_rate,
                "detection_rate_se": self.detection_rate_se, "detection_limit": self.detection_limit,
                "localisation_error_m": self.localisation_error_m, "coverage95": self.coverage95,
                "criterion": self.criterion, "better_than_reference_on": list(self.better_on),
                "detection_rate_diff": self.detection_rate_diff,
                "detection_rate_diff_se": self.detection_rate_diff_se,
                "detection_rate_count": self.detection_rate_count, "detection_rate_n": self.detection_rate_n,
                "detection_rate_ci95": None if self.detection_rate_ci95 is None else list(self.detection_rate_ci95)}


@dataclass(frozen=True)
class VerificationRanking:
    """Layouts best first by verification, against a reference layout (the criterion's optimum)."""

    entries: tuple  # RankedLayout, best first
    reference: str
    criterion: str | None = None

    @property
    def verifies_better(self):
        """Names of the layouts ranked above the reference."""
        names = [e.name for e in self.entries]
        return tuple(names[:names.index(self.reference)])

    def summary(self):
        crit = f"{self.criterion}-optimal" if self.criterion else "reference"
        lines = [f"Ranking by verification ({_ORDER}):"]
        for e in self.entries:
            lines.append(f"  {e.rank:2d}. {e.name[:26]:26s} detection {e.detection_text():>26s}  limit {_f(e.detection_limit):>5s}"
                         f"  loc. err {_f(e.localisation_error_m, '.2f'):>5s} m  coverage95 {_f(e.coverage95):>5s}"
                         + ("" if e.criterion is None else f"  criterion {e.criterion:.6g}"))
        better = [e for e in self.entries if e.name in self.verifies_better]
        ref = next(e for e in self.entries if e.name == self.reference)
        if not better:
            lines.append(f"  the {crit} layout ({self.reference}) verifies best.")
        for e in better:
            diff = "" if e.detection_rate_diff is None else f"; detection rate {_paired_text(e)}"
            diff += f"; detection limit {_f(e.detection_limit)} vs {_f(ref.detection_limit)}"
            lines.append(f"  NOTE: baseline {e.name} verifies better than the {crit} layout "
                         f"(better on {', '.join(e.better_on) or 'ties broken in its favour'}{diff}): "
                         "this criterion's optimum is not the best layout for detection here.")
        return "\n".join(lines)

    def to_dict(self):
        return {"verification_ranking": [e.to_dict() for e in self.entries],
                "baseline_verifies_better": list(self.verifies_better)}


def _paired_text(entry):
    """The paired difference of detection rates to the reference: "+0.250 ± 0.144 (paired s.e.)", or that
    both layouts detected the same losses (a difference of 0 with a paired s.e. of 0 says no more)."""
    if not entry.detection_rate_diff_se and entry.detection_rate_diff == 0.0:
        return "the same, loss by loss"
    return f"{entry.detection_rate_diff:+.3f} ± {_f(entry.detection_rate_diff_se)} (paired s.e.)"


def _f(value, fmt=".3f"):
    return "n/a" if value is None or (isinstance(value, float) and math.isnan(value)) else format(value, fmt)


def _paired(score, ref, key="detected"):
    """Mean and standard error of the per-scenario differences over the local losses."""
    a = [getattr(r, key) for r in score.records if r.kind == "local"]
    b = [getattr(r, key) for r in ref.records if r.kind == "local"]
    if not a or len(a) != len(b):
        return None, None
    d = np.asarray(a, float) - np.asarray(b, float)
    se = float(d.std(ddof=1) / math.sqrt(d.size)) if d.size > 1 else None
    return float(d.mean()), se


def _key(score):
    m = score.metrics
    det = m["detection_rate"].mean
    loc = m["localisation_error_m"].mean
    cov = m["coverage95"].mean
    return (-(0.0 if math.isnan(det) else det), -(score.detection_limit or 0.0),
            math.inf if math.isnan(loc) else loc, math.inf if math.isnan(cov) else abs(cov - 0.95))


def _better_on(score, ref):
    """Metrics on which ``score`` beats ``ref`` by more than their combined standard error (limit: exactly)."""
    out = []
    m, r = score.metrics, ref.metrics
    for name, sign in (("detection_rate", 1.0), ("localisation_error_m", -1.0)):
        a, b = m[name], r[name]
        if not (math.isnan(a.mean) or math.isnan(b.mean)) and sign * (a.mean - b.mean) > np.nan_to_num(
                math.hypot(a.se, b.se)):
            out.append(name)
    if score.detection_limit is not None and ref.detection_limit is not None and (
            score.detection_limit > ref.detection_limit + 1e-3):
        out.append("detection_limit")
    a, b = m["coverage95"], r["coverage95"]
    if abs(a.mean - 0.95) < abs(b.mean - 0.95) - np.nan_to_num(math.hypot(a.se, b.se)):
        out.append("coverage95")
    return tuple(out)


def rank_layouts(verification, *, reference="recommended", criterion=None, values=None):
    """Rank the layouts of ``verification`` (a VerificationResult with names) by verification.

    ``values`` maps layout names to their criterion values (shown next to the metrics).
    """
    names = list(verification.names) or [s.label for s in verification.layouts]
    scores = dict(zip(names, verification.layouts))
    ref = scores[reference]
    order = sorted(names, key=lambda n: (_key(scores[n]), n != reference))
    entries = []
    for rank, name in enumerate(order, start=1):
        s = scores[name]
        diff, se = _paired(s, ref) if name != reference else (None, None)
        det = s.metrics["detection_rate"]
        entries.append(RankedLayout(
            name, rank, detection_rate=_mean(det), detection_rate_se=None if math.isnan(det.se) else det.se,
            detection_limit=s.detection_limit, localisation_error_m=_mean(s.metrics["localisation_error_m"]),
            coverage95=_mean(s.metrics["coverage95"]), criterion=None if values is None else values.get(name),
            better_on=() if name == reference else _better_on(s, ref), detection_rate_diff=diff,
            detection_rate_diff_se=se, detection_rate_count=det.count, detection_rate_n=det.n,
            detection_rate_ci95=det.ci95 if det.n else None))
    return VerificationRanking(tuple(entries), reference, criterion)
