"""EI bands that stay honest when a local loss is present: averaging over damage hypotheses.

The GMRF prior penalises every jump of log EI between neighbouring
elements, so a sharp local loss is smeared and the bands around it are too
narrow.  Hypothesis h says "there is a loss with sharp edges on the zone
[a_h, b_h]": its prior is the GMRF without the difference terms that cross
the zone's two edges (the zone's level floats, held only by the proper
marginal part), a rank-r downdate Q_h = Q - U U^T of the prior precision.
For each component k of the posterior (a Laplace posterior N(theta_k, C_k)
at a node tau_k), the posterior under h of the model linearised at theta_k
is Gaussian with, by Woodbury and one exact Newton step,

    C_h = C_k + C_k U (I - U^T C_k U)^{-1} U^T C_k,
    theta_h = theta_k + C_h U U^T (theta_k - theta_0),

and its log evidence relative to component k is

    1/2 d^T U U^T d + 1/2 g^T C_h g + 1/2 log det(I - U^T Q_k^{-1} U)
    - 1/2 log det(I - U^T C_k U),     d = theta_k - theta_0, g = U U^T d.

The posterior averages the components: the undamaged ones with prior mass
1 - p and the zones with p / H each (p = ``prior_damage``, H zones), weighted
by their evidence.  No forward evaluation is needed.

Owns: damage hypotheses in the EI posterior.  May import: model, detection and the foundations.
"""

import numpy as np
import scipy.linalg

from ..model.prior import difference_operator

__all__ = ["damage_hypotheses"]


def _edge_rows(n_elements, order, edge):
    """Rows of the difference operator that couple elements on both sides of element edge ``edge``."""
    rows = np.arange(n_elements - order)
    return rows[(rows < edge) & (rows + order >= edge)]


def damage_hypotheses(weights, thetas, covariances, taus, theta0, *, prior, n_elements, edges, zones,
                      prior_damage=0.5, keep=0.999):
    """Extend a posterior mixture with damage hypotheses (see the module docstring).

    Parameters
    ----------
    weights, thetas, covariances, taus : the mixture's components (K,), (K, P), (K, P, P), (K,).
    theta0 : ndarray (P,)
        Prior mean (nominal log EI and log spring stiffnesses).
    prior : GMRFPrior
    n_elements : int
    edges : ndarray (n_elements + 1,)
        Element edges [m]; zones are snapped to them.
    zones : ndarray (H, 2)
        Candidate damaged zones [start, stop] [m].
    prior_damage : float
        Prior probability that some zone is damaged.
    keep : float
        Components are kept, largest weight first, up to this share of the total.

    Returns
    -------
    (weights, thetas, covariances, component_index, zone_index, damage_probability)
        The extended mixture (component_index: the undamaged component each new
        component comes from; zone_index: -1 for the undamaged ones) and the
        posterior probability of a damaged zone.
    """
    d_op = difference_operator(n_elements, prior.order).toarray()
    n_params = thetas.shape[1]
    snapped = {}
    for a, b in np.asarray(zones, dtype=float):
        i0, i1 = int(np.argmin(np.abs(edges - a))), int(np.argmin(np.abs(edges - b)))
        if i0 < i1 and not (i0 == 0 and i1 == n_elements):
            snapped.setdefault((i0, i1), len(snapped))
    zone_edges = list(snapped)
    n_zones = max(len(zone_edges), 1)
    log_w, new_thetas, new_covs, comp, zone = [], [], [], [], []
    for k in range(weights.size):
        theta_k, cov_k, tau_k = thetas[k], covariances[k], taus[k]
        q_k = prior.precision(n_elements, n_params - n_elements, tau=tau_k)
        q_chol = scipy.linalg.cho_factor(q_k)
        d = theta_k - theta0
        log_w.append(np.log(weights[k]) + np.log1p(-prior_damage))
        new_thetas.append(theta_k)
        new_covs.append(cov_k)
        comp.append(k)
        zone.append(-1)
        for h, (i0, i1) in enumerate(zone_edges):
            rows = np.unique(np.concatenate([_edge_rows(n_elements, prior.order, e) for e in (i0, i1)
                                             if 0 < e < n_elements]))
            if rows.size == 0:
                continue
            u = np.zeros((n_params, rows.size))
            u[:n_elements] = np.sqrt(tau_k) * d_op[rows].T
            cu = cov_k @ u
            inner = np.eye(rows.size) - u.T @ cu
            prior_inner = np.eye(rows.size) - u.T @ scipy.linalg.cho_solve(q_chol, u)
            try:
                inner_chol = np.linalg.cholesky(inner)
                prior_chol = np.linalg.cholesky(prior_inner)
            except np.linalg.LinAlgError:
                continue
            cov_h = cov_k + cu @ scipy.linalg.cho_solve((inner_chol, True), cu.T)
            g = u @ (u.T @ d)
            shift = cov_h @ g
            log_ratio = (0.5 * float(d @ g) + 0.5 * float(g @ shift) + float(np.sum(np.log(np.diag(prior_chol))))
                         - float(np.sum(np.log(np.diag(inner_chol)))))
            log_w.append(np.log(weights[k]) + np.log(prior_damage / n_zones) + log_ratio)
            new_thetas.append(theta_k + shift)
            new_covs.append(0.5 * (cov_h + cov_h.T))
            comp.append(k)
            zone.append(h)
    log_w = np.asarray(log_w)
    w = np.exp(log_w - log_w.max())
    w /= w.sum()
    zone = np.asarray(zone)
    damage_probability = float(w[zone >= 0].sum())
    order = np.argsort(-w)
    n_keep = int(np.searchsorted(np.cumsum(w[order]), keep) + 1)
    chosen = np.sort(order[:n_keep])
    w = w[chosen] / w[chosen].sum()
    return (w, np.asarray(new_thetas)[chosen], np.asarray(new_covs)[chosen], np.asarray(comp)[chosen],
            zone[chosen], damage_probability)
