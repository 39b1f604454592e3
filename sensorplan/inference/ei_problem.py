"""The EI problem of the inversion: log EI per element (or compliance) and spring log stiffnesses.

Model (paper section Bayesian Inference Framework): whitened data
r = W (y - F(theta)) / std ~ N(0, alpha^2 I), where W applies the AR(1)
whitening per sensor and crossing, std the configured noise of each sensor
and alpha a common noise scale; prior theta ~ N(theta_0, Q(tau)^{-1}) with
Q(tau) = tau S + F (GMRF roughness S on log EI plus the fixed proper part F,
:func:`prior_matrices`).  :class:`EIProblem` is a thin subclass of the
engine's :class:`~.engine.WhitenedProblem`: it gives the whitened predictions
and Jacobians of each group of crossings (equal positions and load factors
share them); the engine forms the normal equations.

Owns: the EI parameterisation and its predictions.  May import: model, the engine, the foundations.
"""

from functools import cached_property

import numpy as np

from .._errors import ConfigError
from ..model.force_method import SharedCache
from .engine import WhitenedProblem
from .fixed_lines import FixedLines
from .posterior import CrossingFit

__all__ = ["EIProblem", "prior_matrices"]


class EIProblem(WhitenedProblem):
    """Whitened residuals and Jacobians of all crossings for a parameter vector (log EI or compliance, springs).

    Parameters
    ----------
    case, crossings
        As for :class:`~.engine.WhitenedProblem`.
    estimate_springs : bool
        The elastic springs' log stiffnesses are parameters (after EI).
    parameterisation : {"log_ei", "compliance"}
        ``compliance`` (1 / EI) is the linear-Gaussian case of a
        statically determinate bridge.
    mesh : Mesh, optional
        The EI mesh (default the case's).
    """

    def __init__(self, case, crossings, *, estimate_springs, parameterisation, mesh=None):
        super().__init__(case, crossings)
        self.mesh = case.mesh if mesh is None else mesh
        self.parameterisation = parameterisation
        self.n_elements = self.mesh.n_elements
        self.spring_names = case.bridge.spring_names if estimate_springs else ()
        self.n_springs = len(self.spring_names)
        self.n_params = self.n_elements + self.n_springs
        self.ei_nominal = np.asarray(case.ei_at(self.mesh.midpoints), dtype=float)
        self.spring_nominal = case.bridge.spring_stiffness() if estimate_springs else np.zeros(0)
        if parameterisation == "log_ei":
            self.theta0 = np.concatenate([np.log(self.ei_nominal), np.log(self.spring_nominal)])
        elif parameterisation == "compliance":
            if self.n_springs or len(case.bridge.spring_parameters) or case.bridge.n_spans > 1 or any(
                    k > 0 for k in case.bridge.rotational_springs):
                raise ConfigError("parameterisation='compliance' is the linear-Gaussian case: it needs a "
                                  "statically determinate bridge (one pinned span, rigid supports).")
            self.theta0 = 1.0 / self.ei_nominal
        else:
            raise ConfigError(f"The 'parameterisation' parameter must be 'log_ei' or 'compliance'. "
                              f"Got {parameterisation!r} instead.")
        self.n_evaluations = 0

    @property
    def inversion_case(self):
        """The case on the inversion mesh (the case itself when the mesh is the case's)."""
        return self.case if self.mesh is self.case.mesh else self.case.with_mesh(self.mesh)

    def split(self, theta):
        """EI per element and the bridge with the springs of ``theta`` ((None, None) for a non-positive compliance)."""
        n = self.n_elements
        if self.parameterisation == "log_ei":
            ei = np.exp(theta[:n])
        else:
            if np.any(theta[:n] <= 0.0):
                return None, None
            ei = 1.0 / theta[:n]
        bridge = self.case.bridge
        if self.n_springs:
            bridge = bridge.with_spring_stiffness(np.exp(theta[n:]))
        return ei, bridge

    def lines(self, theta):
        """Influence lines per distinct position set (``self.position_sets``), or None outside the domain."""
        ei, bridge = self.split(theta)
        if ei is None:
            return None
        self.n_evaluations += 1
        return [lines.at(bridge, ei) for lines in self.fixed_lines]

    @cached_property
    def fixed_lines(self):
        """:class:`~.fixed_lines.FixedLines` of each position set (the forward model at any EI)."""
        return [FixedLines(self.case.bridge, self.mesh, self.sensors, self.case.vehicle, positions)
                for positions in self.position_sets]

    def whitened_model(self, theta, *, jacobian):
        """Per group of crossings: whitened predictions and Jacobian (the engine forms the normal equations)."""
        lines = self.lines(theta)
        if lines is None:
            return None
        out = []
        for group in self.groups:
            ln, lf = lines[group.position_set], group.load_factor
            white_pred = self.noise.whiten(ln.predictions * lf[None, :], group.positions, times=group.times)
            white_jac = None
            if jacobian:
                jac = self.raw_jacobian(ln) * lf[None, :, None]
                white_jac = self.noise.whiten(jac, group.positions, times=group.times).reshape(-1, self.n_params)
            out.append((white_pred, white_jac))
        return out

    def raw_jacobian(self, lines):
        """dF/dtheta (S, K, P) of ``lines`` in the problem's parameters."""
        if self.parameterisation == "log_ei":
            return lines.jacobian("log_ei", springs=self.n_springs > 0)
        return lines.jacobian("compliance")

    def fits(self, theta, covariance, alpha):
        """Data, model and posterior predictive spread per crossing."""
        lines = self.lines(theta)
        spread = []
        for group in self.groups:
            ln, lf = lines[group.position_set], group.load_factor
            pred = ln.predictions * lf[None, :]
            j = self.raw_jacobian(ln) * lf[None, :, None]
            var = np.sum((j @ covariance) * j, axis=-1)
            spread.append((pred, np.sqrt(np.clip(var, 0.0, None))))
        return tuple(CrossingFit(c.label, c.positions, c.values, *spread[g], alpha * self.noise.std, times=c.times)
                     for c, g in zip(self.crossings, self.group_of))


def prior_matrices(problem, prior):
    """Roughness S and fixed part F of the prior precision in the problem's parameters (read-only, kept by value)."""
    n, s = problem.n_elements, problem.n_springs
    scale = 1.0 / problem.theta0 if problem.parameterisation == "compliance" else None
    return _PRIOR_MATRICES.get((prior, n, s, scale), lambda: _prior_matrices(prior, n, s, scale))


_PRIOR_MATRICES = SharedCache(8)  # a verification inverts hundreds of data sets under one prior


def _prior_matrices(prior, n, s, scale):
    rough = np.zeros((n + s, n + s))
    rough[:n, :n] = prior.structure(n)
    fixed = prior.precision(n, s, tau=0.0)
    if scale is not None:
        # compliance: the same quadratic form to first order, d log EI = -d v / v_0
        rough = rough * np.outer(scale, scale)
        fixed = fixed * np.outer(scale, scale)
    for arr in (rough, fixed):
        arr.setflags(write=False)
    return rough, fixed
