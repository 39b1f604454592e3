"""Verify layouts by full Bayesian inversion of synthetic damage scenarios.

Every scenario is simulated on a truth mesh that is finer than the
inversion mesh *and* differently aligned (4 k + 1 elements per span of k),
so damage edges do not coincide with inversion elements and no inverse
crime is committed.  Noise comes from the case's noise model (AR(1)
included).  The data are inverted with :func:`sensorplan.invert`,
hyperparameters included, exactly as ``sensorplan invert`` does.

Scenarios run through any ``concurrent.futures.Executor`` or a Dask
cluster (:mod:`.dispatch`: one task graph, scenarios in chunks); each one
draws its noise from its own child of ``numpy.random.SeedSequence(seed)``,
so the results are identical whatever the number of workers.
"""

import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Executor
from contextlib import nullcontext
from dataclasses import KW_ONLY, dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy import special

from .._errors import ConfigError, SensorplanWarning
from .._executors import executor_for
from .._threads import single_threaded
from ..detection.signatures import whitened_signatures
from ..inference.inversion import invert
from ..model.sensors import SensorLayout
from ..model.simulate import simulate_crossings
from .dispatch import run_plans
from .results import LayoutScore, ScenarioRecord, VerificationResult
from .scenarios import Scenario, element_average_ei, make_scenarios, truth_mesh

if TYPE_CHECKING:
    from ..model.case import Case

__all__ = ["verify_layouts", "detection_limit", "plan_verification", "VerificationPlan"]


@dataclass(frozen=True, kw_only=True)
class _Task:
    """One inversion to run: a layout's sensors on one scenario, with its noise seed and warm start."""

    case: object
    layout: SensorLayout  # positions, kinds and noise std of the sensors
    scenario: Scenario
    seed: object
    n_crossings: int
    false_alarm: float
    nuisance: str
    start: tuple = (1.0, None)  # warm start of (noise scale, tau)


def _as_sensors(case, layout, kind, noise_std):
    """A layout as sensors with noise: positions [m] are of ``kind``; a SensorLayout keeps its kinds.

    Sensors without a noise std take ``noise_std`` (one value, or a mapping kind -> value) or else
    :meth:`Case.noise_std_for` of their kind.
    """
    if isinstance(layout, SensorLayout):
        positions, kinds, stds = layout.positions, layout.kinds, layout.noise_std
    else:
        positions = np.asarray([float(x) for x in layout])
        kinds, stds = (kind,) * positions.size, None
    if stds is None:
        given = noise_std if isinstance(noise_std, Mapping) else {kind: noise_std}
        stds = [case.noise_std_for(k, given.get(k)) for k in kinds]
    names = [f"{x:.6g}" for x in positions]
    if len(set(names)) != len(names):
        names = [f"{n}:{k}" for n, k in zip(names, kinds)]
    return SensorLayout(positions, tuple(kinds), tuple(names), tuple(float(v) for v in stds))


@single_threaded
def _run_task(task, *, posterior=False):
    case = task.case
    sensors = task.layout
    case = case.with_sensors(sensors)  # the layout's noise by the one rule (the case's correlation or time model)
    fine_mesh = truth_mesh(case)
    fine = case.with_mesh(fine_mesh)
    truth_fine = task.scenario.truth(fine_mesh, fine.ei)
    rng = np.random.default_rng(task.seed)
    data = simulate_crossings(fine, task.n_crossings, noise=True, rng=rng, ei=truth_fine)
    with warnings.catch_warnings(record=True):  # counted through post.converged, not printed per scenario
        warnings.simplefilter("always", SensorplanWarning)
        # the data are the model's own simulation: no screening and no unit-slip check (a forward solve each)
        post = invert(case, data, screen=False, check_scale=False, noise_scale=task.start[0], tau=task.start[1],
                      detect=not posterior, false_alarm=task.false_alarm, nuisance=task.nuisance, rng=rng)
    if posterior:
        return post
    detection = post.damage
    return _score(case, post, detection, task.scenario, element_average_ei(fine_mesh, truth_fine, case.mesh))


def _score(case, post, detection, scenario, truth):
    """Metrics of one scenario: the inversion's accuracy and bands, the detector's verdict."""
    ci = post.credible_interval(0.95)
    covered = float(np.mean((truth >= ci[:, 0]) & (truth <= ci[:, 1])))
    width = float(np.mean((ci[:, 1] - ci[:, 0]) / post.ei_nominal))
    rmse = float(np.sqrt(np.mean((post.ei_mean / truth - 1.0) ** 2)))
    common = dict(kind=scenario.kind, centre_m=scenario.centre, rmse=rmse, coverage95=covered, band_width=width,
                  converged=float(bool(post.converged)), statistic=detection.statistic,
                  threshold=detection.threshold, verdict=None if post.verdict is None else post.verdict.status)
    if scenario.kind == "control":
        return ScenarioRecord(**common, false_alarm=float(detection.detected))
    if scenario.kind == "local" and detection.detected:
        lo, hi = detection.loss_ci95
        return ScenarioRecord(**common, detected=float(detection.detected),
                              localisation_error_m=float(abs(detection.centre_m - scenario.centre)),
                              loss_covered=float(lo <= scenario.severity <= hi))
    return ScenarioRecord(**common, detected=float(detection.detected))


