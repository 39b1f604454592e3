"""Result types of the gap diagnosis: Gap, SensorGap, EffectFit, Confounding, GapDiagnosis.

Owns: the diagnosis's results and their JSON form.  May import: the foundations.
"""

from dataclasses import asdict, dataclass, field

import numpy as np

__all__ = ["SensorGap", "Gap", "EffectFit", "Confounding", "GapDiagnosis"]


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
    """

    name: str
    log_bayes_factor: float
    heldout_score_gain: float | None
    rms_after: float
    heldout_rms_after: float | None
    parameters: dict
    ei_shift: tuple
    max_ei_shift: float

    def to_dict(self):
        out = asdict(self)
        out["ei_shift"] = list(self.ei_shift)
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

    def summary(self):
        g = self.gap
        lines = [f"Sim-to-real gap: residual rms {g.rms_residual:.3g}, systematic {g.systematic_rms:.3g}, "
                 f"noise {g.noise_rms:.3g} (p = {g.p_value:.2g}; "
                 f"{'significant' if g.significant else 'not significant'})"]
        if g.worst_positions_m:
            lines.append("  gap concentrates at load positions [m]: "
                         + ", ".join(f"{x:.2f}" for x in g.worst_positions_m))
        lines.append(f"  {'effect':28s} {'log BF':>9s} {'held-out gain':>14s} {'rms after':>11s} "
                     f"{'held-out rms':>13s} {'max EI shift':>13s}")
        for e in self.effects:
            gain = "n/a" if e.heldout_score_gain is None else f"{e.heldout_score_gain:.2f}"
            hrms = "n/a" if e.heldout_rms_after is None else f"{e.heldout_rms_after:.3g}"
            lines.append(f"  {e.name:28s} {e.log_bayes_factor:9.2f} {gain:>14s} {e.rms_after:11.3g} "
                         f"{hrms:>13s} {100 * e.max_ei_shift:12.1f}%")
        for c in self.confounded:
            where = "" if c.separating_sensor_m is None else (
                f"; a sensor at {c.separating_sensor_m:.2f} m would separate them")
            lines.append(f"  confounded: {c.name} can be mimicked by an EI change "
                         f"({100 * c.information_kept:.0f} % of its information survives){where}")
        lines.append(f"  verdict: {self.verdict}")
        return "\n".join(lines)

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
        }


