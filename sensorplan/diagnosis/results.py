"""Result types of the gap diagnosis: the gap, each effect's fit, findings, the corrected model, the diagnosis.

Every result is a frozen dataclass; ``to_dict()`` gives its JSON form
(the CLI's ``--json``).

Owns: the diagnosis's results and their JSON form.  May import: the foundations.
"""

from dataclasses import KW_ONLY, asdict, dataclass, field

import numpy as np

from ..verdict import Verdict

__all__ = ["Binning", "Confounding", "CorrectedModel", "EffectFit", "Finding", "Gap", "GapDiagnosis", "ResidualMap",
           "SensorGap", "SensorShrinkage"]


@dataclass(frozen=True)
class Finding:
    """An effect in engineering terms: where, the value and its 95 % interval in ``unit``, and the sentence.

    ``case_value``, ``differs``: for the case's own springs, the configured
    value and whether the interval excludes it (None otherwise).
    """

    where: str
    value: float
    low: float
    high: float
    unit: str
    text: str
    case_value: float | None = None
    differs: bool | None = None

    def to_dict(self):
        out = {"where": self.where, "value": self.value, "low": self.low, "high": self.high, "unit": self.unit,
               "text": self.text}
        if self.case_value is not None:
            out["case_value"] = self.case_value
            out["differs"] = self.differs
        return out


@dataclass(frozen=True)
class SensorGap:
    """One sensor's residual split into noise and systematic parts (in the sensor's unit), with tests."""

    rms_residual: float
    _: KW_ONLY
    systematic_rms: float
    noise_rms: float
    p_systematic: float
    p_ljung_box: float

    def to_dict(self):
        return asdict(self)


@dataclass(frozen=True)
class Gap:
    """The gap between a model and the data.

    Attributes
    ----------
    rms_residual, systematic_rms, noise_rms : float
        Over all sensors (mixed units when sensors of both kinds are present).
    by_sensor : dict
        Sensor name -> SensorGap.
    worst_positions_m : tuple of float
        Load positions [m] where the gap concentrates.
    p_value : float
        Bonferroni p-value of the systematic and structure tests.
    significant : bool
    testable : bool
        Whether any test could be run (False: a single crossing too short
        for the structure test; the gap then says nothing).
    """

    rms_residual: float
    _: KW_ONLY
    systematic_rms: float
    noise_rms: float
    by_sensor: dict
    worst_positions_m: tuple
    p_value: float
    significant: bool
    testable: bool = True

    def to_dict(self):
        return {"rms_residual": self.rms_residual, "systematic_rms": self.systematic_rms,
                "noise_rms": self.noise_rms, "by_sensor": {k: v.to_dict() for k, v in self.by_sensor.items()},
                "worst_positions_m": list(self.worst_positions_m), "p_value": self.p_value,
                "significant": self.significant, "testable": self.testable}


@dataclass(frozen=True)
class EffectFit:
    """One candidate effect refitted jointly with log EI.

    Attributes
    ----------
    name : str
    log_bayes_factor : float
        Laplace log evidence against the base model.
    heldout_score_gain : float or None
        Held-out log predictive density gain (None without folds).
    rms_after, heldout_rms_after : float
        Residual rms after the refit, in fit and held out.
    parameters : dict
        Parameter name -> {"map", "std"} (the effect's own parameterisation).
    ei_shift : tuple of float
        Relative change of EI per element caused by adding the effect.
    max_ei_shift : float
    converged : bool
        False: the refit did not converge; the entry never decides a verdict.
    abandoned : bool
        The refit was stopped before converging because it could not come
        near the best candidate's evidence (its Bayes factor is what it had
        reached; not converged).
    findings : tuple of Finding
        The effect in engineering terms (where, value, 95 % interval, unit).
    """

    name: str
    _: KW_ONLY
    log_bayes_factor: float
    heldout_score_gain: float | None
    rms_after: float
    heldout_rms_after: float | None
    parameters: dict
    ei_shift: tuple
    max_ei_shift: float
    converged: bool = True
    findings: tuple = ()
    abandoned: bool = False

    def to_dict(self):
        out = asdict(self)
        out["ei_shift"] = list(self.ei_shift)
        out["findings"] = [f.to_dict() for f in self.findings]
        return out


@dataclass(frozen=True)
class Confounding:
    """An effect an EI change can mimic, and the sensor position that would separate them."""

    name: str
    information_kept: float
    separating_sensor_m: float | None

    def to_dict(self):
        return asdict(self)


@dataclass(frozen=True, eq=False)
class ResidualMap:
    """The mean residual over the crossings per sensor, in noise standard deviations, on a grid of load positions.

    ``grid_m`` (G,) [m]; ``normalised_mean_residual`` (S, G).
    """

    grid_m: np.ndarray
    normalised_mean_residual: np.ndarray


@dataclass(frozen=True)
class SensorShrinkage:
    """One sensor's residual rms before and after the selected effects, in fit and held out [rad or m]."""

    kind: str
    rms_before: float
    rms_after: float
    heldout_rms_before: float | None
    heldout_rms_after: float | None

    def to_dict(self):
        return asdict(self)


