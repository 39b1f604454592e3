"""Confounding of an effect with an EI change, and the sensor position that would separate them.

Owns: the confounding scans.  May import: model and the foundations.
"""

from dataclasses import replace

import numpy as np

from ..model.crossings import Crossings
from ..model.noise import NoiseModel
from ..model.sensors import SensorLayout
from .joint.problem import JointProblem
from .results import Confounding

__all__ = ["confounding", "kept_fraction"]

KEPT_LIMIT = 0.2  # an effect keeping less of its information under unknown EI is confounded with EI
N_CANDIDATES = 41  # candidate sensor positions along the bridge


def confounding(case, crossings, effects, *, prior, theta_base, alpha, tau, estimate_springs):
    """Confounding entries of the ``effects`` (objects) that keep < 20 % of their information under unknown EI."""
    out = []
    for effect in effects:
        problem = JointProblem(case, crossings, [effect], prior, estimate_springs=estimate_springs)
        theta = _at_base(problem, theta_base)
        lin = problem.evaluate(theta)
        if lin is None:
            continue
        _, sl = problem.block(effect.name)
        info = lin.jtj / alpha**2
        kept = kept_fraction(info, problem, tau, sl)
        if kept >= KEPT_LIMIT:
            continue
        where = None
        if not effect.per_sensor:  # a sensor elsewhere cannot inform the data's own sensors' parameters
            where = _separating_sensor(case, crossings, effect, prior, theta, info, alpha=alpha, tau=tau, kept=kept,
                                       estimate_springs=estimate_springs)
        out.append(Confounding(effect.name, kept, where))
    return out


def _at_base(problem, theta_base):
    theta = problem.theta0.copy()
    n_base = theta_base.size
    theta[:n_base] = theta_base  # base blocks (log EI, the case's springs) come first
    return theta


def kept_fraction(info, problem, tau, sl):
    """Smallest fraction of the effect's (data-informed) precision that survives when the rest is unknown."""
    q = tau * problem.rough + problem.fixed
    f = np.zeros(problem.n_params, bool)
    f[sl] = True
    e = ~f
    known = info[np.ix_(f, f)] + q[np.ix_(f, f)]
    marg = known - info[np.ix_(f, e)] @ np.linalg.solve(info[np.ix_(e, e)] + q[np.ix_(e, e)], info[np.ix_(e, f)])
    data_known = info[np.ix_(f, f)]
    # directions the data would inform if EI were known (data info >= 3 x prior)
    vals, vecs = np.linalg.eigh(data_known)
    useful = vecs[:, vals >= 3.0 * np.max(np.diag(q[np.ix_(f, f)]))]
    if useful.shape[1] == 0:
        return 1.0
    a = useful.T @ known @ useful
    b = useful.T @ marg @ useful
    ratio = np.linalg.eigvals(np.linalg.solve(a, b)).real
    return float(np.clip(ratio.min(), 0.0, 1.0))


def _separating_sensor(case, crossings, effect, prior, theta, base_info, *, alpha, tau, kept, estimate_springs):
    """The candidate position (41 along the bridge, all in one forward evaluation) that raises ``kept`` most."""
    kind = case.sensors.kinds[0]
    binned = getattr(crossings[0], "noise", None)  # binned data (joint/binning.py): the readings' noise model
    noise = binned if binned is not None else case.noise
    std = float(np.median(noise.std)) if noise is not None else 1e-6
    xs = np.linspace(0.0, case.bridge.length, N_CANDIDATES)
    names = tuple(f"candidate_{i}" for i in range(xs.size))
    sensors = SensorLayout(xs, kind, names, [std] * xs.size)
    cand_noise = (NoiseModel([std] * xs.size) if noise is None
                  else noise.for_sensors((kind,) * noise.n_sensors, (kind,) * xs.size, [std] * xs.size))
    if binned is None:
        cand_case = replace(case, sensors=sensors, noise=cand_noise)
        dummy = Crossings(names, tuple(replace(c, values=np.zeros((xs.size, c.n_loads))) for c in crossings))
    else:  # the candidates' readings whitened and binned as the data's
        cand_case = replace(case, sensors=sensors, noise=NoiseModel(np.ones(xs.size), 0.0))
        dummy = Crossings(names, tuple(replace(c, values=np.zeros((xs.size, c.n_loads)), noise=cand_noise,
                                               raw_values=np.zeros((xs.size, c.raw_positions.size)))
                                       for c in crossings))
    cand = JointProblem(cand_case, dummy, [effect], prior, estimate_springs=estimate_springs)
    base = JointProblem(case, crossings, [effect], prior, estimate_springs=estimate_springs)
    if cand.n_params != base.n_params:
        return None
    _, sl = base.block(effect.name)
    rows = cand.rows(theta)
    jac, sensor = rows[1], rows[4]
    best, best_kept = None, kept
    for i, x in enumerate(xs):
        j = jac[sensor == i]
        k = kept_fraction(base_info + j.T @ j / alpha**2, base, tau, sl)
        if k > best_kept + 1e-6:
            best, best_kept = float(x), k
    return best
