"""Integration over the hyperparameters: the posterior as a mixture over log tau.

The hyperparameters get a proper prior (:class:`~sensorplan.model.prior.HyperPrior`:
a log-normal or PC prior on the smoothness std sigma = tau^{-1/2}, a log-normal prior on
the noise scale alpha) and are integrated out instead of being estimated:

    p(theta | y) = int p(theta | y, tau) p(log tau | y) d log tau.

* At a fixed tau the noise scale is integrated by Laplace's method in v = log alpha (its posterior
  is very narrow: the curvature is about 2M for M readings), and p(theta | y, tau) is the Laplace
  posterior at the MAP with alpha at its conditional mode.
* The hyper-posterior p(log tau | y) is proportional to the Laplace
  evidence times both hyperpriors.  It is integrated by the trapezoidal
  rule on an equispaced grid of log tau (spectrally accurate for a smooth
  integrand that decays at both ends): the grid is centred at the mode,
  its step is a fraction of the hyper-posterior standard deviation there,
  and it is extended node by node until the weight of the last node in each
  direction is negligible (e^-10 of the largest).  The result is a Gaussian
  mixture with one component per node.
* Cost: the forward model is evaluated only to (re-)linearise.  The model
  linearised at a MAP, y = J theta + e, has a closed-form evidence and MAP
  for any (alpha, tau) (a generalized eigendecomposition of (J^T J, Q(tau))),
  so the mode of the hyper-posterior is found without forward solves, and
  each node starts from the Gauss-Newton step of its neighbour's
  linearisation: often one forward + Jacobian evaluation per node confirms
  the MAP.  Further steps are Gauss-Newton with a backtracking line search;
  a node where no step decreases the objective falls back to the
  Levenberg-Marquardt MAP of :func:`solve_map`.  Nodes far in the tails
  (below e^-5 of the largest weight) are taken from the neighbour's
  linearisation without a new evaluation.

Owns: the quadrature over log tau.  May import: model, errors.
"""

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np
import scipy.optimize
from scipy.linalg import lapack

from .._cache import Cache
from .._errors import DataError
from .engine import LOG_NOISE_FLOOR, SecantCurvature, solve_map
from .mixture import GaussianMixture

__all__ = ["IntegratedFit", "integrate_problem", "LOG_TAU_BOUNDS", "BOUND_MASS"]

LOG_TAU_BOUNDS = (math.log(1e-8), math.log(1e14))  # hard ends of the grid (those of evidence maximisation)
NEGLIGIBLE = 10.0  # a node this far (in log weight) below the largest ends the grid in its direction
BOUND_MASS = 1e-3  # weight of an end node cut by a hard bound above which the result is flagged
MAX_STEP = 1.0  # largest grid step in log tau
STEP_FACTOR = 0.75  # grid step / standard deviation of the hyper-posterior of log tau at its mode
MIN_SIGNIFICANT = 5  # fewer nodes with weight > 1e-3 than this: the grid is refined (step halved)
NODE_TOL = 1e-2  # Gauss-Newton decrement at which a node is accepted (its MAP is then the GN step from there)
TAIL = 5.0  # a node predicted this far below the largest log weight (< 0.7 %) is taken from the
TAIL_MOVE = 10.0  # neighbour's linearisation, unless its MAP moves more than this (H-norm squared) from it
MAX_NODES = 150
_SYGVD = lapack.dsygvd  # the driver scipy.linalg.eigh uses for a generalized problem


@dataclass(frozen=True)
class _Context:
    problem: object
    rough: np.ndarray
    fixed: np.ndarray
    theta0: np.ndarray
    hyperprior: object
    n_data: int
    constant: float  # -log det(Sigma_0) / 2 - M log(2 pi) / 2
    gauss_newton_max_iter: int | None = None  # evaluations before the LM fallback (None: max_iter)
    # nodes differ only in tau: once Gauss-Newton failed on one, the others go straight to the fallback
    gauss_newton_failed: list = field(default_factory=list)
    atol: float = 0.0  # the fallback's absolute Newton-decrement tolerance (solve_map's atol)
    curvature: object = None  # the fallback's SecantCurvature, carried from node to node (or None)


