"""Design studies: recommend layouts for many cases and criteria, verify them all, one table.

:func:`design_study` runs, for every case, sensor count and criterion,
:func:`sensorplan.recommend` (plus the chosen baselines), then verifies
every distinct layout of a case on that case's scenarios with
:func:`sensorplan.verify_layouts`' machinery.  All the work, the
recommendations, the pilot inversions and each (case, layout, scenario),
goes through one executor: this process, a process pool, or a Dask
cluster (``scheduler``).  Each case's scenarios draw their noise from the
children of ``SeedSequence(seed)`` exactly as ``verify_layouts(case,
layouts, seed=seed)`` does, so a row's numbers equal that call's and do
not depend on where the work ran.
"""

import csv
import io
import math
import os
from collections.abc import Callable, Sequence
from concurrent.futures import Executor
from contextlib import nullcontext
from dataclasses import KW_ONLY, asdict, dataclass, fields
from typing import TYPE_CHECKING

from .._errors import ConfigError
from .._executors import executor_for
from .study_tasks import DesignJob, distinct_layouts, keep_row, run_study
from .verify import plan_verification

if TYPE_CHECKING:
    from ..model.case import Case

__all__ = ["design_study", "DesignStudy", "StudyRow"]


@dataclass(frozen=True, kw_only=True)
class StudyRow:
    """One layout of a design study with its criterion value and its verification metrics.

    ``criterion`` is the criterion that chose the layout (for a baseline, the
    one its value and efficiency refer to); ``layout`` is "recommended" or the
    baseline's name.  ``efficiency`` is the certified efficiency against the
    relaxation bound.  Metrics are means over the scenarios with their
    Monte-Carlo standard errors (``*_se``); the two rates also with their
    counts and Wilson 95 % intervals (``*_low``, ``*_high``);
    ``detection_limit`` is the layout's known-location power
    (:func:`sensorplan.verification.verify.detection_limit`).
    """

    case: str
    count: int
    criterion: str
    layout: str
    layout_m: tuple
    value: float
    efficiency: float
    detection_rate: float
    detection_rate_se: float
    detection_limit: float | None
    localisation_error_m: float
    localisation_error_m_se: float
    coverage95: float
    coverage95_se: float
    false_alarm_rate: float
    false_alarm_rate_se: float
    n_scenarios: int
    # the rates' Wilson 95 % intervals (verification.results.wilson_interval) and what they count
    detection_rate_low: float = math.nan
    detection_rate_high: float = math.nan
    n_detected: int = 0  # of n_local local losses
    n_local: int = 0
    false_alarm_rate_low: float = math.nan
    false_alarm_rate_high: float = math.nan
    n_false_alarms: int = 0  # of n_controls undamaged controls
    n_controls: int = 0


@dataclass(frozen=True, eq=False)
class DesignStudy:
    """The table of a design study (:func:`design_study`): one :class:`StudyRow` per case, count, criterion, layout."""

    rows: tuple
    _: KW_ONLY
    seed: int
    n_crossings: int
    severity: float
    length: float
    false_alarm: float
    nuisance: str
    verifications: dict  # case name -> VerificationResult of its distinct layouts

    COLUMNS = tuple(f.name for f in fields(StudyRow))

    def columns(self):
        """The table as a dict of columns (layout_m as "x1;x2;..." strings in metres)."""
        out = {name: [] for name in self.COLUMNS}
        for row in self.rows:
            for name, value in asdict(row).items():
                out[name].append(";".join(f"{x:g}" for x in value) if name == "layout_m" else value)
        return out

    def to_csv(self, path: "str | os.PathLike[str] | None" = None) -> str:
        """The table as CSV text (empty cells for missing values); written to ``path`` when given."""
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        cols = self.columns()
        writer.writerow(self.COLUMNS)
        for i in range(len(self.rows)):
            writer.writerow(["" if _missing(cols[c][i]) else cols[c][i] for c in self.COLUMNS])
        text = buffer.getvalue()
        if path is not None:
            with open(path, "w", encoding="utf-8", newline="") as handle:
                handle.write(text)
        return text

    def to_dict(self):
        return {"rows": [dict(asdict(r), layout_m=list(r.layout_m)) for r in self.rows], "seed": self.seed,
                "n_crossings": self.n_crossings, "severity": self.severity, "damage_length_m": self.length,
                "false_alarm": self.false_alarm, "nuisance": self.nuisance}

    def summary(self):
        lines = [f"Design study: {len(self.verifications)} case(s), {len(self.rows)} rows; local losses of "
                 f"{100 * self.severity:.0f} % over {self.length:g} m, {self.n_crossings} crossings per scenario, "
                 f"seed {self.seed}",
                 f"  {'case':16s} {'R':>2s} {'crit.':>5s} {'layout':20s} {'efficiency':>10s} {'detection':>22s} "
                 f"{'limit':>6s} {'loc. err [m]':>13s} {'coverage95':>12s} {'false alarm':>22s}  positions [m]"]
        for r in self.rows:
            limit = "n/a" if r.detection_limit is None else f"{r.detection_limit:.3f}"
            lines.append(f"  {r.case[:16]:16s} {r.count:2d} {r.criterion[:5]:>5s} {r.layout[:20]:20s} "
                         f"{100 * r.efficiency:9.1f}% {_detection(r):>22s} {limit:>6s} "
                         f"{_pm(r.localisation_error_m, r.localisation_error_m_se, 'no detections'):>13s} "
                         f"{_pm(r.coverage95, r.coverage95_se):>12s} {_false_alarm(r):>22s}"
                         "  " + ", ".join(f"{x:g}" for x in r.layout_m))
        lines.append("  (detection and false alarm: share of the scenarios with its count and Wilson 95 % interval; "
                     "other columns mean ± Monte-Carlo standard error over the scenarios; efficiency certified "
                     "against the relaxation bound of the row's criterion)")
        return "\n".join(lines)


