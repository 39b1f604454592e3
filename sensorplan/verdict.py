"""One verdict on measured data, written once and read by every output.

A :class:`Verdict` is what a bridge owner reads first: one status, one
sentence, where and how much.  ``invert``, ``diagnose``, ``verify`` and
``report`` all show the same object (JSON key ``verdict``); headlines,
figure titles and the report's conclusion are written from it, so they
cannot contradict it or the numbers printed beside it.

Statuses, in order of precedence (the first that applies is the verdict):

``model_error``
    A significant systematic misfit that a change of EI does not explain
    (the residuals of the fit with EI free fail their test, or the noise is
    far from its configured level): a wrong sensor sign, position or unit, a
    settled or lifted support, an unmodelled effect.  It takes precedence
    over any damage headline, because a detector that assumes the model is
    right cannot be read when the model is wrong; it names the next step.
``local_damage``
    The damage detector fires at its calibrated false-alarm rate and the
    posterior favours a loss (its probability at least one half): where,
    how much, at which rate.  Requiring both keeps the headline from
    contradicting the posterior printed beside it; the rate of false
    headlines is then at most the detector's rate.
``departure``
    EI lies outside its nominal value somewhere, judged by a simultaneous
    credible band (Bonferroni over the elements, so that an undamaged
    bridge shows no departure at the stated level anywhere), without a
    localised loss the detector finds: where and by how much.
``insufficient_data``
    The data cannot test for a change (the detector had no testable zone:
    every local-loss signature lies in the span of the nuisance, or no
    residual degree of freedom is left).
``no_change``
    None of the above.

Owns: Verdict, the verdict rules.  May import: numpy, scipy (foundations).
"""

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import special

__all__ = ["Verdict", "STATUSES", "band_departures", "combined_verdict", "inversion_verdict"]

STATUSES = ("no_change", "departure", "local_damage", "model_error", "insufficient_data")
MIN_LOSS_PROBABILITY = 0.5  # posterior probability of a loss a damage headline needs
BAND_LEVEL = 0.95  # simultaneous level of the band a departure is judged by
NOISE_SCALE_LIMIT = 2.0  # estimated / configured noise above which the misfit is systematic


@dataclass(frozen=True)
class Verdict:
    """The one conclusion drawn from measured data.

    Attributes
    ----------
    status : str
        One of :data:`STATUSES`.
    summary : str
        One sentence an owner can sign.
    location_m : (float, float) or None
        Where [m]: the detected zone, or the stretch outside the band.
    loss : float or None
        Fraction of EI lost (negative: stiffer than nominal).
    evidence : mapping
        The numbers the verdict rests on (test statistics, levels, p-values).
    next_step : str or None
        What to do next (model errors, insufficient data).
    """

    status: str
    summary: str
    location_m: tuple | None = None
    loss: float | None = None
    evidence: Mapping = field(default_factory=dict)
    next_step: str | None = None

    def __post_init__(self):
        if self.status not in STATUSES:
            raise ValueError(f"The 'status' parameter of Verdict must be one of {', '.join(STATUSES)}. "
                             f"Got {self.status!r} instead.")

    @property
    def headline(self) -> str:
        """A short title for figures: the status in words with where and how much."""
        words = {"no_change": "no change detected", "departure": "EI departs from nominal",
                 "local_damage": "local loss detected", "model_error": "model error: the fit is not to be trusted",
                 "insufficient_data": "insufficient data"}[self.status]
        if self.location_m is not None and self.status in ("departure", "local_damage"):
            a, b = self.location_m
            words += f" at {a:.1f}-{b:.1f} m"
            if self.loss is not None:
                words += f" ({_percent(self.loss)})"
        return words

    def to_dict(self) -> dict:
        return {"status": self.status, "summary": self.summary,
                "location_m": None if self.location_m is None else [float(v) for v in self.location_m],
                "loss": None if self.loss is None else float(self.loss),
                "evidence": _plain(self.evidence), "next_step": self.next_step}


def _plain(value: Any) -> Any:
    """``value`` with numpy scalars and arrays turned into JSON types."""
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def _percent(loss: float) -> str:
    return f"{100 * loss:.0f} % loss" if loss >= 0 else f"{-100 * loss:.0f} % stiffer"


