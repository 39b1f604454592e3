"""Verify layouts by full Bayesian inversion of synthetic damage scenarios.

Every scenario is simulated on a truth mesh that is finer than the
inversion mesh *and* differently aligned (4 k + 1 elements per span of k),
so damage edges do not coincide with inversion elements and no inverse
crime is committed.  Noise comes from the case's noise model (AR(1)
included).  The data are inverted with :func:`sensorplan.invert`,
hyperparameters included, exactly as ``sensorplan invert`` does.

Scenarios run through any ``concurrent.futures.Executor``; each one draws
its noise from its own child of ``numpy.random.SeedSequence(seed)``, so the
results are identical whatever the number of workers.
"""

import math
import warnings
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, replace

import numpy as np
from scipy import stats

from .._errors import ConfigError, SensorplanWarning
from ..inference.inversion import invert
from ..model.noise import NoiseModel
from ..model.sensors import SensorLayout
from ..model.simulate import simulate_crossings
from ..model.structure import Mesh
from .._threads import single_threaded

__all__ = ["Scenario", "make_scenarios", "verify_layouts", "VerificationResult", "LayoutScore"]

METRICS = ("rmse", "localisation_error_m", "detection_rate", "false_alarm_rate", "coverage95", "band_width")
EXTRA_METRICS = ("control_coverage95",)


@dataclass(frozen=True)
class Scenario:
    """A synthetic truth: ``kind`` is "local", "span" or "control"."""

    kind: str
    start: float = 0.0  # damaged zone [m]
    stop: float = 0.0
    severity: float = 0.0  # fraction of EI lost

    @property
    def centre(self):
        return 0.5 * (self.start + self.stop)

    def truth(self, mesh, nominal):
        """EI on ``mesh`` (per element) for this scenario."""
        ei = np.array(nominal, dtype=float)
        if self.kind == "control":
            return ei
        inside = (mesh.midpoints > self.start) & (mesh.midpoints < self.stop)
        ei[inside] *= 1.0 - self.severity
        return ei


def make_scenarios(case, n_locations=8, *, severity=0.25, length=2.0, n_controls=None, spans=True):
    """Local losses scanned across the bridge, span-wise softening and undamaged controls."""
    if not 0.0 < severity < 1.0:
        raise ConfigError(f"The 'severity' parameter must be in (0, 1). Got {severity!r} instead.")
    total = case.bridge.length
    if not 0.0 < length < total:
        raise ConfigError(f"The 'length' parameter must be in (0, {total:g}) m. Got {length!r} instead.")
    if int(n_locations) != n_locations or n_locations < 1:
        raise ConfigError(f"The 'scenarios' parameter must be a positive integer. Got {n_locations!r} instead.")
    h = float(np.min(case.mesh.lengths))
    # centres spread over the bridge, shifted by a fraction of an element so
    # that damage edges fall inside inversion elements
    centres = length / 2 + (total - length) * (np.arange(n_locations) + 0.5) / n_locations + 0.37 * h
    centres = np.clip(centres, length / 2, total - length / 2)
    out = [Scenario("local", c - length / 2, c + length / 2, severity) for c in centres]
    if spans:
        xs = case.bridge.support_positions
        out += [Scenario("span", a, b, severity) for a, b in zip(xs[:-1], xs[1:])]
    n_controls = max(5, n_locations // 2) if n_controls is None else int(n_controls)
    out += [Scenario("control")] * n_controls
    return out


def truth_mesh(case):
    """Finer, differently aligned mesh: 4 k + 1 elements in a span of k elements."""
    counts = np.bincount(case.bridge.span_of(case.mesh.midpoints), minlength=case.bridge.n_spans)
    return Mesh._from_counts(case.bridge, [4 * int(k) + 1 for k in counts])


def element_average_ei(fine_mesh, fine_ei, mesh):
    """EI of each element of ``mesh`` equivalent to ``fine_ei`` (average compliance, paper eq. v_avg)."""
    lo = np.maximum(mesh.edges[:-1, None], fine_mesh.edges[None, :-1])
    hi = np.minimum(mesh.edges[1:, None], fine_mesh.edges[None, 1:])
    overlap = np.clip(hi - lo, 0.0, None)
    return mesh.lengths / (overlap @ (1.0 / fine_ei))


@dataclass(frozen=True)
class _Task:
    case: object
    layout: tuple
    kind: str
    scenario: Scenario
    seed: object
    n_crossings: int
    detection_threshold: float
    window: int
    start: tuple = (1.0, None)  # warm start of (noise scale, tau)
    noise_std: float = None


@single_threaded
def _run_task(task, *, posterior=False):
    case = task.case
    std = float(np.median(case.noise.std)) if task.noise_std is None else float(task.noise_std)
    sensors = SensorLayout.candidates(list(task.layout), task.kind, noise_std=[std] * len(task.layout))
    noise = NoiseModel(sensors.noise_std, case.noise.correlation_length)
    case = replace(case, sensors=sensors, noise=noise)
    fine_mesh = truth_mesh(case)
    fine = case.with_mesh(fine_mesh)
    truth_fine = task.scenario.truth(fine_mesh, fine.ei)
    rng = np.random.default_rng(task.seed)
    data = simulate_crossings(fine, task.n_crossings, noise=True, rng=rng, ei=truth_fine)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SensorplanWarning)
        post = invert(case, data, screen=False, noise_scale=task.start[0], tau=task.start[1])
    if posterior:
        return post
    return _score(case, post, task.scenario, element_average_ei(fine_mesh, truth_fine, case.mesh),
                  task.detection_threshold, task.window)