def _missing(value):
    return value is None or (isinstance(value, float) and math.isnan(value))


def _pm(mean, se, empty="n/a"):
    if math.isnan(mean):
        return empty
    return f"{mean:5.3f}±{se:5.3f}" if not math.isnan(se) else f"{mean:5.3f}"


def _rate(mean, count, n, low, high):
    if n == 0:
        return "no scenarios"
    return f"{mean:.2f} ({count}/{n}; {low:.2f}-{high:.2f})"


def _detection(row):
    return _rate(row.detection_rate, row.n_detected, row.n_local, row.detection_rate_low, row.detection_rate_high)


def _false_alarm(row):
    return _rate(row.false_alarm_rate, row.n_false_alarms, row.n_controls, row.false_alarm_rate_low,
                 row.false_alarm_rate_high)


def _load(case):
    from ..io.config import EXAMPLES, example_case, load_case

    if isinstance(case, (str, os.PathLike)):
        return example_case(case) if isinstance(case, str) and case in EXAMPLES else load_case(case)
    if not hasattr(case, "bridge"):
        raise ConfigError(f"The 'cases' parameter takes Case objects, example names or TOML paths. "
                          f"Got {case!r} instead.")
    return case


def design_study(cases: Sequence, *, criteria: Sequence[str] = ("D",), counts: "int | Sequence[int] | None" = None,
                 baselines: "bool | Sequence[str]" = True, n_scenarios: int = 8, n_controls: int | None = None,
                 n_crossings: int = 10,
                 severity: float = 0.25, length: float = 2.0, false_alarm: float = 0.05, nuisance: str = "smooth",
                 spacing: float = 0.5, design_crossings: int = 1, seed: int = 0,
                 executor: Executor | None = None, workers: int = 1, scheduler: str | None = None,
                 progress: "Callable[[int, int], None] | None" = None) -> DesignStudy:
    """Recommend and verify layouts for several cases; returns one table (:class:`DesignStudy`).

    Parameters
    ----------
    cases : sequence of Case, example name or TOML path
    criteria : sequence of str
        Design criteria (see :data:`sensorplan.CRITERIA`), each recommending its own layout.
    counts : int or sequence of int, optional
        Numbers of new sensors R studied (default: each case's own number of sensors).
    baselines : bool or sequence of str
        Verify the feasible baselines of each design too (True: all; or their names, e.g.
        ``["equally_spaced"]``).
    n_scenarios, n_controls, n_crossings, severity, length, false_alarm, nuisance :
        The verification, as in :func:`sensorplan.verify_layouts` (``n_scenarios`` is its ``n_locations``).
    spacing, design_crossings :
        Candidate grid spacing [m] and crossings per campaign of the design (as ``recommend``).
    seed : int
        Seed of the scenarios' noise (as ``verify_layouts``) and of the random baseline.
    executor, workers, scheduler :
        Where the work runs, as in :func:`sensorplan.verify_layouts`; the table does not depend on it.
    progress : callable, optional
        Called with (done, total) as the work finishes: a design counts 1, a verification scenario 1.
        The whole study is one task graph (on Dask submitted at once, see
        :mod:`sensorplan.verification.study_tasks`).
    """
    loaded = _load_cases(cases)
    criteria = _check_criteria(criteria)
    _check_baseline_names(baselines)
    jobs = [DesignJob(case, int(r), crit, float(spacing), int(design_crossings), int(seed))
            for case, cs in zip(loaded, _counts(loaded, counts)) for r in cs for crit in criteria]
    options = dict(n_locations=n_scenarios, severity=severity, length=length, n_controls=n_controls,
                   n_crossings=n_crossings, seed=seed, false_alarm=false_alarm, nuisance=nuisance)
    with nullcontext(executor) if executor is not None else executor_for(workers, scheduler) as runner:
        designs, records = run_study(runner, loaded, jobs, baselines=baselines, options=options, progress=progress)
    _check_baselines(baselines, designs)
    verifications = {}
    for case, slots in zip(loaded, records):
        layouts = distinct_layouts([rows for job, rows in zip(jobs, designs) if job.case is case], baselines)
        plan = plan_verification(case, layouts, kind=case.default_kind, **options)
        verifications[case.name] = plan.result([r for slot in slots[:len(layouts)] for r in slot])
    rows = [row for job, design in zip(jobs, designs)
            for row in _study_rows(job, [r for r in design if keep_row(r.name, baselines)],
                                   verifications[job.case.name])]
    return DesignStudy(tuple(rows), seed=int(seed), n_crossings=int(n_crossings), severity=float(severity),
                       length=float(length), false_alarm=float(false_alarm), nuisance=nuisance,
                       verifications=verifications)


