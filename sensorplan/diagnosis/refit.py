"""Fast refits of the extended model: warm-started Gauss-Newton at fixed hyperparameters, linearised folds.

Where the time went (cProfile, before this module): every candidate effect
was refitted from scratch with its hyperparameters re-estimated (up to 60
outer evidence iterations of a full Levenberg-Marquardt solve), and again in
each of four held-out folds and in every forward-selection round: about
9 x 5 x (rounds) nonlinear fits with hyperparameters, 15-900 s on small
cases.  Now:

* screening: the extended model starts at the base MAP (effect parameters
  at their prior means) with the base fit's noise scale and tau held fixed;
  Levenberg-Marquardt then needs 2-6 evaluations (the effects are small
  extensions of a model already fitted);
* held-out folds: exact rank updates of the problem linearised at that
  MAP (leave-fold-out Newton step from the full-data optimum and its
  Gaussian predictive density, by the Woodbury identity), with the noise
  scale taken from the other folds: one forward evaluation for all folds;
* only the final selected model is refitted with its hyperparameters.

Owns: quick fits and held-out scores.  May import: inference, model and the foundations.
"""

import math
import warnings
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from .._errors import DataError
from ..inference.hyperposterior import integrate_problem
from ..inference.laplace import log_evidence, solve_map
from ..model.prior import HyperPrior

__all__ = []


@dataclass(frozen=True, eq=False)
class QuickFit:
    """MAP and Laplace evidence of an extended model at fixed hyperparameters (internal).

    ``ceiling``: the log evidence the fit could still reach by an estimate
    (its log evidence plus twice the Newton decrement plus 3; = the log
    evidence once converged).  ``abandoned``: stopped before convergence
    because the ceiling fell below the level that matters (not converged).
    """

    problem: object
    theta: np.ndarray
    hessian: np.ndarray
    log_evidence: float
    converged: bool
    n_iter: int
    noise_scale: float
    tau: float
    ceiling: float = math.inf
    abandoned: bool = False

    @property
    def covariance(self):
        return np.linalg.inv(self.hessian)


def _evidence(problem, lin, theta, alpha, q):
    """Laplace log evidence at ``theta`` and its ceiling (see :class:`QuickFit`)."""
    # plus the log prior of the effects' discrete choices (a sensor's sign)
    ev = log_evidence(problem, lin, theta, problem.theta0, alpha, q) + problem.log_prior_constant
    hess = lin.jtj / alpha**2 + q
    grad = -lin.jtr / alpha**2 + q @ (theta - problem.theta0)
    try:
        with warnings.catch_warnings():  # ill-conditioned far from the optimum: a large decrement, a high ceiling
            warnings.simplefilter("ignore", scipy.linalg.LinAlgWarning)
            decrement = float(grad @ scipy.linalg.solve(hess, grad, assume_a="pos"))
    except (np.linalg.LinAlgError, ValueError):
        decrement = math.inf
    # Far from the optimum Levenberg-Marquardt converges linearly along curved valleys; on the slow fits
    # measured (a candidate missing a settled bearing) the objective fell by 0.4-2 Newton decrements after
    # the point where it was measured: twice the decrement plus 3 bounds what is left in those traces.
    return ev, hess, ev + 2.0 * max(decrement, 0.0) + 3.0


def quick_fit(problem, start, alpha, tau, *, max_iter=40, floor=None, budget=False):
    """Levenberg-Marquardt from ``start`` with the hyperparameters held; None if the start is invalid.

    With ``floor``, the fit gives up (``abandoned``) once its ceiling falls
    below ``floor``: it cannot matter to a decision that needs that level.
    With ``budget`` (a fit that counts only if it converges within
    ``max_iter`` steps), also once twice the larger of its last two gains
    in every step left would not reach ``floor``: far from its optimum the
    ceiling is no guide (a swap that removes a flipped sensor: ceilings
    2e5-1e6 above the floor while the evidence crawled up by 0.5-3e3 per
    step, 2e5 below it, through all 15 steps).
    """
    q = tau * problem.rough + problem.fixed
    stop = None
    too_slow = False  # given up at the pace of its last steps (budget)
    if floor is not None:
        reached = []

        def stop(theta, lin):
            nonlocal too_slow
            ev, _, ceiling = _evidence(problem, lin, theta, alpha, q)
            reached.append(ev)
            if ceiling < floor:
                return True
            if not budget or len(reached) < 3:
                return False
            pace = max(reached[-1] - reached[-2], reached[-2] - reached[-3])
            too_slow = ev < floor and 2.0 * pace * (max_iter - len(reached)) < floor - ev
            return too_slow
    try:
        # stop when the Newton decrement is ~0.01 (log-density units): enough for Bayes factors and scores.
        # Relative to the objective (~ n_data / 2 at the base fit's noise scale) and at least 0.01 absolute:
        # an effect that explains the gap shrinks the objective, and a purely relative test then asked
        # for ever smaller decrements (a clamped end restraint crawled 55 steps at 0.05-0.005, flagged
        # not converged, and its log Bayes factor of 789 was thrown away)
        tol = 0.02 / max(problem.n_data, 1)
        theta, lin, it, ok = solve_map(problem, start, alpha, q, problem.theta0, max_iter=max_iter, tol=tol,
                                       stop=stop, atol=0.01)
    except DataError:
        return None
    if lin is None or lin.jtj is None:
        lin = problem.evaluate(theta)
    ev, hess, ceiling = _evidence(problem, lin, theta, alpha, q)
    finite = bool(np.isfinite(ev) and np.all(np.isfinite(hess)))
    converged = bool(ok and finite)
    return QuickFit(problem, theta, hess, float(ev), converged, it, alpha, tau,
                    ceiling=float(ev) if converged else float(ceiling),
                    abandoned=bool(not converged and floor is not None and (ceiling < floor or too_slow)))