def _zone_probability(post, weights, threshold):
    """P(weighted mean of log(EI / nominal) <= log threshold) under the Laplace posterior."""
    n = post.n_elements
    a = weights / weights.sum()
    mean = a @ (post.theta[:n] - np.log(post.ei_nominal))
    sd = math.sqrt(max(a @ post.covariance[:n, :n] @ a, 1e-300))
    return float(stats.norm.cdf((math.log(threshold) - mean) / sd))


def _score(case, post, scenario, truth, threshold, window):
    mesh = case.mesh
    ci = post.credible_interval(0.95)
    covered = float(np.mean((truth >= ci[:, 0]) & (truth <= ci[:, 1])))
    width = float(np.mean((ci[:, 1] - ci[:, 0]) / post.ei_nominal))
    rmse = float(np.sqrt(np.mean((post.ei_mean / truth - 1.0) ** 2)))
    out = {"kind": scenario.kind, "centre_m": scenario.centre, "rmse": rmse, "coverage95": covered,
           "band_width": width, "converged": post.converged}
    level = 1.0 - 0.5 * scenario.severity if scenario.kind != "control" else None
    if scenario.kind == "control":
        # false alarm: any window of the damage length flagged at the detection level of a
        # 25 % loss (the probability of a 12.5 % drop there exceeds the threshold)
        probs = [_zone_probability(post, np.r_[np.zeros(i), mesh.lengths[i:i + window], np.zeros(
            mesh.n_elements - i - window)], 1.0 - 0.125) for i in range(mesh.n_elements - window + 1)]
        out["max_zone_probability"] = float(max(probs))
        out["false_alarm"] = float(max(probs) >= threshold)
        return out
    lo = np.maximum(mesh.edges[:-1], scenario.start)
    hi = np.minimum(mesh.edges[1:], scenario.stop)
    weights = np.clip(hi - lo, 0.0, None)
    prob = _zone_probability(post, weights, level)
    out["detection_probability"] = prob
    out["detected"] = float(prob >= threshold)
    if scenario.kind == "local":
        ratio = post.ei_mean / post.ei_nominal
        out["localisation_error_m"] = float(abs(mesh.midpoints[np.argmin(ratio)] - scenario.centre))
    return out