def _load_cases(cases):
    """The cases as Case objects, at least one, with distinct names."""
    loaded = [_load(c) for c in cases]
    if not loaded:
        raise ConfigError("The 'cases' parameter needs at least one case.")
    names = [c.name for c in loaded]
    if len(set(names)) != len(names):
        raise ConfigError(f"The 'cases' parameter has cases with the same name ({', '.join(names)}); rename them "
                          "(Case.name) so that the rows can tell them apart.")
    return loaded


def _check_criteria(criteria):
    """The criteria as a list, every one known."""
    from ..design.criteria import CRITERIA

    criteria = [criteria] if isinstance(criteria, str) else list(criteria)
    unknown = [c for c in criteria if c not in CRITERIA]
    if not criteria or unknown:
        raise ConfigError(f"The 'criteria' parameter must list criteria among {', '.join(CRITERIA)}. "
                          f"Got {criteria!r} instead.")
    return criteria


def _counts(loaded, counts):
    """The sensor counts studied for each case (default: the case's own number of sensors)."""
    per_case = [[c.sensors.n_sensors] if counts is None else [counts] if isinstance(counts, int) else list(counts)
                for c in loaded]
    for cs in per_case:
        if not cs or any(isinstance(r, bool) or int(r) != r or r < 1 for r in cs):
            raise ConfigError(f"The 'counts' parameter must be positive integers. Got {counts!r} instead.")
    return per_case


def _check_baseline_names(baselines):
    """Baselines named by the caller must be baselines recommend knows (before any work is done)."""
    import inspect

    from ..design.baselines import BASELINES
    from ..design.recommend import recommend

    if isinstance(baselines, bool):
        return
    n_random = inspect.signature(recommend).parameters["n_random"].default
    known = {label.format(n_random=n_random) for label in BASELINES}
    unknown = sorted(set(baselines) - known)
    if unknown:
        raise ConfigError(f"The 'baselines' parameter names unknown baselines: {', '.join(unknown)}; choose among "
                          f"{', '.join(sorted(known))}.")


def _check_baselines(baselines, designs):
    """Baselines named by the caller must be feasible baselines of some design."""
    if isinstance(baselines, bool):
        return
    known = {row.name for rows in designs for row in rows}
    missing = sorted(set(baselines) - known)
    if missing:
        raise ConfigError(f"The 'baselines' parameter names no feasible baseline of these designs: "
                          f"{', '.join(missing)}; choose among {', '.join(sorted(known - {'recommended'}))}.")


def _study_rows(job, chosen, result):
    """The rows of one job's chosen layouts, with their scores in the case's verification."""
    scores = {s.layout_m: s for s in result.layouts}
    rows = []
    for row in chosen:
        score = scores[tuple(float(x) for x in row.layout_m)]
        m = score.metrics
        rows.append(StudyRow(
            case=job.case.name, count=job.count, criterion=job.criterion, layout=row.name, layout_m=score.layout_m,
            value=float(row.value), efficiency=float(row.efficiency), detection_rate=m["detection_rate"].mean,
            detection_rate_se=m["detection_rate"].se, detection_limit=score.detection_limit,
            localisation_error_m=m["localisation_error_m"].mean, localisation_error_m_se=m["localisation_error_m"].se,
            coverage95=m["coverage95"].mean, coverage95_se=m["coverage95"].se,
            false_alarm_rate=m["false_alarm_rate"].mean, false_alarm_rate_se=m["false_alarm_rate"].se,
            n_scenarios=score.n_scenarios,
            **_rate_fields("detection_rate", m["detection_rate"], "n_detected", "n_local"),
            **_rate_fields("false_alarm_rate", m["false_alarm_rate"], "n_false_alarms", "n_controls")))
    return rows


def _rate_fields(name, metric, count, total):
    """A rate Metric as the StudyRow fields of its interval and counts."""
    low, high = metric.ci95
    return {f"{name}_low": low, f"{name}_high": high, count: metric.count, total: metric.n}
