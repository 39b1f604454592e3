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

    @property
    def verified_names(self):
        return ("recommended",) + tuple(b.name for b in self.design.baselines if b.feasible)


def analyse(case: "Case", *, data: "Crossings | None" = None, count: int | None = None, criterion: str = "D",
            spacing: float | None = None, n_scenarios: int = 6, n_crossings: int = 10, seed: int = 0,
            progress: "Callable[[str], None] | None" = None, design_options: dict | None = None,
            detect: bool = True, progress_units: "Callable[[int, int], None] | None" = None) -> Analysis:
    """Run the analyses of a report: informativeness, layout, verification, identification, gap.

    Parameters
    ----------
    case : Case
    data : Crossings, optional
        Measured crossings: adds the identified EI and the gap diagnosis.
    count : int, optional
        Sensors to place (default: as many as the case has).
    criterion : str
        Design criterion.
    spacing : float, optional
        Candidate spacing [m] (default: about length / 60).
    n_scenarios, n_crossings, seed : verification settings.
    progress : callable, optional
        Called with a short message when each stage starts.
    design_options : dict, optional
        Keyword arguments of :func:`sensorplan.design.recommend.recommend`
        (``grid``, ``constraints``, ``kind``, ``noise_std``, ...); a ``grid``
        here overrides ``spacing``.
    detect : bool
        Add the detectability map of the recommended layout.
    progress_units : callable, optional
        Called with (done, total) after each repeated unit of a stage (the
        verification's scenario inversions).

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
    detect_map = None
    if detect:
        say("mapping what the layout detects along the bridge")
        detect_map = _installed_detectability(case, design, n_crossings=n_crossings)
    posterior, diagnosis = _measured(case, data, say) if data is not None else (None, None)
    return Analysis(case, candidates, design, verification, posterior=posterior, diagnosis=diagnosis,
                    detectability=detect_map, exclude=tuple(getattr(options["grid"], "exclude", ())))


def _measured(case, data, say):
    """The EI identified from measured ``data`` and the diagnosis of their gap to the model."""
    from .diagnosis.diagnose import diagnose
    from .inference.inversion import invert

    say(f"identifying EI from the {len(data)} measured crossing(s)")
    posterior = invert(case, data)
    say("diagnosing the gap between the model and the data")
    return posterior, diagnose(case, data)


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


def _installed_detectability(case, design, *, n_crossings):
    """The detectability map of the new and existing sensors, each with its own kind and noise."""
    from .design.candidates import sensor_layout
    from .detection.detectability import detectability
    from .model.noise import NoiseModel

    installed = sensor_layout(tuple(design.layout_m) + tuple(design.fixed_m),
                              tuple(design.layout_kind) + tuple(design.fixed_kind),
                              [design.noise_std[k] for k in design.layout_kind] + list(design.fixed_noise_std))
    noise = NoiseModel(np.asarray(installed.noise_std), case.noise.correlation_length if case.noise else 0.0)
    return detectability(case.with_sensors(installed, noise), n_crossings=n_crossings)