class _Surrogate:
    """The problem linearised at ``theta``: y_lin = J theta + e with y_lin = r + J theta."""

    def __init__(self, lin, theta, ctx):
        d = theta - ctx.theta0
        self.lin, self.theta, self.ctx = lin, theta, ctx
        self.g = lin.jtr + lin.jtj @ d  # J^T (y_lin - J theta0)
        self.yy = float(lin.rr + 2.0 * d @ lin.jtr + d @ lin.jtj @ d)  # |y_lin - J theta0|^2
        self.slices = Cache(maxsize=64)

    def at(self, log_tau):  # slices are kept: the search for the mode and the march ask for some twice
        return self.slices.get((float(log_tau),), lambda: _Slice(self, log_tau))


class _Slice:
    """The surrogate at one tau: J^T J W = Q W diag(mu), W^T Q W = I, c = W^T g.

    For a = alpha^2, the evidence of y_lin ~ N(J theta0, a I + J Q^{-1} J^T) is
    const - M log alpha - sum log(1 + mu/a)/2 - (|y_c|^2 - sum c^2/(a + mu)) / (2a);
    the MAP is theta0 + W c/(a + mu) and the covariance W diag(a/(a + mu)) W^T.
    """

    def __init__(self, surrogate, log_tau):
        ctx = surrogate.ctx
        self.surrogate, self.log_tau = surrogate, float(log_tau)
        self.precision = math.exp(log_tau) * ctx.rough + ctx.fixed
        mu, w = _generalized_eigh(surrogate.lin.jtj, self.precision)
        self.mu, self.w = np.clip(mu, 0.0, None), w
        self.c = w.T @ surrogate.g
        self.c2, self.mu2 = self.c**2, self.mu**2

    def log_posterior_v(self, v):
        """log p(y | alpha, tau) + log p(log alpha) at v = log alpha, with its first two v-derivatives."""
        ctx, mu = self.surrogate.ctx, self.mu
        a = math.exp(2.0 * v)
        quad = self.surrogate.yy - np.sum(self.c2 / (a + mu))
        value = ctx.constant - ctx.n_data * v - 0.5 * np.sum(np.log1p(mu / a)) - 0.5 * quad / a
        d1, d2 = self._derivatives(v, a)
        return (float(value + ctx.hyperprior.log_density_log_noise(v)), d1, d2)

    def _derivatives(self, v, a):  # of log_posterior_v at v = log alpha, a = alpha^2
        ctx, mu, c2, yy = self.surrogate.ctx, self.mu, self.c2, self.surrogate.yy
        r = 1.0 / (a + mu)
        r2 = r * r
        d1 = -ctx.n_data + mu @ r + yy / a - (c2 @ ((2.0 * a + mu) * r2)) / a
        d2 = -2.0 * a * (mu @ r2) - 2.0 * yy / a + 2.0 * (c2 @ ((4.0 * a * a + 3.0 * a * mu + self.mu2) * (r2 * r))) / a
        s2 = ctx.hyperprior.noise_log_std**2
        return float(d1 - v / s2), float(d2 - 1.0 / s2)

    def best_v(self, v):
        """The conditional mode of log alpha (safeguarded Newton)."""
        for _ in range(100):
            d1, d2 = self._derivatives(v, math.exp(2.0 * v))
            step = -d1 / d2 if d2 < 0.0 else math.copysign(0.5, d1)
            step = max(-1.0, min(1.0, step))
            v = max(v + step, LOG_NOISE_FLOOR)
            if abs(step) < 1e-12 or v == LOG_NOISE_FLOOR:
                break
        return v

    def log_weight(self, v):
        """log p(log tau | y) + const: Laplace over log alpha at its mode ``v``, times the prior of log tau."""
        value, _, d2 = self.log_posterior_v(v)
        hyper = self.surrogate.ctx.hyperprior
        return float(value + 0.5 * math.log(2.0 * math.pi) - 0.5 * math.log(max(-d2, 1e-300))
                     + hyper.log_density_log_tau(self.log_tau))

    def map_point(self, v):
        a = math.exp(2.0 * v)
        return self.surrogate.ctx.theta0 + self.w @ (self.c / (a + self.mu))

    def covariance(self, v):
        a = math.exp(2.0 * v)
        cov = (self.w * (a / (a + self.mu))) @ self.w.T
        return 0.5 * (cov + cov.T)

    def decrement(self, step, v):
        """step^T H step with H = J^T J / alpha^2 + Q (twice the predicted decrease of the objective)."""
        a = math.exp(2.0 * v)
        lin = self.surrogate.lin
        return float(step @ (lin.jtj @ step) / a + step @ (self.precision @ step))


