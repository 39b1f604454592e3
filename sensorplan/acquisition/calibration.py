"""The threshold of the vehicle test for a stated false-event rate.

The scan statistic Z(k) = max over the speed grid of z(k, v) (:mod:`.scan`)
is, without a vehicle, the maximum of a family of standard normal fields
(exactly normal under the noise model: the record is whitened).  Because
entry time and speed are searched, Z is far from a chi-square variable: its
exceedances over a level u come in clusters, and a false event is one such
cluster.  For smooth Gaussian fields the expected number of clusters above a
high u is the expected Euler characteristic of the excursion set, of the form

    rate(u) = (alpha + beta u) phi(u)   per sample,   phi the normal density

(Adler & Taylor, *Random Fields and Geometry*, 2007, ch. 12; Worsley 1994 for
the scan over a time-scale family: the constant term is the time search, the
``u`` term the search over the scale, here the speed).  ``alpha`` and
``beta`` depend only on the whitened templates, so they are measured by
simulating the null in the whitened domain (white standard normal records,
seeded) and counting the upcrossings of Z at moderate levels (2.5 to 4.25), then the formula is solved for the level
whose rate is the stated false-event rate (e.g. one per day of record, a
level near 6.5, where direct simulation would need years of record).
Counting upcrossings over-counts clusters at the moderate levels (a cluster
can cross several times), which only raises the fitted rate: the threshold
errs on the safe side.  The rate at the calibrated level is checked against
direct simulation at an intermediate level in the tests and over 5 h of
record in ``studies/realdata/crossings_acceptance.py``.
"""

from dataclasses import dataclass

import numpy as np

from .._cache import Cache, value_key
from .scan import ScanResult, scan, upcrossings

__all__ = ["Calibration", "calibrate", "DAY"]

DAY = 86400.0  # s
# Levels whose upcrossings are counted in the null simulation.
LEVELS = np.arange(2.5, 4.26, 0.25)
MIN_COUNT = 10  # a level enters the fit with at least this many upcrossings
CHUNK = 2**16  # null samples scanned at a time
ENOUGH = 50  # the simulation stops once the third-highest level has this many upcrossings

_CALIBRATIONS = Cache(maxsize=16)


def _phi(u):
    return np.exp(-0.5 * np.square(u)) / np.sqrt(2.0 * np.pi)


@dataclass(frozen=True)
class Calibration:
    """False-event rate of the scan as a function of the level, and the threshold.

    Attributes
    ----------
    alpha, beta : float
        rate(u) = (alpha + beta u) phi(u) false events per sample.
    dt : float
        Sample interval [s].
    false_events_per_day : float
        The stated rate the threshold is set for.
    threshold : float
        Level of z (the GLR's threshold is its square).
    n_simulated : int
        Samples of null record simulated.
    """

    alpha: float
    beta: float
    dt: float
    false_events_per_day: float
    threshold: float
    n_simulated: int

    def events_per_day(self, z):
        """Expected false events per day of record with a statistic z or above."""
        return np.exp(self._log_per_day(z))

    def _log_per_day(self, z):
        z = np.asarray(z, dtype=float)
        with np.errstate(divide="ignore"):
            return (np.log(self.alpha + self.beta * z) - 0.5 * z**2 - 0.5 * np.log(2.0 * np.pi)
                    + np.log(DAY / self.dt))

    def level(self, per_day):
        """The z whose expected false events per day of record is ``per_day``."""
        from scipy.optimize import brentq

        target = float(per_day)
        if self.events_per_day(1.0) <= target:  # the rate falls from z = 1 on for any alpha, beta >= 0
            return 1.0
        return float(brentq(lambda z: self._log_per_day(z) - np.log(target), 1.0, 40.0))

    def to_dict(self):
        return {"false_events_per_day": self.false_events_per_day, "threshold_z": self.threshold,
                "threshold_glr": self.threshold**2, "rate_alpha_per_sample": self.alpha,
                "rate_beta_per_sample": self.beta, "null_samples_simulated": self.n_simulated,
                "method": "Euler-characteristic tail (alpha + beta z) phi(z) fitted to upcrossings of a "
                          "simulated whitened null"}


def _fit_rate(counts, n):
    """(alpha, beta) >= 0 of counts ~ n (alpha + beta u) phi(u), weighted least squares (Poisson)."""
    use = counts >= MIN_COUNT
    if use.sum() < 2:
        use = counts > 0
    if not use.any():
        return 1.0, 0.0  # no upcrossing at all: a (very) conservative one-per-sample rate
    u = LEVELS[use]
    y = counts[use] / (n * _phi(u))
    weight = np.sqrt(counts[use]) / y  # 1 / relative error of each count
    design = np.column_stack([np.ones_like(u), u]) * weight[:, None]
    alpha, beta = np.linalg.lstsq(design, y * weight, rcond=None)[0]
    if beta < 0.0 or alpha < 0.0:  # keep the rate's form: one non-negative term
        with_beta = float(np.sum(weight**2 * y * u) / np.sum(weight**2 * u**2))
        alpha, beta = (0.0, with_beta) if alpha < 0.0 else (float(np.sum(weight**2 * y) / np.sum(weight**2)), 0.0)
    return float(alpha), float(beta)


def _simulate(templates, n_max, seed):
    """Upcrossing counts of LEVELS by the scan of white null records, in chunks until the top levels are
    well counted (CHUNK samples at a time, at most ``n_max``); returns (counts, samples scanned)."""
    rng = np.random.default_rng(seed)
    n_channels = templates.columns[0].shape[0]
    longest = max(c.shape[1] for c in templates.columns)
    chunk = max(CHUNK, 4 * longest)
    counts = np.zeros(LEVELS.size, dtype=int)
    n = 0
    while n < n_max and counts[-3] < ENOUGH:
        result = scan(rng.standard_normal((n_channels, chunk + longest)), templates)
        counts += upcrossings(result.z[:chunk], LEVELS)  # entries whose template lies wholly in the chunk
        n += chunk
    return counts, n


def calibrate(templates, dt, *, false_events_per_day=1.0, n_samples=2**19, seed=0):
    """The :class:`Calibration` of the scan with ``templates`` on a grid of step ``dt`` [s].

    White standard normal noise per channel (from ``seed``) is scanned in
    chunks until the level 3.75 has been crossed ``ENOUGH`` times or
    ``n_samples`` have been scanned; results are cached by the templates' values.
    """
    key = value_key(templates, float(dt), float(false_events_per_day), int(n_samples), int(seed))
    found, value = _CALIBRATIONS.lookup((), key=key)
    if found:
        return value
    counts, n = _simulate(templates, int(n_samples), seed)
    alpha, beta = _fit_rate(counts, n)
    partial = Calibration(alpha, beta, float(dt), float(false_events_per_day), np.nan, n)
    value = Calibration(alpha, beta, float(dt), float(false_events_per_day),
                        partial.level(false_events_per_day), n)
    _CALIBRATIONS.put((), value, key=key)
    return value


def null_scan(templates, n_samples, rng):
    """A :class:`~.scan.ScanResult` of a white standard normal null record (for checks and studies)."""
    rng = np.random.default_rng(rng)
    n_channels = templates.columns[0].shape[0]
    longest = max(c.shape[1] for c in templates.columns)
    result = scan(rng.standard_normal((n_channels, int(n_samples) + longest)), templates)
    return ScanResult(result.z[: int(n_samples)], result.speed_index[: int(n_samples)])