@dataclass(frozen=True, eq=False)
class IntegratedModel:
    """A model fitted with its hyperparameters integrated out, as ``invert`` does (internal)."""

    problem: object
    mixture: object
    noise_scale: float  # at the mode of the hyper-posterior
    tau: float
    theta_mode: np.ndarray  # MAP at the mode
    converged: bool

    def band(self, probability=0.95):
        """(low, high) of every parameter, from the mixture's quantiles."""
        a = 0.5 * (1.0 - probability)
        return self.mixture.quantile(a), self.mixture.quantile(1.0 - a)


def integrated_fit(problem, prior, *, start=None, noise_scale=1.0, tau=None):
    """The problem fitted as ``invert`` fits (hyperparameters integrated under the default hyperprior)."""
    hyperprior = HyperPrior().for_prior(prior)
    # Each node of the tau grid is solved to a Newton decrement of ~0.01 (log-density units), as the quick
    # fits and the hyper-posterior's own node tolerance; Gauss-Newton gets 10 evaluations (a node that
    # converges at all does so in <= 8 here) before the Levenberg-Marquardt fallback.  On grossly
    # misfitting data (a sign-flipped sensor, position offsets with a settled bearing) Gauss-Newton crawls
    # and the default (100 evaluations, then LM to a relative 1e-10) spent 15-45 s; LM to that decrement
    # takes 10-30 evaluations (cProfile, three-span sign flip: 2533 -> 614 evaluations, log evidence
    # equal to 0.01).
    fit = integrate_problem(problem, problem.rough, problem.fixed, problem.theta0, hyperprior,
                            noise_scale=noise_scale, tau=prior.tau if tau is None else tau, start=start,
                            max_iter=40, tol=0.02 / max(problem.n_data, 1), gauss_newton_max_iter=10, atol=0.01,
                            secant=True)
    mix = fit.mixture
    top = int(np.argmax(mix.weights))
    return IntegratedModel(problem, mix, float(fit.noise_scale_mode), float(math.exp(fit.log_tau_mode)),
                           np.array(mix.thetas[top]), bool(fit.converged))


def blocks_of(problem, theta):
    """The parameter vector as {"log_ei": ..., effect name: ...} (to warm-start a larger model)."""
    out = {"log_ei": theta[:problem.n_elements].copy()}
    for e, sl in zip(problem.effects, problem.slices):
        out[e.name] = theta[sl].copy()
    return out


def warm_start(problem, blocks):
    """Start vector of ``problem`` from the blocks of a smaller model's fit (new blocks at their prior mean)."""
    theta = problem.theta0.copy()
    theta[:problem.n_elements] = blocks["log_ei"]
    for e, sl in zip(problem.effects, problem.slices):
        if e.name in blocks and blocks[e.name].size == sl.stop - sl.start:
            theta[sl] = blocks[e.name]
    return theta


def fold_rows(crossings, folds, cross, load):
    """Boolean row masks of the test part of each fold (rows as in :meth:`JointProblem.rows`)."""
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
    others stay level is not: an effect at one end of the bridge (a
    restraint at the far end of three spans) shows mainly while the loads
    are near that end, which one fold's blocks hold (fold gains -2.3, -0.8,
    1.1, 6.4 with a log Bayes factor of 9.4; the rule that the others had to
    gain in sum, used before, dropped it).
    """
    if new is None or current is None:
        return False, None
    d = new.log_density - current.log_density
    total = float(d.sum())
    if d.size >= 3:
        return bool(total > threshold and total - float(d.max()) > -threshold), total
    return bool(total > threshold), total