def detection_limit(case, layout, scenarios, *, kind="rotation", noise_std=None, n_crossings, false_alarm,
                    nuisance="smooth"):
    """Mean over the local scenarios of Phi(d - z_{1 - alpha/m}), m = floor(L / length) zones.

    d is the known-location noncentrality of :func:`sensorplan.detectability`
    (exact forward difference, nuisance projected off): the power of the
    optimal test of each scenario's own zone at the Bonferroni level for m
    zones, a conservative stand-in for what a scan over unknown locations can
    reach.  None without local scenarios.  ``layout`` is positions [m] of
    ``kind`` sensors or a SensorLayout (see :func:`verify_layouts`).
    """
    local = [s for s in scenarios if s.kind == "local"]
    if not local:
        return None
    length = local[0].stop - local[0].start
    sensors = _as_sensors(case, layout, kind, noise_std)
    sig = whitened_signatures(case, sensors, case.noise_for(sensors), [s.centre for s in local], severity=local[0].severity,
                              length=length, nuisance=nuisance)
    d = sig.projected_norms("damage") * math.sqrt(n_crossings)
    m = max(1, int(math.floor(case.bridge.length / length)))
    return float(np.mean(special.ndtr(d + special.ndtri(false_alarm / m))))


@single_threaded
def verify_layouts(case: "Case", layouts: "Sequence[Sequence[float] | SensorLayout]", *,
                   names: "Sequence[str] | None" = None,
                   n_locations: int = 8, severity: float = 0.25, length: float = 2.0, n_controls: int | None = None,
                   n_crossings: int = 10, seed: int = 0, kind: str = "rotation",
                   noise_std: "float | Mapping[str, float] | None" = None,
                   executor: "Executor | None" = None, workers: int = 1, false_alarm: float = 0.05,
                   nuisance: str = "smooth", progress: "Callable[[int, int], None] | None" = None,
                   scheduler: str | None = None) -> VerificationResult:
    """Score ``layouts`` (lists of positions [m]) on the same synthetic scenarios.

    Parameters
    ----------
    case : Case
        Model, inversion mesh and noise (correlation length, and the noise std of the layouts' sensors).
    layouts : sequence of (sequence of float or SensorLayout)
        Positions [m] of sensors of ``kind``, or a SensorLayout for sensors of
        several kinds (its noise std if set, else as for ``noise_std``).
    n_locations : int
        Local-damage locations scanned across the bridge.
    severity, length : float
        Fraction of EI lost and length [m] of the local damage.
    n_controls : int, optional
        Undamaged controls (default max(5, n_locations // 2)).
    n_crossings : int
    kind : {"rotation", "deflection"}
    noise_std : float or mapping kind -> float, optional
        Noise std of the sensors [rad or m] (default: :meth:`Case.noise_std_for`, the median
        of the case's sensors of the same kind).
    seed : int
        Seed of the numpy SeedSequence; results do not depend on the workers.
    executor : concurrent.futures.Executor, optional
        Any executor (e.g. Dask's or Ray's); by default a process pool of
        ``workers`` processes, or none when ``workers == 1``.
    scheduler : str, optional
        Run on a Dask cluster instead (the ``dask`` extra): the address of a
        running ``dask scheduler`` (e.g. ``"tcp://127.0.0.1:8786"``) or
        ``"local"`` for a LocalCluster of ``workers`` processes, closed afterwards.
        Ignored when ``executor`` is given.  Results are identical to ``workers=1``.
    false_alarm, nuisance :
        The damage detector (:func:`sensorplan.detect_damage`) of every
        scenario: its false-alarm rate and what an undamaged bridge may do.
        ``detection_rate``, ``false_alarm_rate`` and ``localisation_error_m``
        are the detector's; each layout's ``detection_limit`` is the
        physical limit it is measured against (:func:`detection_limit`).
    progress : callable, optional
        Called with (done, total) scenarios as they finish (on a pool or a cluster, a chunk at a time).
    """
    plan = plan_verification(case, layouts, n_locations=n_locations, severity=severity, length=length,
                             n_controls=n_controls, n_crossings=n_crossings, seed=seed, kind=kind,
                             noise_std=noise_std, false_alarm=false_alarm, nuisance=nuisance)
    with nullcontext(executor) if executor is not None else executor_for(workers, scheduler) as runner:
        records = run_plans(runner, [plan], progress=progress)[0]
    return plan.result(records, names)


