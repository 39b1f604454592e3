"""What slower or more crossings buy for a layout, and where the wander caps the gain.

Under the noise model in time (:class:`~sensorplan.model.noise.NoiseModel`
with an Ornstein-Uhlenbeck part or a random walk) the information one
crossing carries depends on its speed: a slower crossing spreads the same
load positions over a longer time, so its readings average more logger
samples and more independent stretches of the correlated part, but the
wander grows with the crossing's duration and its level is an unknown.  The
information per crossing therefore rises as the speed falls until the
wander caps it.  Independent crossings add their information.

:func:`crossing_trade` evaluates the layout's Fisher information in log EI
at a grid of speeds and reports the mean posterior standard deviation of log
EI (the design's prior, the GMRF of :class:`~sensorplan.model.prior.GMRFPrior`)
for each speed and number of crossings, and the speed of the grid at which
one crossing carries the most information (trace of the Fisher information).
"""

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy.linalg

from .._errors import ConfigError
from ..model.fisher import fisher_blocks
from ..model.prior import GMRFPrior

if TYPE_CHECKING:
    from collections.abc import Sequence

    from ..model.case import Case
    from ..model.sensors import SensorLayout

SPEED_FACTORS = (0.25, 0.5, 1.0, 2.0, 4.0)
CROSSINGS = (1, 2, 5, 10, 20, 50)


@dataclass(frozen=True)
class CrossingTrade:
    """The posterior spread of log EI against crossing speed and count for one layout.

    Attributes
    ----------
    speeds : ndarray, shape (n_speeds,)
        Crossing speeds [m/s], ascending.
    crossings : ndarray, shape (n_counts,)
        Numbers of independent crossings.
    posterior_std : ndarray, shape (n_speeds, n_counts)
        Mean over the elements of the posterior standard deviation of log EI.
    information : ndarray, shape (n_speeds,)
        Trace of one crossing's Fisher information, relative to that at
        ``speed``.
    speed : float
        The case's crossing speed [m/s].
    best_speed : float
        The speed of the grid at which one crossing carries the most
        information; the lowest speed when slowing down never stops gaining
        in the grid.
    prior_std : float
        Mean prior standard deviation of log EI (no data).
    """

    speeds: np.ndarray
    crossings: np.ndarray
    posterior_std: np.ndarray
    information: np.ndarray
    speed: float
    best_speed: float
    prior_std: float

    @property
    def capped(self):
        """Whether the wander caps the gain within the grid (a speed above the lowest carries the most)."""
        return bool(self.best_speed > self.speeds[0])

    def summary(self):
        head = "".join(f"{n:>8d}" for n in self.crossings)
        lines = [f"Crossing speed and count: mean posterior std of log EI [%] (prior {100 * self.prior_std:.3g} %)",
                 f"  {'speed':>9s}  {'info':>6s}{head}  crossings"]
        for v, info, row in zip(self.speeds, self.information, self.posterior_std):
            mark = " <- case" if np.isclose(v, self.speed) else ""
            lines.append(f"  {v:7.3g} m/s {info:5.2f}x" + "".join(f"{100 * s:8.3g}" for s in row) + mark)
        if self.best_speed == self.speeds[-1]:
            lines.append(f"  faster crossings gain up to {self.best_speed:.3g} m/s (the fastest evaluated): over a "
                         "longer crossing the correlated noise and the wander cost more than the averaging gains")
        elif self.capped:
            lines.append(f"  one crossing carries the most information at {self.best_speed:.3g} m/s; slower, the "
                         "wander costs more than the averaging gains")
        else:
            lines.append(f"  slower crossings gain down to {self.speeds[0]:.3g} m/s (the slowest evaluated)")
        return "\n".join(lines)

    def to_dict(self):
        return {"speeds_m_s": self.speeds.tolist(), "crossings": self.crossings.tolist(),
                "posterior_std_log_ei": self.posterior_std.tolist(), "information_relative": self.information.tolist(),
                "speed_m_s": self.speed, "best_speed_m_s": self.best_speed, "capped_by_wander": self.capped,
                "prior_std_log_ei": self.prior_std}


def crossing_trade(case: "Case", sensors: "SensorLayout", *, speeds: "Sequence[float] | None" = None,
                   crossings: "Sequence[int]" = CROSSINGS, prior: GMRFPrior | None = None) -> CrossingTrade:
    """The mean posterior std of log EI of ``sensors`` against crossing speed and count.

    Parameters
    ----------
    case : Case
        Its noise must have a part in time (the speed changes nothing otherwise).
    sensors : SensorLayout
        The layout (new sensors take the case's noise by :meth:`Case.noise_for`).
    speeds : sequence of float, optional
        Speeds [m/s] (default: the case's speed times 0.25, 0.5, 1, 2, 4).
    crossings : sequence of int
        Numbers of independent crossings.
    prior : GMRFPrior, optional
        The design's prior (default ``GMRFPrior()``, as :func:`~.recommend.recommend`).
    """
    noise = case.noise_for(sensors)
    if noise is None or not noise.in_time:
        raise ConfigError("The crossing speed trade needs a noise model in time ([noise] correlated_std, "
                          "correlation_time_s, random_walk and speed); estimate one with 'sensorplan noise'.")
    speed = float(noise.speed)
    grid = np.asarray(sorted(speed * np.asarray(SPEED_FACTORS) if speeds is None else speeds), dtype=float)
    counts = np.asarray(crossings)
    if grid.size == 0 or np.any(~np.isfinite(grid) | (grid <= 0.0)):
        raise ConfigError(f"The 'speeds' must be positive speeds in m/s. Got {grid.tolist()!r} instead.")
    if counts.size == 0 or np.any(counts < 1) or np.any(counts != np.round(counts)):
        raise ConfigError(f"The 'crossings' must be positive whole counts. Got {counts.tolist()!r} instead.")
    counts = counts.astype(int)
    prior = GMRFPrior() if prior is None else prior
    # Q = L L^T; the generalised eigenproblem F v = lambda Q v gives (Q + n F)^-1 = V (I + n Lambda)^-1 V^T
    q = prior.precision(case.n_elements, 0)
    prior_var = np.diag(scipy.linalg.cho_solve(scipy.linalg.cho_factor(q), np.eye(q.shape[0])))
    table = np.empty((grid.size, counts.size))
    trace = np.empty(grid.size)
    for i, v in enumerate(grid):
        info = fisher_blocks(case, sensors=sensors, noise=noise.at_speed(v), parameterisation="log_ei").total()
        trace[i] = np.trace(info)
        lam, vecs = scipy.linalg.eigh(info, q)  # vecs^T q vecs = I
        lam = np.maximum(lam, 0.0)
        variance = (vecs**2) @ (1.0 / (1.0 + np.outer(lam, counts)))
        table[i] = np.mean(np.sqrt(variance), axis=0)
    at_case = np.flatnonzero(grid == speed)
    ref = trace[at_case[0]] if at_case.size else np.trace(
        fisher_blocks(case, sensors=sensors, noise=noise, parameterisation="log_ei").total())
    return CrossingTrade(grid, counts, table, trace / ref, speed, float(grid[np.argmax(trace)]),
                         float(np.mean(np.sqrt(prior_var))))