def band_departures(edges: np.ndarray, log_mean: np.ndarray, log_std: np.ndarray, log_nominal: np.ndarray,
                    *, level: float = BAND_LEVEL, below: np.ndarray | None = None,
                    simultaneous: bool = True) -> list[dict]:
    """Stretches where the nominal log EI lies outside the simultaneous ``level`` band.

    The band is Bonferroni over the elements (conservative: under the
    posterior the whole field lies inside it with probability at least
    ``level``): element i departs when its two-sided tail probability
    2 min(F_i, 1 - F_i) is below (1 - level) / n, with F_i the posterior
    probability that log EI_i lies below the nominal.  ``below`` gives F_i
    (e.g. from a skewed mixture posterior); by default it is the Gaussian
    Phi((nominal - mean) / std).  Returns one dict per contiguous stretch
    (one side of the nominal): ``start``, ``stop`` [m], ``loss`` (1 -
    EI/EI_nominal of the posterior mean at the element furthest out) and
    ``z`` (its two-sided tail as a signed normal quantile).  With
    ``simultaneous=False`` the band is the pointwise one the figures show.
    """
    edges, mean, std, nominal = (np.asarray(a, float) for a in (edges, log_mean, log_std, log_nominal))
    if below is None:
        below = special.ndtr((nominal - mean) / np.where(std > 0, std, np.inf))
    below = np.clip(np.asarray(below, float), 1e-300, 1.0)
    tail = 2.0 * np.minimum(below, 1.0 - below)
    z = np.where(below > 0.5, -1.0, 1.0) * -special.ndtri(np.maximum(tail, 1e-300) / 2.0)
    outside = tail < (1.0 - level) / (mean.size if simultaneous else 1)
    out = []
    j = 0
    while j < mean.size:
        if not outside[j]:
            j += 1
            continue
        k = j
        while k + 1 < mean.size and outside[k + 1] and np.sign(z[k + 1]) == np.sign(z[j]):
            k += 1
        worst = j + int(np.argmax(np.abs(z[j:k + 1])))
        out.append({"start": float(edges[j]), "stop": float(edges[k + 1]),
                    "loss": float(1.0 - np.exp(mean[worst] - nominal[worst])), "z": float(z[worst])})
        j = k + 1
    return out


def inversion_verdict(*, edges: np.ndarray, log_mean: np.ndarray, log_std: np.ndarray, log_nominal: np.ndarray,
                      residual_p: Sequence[float], residual_level: float, sensor_names: Sequence[str],
                      noise_scale: float, noise_configured: bool, detection: Any = None,
                      damage_probability: float | None = None, below: np.ndarray | None = None,
                      detector_run: bool = True, noise_limit: float = NOISE_SCALE_LIMIT) -> Verdict:
    """The verdict of an inversion of measured crossings.

    Parameters
    ----------
    edges, log_mean, log_std, log_nominal : ndarray
        Element edges [m] and the posterior mean and std of log EI with its
        nominal, per element.
    residual_p : sequence of float
        p-value per sensor of the systematic-residual test (nan: untested).
    residual_level : float
        Family-wise level of that test (Bonferroni over the sensors).
    noise_scale : float
        Estimated / configured noise.
    noise_configured : bool
        Whether the noise level was configured (else it was estimated and
        its scale says nothing).
    noise_limit : float
        Noise scale above which the misfit counts as systematic (the
        inversion passes the upper end of its own trust range).
    detection : DamageDetection or None
        The detector's outcome (None: it could not run).
    damage_probability : float or None
        Posterior probability of a local loss (reported as evidence).
    below : ndarray, optional
        Posterior probability that log EI lies below its nominal, per
        element (default: from the Gaussian of ``log_mean``, ``log_std``).
    detector_run : bool
        False when the detector was not asked for: no local-loss conclusion
        is drawn either way, and a missing detection is not a lack of data.
    """
    p = np.asarray(residual_p, float)
    flagged = [str(sensor_names[i]) for i in range(p.size) if np.isfinite(p[i]) and p[i] < residual_level / p.size]
    stretches = band_departures(edges, log_mean, log_std, log_nominal, below=below)
    pointwise = band_departures(edges, log_mean, log_std, log_nominal, below=below, simultaneous=False)
    evidence: dict = {
        "residual_test": {"level": residual_level, "flagged": flagged,
                          "min_p": float(np.nanmin(p)) if np.any(np.isfinite(p)) else None},
        "noise_scale": float(noise_scale),
        "band": {"level": BAND_LEVEL, "simultaneous": "Bonferroni over elements", "outside": stretches,
                 "outside_pointwise": pointwise},
        "detector": None if detection is None else detection.to_dict(),
        "damage_probability": damage_probability,
    }
    if flagged or (noise_configured and noise_scale > noise_limit):
        why = (f"systematic residuals at {', '.join(flagged)}" if flagged else
               f"the residuals are {noise_scale:.2g} times the configured noise")
        return Verdict("model_error", f"Model error: {why} that a change of EI does not explain; no damage "
                       f"conclusion can be drawn until it is resolved.", evidence=evidence,
                       next_step="check each flagged sensor's sign, position and unit and the supports, then run "
                                 "`sensorplan diagnose` to name the unmodelled effect")
    return _data_verdict(stretches, detection, damage_probability, evidence, detector_run)