@dataclass(frozen=True)
class Binning:
    """How a dense record was fitted: bins of ``size`` readings (``width_m`` [m]), ``rows`` readings in ``bins``
    bins, each keeping at least ``keep`` of the information on EI."""

    size: int
    width_m: float
    rows: int
    bins: int
    keep: float

    def to_dict(self):
        return asdict(self)


@dataclass(frozen=True)
class CorrectedModel:
    """The model state of the selected model's final MAP (SI): what a corrected case holds, and what it cannot.

    ``not_in_case``: the selected effects that are properties of the data
    (offsets, drift, gains, amplification, load positions or levels).
    """

    rotational_springs: tuple
    vertical_springs: tuple
    sensor_positions: tuple
    axle_loads: tuple
    not_in_case: tuple

    def to_dict(self):
        return {"rotational_springs": list(self.rotational_springs), "vertical_springs": list(self.vertical_springs),
                "sensor_positions": list(self.sensor_positions), "axle_loads": list(self.axle_loads),
                "not_in_case": list(self.not_in_case)}


@dataclass(frozen=True, eq=False)
class GapDiagnosis:
    """Result of :func:`~sensorplan.diagnosis.diagnose.diagnose` (JSON keys as in the CLI).

    ``verdict``: the one :class:`~sensorplan.verdict.Verdict` (status,
    summary, where, how much, evidence, next step;
    :mod:`~sensorplan.diagnosis.conclusion`); ``statement``: the one-line
    statement of the causes (causes found, unexplained, adequate);
    ``effects``: one :class:`EffectFit` per candidate, best log Bayes factor
    first; ``causes``: the selected effects in order of selection, named
    only when the model with them leaves no significant gap (else they are
    ``partial``: they reduce the gap but leave it significant, and
    ``partial_gap`` and ``partial_shrinkage`` say by how much); per
    cause its ``findings`` (of the final refit), ``alternatives`` (effects
    explaining the gap about as well) and ``includes`` (candidates it holds
    as a special case); ``not_offered``: effect -> why it cannot act on
    these data; ``shrinkage``: sensor -> :class:`SensorShrinkage`;
    ``springs``: findings of the case's elastic springs (estimated as
    invert does); ``binning``: how a dense record was fitted (None: row by
    row); ``heldout_ratio_before``/``after``: held-out rms / configured
    noise; ``corrected_model``: None when not formed.
    """

    gap: Gap
    _: KW_ONLY
    effects: tuple
    causes: tuple
    unexplained: bool
    confounded: tuple
    statement: str
    verdict: Verdict
    gap_after: Gap
    ei_edges: np.ndarray
    ei_base: np.ndarray
    ei_final: np.ndarray
    residual_map: ResidualMap | None = None
    ei_base_band: tuple = ()  # (low, high) 95 % per element [N m^2]
    ei_final_band: tuple = ()  # of the selected model refitted with its hyperparameters
    findings: dict = field(default_factory=dict)
    alternatives: dict = field(default_factory=dict)
    not_offered: dict = field(default_factory=dict)
    shrinkage: dict = field(default_factory=dict)
    springs: tuple = ()
    springs_estimated: bool = False
    noise_scale: float = float("nan")
    converged: bool = True
    heldout_ratio_before: float | None = None
    heldout_ratio_after: float | None = None
    corrected_model: CorrectedModel | None = None
    binning: Binning | None = None
    includes: dict = field(default_factory=dict)
    partial: tuple = ()
    partial_gap: Gap | None = None
    partial_shrinkage: dict = field(default_factory=dict)

    def summary(self):
        from .summary import summary_lines

        return "\n".join(summary_lines(self))

    def to_dict(self):
        return {
            "gap": self.gap.to_dict(),
            "effects": [e.to_dict() for e in self.effects],
            "causes": list(self.causes),
            "unexplained": bool(self.unexplained),
            "confounded": [c.to_dict() for c in self.confounded],
            "verdict": self.verdict.to_dict(),
            "statement": self.statement,
            "partial": list(self.partial),
            "partial_gap": None if self.partial_gap is None else self.partial_gap.to_dict(),
            "partial_shrinkage": {k: v.to_dict() for k, v in self.partial_shrinkage.items()},
            "gap_after": self.gap_after.to_dict(),
            "ei_edges_m": self.ei_edges.tolist(),
            "ei_base": self.ei_base.tolist(),
            "ei_final": self.ei_final.tolist(),
            "ei_base_band": [np.asarray(b).tolist() for b in self.ei_base_band],
            "ei_final_band": [np.asarray(b).tolist() for b in self.ei_final_band],
            "findings": {k: [f.to_dict() for f in v] for k, v in self.findings.items()},
            "alternatives": {k: list(v) for k, v in self.alternatives.items()},
            "not_offered": dict(self.not_offered),
            "shrinkage": {k: v.to_dict() for k, v in self.shrinkage.items()},
            "springs_estimated": self.springs_estimated,
            "springs": [f.to_dict() for f in self.springs],
            "noise_scale": self.noise_scale,
            "converged": self.converged,
            "heldout_ratio_before": self.heldout_ratio_before,
            "heldout_ratio_after": self.heldout_ratio_after,
            "corrected_model": {} if self.corrected_model is None else self.corrected_model.to_dict(),
            "binning": {} if self.binning is None else self.binning.to_dict(),
            "includes": {k: list(v) for k, v in self.includes.items()},
        }
