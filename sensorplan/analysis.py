"""Everything the report shows, computed as result objects (no rendering here).

Owns: :func:`analyse` and :class:`Analysis`.  May import: model, inference,
design, verification, diagnosis (never plotting, report or cli).
"""

from collections.abc import Callable
from dataclasses import KW_ONLY, dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .model.case import Case
    from .model.crossings import Crossings

__all__ = ["Analysis", "analyse"]


@dataclass(frozen=True, eq=False)
class Analysis:
    """The results of one study of a case.

    Attributes
    ----------
    case : Case
    candidates : FisherBlocks
        Informativeness (EI parameters) of 9 evenly spaced candidate tiltmeters.
    design : DesignResult
    verification : VerificationResult
        The recommended layout and the feasible baselines, on the same scenarios.
    detectability : DetectabilityMap or None
        What the recommended layout detects along the bridge.
    exclude : tuple of (float, float)
        Exclusion zones of the design [m].
    posterior : PosteriorResult or None
        EI identified from ``data`` (when given).
    diagnosis : GapDiagnosis or None
        Sim-to-real gap of ``data`` (when given).
    target : TargetDesign or None
        The requirement (worst-case detection power ``target_power`` for the
        detectability defaults) and the fewest sensors placed for detection
        that meet it (:func:`sensorplan.design.target.design_for_target`).
    recommended_power : float or None
        Worst-case power of the recommended layout for the same requirement.
    crossings_needed : int or None
        Crossings with which the recommended layout would meet the requirement.
    verdict : Verdict or None
        The one verdict on ``data`` (the inversion's, overruled by a model
        error the gap diagnosis finds).
    """

    case: object
    candidates: object
    design: object
    verification: object
    _: KW_ONLY
    posterior: object = None
    diagnosis: object = None
    detectability: object = None
    exclude: tuple = ()
    target: object = None
    recommended_power: float | None = None
    crossings_needed: int | None = None
    verdict: object = None

    @property
    def verified_names(self):
        return ("recommended",) + tuple(b.name for b in self.design.baselines if b.feasible)


def analyse(case: "Case", *, data: "Crossings | None" = None, count: int | None = None, criterion: str = "D",
            spacing: float | None = None, n_scenarios: int = 6, n_crossings: int = 10, seed: int = 0,
            progress: "Callable[[str], None] | None" = None, design_options: dict | None = None,
            detect: bool = True, progress_units: "Callable[[int, int], None] | None" = None,
            target_power: float = 0.9, requirement: dict | None = None) -> Analysis:
    """Run the analyses of a report: informativeness, layout, verification, identification, gap.

    Parameters
    ----------
    case : Case
    data : Crossings, optional
        Measured crossings: adds the identified EI and the gap diagnosis.
    count : int, optional
        Sensors to place (default: as many as the case has).
    criterion, spacing : str, float
        Design criterion; candidate spacing [m] (default: about length / 60).
    n_scenarios, n_crossings, seed : verification settings.
    progress : callable, optional
        Called with a short message when each stage starts.
    design_options : dict, optional
        Keyword arguments of :func:`sensorplan.design.recommend.recommend`
        (``grid``, ``constraints``, ``kind``, ``noise_std``, ...); a ``grid``
        here overrides ``spacing``.
    detect : bool
        Add the detectability map of the recommended layout and the
        requirement's answer (``target``).
    progress_units : callable, optional
        Called with (done, total) after each repeated unit of a stage (the
        verification's scenario inversions).
    target_power : float
        The requirement: worst-case power of detecting the detectability
        defaults' loss (25 % over 2 m at a false-alarm rate of 5 %).
    requirement : dict, optional
        Other keyword arguments of :func:`sensorplan.design.target.design_for_target`
        (``target``: the loss, nuisance and false-alarm rate; ``region``).

    Returns
    -------
    Analysis
    """
    from .design.recommend import CandidateGrid, recommend

    say = progress if progress is not None else (lambda text: None)
    count = case.sensors.n_sensors if count is None else int(count)
    spacing = spacing if spacing is not None else max(0.25, round(case.bridge.length / 60.0 * 4) / 4)
    candidates = _candidate_informativeness(case)
    options = {"grid": CandidateGrid(spacing=spacing), "rng": seed, **(design_options or {})}
    say(f"recommending a {criterion}-optimal layout of {count} sensor(s)")
    design = recommend(case, count, criterion, **options)
    say(f"verifying the recommended layout and {sum(b.feasible for b in design.baselines)} baseline(s) by "
        f"inversion of synthetic damage ({n_scenarios} locations, {n_crossings} crossings each)")
    verification = _verify_design(case, design, n_scenarios=n_scenarios, n_crossings=n_crossings, seed=seed,
                                  progress=progress_units)
    requirement_of = {}
    if detect:
        requirement_of = _requirement(case, design, options, count=count, n_crossings=n_crossings,
                                      power=target_power, say=say, extra=requirement or {})
    measured = {} if data is None else _measured(case, data, say)
    return Analysis(case, candidates, design, verification, exclude=tuple(getattr(options["grid"], "exclude", ())),
                    **measured, **requirement_of)