@dataclass(frozen=True, eq=False)
class VerificationPlan:
    """The work of one verification: pilot inversions, then one task per (layout, scenario).

    Every task carries its own seed (a child of ``SeedSequence(seed)`` per
    scenario, shared by the layouts), so :meth:`result` does not depend on
    where or in which order the tasks ran.
    """

    case: object
    layouts: tuple  # SensorLayout per layout (positions, kinds, noise std)
    _: KW_ONLY
    scenarios: tuple
    seeds: tuple
    n_crossings: int
    false_alarm: float
    nuisance: str
    seed: int
    severity: float
    length: float

    def pilots(self):
        """One pilot task per layout (the first scenario): its posterior warm-starts that layout's tasks."""
        return [self._task(layout, self.scenarios[0], self.seeds[0]) for layout in self.layouts]

    def tasks(self, starts):
        """The (layout, scenario) tasks, layout by layout; ``starts`` are the pilots' results."""
        return [self._task(layout, scenario, s, start)
                for layout, start in zip(self.layouts, starts) for scenario, s in zip(self.scenarios, self.seeds)]

    def pilot(self, k):
        """The pilot task of layout ``k``."""
        return self._task(self.layouts[k], self.scenarios[0], self.seeds[0])

    def layout_tasks(self, k, start, indices):
        """The tasks of layout ``k`` on the scenarios ``indices``, warm-started at its pilot's ``start``."""
        return [self._task(self.layouts[k], self.scenarios[i], self.seeds[i], start) for i in indices]

    @single_threaded  # one BLAS limit for the call, not one per inversion (on a worker)
    def run_pilot(self, k):
        """(noise scale, tau) of layout ``k``'s pilot inversion."""
        return run_pilot(self.pilot(k))

    @single_threaded
    def run_scenarios(self, k, start, indices):
        """The records of layout ``k`` on the scenarios ``indices``, warm-started at ``start``."""
        return [run_scenario(t) for t in self.layout_tasks(k, start, indices)]

    def _task(self, layout, scenario, seed, start=(1.0, None)):
        return _Task(case=self.case, layout=layout, scenario=scenario, seed=seed, n_crossings=self.n_crossings,
                     false_alarm=self.false_alarm, nuisance=self.nuisance, start=start)

    def result(self, records, names=None):
        """The VerificationResult of the tasks' records (in the order of :meth:`tasks`)."""
        n = len(self.scenarios)
        scores = tuple(LayoutScore.from_records(
            layout.positions, records[k * n:(k + 1) * n],
            detection_limit=detection_limit(self.case, layout, self.scenarios, n_crossings=self.n_crossings,
                                            false_alarm=self.false_alarm, nuisance=self.nuisance),
            layout_kind=layout.kinds) for k, layout in enumerate(self.layouts))
        return VerificationResult(scores, self.scenarios, n_crossings=self.n_crossings, seed=self.seed,
                                  severity=self.severity, length=self.length, names=tuple(names) if names else (),
                                  false_alarm=self.false_alarm, nuisance=self.nuisance)


def plan_verification(case, layouts, *, n_locations=8, severity=0.25, length=2.0, n_controls=None, n_crossings=10,
                      seed=0, kind="rotation", noise_std=None, false_alarm=0.05, nuisance="smooth"):
    """Check the inputs of :func:`verify_layouts` and lay out its work (nothing is computed yet)."""
    if case.noise is None:
        raise ConfigError("Verification needs a noise model: set noise_std in [sensors].")
    layout_list = tuple(_as_sensors(case, layout, kind, noise_std) for layout in layouts)
    if not layout_list:
        raise ConfigError("Give at least one layout to verify.")
    for layout in layout_list:
        case.bridge.check_on_bridge(layout.positions, "layout", "verify")
    scenarios = make_scenarios(case, n_locations, severity=severity, length=length, n_controls=n_controls)
    seeds = np.random.SeedSequence(seed).spawn(len(scenarios))
    return VerificationPlan(case, layout_list, scenarios=tuple(scenarios), seeds=tuple(seeds),
                            n_crossings=int(n_crossings), false_alarm=float(false_alarm), nuisance=nuisance,
                            seed=int(seed), severity=float(severity), length=float(length))


def run_pilot(task):
    """(noise scale, tau) of a pilot inversion: the warm start of a layout's scenarios."""
    post = _run_task(task, posterior=True)
    return (post.noise_scale, post.tau)


def run_scenario(task):
    """The scored record of one (layout, scenario) task."""
    return _run_task(task)