def _data_verdict(stretches: list, detection: Any, damage_probability: float | None, evidence: dict,
                  detector_run: bool = True) -> Verdict:
    """The verdict of a fit without a model error: a local loss, a departure, insufficient data or no change."""
    fired = detection is not None and detection.detected
    doubted = fired and damage_probability is not None and damage_probability < MIN_LOSS_PROBABILITY
    if detection is not None and fired and not doubted:
        half = 0.5 * detection.length_m
        where = (detection.centre_m - half, detection.centre_m + half)
        lo, hi = detection.loss_ci95
        return Verdict("local_damage", f"Local damage: a loss of {100 * detection.loss:.0f} % (95 % interval "
                       f"{100 * lo:.0f}-{100 * hi:.0f} %) over {detection.length_m:.1f} m centred at "
                       f"{detection.centre_m:.1f} m, detected at a false-alarm rate of "
                       f"{detection.false_alarm_rate:g}.", location_m=where, loss=detection.loss, evidence=evidence)
    if stretches:
        worst = max(stretches, key=lambda s: abs(s["z"]))
        where = (worst["start"], worst["stop"])
        return Verdict("departure", f"EI departs from its nominal value at {where[0]:.1f}-{where[1]:.1f} m "
                       f"({_percent(worst['loss'])}, outside the simultaneous {100 * BAND_LEVEL:.0f} % band), "
                       f"without a localised loss the detector finds.", location_m=where, loss=worst["loss"],
                       evidence=evidence)
    if detection is None and not detector_run:
        return Verdict("no_change", "No change in the band: the nominal EI stays within the simultaneous 95 % band; "
                       "the damage detector was not run, so a local loss was not tested for."
                       + _pointwise_hint(evidence["band"]["outside_pointwise"]), evidence=evidence)
    if detection is None or not getattr(detection, "testable", True):
        return Verdict("insufficient_data", "Insufficient data: no zone of the bridge can be tested for a local "
                       "loss with these sensors and crossings, and the nominal EI stays within the simultaneous 95 % band.",
                       evidence=evidence, next_step="add crossings or sensors (`sensorplan recommend --target-power`)")
    hint = _pointwise_hint(evidence["band"]["outside_pointwise"])
    if doubted:
        return Verdict("no_change", f"No change: the nominal EI stays within the simultaneous 95 % band; the detector's statistic exceeds "
                       f"its threshold, but the posterior probability of a loss is only {damage_probability:.2f}, "
                       f"so no loss is concluded.{hint}", evidence=evidence)
    return Verdict("no_change", f"No change: the nominal EI stays within the simultaneous 95 % band and no local loss is detected at a "
                   f"false-alarm rate of {detection.false_alarm_rate:g}.{hint}", evidence=evidence)


def _pointwise_hint(stretches: list) -> str:
    """A sentence on where the pointwise band (the one the figures show) leaves the nominal, if anywhere."""
    if not stretches:
        return ""
    where = ", ".join(f"{s['start']:.1f}-{s['stop']:.1f} m ({_percent(s['loss'])})" for s in stretches)
    return (f" The pointwise 95 % band leaves the nominal at {where}, but the simultaneous band does not: an "
            f"indication worth more crossings, not a conclusion.")


_PRECEDENCE = ("model_error", "local_damage", "departure", "insufficient_data", "no_change")


def combined_verdict(*verdicts: "Verdict | None") -> "Verdict | None":
    """The verdict of the same data judged several ways: the first by precedence (a model error first).

    Non-verdicts (None, or a diagnosis's plain text) are skipped; None when no verdict is given.
    """
    given = [v for v in verdicts if isinstance(v, Verdict)]
    if not given:
        return None
    return min(given, key=lambda v: _PRECEDENCE.index(v.status))