def _generalized_eigh(a, b):
    """``scipy.linalg.eigh(a, b)`` (its driver, sygvd, the same values) without scipy's argument handling."""
    mu, w, info = _SYGVD(a, b) if np.isfinite(a).all() and np.isfinite(b).all() else (None, None, -1)
    if info != 0:
        raise np.linalg.LinAlgError(f"the generalized eigenproblem failed (LAPACK sygvd info {info})")
    return mu, w


@dataclass(frozen=True, eq=False)
class _Node:
    log_tau: float
    v: float
    theta: np.ndarray
    covariance: np.ndarray
    log_weight: float
    surrogate: _Surrogate
    n_iter: int
    converged: bool


def _objective(lin, theta, sl, v, theta0):
    """Negative log posterior |r|^2 / (2 alpha^2) + (theta - theta0)^T Q (theta - theta0) / 2 at v = log alpha."""
    d = theta - theta0
    return 0.5 * lin.rr * math.exp(-2.0 * v) + 0.5 * d @ (sl.precision @ d)


def _gauss_newton(ctx, x, lin, log_tau, v, max_iter):
    """Gauss-Newton from ``x`` with a backtracking (Armijo) line search on the negative log posterior.

    Returns the node once the next step's decrement is below NODE_TOL (its MAP is that next step), or None
    when no step decreases the objective or ``max_iter`` evaluations are spent; also the number of
    evaluations and the last point accepted (where a fallback starts).
    """
    n_iter = 0
    while lin is not None and n_iter < max_iter:
        here = _Surrogate(lin, x, ctx)
        sl = here.at(log_tau)
        v = sl.best_v(v)
        step = sl.map_point(v) - x
        decrement = sl.decrement(step, v)
        if decrement < NODE_TOL:
            return _Node(log_tau, v, x + step, sl.covariance(v), sl.log_weight(v), here, n_iter, True), n_iter, x
        current = _objective(lin, x, sl, v, ctx.theta0)
        t, accepted = 1.0, None
        for _ in range(8):
            trial = x + t * step
            trial_lin = ctx.problem.evaluate(trial)
            n_iter += 1
            if trial_lin is not None and (_objective(trial_lin, trial, sl, v, ctx.theta0)
                                          <= current - 1e-4 * t * decrement):
                accepted = trial, trial_lin
                break
            t *= 0.5
        if accepted is None:
            break
        x, lin = accepted
    return None, n_iter, x


def _levenberg_marquardt(ctx, theta, log_tau, v, *, max_iter, tol, n_iter):
    """The node by the safeguarded MAP of :func:`solve_map` from ``theta``, then one surrogate step for alpha."""
    q = math.exp(log_tau) * ctx.rough + ctx.fixed
    theta, lin, it, ok = solve_map(ctx.problem, theta, math.exp(v), q, ctx.theta0, max_iter=max_iter, tol=tol,
                                   atol=ctx.atol, curvature=ctx.curvature)
    here = _Surrogate(lin, theta, ctx)
    sl = here.at(log_tau)
    v = sl.best_v(v)
    return _Node(log_tau, v, sl.map_point(v), sl.covariance(v), sl.log_weight(v), here, n_iter + it, ok)


def _solve_node(ctx, surrogate, log_tau, v, *, max_iter, tol):
    """Laplace posterior at ``log_tau``, starting from the Gauss-Newton step of ``surrogate``.

    Levenberg-Marquardt from the neighbour's MAP is the fallback.
    """
    sl = surrogate.at(log_tau)
    v = sl.best_v(v)
    n_iter = 0
    x = sl.map_point(v)
    if not ctx.gauss_newton_failed:
        lin = ctx.problem.evaluate(x)
        node, n_iter, last = _gauss_newton(ctx, x, lin, log_tau, v, _gn_budget(ctx, max_iter))
        n_iter += 1
        if node is not None:
            return dataclasses.replace(node, n_iter=n_iter)
        ctx.gauss_newton_failed.append(log_tau)
        x = last  # where Gauss-Newton got to (its steps only lowered the objective)
    if ctx.problem.evaluate(x) is None:  # the neighbour's prediction out of the model's domain
        x = surrogate.theta
    return _levenberg_marquardt(ctx, x, log_tau, v, max_iter=max_iter, tol=tol, n_iter=n_iter)


