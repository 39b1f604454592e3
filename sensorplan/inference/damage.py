"""EI bands that stay honest when a local loss is present: averaging over damage hypotheses.

The GMRF prior penalises every jump of log EI between neighbouring
elements, so a sharp local loss is smeared and the bands around it are too
narrow.  Hypothesis h says "there is a loss with sharp edges on the zone
[a_h, b_h]": its prior is the GMRF without the difference terms that cross
the zone's two edges (the zone's level floats, held only by the proper
marginal part), a rank-r downdate Q_h = Q - U U^T of the prior precision.
For each component k of the posterior (a Laplace posterior N(theta_k, C_k)
at a node tau_k, noise scale alpha_k), with H_k = J^T J / alpha_k^2 + Q_k
rebuilt from the data information J^T J at the posterior mean (inverting
C_k instead loses accuracy when tau is large), the posterior under h of the
model linearised at theta_k is Gaussian with, by one exact Newton step,

    H_h = H_k - U U^T,   C_h = C_k + H_k^-1 U (I - U^T H_k^-1 U)^-1 U^T H_k^-1,
    theta_h = theta_k + H_h^-1 g,   g = U U^T d,   d = theta_k - theta_0,

and its log evidence relative to component k is

    1/2 d^T g + 1/2 g^T H_h^-1 g + 1/2 log det(I - U^T Q_k^-1 U)
    - 1/2 log det(I - U^T H_k^-1 U).

Zones with the same number of released rows are evaluated together (all
the small r x r matrices at once); covariances are built only for the
components that are kept.

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


def damage_hypotheses(weights, thetas, covariances, taus, noise_scales, theta0, information, *, prior, n_elements,
                      edges, zones, prior_damage=0.5, keep=0.999, max_components=300):
    """Extend a posterior mixture with damage hypotheses (see the module docstring).

    Parameters
    ----------
    weights, thetas, covariances, taus, noise_scales : the mixture's components (K,), (K, P), (K, P, P),
        (K,), (K,).
    theta0 : ndarray (P,)
        Prior mean (nominal log EI and log spring stiffnesses).
    information : ndarray (P, P)
        J^T J of the whitened data at the posterior mean (divided by alpha_k^2
        per component): the precisions are rebuilt as J^T J / alpha_k^2 + Q
        rather than inverted from C_k, which loses accuracy when tau is large.
    prior : GMRFPrior
    n_elements : int
    edges : ndarray (n_elements + 1,)
        Element edges [m]; zones are snapped to them.
    zones : ndarray (H, 2)
        Candidate damaged zones [start, stop] [m].
    prior_damage : float
        Prior probability that some zone is damaged.
    keep, max_components :
        Components are kept, largest weight first, up to this share of the
        total weight and at most this many.

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
    zone_rows = []
    for i0, i1 in zone_edges:
        rows = [_edge_rows(n_elements, prior.order, e) for e in (i0, i1) if 0 < e < n_elements]
        zone_rows.append(np.unique(np.concatenate(rows)) if rows else np.zeros(0, int))
    by_size = {}
    for h, rows in enumerate(zone_rows):
        if rows.size:
            by_size.setdefault(rows.size, []).append(h)
    groups = [(np.array([zone_rows[h] for h in ids]), np.array(ids)) for ids in by_size.values()]
    d_pad = np.zeros((d_op.shape[0], n_params))
    d_pad[:, :n_elements] = d_op
    candidates = []  # (log weight, k, h)
    nodes = {}  # k -> (tau, H^-1 D^T, D H^-1 D^T, D d)
    for k in range(weights.size):
        candidates.append((np.log(weights[k]) + np.log1p(-prior_damage), k, -1))
        if weights[k] < 1e-8:
            continue
        tau_k = taus[k]
        q_k = prior.precision(n_elements, n_params - n_elements, tau=tau_k)
        h_factor = scipy.linalg.cho_factor(information / noise_scales[k] ** 2 + q_k)
        x_h = scipy.linalg.cho_solve(h_factor, d_pad.T)
        g_h = d_pad @ x_h
        g_q = d_pad @ scipy.linalg.cho_solve(scipy.linalg.cho_factor(q_k), d_pad.T)
        dd = d_pad @ (thetas[k] - theta0)
        nodes[k] = (tau_k, x_h, g_h, dd)
        for rows_group, zone_ids in groups:
            # all zones with the same number r of released rows at once: (Z, r) row indices
            ghr = g_h[rows_group[:, :, None], rows_group[:, None, :]]
            ddr = dd[rows_group]
            eye = np.eye(rows_group.shape[1])
            sign_h, logdet_mh = np.linalg.slogdet(eye - tau_k * ghr)
            sign_q, logdet_mq = np.linalg.slogdet(eye - tau_k * g_q[rows_group[:, :, None], rows_group[:, None, :]])
            b = np.einsum("zij,zj->zi", ghr, ddr)
            ok = (sign_h > 0) & (sign_q > 0)
            m_b = np.linalg.solve(np.where(ok[:, None, None], eye - tau_k * ghr, eye), b[..., None])[..., 0]
            # g = tau D_R^T D_R d:  d^T g, g^T H_h^-1 g (Woodbury on the well-conditioned H_k)
            d_g = tau_k * np.einsum("zi,zi->z", ddr, ddr)
            g_ch_g = tau_k**2 * np.einsum("zi,zi->z", ddr, b) + tau_k**3 * np.einsum("zi,zi->z", b, m_b)
            log_ratio = 0.5 * d_g + 0.5 * g_ch_g + 0.5 * logdet_mq - 0.5 * logdet_mh
            base = np.log(weights[k]) + np.log(prior_damage / n_zones)
            for h, lr in zip(zone_ids[ok], log_ratio[ok]):
                candidates.append((base + float(lr), k, int(h)))
    log_w = np.array([c[0] for c in candidates])
    w = np.exp(log_w - log_w.max())
    w /= w.sum()
    damage_probability = float(sum(wi for wi, c in zip(w, candidates) if c[2] >= 0))
    order = np.argsort(-w)
    n_keep = min(int(np.searchsorted(np.cumsum(w[order]), keep) + 1), max_components)
    chosen = np.sort(order[:n_keep])
    new_thetas, new_covs = [], []
    for i in chosen:
        _, k, h = candidates[i]
        if h < 0:
            new_thetas.append(thetas[k])
            new_covs.append(covariances[k])
            continue
        tau_k, x_h, g_h, dd = nodes[k]
        rows = zone_rows[h]
        x_r = x_h[:, rows]
        m_inv = np.linalg.inv(np.eye(rows.size) - tau_k * g_h[np.ix_(rows, rows)])
        h_inv_g = tau_k * x_r @ dd[rows]  # H_k^-1 g
        shift = h_inv_g + tau_k * x_r @ (m_inv @ (x_r.T @ (tau_k * d_pad[rows].T @ dd[rows])))
        cov_h = covariances[k] + tau_k * x_r @ m_inv @ x_r.T
        new_thetas.append(thetas[k] + shift)
        new_covs.append(0.5 * (cov_h + cov_h.T))
    w = w[chosen] / w[chosen].sum()
    comp = np.array([candidates[i][1] for i in chosen])
    zone = np.array([candidates[i][2] for i in chosen])
    return w, np.asarray(new_thetas), np.asarray(new_covs), comp, zone, damage_probability

