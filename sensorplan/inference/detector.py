"""The damage detector on data: the null fit under the nuisance, then the scan of :mod:`sensorplan.detection.scan`.

Null hypothesis: the undamaged bridge under the nuisance (by default a
smooth within-span variation log EI = log EI_nominal + a + b x + c x^2 per
span, and the log stiffness of every elastic spring).  :class:`NullProblem`
is that model as a problem of the engine (:class:`~.engine.WhitenedProblem`);
it is fitted by the engine's :func:`~.engine.ridge_gauss_newton`, and the
whitened residual, nuisance Jacobian and compliance columns at the fit are
what the scan test needs (the statistic, its calibrated threshold and the
estimates: :func:`~sensorplan.detection.scan.scan_null_fit`).

Owns: the null model and :func:`detect_damage`.  May import: model, detection, the engine, the foundations.
"""

import numpy as np

from ..detection.nuisance import nuisance_matrix
from ..detection.scan import check_scan_options, scan_null_fit, zone_lengths
from .engine import Stacked, WhitenedProblem, ridge_gauss_newton

__all__ = ["NullProblem", "detect_damage"]


class NullProblem(WhitenedProblem):
    """Whitened data and the model under the nuisance: log EI = log EI_0 + P eta, log k = log k_0 + eta_k.

    Parameters: eta, the nuisance coefficients of log EI (the columns of
    :func:`~sensorplan.detection.nuisance.nuisance_matrix`) then the springs'
    log-stiffness changes, all zero at the nominal model.  The noise is the
    engine's (:func:`~.engine.data_sensors`); the scan estimates its scale.
    """

    def __init__(self, case, crossings, *, nuisance):
        super().__init__(case, crossings)
        self.p_ei = nuisance_matrix(case.bridge, case.mesh, nuisance)
        self.n_springs = len(case.bridge.spring_names)
        self.n_params = self.p_ei.shape[1] + self.n_springs

    def state(self, eta):
        """EI per element and the bridge at ``eta``."""
        n = self.p_ei.shape[1]
        ei = self.case.ei * np.exp(self.p_ei @ eta[:n])
        bridge = self.case.bridge
        if self.n_springs:
            bridge = bridge.with_spring_stiffness(bridge.spring_stiffness() * np.exp(eta[n:]))
        return ei, bridge

    def group_terms(self, eta, *, compliance=True):
        """Per group of crossings: whitened predictions, nuisance Jacobian (rows, P) and compliance columns.

        The compliance columns are d y / d r_e for a relative compliance
        increase of element e (v_e dy/dv_e), whitened, (rows, n_elements);
        None without ``compliance`` (the fit's steps do not use them).
        """
        ei, bridge = self.state(eta)
        lines = [self.case.influence_lines(ei, sensors=self.sensors, positions=x, bridge=bridge)
                 for x in self.position_sets]
        out = []
        for group in self.groups:
            ln, lf = lines[group.position_set], group.load_factor[None, :]
            t = group.times
            pred = self.noise.whiten(ln.predictions * lf, group.positions, times=t)
            cols = [(ln.jacobian("log_ei") * lf[..., None]) @ self.p_ei]
            if self.n_springs:
                cols.append(ln.spring_log_jacobian * lf[..., None])
            jac = self.noise.whiten(np.concatenate(cols, axis=2), group.positions, times=t).reshape(-1, self.n_params)
            comp = (self.noise.whiten(ln.kernel * (lf[..., None] / ei), group.positions, times=t).reshape(-1, ei.size)
                    if compliance else None)
            out.append((pred, jac, comp))
        return out

    def whitened_model(self, theta, *, jacobian):
        return [(pred, jac if jacobian else None) for pred, jac, _ in self.group_terms(theta, compliance=False)]

    def stacked(self, eta, *, compliance=False):
        """The whitened residual, nuisance Jacobian and (``extra``, with ``compliance``) compliance columns,
        stacked over the crossings."""
        terms = self.group_terms(eta, compliance=compliance)
        res, jac, comp = [], [], []
        for white, g in zip(self.white_data, self.group_of):
            pred, j, c = terms[g]
            res.append((white - pred).ravel())
            jac.append(j)
            comp.append(c)
        return Stacked(np.concatenate(res), np.concatenate(jac), np.concatenate(comp) if compliance else None)

    def fit(self, *, max_iter=30, prior_std=(1.0, 3.0)):
        """The null fit (:func:`~.engine.ridge_gauss_newton` from the nominal model); returns (eta, Stacked).

        A weak Gaussian prior (std ``prior_std`` on the log-EI coefficients and
        on the spring log stiffnesses) keeps directions the data do not see
        (an unobservable spring, say) finite; the scan projects the nuisance
        off exactly, so the prior only fixes the point of linearisation.
        """
        n_ei = self.p_ei.shape[1]
        ridge = np.concatenate([np.full(n_ei, 1.0 / prior_std[0]), np.full(self.n_springs, 1.0 / prior_std[1])])
        eta, _ = ridge_gauss_newton(self, np.zeros(self.n_params), ridge, max_iter=max_iter)
        return eta, self.stacked(eta, compliance=True)  # the compliance columns at the fit only


def detect_damage(case, crossings, *, false_alarm=0.05, nuisance="smooth", lengths=None, n_null=20000,
                  rng=0, max_loss=1.0):
    """Scan test for a local loss of unknown location and length (see :mod:`sensorplan.detection.scan`).

    Parameters
    ----------
    case : Case
        Nominal model, mesh (the zones' signatures are integrated over its
        elements), sensors and noise.
    crossings : Crossings
    false_alarm : float
        False-alarm rate of the test on undamaged bridges.
    nuisance : {"smooth", "levels"}
        What an undamaged bridge may do: a quadratic log EI per span, or one
        factor per span (plus the elastic springs either way).
    lengths : sequence of float, optional
        Zone lengths [m] (default :func:`~sensorplan.detection.scan.scan_lengths`).
    n_null : int
        Null draws of the threshold simulation.
    rng : seed or Generator
    max_loss : float
        Upper end of the uniform prior of the lost fraction in the estimates.

    Returns
    -------
    DamageDetection
    """
    check_scan_options(false_alarm=false_alarm, max_loss=max_loss)
    rng = np.random.default_rng(rng)
    lengths = zone_lengths(case, lengths)
    _, null = NullProblem(case, crossings, nuisance=nuisance).fit()
    return scan_null_fit(case, null.residual, null.jacobian, null.extra, false_alarm=false_alarm,
                         nuisance=nuisance, lengths=lengths, n_null=n_null, rng=rng, max_loss=max_loss)