def _start_node(ctx, theta, log_tau, v, *, max_iter, tol):
    """Laplace posterior at the start values, from ``theta`` (Levenberg-Marquardt as the fallback)."""
    lin = ctx.problem.evaluate(theta)
    if lin is None:
        raise DataError("The start point gives an invalid model (non-positive EI).")
    node, n_iter, last = _gauss_newton(ctx, theta, lin, log_tau, v, _gn_budget(ctx, max_iter))
    n_iter += 1
    if node is not None:
        return dataclasses.replace(node, n_iter=n_iter)
    ctx.gauss_newton_failed.append(log_tau)
    return _levenberg_marquardt(ctx, last, log_tau, v, max_iter=max_iter, tol=tol, n_iter=n_iter)


def _gn_budget(ctx, max_iter):
    return max_iter if ctx.gauss_newton_max_iter is None else min(max_iter, ctx.gauss_newton_max_iter)


def _mode(surrogate, log_tau, v):
    """Mode of the surrogate's hyper-posterior of log tau and the grid step there."""
    lo, hi = LOG_TAU_BOUNDS
    cache = {}

    def weight(u):
        if u not in cache:
            sl = surrogate.at(u)
            cache[u] = sl.log_weight(sl.best_v(v))
        return cache[u]

    start = min(max(log_tau, lo), hi)
    best_u = start
    for direction in (-1.0, 1.0):
        # unit steps near the start, then doubling, until 15 below the best (or the bound)
        u, step, n = start, 1.0, 0
        while True:
            u = min(max(u + direction * step, lo), hi)
            if weight(u) > weight(best_u):
                best_u = u
            n += 1
            if weight(u) < weight(best_u) - 15.0 or u in (lo, hi):
                break
            step = 1.0 if n < 4 else 2.0 * step
    keys = sorted(cache)
    i = keys.index(best_u)
    left, right = keys[max(i - 1, 0)], keys[min(i + 1, len(keys) - 1)]
    res = scipy.optimize.minimize_scalar(lambda u: -weight(float(u)), bounds=(left, right), method="bounded",
                                         options={"xatol": 1e-3})
    u_hat = float(res.x) if -res.fun >= weight(best_u) else best_u
    delta = 0.1
    curvature = (weight(u_hat + delta) - 2.0 * weight(u_hat) + weight(u_hat - delta)) / delta**2
    sd = 1.0 / math.sqrt(-curvature) if curvature < 0.0 else math.inf
    return u_hat, min(MAX_STEP, STEP_FACTOR * sd)


@dataclass(frozen=True, eq=False)
class IntegratedFit:
    """Result of :func:`integrate_problem` (internal)."""

    mixture: GaussianMixture
    log_tau_mode: float
    noise_scale_mode: float
    log_evidence: float
    mass_at_bound: float
    step: float
    converged: bool
    n_iter: int


def _tail_node(previous, log_tau, largest):
    """The node at ``log_tau`` from the neighbour's linearisation, if it is in the tail (else None)."""
    surrogate = previous.surrogate
    sl = surrogate.at(log_tau)
    v = sl.best_v(previous.v)
    log_weight = sl.log_weight(v)
    x = sl.map_point(v)
    if log_weight > largest - TAIL or sl.decrement(x - surrogate.theta, v) > TAIL_MOVE:
        return None
    return _Node(log_tau, v, x, sl.covariance(v), log_weight, surrogate, 0, True)


def _march(ctx, centre, step, *, max_iter, tol):
    """Nodes centre.log_tau + k step, k = 0, +-1, ..., until negligible; returns (nodes by k, bound hit per end)."""
    nodes = {0: centre}
    hit = {}
    lo, hi = LOG_TAU_BOUNDS
    for direction in (1, -1):
        k, previous = 0, centre
        hit[direction] = False
        while len(nodes) < MAX_NODES:
            k += direction
            u = centre.log_tau + k * step
            if not lo - 1e-9 <= u <= hi + 1e-9:
                hit[direction] = True
                break
            largest = max(n.log_weight for n in nodes.values())
            node = _tail_node(previous, u, largest)
            if node is None:
                node = _solve_node(ctx, previous.surrogate, u, previous.v, max_iter=max_iter, tol=tol)
            nodes[k] = previous = node
            if node.log_weight < largest - NEGLIGIBLE:
                break
        else:
            hit[direction] = True
    return nodes, hit


