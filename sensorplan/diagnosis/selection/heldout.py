"""Held-out scores of a fit: folds of the data, linearised leave-fold-out predictive densities, the gain test.

The whitened rows are independent standard normals under the model, so any
partition of them is a valid split into training and held-out data.  A
fit's held-out score is computed by exact rank updates of the problem
linearised at its MAP (a leave-fold-out Newton step from the full-data
optimum and its Gaussian predictive density, by the Woodbury identity),
with the noise scale of each fold taken from the other folds: one forward
evaluation serves every fold.

Owns: the folds, :class:`Heldout`, :func:`heldout`, :func:`gain_is_significant`.  May import: numpy, scipy.
"""

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg

__all__ = ["Heldout", "fold_rows", "make_folds", "gain_is_significant", "heldout"]


def make_folds(crossings, n_folds=4):
    """Masks (train, test) per fold.

    With load sweeps (>= 8 positions per crossing) every fold holds out two
    contiguous blocks of load positions in every crossing, one in each half
    of the sweep (blocks b and b + n_folds of 2 n_folds), so parameters of a
    single crossing (offsets, drift, amplification, trigger shifts) are
    estimated from the rest of that crossing.  With fewer positions (static
    load steps) whole crossings are held out.
    """
    n_c = len(crossings)
    folds = []
    if all(c.n_loads >= 8 for c in crossings):
        for b in range(n_folds):
            test = []
            for c in crossings:
                mask = np.zeros(c.n_loads, bool)
                blocks = np.array_split(np.arange(c.n_loads), 2 * n_folds)
                mask[np.concatenate([blocks[b], blocks[b + n_folds]])] = True
                test.append(mask)
            folds.append(([~m for m in test], test))
        return folds
    if n_c >= 2:
        groups = np.array_split(np.arange(n_c), min(n_folds, n_c))
        for g in groups:
            train = [np.full(c.n_loads, i not in g) for i, c in enumerate(crossings)]
            test = [np.full(c.n_loads, i in g) for i, c in enumerate(crossings)]
            folds.append((train, test))
    return folds


def fold_rows(crossings, folds, cross, load):
    """Boolean row masks of the test part of each fold (rows as in :meth:`~sensorplan.diagnosis.joint.problem.JointProblem.rows`)."""
    offsets = np.concatenate([[0], np.cumsum([c.n_loads for c in crossings])])[:-1]
    index = offsets[cross] + load
    return [np.concatenate(test)[index] for _, test in folds]


@dataclass(frozen=True)
class Heldout:
    """Held-out log predictive density per fold and held-out residuals (internal)."""

    log_density: np.ndarray  # per fold
    rms: float  # per reading, in the sensors' units (whitened rms times the sensor's noise std)
    rms_by_sensor: np.ndarray  # per sensor, in its unit
    ratio: float  # whitened held-out rms per reading (1 = the configured noise)


def heldout(fit, test_masks):
    """Linearised leave-fold-out scores of ``fit`` (noise scale of each fold from the other folds)."""
    if not test_masks:
        return None
    problem = fit.problem
    r, jac, _, _, sensor = problem.rows(fit.theta)
    q = fit.tau * problem.rough + problem.fixed
    d = fit.theta - problem.theta0
    jtj, jtr = jac.T @ jac, jac.T @ r
    n = r.size
    logp, pred = [], np.zeros(n)
    for test in test_masks:
        jt, rt = jac[test], r[test]
        n_t = int(test.sum())
        a2 = max(float(r @ r - rt @ rt) / max(n - n_t, 1), 1e-300)  # noise variance from the other folds
        h = jtj / a2 + q
        hf = h - jt.T @ jt / a2
        grad = -(jtr - jt.T @ rt) / a2 + q @ d  # gradient of the training objective at the MAP
        try:
            cf = scipy.linalg.cho_factor(hf)
            ch = scipy.linalg.cho_factor(h)
        except np.linalg.LinAlgError:
            return None
        rp = rt + jt @ scipy.linalg.cho_solve(cf, grad)
        w = jt.T @ rp
        quad = float(rp @ rp) / a2 - float(w @ scipy.linalg.cho_solve(ch, w)) / a2**2
        logdet = n_t * math.log(a2) + 2 * np.sum(np.log(np.diag(ch[0]))) - 2 * np.sum(np.log(np.diag(cf[0])))
        logp.append(-0.5 * quad - 0.5 * logdet - 0.5 * n_t * math.log(2 * math.pi))
        pred[test] = rp
    used = np.any(np.stack(test_masks), axis=0)
    std = problem.sensor_std

    def per_reading(ms):
        # whitened bins of k readings (binning.py): unit noise plus sqrt(k) x the readings' mean model error, so
        # a bin's mean square is 1 + k e^2 where a reading's is 1 + e^2 (e smooth within a bin)
        return max(1.0 + (ms - 1.0) / problem.bin_size, 0.0)

    ms = np.array([per_reading(float(np.mean(pred[used & (sensor == i)] ** 2))) for i in range(problem.n_sensors)])
    counts = np.array([np.sum(used & (sensor == i)) for i in range(problem.n_sensors)])
    raw = float(np.sum(counts * ms * std**2) / np.sum(counts))
    return Heldout(np.array(logp), math.sqrt(raw), np.sqrt(ms) * std,
                   math.sqrt(per_reading(float(np.mean(pred[used] ** 2)))))


def gain_is_significant(new, current, threshold):
    """Held-out gain of ``new`` over ``current``: total above ``threshold``, and not bought by losses elsewhere.

    With three folds or more, the folds other than the best one must not
    lose more than ``threshold`` together: a gain that one block of load
    positions carries while the others get worse is an artefact of that
    block, not a better model.  A gain that one block carries while the
    others stay level is not: an effect at one end of the bridge shows
    mainly while the loads are near that end, which one fold's blocks hold.
    """
    if new is None or current is None:
        return False, None
    d = new.log_density - current.log_density
    total = float(d.sum())
    if d.size >= 3:
        return bool(total > threshold and total - float(d.max()) > -threshold), total
    return bool(total > threshold), total
