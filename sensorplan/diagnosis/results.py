"""Result types of the gap diagnosis: Gap, SensorGap, EffectFit, Confounding, GapDiagnosis.

Owns: the diagnosis's results and their JSON form.  May import: the foundations.
"""

from dataclasses import asdict, dataclass, field

import numpy as np

__all__ = ["Confounding", "EffectFit", "Gap", "GapDiagnosis", "SensorGap"]


@dataclass(frozen=True)
class SensorGap:
    """One sensor's residual split into noise and systematic parts (in the sensor's unit), with tests."""

    rms_residual: float
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
    """

    rms_residual: float
    systematic_rms: float
    noise_rms: float
    by_sensor: dict
    worst_positions_m: tuple
    p_value: float
    significant: bool

    def to_dict(self):
        return {"rms_residual": self.rms_residual, "systematic_rms": self.systematic_rms,
                "noise_rms": self.noise_rms, "by_sensor": {k: v.to_dict() for k, v in self.by_sensor.items()},
                "worst_positions_m": list(self.worst_positions_m), "p_value": self.p_value,
                "significant": self.significant}


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
    findings : tuple of dict
        The effect in engineering terms (where, value, 95 % interval, unit).
    """

    name: str
    log_bayes_factor: float
    heldout_score_gain: float | None
    rms_after: float
    heldout_rms_after: float | None
    parameters: dict
    ei_shift: tuple
    max_ei_shift: float
    converged: bool = True
    findings: tuple = ()  # dicts: where, value, low, high (95 %), unit, text
    abandoned: bool = False

    def to_dict(self):
        out = asdict(self)
        out["ei_shift"] = list(self.ei_shift)
        out["findings"] = [dict(f) for f in self.findings]
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
class GapDiagnosis:
    """Result of :func:`diagnose` (JSON keys as in the CLI)."""

    gap: "Gap"
    effects: tuple  # EffectFit, best log Bayes factor first
    causes: tuple
    unexplained: bool
    confounded: tuple  # Confounding
    verdict: str
    gap_after: "Gap"
    ei_edges: np.ndarray
    ei_base: np.ndarray
    ei_final: np.ndarray
    residual_map: dict = field(default_factory=dict)
    ei_base_band: tuple = ()  # (low, high) 95 % per element [N m^2]
    ei_final_band: tuple = ()  # of the selected model refitted with its hyperparameters
    findings: dict = field(default_factory=dict)  # selected effect -> findings of the final refit
    alternatives: dict = field(default_factory=dict)  # selected effect -> effects explaining the gap about as well
    not_offered: dict = field(default_factory=dict)  # effect -> why it cannot act on these data
    shrinkage: dict = field(default_factory=dict)  # sensor -> kind and residual rms before/after [rad or m]
    springs: tuple = ()  # findings of the case's elastic springs (estimated as invert does)
    springs_estimated: bool = False
    noise_scale: float = float("nan")
    converged: bool = True
    heldout_ratio_before: float | None = None  # held-out rms / configured noise
    heldout_ratio_after: float | None = None
    corrected_model: dict = field(default_factory=dict)  # final MAP state (SI), for a corrected case
    binning: dict = field(default_factory=dict)  # dense records: size, width_m, rows, bins of the fitted bin means
    includes: dict = field(default_factory=dict)  # cause -> candidate effects it holds as a special case

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
            "verdict": self.verdict,
            "gap_after": self.gap_after.to_dict(),
            "ei_edges_m": self.ei_edges.tolist(),
            "ei_base": self.ei_base.tolist(),
            "ei_final": self.ei_final.tolist(),
            "ei_base_band": [np.asarray(b).tolist() for b in self.ei_base_band],
            "ei_final_band": [np.asarray(b).tolist() for b in self.ei_final_band],
            "findings": {k: [dict(f) for f in v] for k, v in self.findings.items()},
            "alternatives": {k: list(v) for k, v in self.alternatives.items()},
            "not_offered": dict(self.not_offered),
            "shrinkage": {k: dict(v) for k, v in self.shrinkage.items()},
            "springs_estimated": self.springs_estimated,
            "springs": [dict(f) for f in self.springs],
            "noise_scale": self.noise_scale,
            "converged": self.converged,
            "heldout_ratio_before": self.heldout_ratio_before,
            "heldout_ratio_after": self.heldout_ratio_after,
            "corrected_model": dict(self.corrected_model),
            "binning": dict(self.binning),
            "includes": {k: list(v) for k, v in self.includes.items()},
        }