def integrate_problem(problem, rough, fixed, theta0, hyperprior, *, noise_scale=1.0, tau=1.0, start=None,
                      max_iter=100, tol=1e-10, gauss_newton_max_iter=None, atol=0.0, secant=False):
    """Posterior mixture over log tau (alpha integrated by Laplace) of any :class:`~.engine.LinearisedProblem`.

    ``hyperprior`` provides ``log_density_log_tau``, ``log_density_log_noise``
    and ``noise_log_std``; ``noise_scale`` and ``tau`` are start values.
    ``gauss_newton_max_iter`` caps the Gauss-Newton evaluations of a node
    before the Levenberg-Marquardt fallback (default ``max_iter``); ``tol``
    and ``atol`` are the fallback's tolerances (:func:`solve_map`).  With
    ``secant`` the fallback also learns the curvature Gauss-Newton leaves
    out, node after node (:class:`~.engine.SecantCurvature`).
    """
    ctx = _Context(problem, rough, fixed, theta0, hyperprior, problem.n_data,
                   -0.5 * problem.log_det_noise - 0.5 * problem.n_data * math.log(2.0 * math.pi),
                   gauss_newton_max_iter, atol=atol,
                   curvature=SecantCurvature(theta0.size) if secant else None)
    theta = theta0.copy() if start is None else np.asarray(start, dtype=float).copy()
    log_tau = min(max(math.log(tau), LOG_TAU_BOUNDS[0]), LOG_TAU_BOUNDS[1])
    v = math.log(noise_scale)
    first = _start_node(ctx, theta, log_tau, v, max_iter=max_iter, tol=tol)
    n_iter = first.n_iter
    surrogate, v = first.surrogate, first.v
    centre = None
    for _ in range(8):
        u_hat, step = _mode(surrogate, log_tau, v)
        if centre is not None and abs(u_hat - centre.log_tau) <= 0.25 * step:
            break
        centre = _solve_node(ctx, surrogate, u_hat, v, max_iter=max_iter, tol=tol)
        n_iter += centre.n_iter
        surrogate, log_tau, v = centre.surrogate, centre.log_tau, centre.v
    for _ in range(4):
        nodes, hit = _march(ctx, centre, step, max_iter=max_iter, tol=tol)
        n_iter += sum(n.n_iter for k, n in nodes.items() if k != 0)
        keys = sorted(nodes)
        log_w = np.array([nodes[k].log_weight for k in keys])
        weights = np.exp(log_w - log_w.max())
        weights /= weights.sum()
        if np.count_nonzero(weights > 1e-3) >= MIN_SIGNIFICANT or step < 1e-3:
            break
        step *= 0.5  # too coarse for the hyper-posterior: halve the step
    ordered = [nodes[k] for k in keys]
    mass_at_bound = (float(weights[-1]) if hit[1] else 0.0) + (float(weights[0]) if hit[-1] else 0.0)
    mixture = GaussianMixture(weights, np.array([n.theta for n in ordered]),
                              np.array([n.covariance for n in ordered]),
                              np.exp([n.log_tau for n in ordered]), np.exp([n.v for n in ordered]))
    top = int(np.argmax(log_w))
    log_tau_mode, v_mode = ordered[top].log_tau, ordered[top].v
    if 0 < top < len(ordered) - 1:  # parabola through the largest node and its neighbours
        a, b, c = log_w[top - 1:top + 2]
        denom = a - 2.0 * b + c
        if denom < 0.0:
            log_tau_mode += 0.5 * step * (a - c) / denom
    log_evidence = float(log_w.max() + math.log(np.sum(np.exp(log_w - log_w.max())) * step))
    # converged: every node of the mixture (the start node only seeds the search for the mode, far from it
    # when the start tau is)
    converged = all(n.converged for n in ordered)
    return IntegratedFit(mixture, log_tau_mode, math.exp(v_mode), log_evidence, mass_at_bound, step,
                         bool(converged), int(n_iter))
