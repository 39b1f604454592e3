"""Result types of damage detection: DetectabilityMap (the design side) and DamageDetection (the scan on data)."""

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

__all__ = ["DetectabilityMap", "DamageDetection", "POWER_TARGET", "BLIND_POWER"]

POWER_TARGET = 0.9  # power that defines the minimum detectable loss
BLIND_POWER = 0.5  # below this power a stretch is reported as a blind spot
_MAX_ROWS = 15


@dataclass(frozen=True, eq=False)
class DetectabilityMap:
    """How well a local EI loss can be told apart from noise and nuisance, along the bridge.

    Attributes
    ----------
    centres_m : ndarray, shape (n_centres,)
        Centres of the damaged zones [m].
    d : ndarray, shape (n_centres,)
        Detectability: norm of the whitened, nuisance-projected damage
        signature over all crossings (signal-to-noise ratio of the optimal
        detector).
    power : ndarray, shape (n_centres,)
        Probability of detecting the loss, Phi(d - z_(1 - false_alarm_rate)).
    min_detectable_loss : tuple of (float or None)
        Smallest loss fraction detected with power >= 0.9 at each centre,
        from the exact forward model; None when it would be >= 0.99.
    false_alarm_rate, n_crossings, severity, nuisance :
        The options the map was computed for.
    length_m : float
        Length of the damaged zone [m].
    sensors_m, supports_m : ndarray
        Sensor and support positions [m].
    sensor_kinds : tuple of str
    d_unit : ndarray, shape (n_centres,)
        d for a unit relative compliance increase r = s / (1 - s) = 1 over
        the zone, linearised (the basis of :attr:`min_detectable_loss`).
    nuisance_names : tuple of str
        The nuisance parameters projected out.
    min_detectable_loss_linear : tuple of (float or None)
        The first-order estimate s = r / (1 + r), d_unit r = z_(1 - alpha) + z_0.9,
        exact for statically determinate bridges, optimistic elsewhere.
    """

    centres_m: np.ndarray
    d: np.ndarray
    power: np.ndarray
    min_detectable_loss: tuple
    false_alarm_rate: float
    n_crossings: int
    severity: float
    length_m: float
    nuisance: str
    sensors_m: np.ndarray
    supports_m: np.ndarray
    sensor_kinds: tuple = ()
    d_unit: np.ndarray | None = None
    nuisance_names: tuple = ()
    min_detectable_loss_linear: tuple = ()

    @property
    def n_centres(self):
        return self.centres_m.size

    @cached_property
    def min_detectable_loss_array(self):
        """:attr:`min_detectable_loss` as floats, NaN where it is None (for plots)."""
        return np.array([np.nan if v is None else v for v in self.min_detectable_loss], dtype=float)

    def stretches(self, mask):
        """Contiguous runs of centres where ``mask`` holds, as ((first, last) [m], ...)."""
        mask = np.asarray(mask, dtype=bool)
        out = []
        start = None
        for i, flag in enumerate(mask):
            if flag and start is None:
                start = i
            if start is not None and (not flag or i == mask.size - 1):
                stop = i if flag else i - 1
                out.append((float(self.centres_m[start]), float(self.centres_m[stop])))
                start = None
        return tuple(out)

    @cached_property
    def blind_spots(self):
        """Stretches of centres where the power is below 0.5."""
        return self.stretches(self.power < BLIND_POWER)

    @cached_property
    def covered(self):
        """Stretches of centres where the power is at least 0.9."""
        return self.stretches(self.power >= POWER_TARGET)

    def _describe(self, i):
        loss = self.min_detectable_loss[i]
        text = "not detectable below 99 %" if loss is None else f"{100 * loss:.0f} %"
        return f"centre {self.centres_m[i]:.2f} m: power {self.power[i]:.2f}, min detectable loss {text}"

    def summary(self):
        kinds = sorted(set(self.sensor_kinds))
        lines = [
            f"Detectability of a {100 * self.severity:g} % EI loss over {self.length_m:g} m "
            f"({self.n_crossings} crossing(s), false alarm rate {100 * self.false_alarm_rate:g} %, "
            f"nuisance: {self.nuisance})",
            f"  sensors ({', '.join(kinds)}) at {_positions(self.sensors_m)} m; "
            f"supports at {_positions(self.supports_m)} m",
            f"  {'centre [m]':>10s} {'d':>8s} {'power':>6s} {'min loss':>9s}",
        ]
        rows = np.arange(self.n_centres)
        if rows.size > _MAX_ROWS:
            rows = np.unique(np.round(np.linspace(0, self.n_centres - 1, _MAX_ROWS - 2)).astype(int))
            rows = np.union1d(rows, [np.argmin(self.power), np.argmax(self.power)])
        for i in rows:
            loss = self.min_detectable_loss[i]
            lines.append(f"  {self.centres_m[i]:10.2f} {self.d[i]:8.2f} {self.power[i]:6.2f} "
                         f"{'> 99 %' if loss is None else f'{100 * loss:.0f} %':>9s}")
        lines.append(f"  worst: {self._describe(int(np.argmin(self.power)))}")
        lines.append(f"  best: {self._describe(int(np.argmax(self.power)))}")
        lines.append(f"  blind spots (power < {BLIND_POWER:g}), zone centres: {_stretch_text(self.blind_spots)}")
        lines.append(f"  well covered (power >= {POWER_TARGET:g}), zone centres: {_stretch_text(self.covered)}")
        return "\n".join(lines)

    def to_dict(self):
        return {
            "centres_m": self.centres_m.tolist(),
            "power": self.power.tolist(),
            "min_detectable_loss": list(self.min_detectable_loss),
            "false_alarm_rate": self.false_alarm_rate,
            "n_crossings": self.n_crossings,
            "severity": self.severity,
            "length_m": self.length_m,
            "nuisance": self.nuisance,
            "d": self.d.tolist(),
            "d_unit": None if self.d_unit is None else self.d_unit.tolist(),
            "sensors_m": self.sensors_m.tolist(),
            "sensor_kinds": list(self.sensor_kinds),
            "supports_m": self.supports_m.tolist(),
            "nuisance_names": list(self.nuisance_names),
            "min_detectable_loss_linear": list(self.min_detectable_loss_linear),
            "blind_spots_m": [list(s) for s in self.blind_spots],
            "covered_m": [list(s) for s in self.covered],
        }