def _requirement(case, design, options, *, count, n_crossings, power, say, extra):
    """The recommended layout's detectability, the fewest sensors meeting ``power`` and the crossings needed."""
    from .design.detect_problem import centres_inside
    from .design.target import DEFAULT_MAX_COUNT, design_for_target

    say("mapping what the layout detects along the bridge")
    loss = extra.get("target")
    detect_map = _installed_detectability(case, design, n_crossings=n_crossings, target=loss)
    say(f"finding the fewest sensors that reach a worst-case detection power of {power:g}")
    keep = {k: options[k] for k in ("grid", "constraints", "kind", "noise_std") if k in options}
    target = design_for_target(case, power=power, max_count=max(count, DEFAULT_MAX_COUNT), n_crossings=n_crossings,
                               progress=say, **keep, **extra)
    inside = centres_inside(detect_map.centres_m, extra.get("region"))
    worst = float(np.min(detect_map.power[inside]))
    needed = None if worst >= power else _crossings_for(case, design, detect_map, power, n_crossings, loss,
                                                                 extra.get("region"))
    return {"detectability": detect_map, "target": target, "recommended_power": worst, "crossings_needed": needed}


def _crossings_for(case, design, detect_map, power, n_crossings, loss, region):
    """Fewest crossings with which the recommended layout reaches worst-case ``power`` (d grows as sqrt(n))."""
    from scipy.special import ndtri

    from .design.detect_problem import centres_inside
    from .design.target import crossings_to_reach

    def worst(dmap, values):
        return float(np.min(values[centres_inside(dmap.centres_m, region)]))

    def worst_power(n):
        dmap = _installed_detectability(case, design, n_crossings=n, target=loss)
        return worst(dmap, dmap.power)

    need = -float(ndtri(detect_map.false_alarm_rate)) + float(ndtri(power))
    return crossings_to_reach(worst_power, power=power, n_crossings=n_crossings,
                              d_min=worst(detect_map, detect_map.d), d_needed=need)


def _measured(case, data, say):
    """The EI identified from measured ``data``, the diagnosis of their gap to the model, and the one verdict."""
    from .diagnosis.diagnose import diagnose
    from .inference.inversion import invert
    from .verdict import combined_verdict

    say(f"identifying EI from the {len(data)} measured crossing(s)")
    posterior = invert(case, data)
    say("diagnosing the gap between the model and the data")
    diagnosis = diagnose(case, data)
    verdict = combined_verdict(posterior.verdict, getattr(diagnosis, "verdict", None))
    return {"posterior": posterior, "diagnosis": diagnosis, "verdict": verdict}


def _candidate_informativeness(case):
    """Fisher blocks (EI parameters) of 9 evenly spaced candidate sensors of the case's default kind."""
    from .model.fisher import fisher_blocks
    from .model.sensors import SensorLayout

    positions = np.linspace(0.0, case.bridge.length, 9)
    return fisher_blocks(case, sensors=SensorLayout.candidates(
        positions, case.default_kind, noise_std=[case.noise_std_for(case.default_kind)] * positions.size),
        parameterisation="ei")


def _verify_design(case, design, *, n_scenarios, n_crossings, seed, progress=None):
    """The recommended layout and the feasible baselines verified on the same scenarios."""
    from .design.candidates import sensor_layout
    from .verification.verify import verify_layouts

    def layout_of(xs, kinds):  # new sensors with the design's noise std of their kind
        kinds = tuple(kinds) or (design.kind,) * len(xs)
        return sensor_layout(xs, kinds, [design.noise_std[k] for k in kinds])

    feasible = [b for b in design.baselines if b.feasible]
    return verify_layouts(case, [layout_of(design.layout_m, design.layout_kind)]
                          + [layout_of(b.layout_m, b.layout_kind) for b in feasible],
                          names=["recommended"] + [b.name for b in feasible], n_locations=n_scenarios,
                          n_crossings=n_crossings, seed=seed, progress=progress)


def _installed_detectability(case, design, *, n_crossings, target=None):
    """The detectability map of the new and existing sensors, each with its own kind and noise."""
    from .design.candidates import sensor_layout
    from .detection.detectability import detectability
    installed = sensor_layout(tuple(design.layout_m) + tuple(design.fixed_m),
                              tuple(design.layout_kind) + tuple(design.fixed_kind),
                              [design.noise_std[k] for k in design.layout_kind] + list(design.fixed_noise_std))
    loss = {} if target is None else {"severity": target.severity, "length": target.length,
                                      "false_alarm": target.false_alarm, "nuisance": target.nuisance,
                                      "step": target.step}
    return detectability(case.with_sensors(installed), n_crossings=n_crossings, **loss)
