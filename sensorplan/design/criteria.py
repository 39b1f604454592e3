"""Optimal-design criteria on the posterior precision Q(w) = Q_0 + sum_i w_i I_i.

Each criterion knows its value, its gradient with respect to the design
weights, its cvxpy expression and how an efficiency is computed from a
value and a bound.  Utilities are maximised (``utility = value`` for D, Ds
and E; ``-value`` for A).

Definitions (Q is the posterior precision in log-EI parameters, optionally
with spring log-stiffnesses appended):

* D  = log det Q
* Ds = log det of the Schur complement of the spring block, i.e. the log
  determinant of the precision of log EI with the springs marginalised
* A  = trace(C Q^{-1} C^T): C = identity (all parameters), rows selecting
  the elements of a region of interest, or given linear functionals
* E  = lambda_min(Q)
"""

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from .._errors import ConfigError

__all__ = ["Criterion", "make_criterion", "CRITERIA"]

CRITERIA = ("D", "A", "E", "Ds")


@dataclass(frozen=True, eq=False)
class Criterion:
    """One design criterion (see the module docstring for definitions)."""

    name: str
    n_params: int
    targets: np.ndarray = None  # A: rows of C; Ds: number of EI parameters via n_keep
    n_keep: int = None  # Ds: leading parameters kept (log EI), the rest marginalised

    @property
    def maximise(self):
        return self.name != "A"

    @property
    def n_effective(self):
        """Dimension used by the D-efficiency (n_params for D, kept parameters for Ds)."""
        return self.n_keep if self.name == "Ds" else self.n_params

    def value(self, q):
        q = 0.5 * (q + q.T)
        if self.name == "D":
            return _logdet(q)
        if self.name == "Ds":
            return _logdet(q) - _logdet(q[self.n_keep:, self.n_keep:]) if self.n_keep < q.shape[0] else _logdet(q)
        if self.name == "A":
            c = self.targets
            chol = _chol(q)
            if c.shape[0] == c.shape[1] and np.array_equal(c, np.eye(c.shape[0])):
                # trace(Q^-1) = ||L^-1||_F^2 (triangular inverse, a third of the cost of a solve)
                z, info = scipy.linalg.lapack.dtrtri(chol, lower=1)
                if info == 0:
                    return float(np.sum(z * z))
            z = scipy.linalg.solve_triangular(chol, c.T, lower=True, check_finite=False)
            return float(np.sum(z * z))
        return float(np.linalg.eigvalsh(q)[0])

    def utility(self, q):
        v = self.value(q)
        return v if self.maximise else -v

    def gradient_matrix(self, q):
        """Symmetric G with d utility / d w_i = <G, I_i> (a supergradient for E)."""
        q = 0.5 * (q + q.T)
        if self.name in ("D", "Ds"):
            g = _inv(q)
            if self.name == "Ds" and self.n_keep < q.shape[0]:
                k = self.n_keep
                g[k:, k:] -= _inv(q[k:, k:])
            return g
        if self.name == "A":
            qi_ct = scipy.linalg.cho_solve((_chol(q), True), self.targets.T)
            return qi_ct @ qi_ct.T
        vals, vecs = np.linalg.eigh(q)
        u = vecs[:, 0]
        return np.outer(u, u)

    def cvxpy_objective(self, cp, q_expr, constraints):
        """cvxpy objective for the relaxation (constraints may be extended)."""
        if self.name == "D":
            return cp.Maximize(cp.log_det(q_expr))
        if self.name == "Ds":
            k = self.n_keep
            if k == self.n_params:
                return cp.Maximize(cp.log_det(q_expr))
            s = cp.Variable((k, k), symmetric=True)
            block = cp.bmat([[q_expr[:k, :k] - s, q_expr[:k, k:]], [q_expr[k:, :k], q_expr[k:, k:]]])
            constraints.append(0.5 * (block + block.T) >> 0)
            return cp.Maximize(cp.log_det(s))
        if self.name == "A":
            return cp.Minimize(cp.matrix_frac(self.targets.T, q_expr))
        return cp.Maximize(cp.lambda_min(q_expr))

    def efficiency(self, value, bound):
        """Certified lower bound on the efficiency of ``value`` against ``bound``."""
        if self.name in ("D", "Ds"):
            return float(np.exp(min(0.0, (value - bound) / self.n_effective)))
        if self.name == "A":
            return float(min(1.0, bound / value)) if value > 0 else 0.0
        return float(min(1.0, value / bound)) if bound > 0 else 0.0


def make_criterion(name, n_params, *, n_elements=None, edges=None, region=None, functionals=None):
    """Build a criterion.

    Parameters
    ----------
    name : {"D", "A", "E", "Ds"}
    n_params : int
        Dimension of Q.
    n_elements : int
        Number of log-EI parameters (the leading ones); needed for Ds and
        for targeted A.
    edges : ndarray
        Element edges [m] (for ``region``).
    region : (float, float), optional
        A-criterion restricted to the elements overlapping [a, b] m.
    functionals : ndarray (m, n_elements), optional
        A-criterion on linear functionals of log EI (e.g. zone means).
    """
    if name not in CRITERIA:
        raise ConfigError(f"The 'criterion' parameter must be one of {', '.join(CRITERIA)}. Got {name!r} instead.")
    n_elements = n_params if n_elements is None else n_elements
    if name == "Ds":
        return Criterion("Ds", n_params, n_keep=n_elements)
    if name != "A":
        if region is not None or functionals is not None:
            raise ConfigError("A region of interest or functionals apply to the A criterion only.")
        return Criterion(name, n_params)
    if region is not None and functionals is not None:
        raise ConfigError("Give either a region of interest or functionals, not both.")
    if region is not None:
        a, b = float(region[0]), float(region[1])
        if edges is None or not b > a:
            raise ConfigError(f"The region of interest must be (start, stop) with stop > start. Got {region!r}.")
        inside = (edges[1:] > a) & (edges[:-1] < b)
        if not inside.any():
            raise ConfigError(f"The region of interest {a:g}..{b:g} m contains no element.")
        targets = np.zeros((int(inside.sum()), n_params))
        targets[np.arange(targets.shape[0]), np.nonzero(inside)[0]] = 1.0
    elif functionals is not None:
        f = np.atleast_2d(np.asarray(functionals, dtype=float))
        if f.shape[1] != n_elements:
            raise ConfigError(f"Functionals must have {n_elements} columns (one per element). Got {f.shape}.")
        targets = np.zeros((f.shape[0], n_params))
        targets[:, :n_elements] = f
    else:
        targets = np.eye(n_params)
    return Criterion("A", n_params, targets=targets)


def _chol(q):
    try:
        return np.linalg.cholesky(q)
    except np.linalg.LinAlgError:
        raise ConfigError("The posterior precision is not positive definite; the prior must be proper.") from None


def _logdet(q):
    return float(2.0 * np.sum(np.log(np.diag(_chol(q)))))


def _inv(q):
    return scipy.linalg.cho_solve((_chol(q), True), np.eye(q.shape[0]))