def _positions(values):
    return ", ".join(f"{x:g}" for x in values)


def _stretch_text(stretches):
    if not stretches:
        return "none"
    return ", ".join(f"{a:g}-{b:g} m" if a != b else f"{a:g} m" for a, b in stretches)


@dataclass(frozen=True, eq=False)
class DamageDetection:
    """Outcome of :func:`detect_damage`.

    Attributes
    ----------
    detected : bool
        statistic > threshold.
    false_alarm_rate : float
        The nominal false-alarm rate the threshold was calibrated for.
    statistic, threshold : float
        max_h z_h and its null (1 - false_alarm_rate) quantile.
    p_value : float
        Null probability of a larger statistic (simulated).
    centre_m, length_m : float or None
        The zone's centre (the posterior mean within the most probable window of +- the
        shortest scanned length) and the most probable length (when detected).
    centre_ci95 : (float, float) or None
        95 % interval of the centre over the zones' posterior weights.
    loss, loss_ci95 : float, (float, float) or None
        Fraction of EI lost (0-1) and its 95 % interval (when detected).
    zones : ndarray (H, 2)
        Scanned zones [start, stop] [m].
    scores : ndarray (H,)
        z_h per zone.
    weights : ndarray (H,)
        Posterior probability of each zone given a loss (sums to 1).
    posterior_loss : ndarray (H, 2)
        Posterior mean and std of the lost fraction s per zone.
    zone_posterior : tuple or callable
        (weights, posterior_loss), or a callable returning them: they are
        computed when first asked for (most uses need the verdict only).
    nuisance : str
    noise_scale : float
        alpha of the null fit.
    untestable : ndarray (U, 2)
        Scanned zones [start, stop] [m] that cannot be tested: their signature lies in the span of the
        nuisance, or no residual degree of freedom is left.
    dof : int
        Residual degrees of freedom of the null fit (readings minus the rank of the nuisance columns);
        the noise scale is estimated from them and the threshold accounts for that.
    n_nuisance : int
        Number of nuisance parameters (columns; the rank may be lower).

    With no testable zone (:attr:`testable` false) nothing is tested: ``detected`` is false and the
    statistic, threshold and p-value are NaN (None in :meth:`to_dict`).
    """

    detected: bool
    false_alarm_rate: float
    statistic: float
    threshold: float
    p_value: float
    centre_m: float | None
    length_m: float | None
    centre_ci95: tuple | None
    loss: float | None
    loss_ci95: tuple | None
    zones: np.ndarray = field(repr=False)
    scores: np.ndarray = field(repr=False)
    zone_posterior: "tuple | Callable[[], tuple]" = field(repr=False)
    nuisance: str = "smooth"
    noise_scale: float = 1.0
    untestable: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)), repr=False)
    dof: int = 0
    n_nuisance: int = 0

    @cached_property
    def weights(self):
        """Posterior probability of each zone given a loss, (H,)."""
        return self._zone_posterior[0]

    @cached_property
    def posterior_loss(self):
        """Posterior mean and std of the lost fraction per zone, (H, 2)."""
        return self._zone_posterior[1]

    @cached_property
    def _zone_posterior(self):
        value = self.zone_posterior
        return value() if callable(value) else value

    @property
    def testable(self):
        """Whether at least one zone could be tested."""
        return len(self.zones) > 0

    @property
    def testable_stretches(self):
        """The union of the testable zones as ((start, stop) [m], ...)."""
        return _union(self.zones)

    def not_testable_text(self):
        """One line: why no zone could be tested."""
        why = (f"the {self.n_nuisance} nuisance parameter(s) ({self.nuisance} EI trend per span and the "
               f"elastic springs) explain every local-loss signature these readings can show"
               if self.dof > 0 else f"the {self.n_nuisance} nuisance parameter(s) leave no residual degree "
                                    f"of freedom in these readings")
        return (f"Damage detection not possible: no zone of the bridge can be tested for a local loss: {why}; "
                f"add sensors, crossings at other load positions, or use nuisance 'levels'.")

    def summary(self):
        if not self.testable:
            return self.not_testable_text()
        head = (f"Damage detection (scan over {len(self.scores)} zones, nuisance {self.nuisance}, false-alarm rate "
                f"{self.false_alarm_rate:g}): statistic {self.statistic:.2f}, threshold {self.threshold:.2f}, "
                f"p = {self.p_value:.3g}")
        if len(self.untestable):
            head += (f"\n  testable: {len(self.zones)} of {len(self.zones) + len(self.untestable)} zones, covering "
                     + ", ".join(f"{a:.1f}-{b:.1f} m" for a, b in self.testable_stretches)
                     + "; the others lie in the span of the nuisance")
        if not self.detected:
            return head + "\n  no local loss detected"
        lo, hi = self.loss_ci95
        clo, chi = self.centre_ci95
        return (head + f"\n  DETECTED: loss of {100 * self.loss:.0f} % (95 % interval {100 * lo:.0f}-{100 * hi:.0f} %) "
                f"over {self.length_m:.2f} m centred at {self.centre_m:.2f} m (95 % interval {clo:.2f}-{chi:.2f} m)")

    def to_dict(self):
        return {"detected": bool(self.detected), "false_alarm_rate": self.false_alarm_rate,
                "statistic": _finite(self.statistic), "threshold": _finite(self.threshold),
                "p_value": _finite(self.p_value), "testable": self.testable,
                "testable_m": [list(z) for z in self.testable_stretches], "n_zones_tested": len(self.zones),
                "n_zones_untestable": len(self.untestable), "dof": int(self.dof),
                "centre_m": self.centre_m, "length_m": self.length_m,
                "centre_ci95": None if self.centre_ci95 is None else list(self.centre_ci95),
                "loss": self.loss, "loss_ci95": None if self.loss_ci95 is None else list(self.loss_ci95),
                "nuisance": self.nuisance}


def _finite(value):
    return float(value) if math.isfinite(value) else None


def _union(zones):
    """The union of intervals ``zones`` (H, 2) as a tuple of (start, stop)."""
    out: list = []
    for a, b in sorted((float(a), float(b)) for a, b in zones):
        if out and a <= out[-1][1] + 1e-9:
            out[-1] = (out[-1][0], max(out[-1][1], b))
        else:
            out.append((a, b))
    return tuple(out)