@dataclass(frozen=True, eq=False)
class LayoutScore:
    """Aggregated metrics of one layout with Monte-Carlo standard errors."""

    layout_m: tuple
    n_scenarios: int
    metrics: dict  # name -> (mean, standard error)
    records: tuple  # one dict per scenario

    def to_dict(self):
        out = {"layout_m": list(self.layout_m), "n_scenarios": self.n_scenarios}
        for name in METRICS + EXTRA_METRICS:
            mean, se = self.metrics[name]
            out[name] = mean
            out[name + "_se"] = se
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
            cells = [f"{score.metrics[m][0]:6.3f}±{score.metrics[m][1]:5.3f}" for m in METRICS]
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
    def mean_se(values):
        values = np.asarray([v for v in values if v is not None and np.isfinite(v)], dtype=float)
        if values.size == 0:
            return (float("nan"), float("nan"))
        se = float(values.std(ddof=1) / math.sqrt(values.size)) if values.size > 1 else float("nan")
        return (float(values.mean()), se)

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


@single_threaded
def verify_layouts(case, layouts, *, names=None, n_locations=8, severity=0.25, length=2.0, n_controls=None,
                   n_crossings=10, seed=0, kind="rotation", noise_std=None, executor=None, workers=1,
                   detection_threshold=0.9, progress=None):
    """Score ``layouts`` (lists of positions [m]) on the same synthetic scenarios.

    Parameters
    ----------
    case : Case
        Model, inversion mesh and noise (median std of the case's sensors).
    layouts : sequence of sequence of float
    n_locations : int
        Local-damage locations scanned across the bridge.
    severity, length : float
        Fraction of EI lost and length [m] of the local damage.
    n_controls : int, optional
        Undamaged controls (default max(5, n_locations // 2)).
    n_crossings : int
    kind : {"rotation", "deflection"}
    noise_std : float, optional
        Noise std of the sensors [rad or m] (default: median of the case's).
    seed : int
        Seed of the numpy SeedSequence; results do not depend on the workers.
    executor : concurrent.futures.Executor, optional
        Any executor (e.g. Dask's or Ray's); by default a process pool of
        ``workers`` processes, or none when ``workers == 1``.
    detection_threshold : float
        A scenario counts as detected (or a control as a false alarm) when
        the posterior probability of the loss reaches this level.
    progress : callable, optional
        Called with (done, total) after each scenario.
    """
    if case.noise is None:
        raise ConfigError("Verification needs a noise model: set noise_std in [sensors].")
    layouts = [tuple(float(x) for x in layout) for layout in layouts]
    if not layouts:
        raise ConfigError("Give at least one layout to verify.")
    for layout in layouts:
        case.bridge.check_on_bridge(layout, "layout", "verify")
    scenarios = make_scenarios(case, n_locations, severity=severity, length=length, n_controls=n_controls)
    seeds = np.random.SeedSequence(seed).spawn(len(scenarios))
    window = max(1, int(round(length / float(np.mean(case.mesh.lengths)))))
    tasks = []
    for layout in layouts:
        # warm start: hyperparameters of a pilot inversion (the first scenario,
        # computed here, before dispatch, so results do not depend on workers)
        pilot = _run_task(_Task(case, layout, kind, scenarios[0], seeds[0], int(n_crossings),
                                detection_threshold, window, noise_std=noise_std), posterior=True)
        start = (pilot.noise_scale, pilot.tau)
        tasks += [_Task(case, layout, kind, scenario, s, int(n_crossings), detection_threshold, window, start,
                        noise_std) for scenario, s in zip(scenarios, seeds)]
    results = []
    own = None
    if executor is None and workers > 1:
        own = executor = ProcessPoolExecutor(max_workers=int(workers))
    try:
        iterator = map(_run_task, tasks) if executor is None else executor.map(
            _run_task, tasks, chunksize=max(1, len(tasks) // (8 * max(1, workers))))
        for i, record in enumerate(iterator, start=1):
            results.append(record)
            if progress is not None:
                progress(i, len(tasks))
    finally:
        if own is not None:
            own.shutdown()
    n = len(scenarios)
    scores = tuple(_aggregate(layout, results[k * n:(k + 1) * n]) for k, layout in enumerate(layouts))
    return VerificationResult(scores, tuple(scenarios), int(n_crossings), int(seed), float(severity),
                              float(length), tuple(names) if names else ())
