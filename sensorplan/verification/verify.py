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
from dataclasses import dataclass, replace

import numpy as np
from scipy import stats

from .._errors import ConfigError, SensorplanWarning
from .._threads import single_threaded
from ..inference.inversion import invert
from ..model.noise import NoiseModel
from ..model.sensors import SensorLayout
from ..model.simulate import simulate_crossings
from .results import VerificationResult, _aggregate
from .scenarios import Scenario, element_average_ei, make_scenarios, truth_mesh

__all__ = ["verify_layouts"]


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
    noise_std: float | None = None


@single_threaded
def _run_task(task, *, posterior=False):
    case = task.case
    std = case.noise_std_for(task.kind, task.noise_std)  # the median of the case's sensors of that kind
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


@single_threaded
def verify_layouts(case, layouts, *, names=None, n_locations=8, severity=0.25, length=2.0, n_controls=None,
                   n_crossings=10, seed=0, kind="rotation", noise_std=None, executor=None, workers=1,
                   detection_threshold=0.9, progress=None):
    """Score ``layouts`` (lists of positions [m]) on the same synthetic scenarios.

    Parameters
    ----------
    case : Case
        Model, inversion mesh and noise (correlation length, and the noise std of the layouts' sensors).
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
        Noise std of the sensors [rad or m] (default: :meth:`Case.noise_std_for`, the median
        of the case's sensors of the same kind).
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
