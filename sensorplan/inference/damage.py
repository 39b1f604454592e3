"""EI bands that stay honest when a local loss is present: averaging over damage hypotheses.

The GMRF prior penalises every jump of log EI between neighbouring
elements, so a sharp local loss is smeared and the bands around it are too
narrow.  Hypothesis h says "on top of the smooth field there is a loss over
the zone [a_h, b_h]": log EI = eta + s v_h, with eta the GMRF field, v_h the
fraction of each element inside the zone (not snapped to the mesh) and a
step s <= 0 of log EI whose size has a proper prior, half-normal with std
``loss_log_std`` (a loss of 1 - exp(-0.5) = 39 % at one std).  Because the
step's size has a proper prior, a hypothesis pays an Occam factor: a zone
whose step the data determine to within sigma_post while finding none keeps
about sigma_post / loss_log_std of its prior mass, and a zone where the data
point to an increase of EI keeps even less (the one-sided prior).

For each component k of the posterior (a Laplace posterior N(theta_k, C_k)
at a node tau_k, noise scale alpha_k), with A = J^T J / alpha_k^2 the data
information at the posterior mean, H_k = A + Q_k and w = Q_k v, the model
linearised at theta_k gives exactly (s and the field integrated jointly):

    theta | s ~ N(theta_k + s x, H_k^-1),   x = H_k^-1 w,
    s ~ N(m_s, 1 / p_s) before truncation,  p_s = 1 / sigma^2 + x^T A v,  m_s = w^T d / p_s,

with d = theta_k - theta_0 (x^T A v = v^T (Q - Q H^-1 Q) v, written without
the cancellation), and the Bayes factor of h against component k

    B = sqrt(sigma^-2 / p_s) exp(m_s^2 p_s / 2) * 2 Phi(-m_s sqrt(p_s)).

The component of h is the moment-matched Gaussian of theta: mean
theta_k + E[s] x, covariance C_k + Var[s] x x^T, with the moments of the
truncated normal of s.  All zones of a component are evaluated at once (one
solve with H_k for all zones); no forward evaluation is needed.

The posterior averages the components: the undamaged ones with prior mass
1 - p and the zones with p / H each (p = ``prior_damage``, H zones), weighted
by their evidence.  A zone whose step the data determine no better than
``min_information`` times the prior does (p_s < min_information / sigma^2)
adds nothing the smooth posterior does not already allow there (its bands
are the prior's), so its prior mass stays with the undamaged component and
``damage_probability`` counts only the zones the data see.

Owns: damage hypotheses in the EI posterior.  May import: model, detection and the foundations.
"""

import numpy as np
import scipy.linalg
from scipy import special

__all__ = ["damage_hypotheses", "zone_fractions"]

_LOG2 = float(np.log(2.0))


def zone_fractions(edges, zones):
    """Fraction of each element inside each zone, shape (H, n_elements)."""
    edges = np.asarray(edges, dtype=float)
    zones = np.atleast_2d(np.asarray(zones, dtype=float))
    lo = np.maximum(zones[:, :1], edges[None, :-1])
    hi = np.minimum(zones[:, 1:], edges[None, 1:])
    return np.clip(hi - lo, 0.0, None) / np.diff(edges)[None, :]


def _truncated_moments(mean, precision):
    """Mean and variance of N(mean, 1 / precision) truncated to s <= 0, and log P(s <= 0)."""
    sd = 1.0 / np.sqrt(precision)
    beta = -mean / sd  # standardised upper bound
    log_mass = special.log_ndtr(beta)
    ratio = np.exp(-0.5 * beta**2 - 0.5 * np.log(2.0 * np.pi) - log_mass)  # phi(beta) / Phi(beta)
    e_s = mean - sd * ratio
    var = sd**2 * np.clip(1.0 - beta * ratio - ratio**2, 0.0, None)
    return e_s, var, log_mass


def step_evidence(information, q_k, theta_k, theta0, fractions, loss_log_std, min_information=2.0):
    """Log Bayes factor of a step in each zone against component k, and the step's posterior.

    Parameters
    ----------
    information : ndarray (P, P)
        A = J^T J / alpha_k^2.
    q_k : ndarray (P, P)
        Prior precision at the component's tau.
    theta_k, theta0 : ndarray (P,)
    fractions : ndarray (H, P)
        v_h (zeros on the spring parameters).
    loss_log_std : float
        sigma of the half-normal prior of -s.

    Returns
    -------
    (log_bf, x, e_s, var_s) with shapes (H,), (P, H), (H,), (H,).
    """
    v = fractions.T
    w = q_k @ v
    x = scipy.linalg.cho_solve(scipy.linalg.cho_factor(information + q_k), w)
    prec_prior = 1.0 / loss_log_std**2
    p_s = prec_prior + np.clip(np.einsum("ph,ph->h", x, information @ v), 0.0, None)
    m_s = (w.T @ (theta_k - theta0)) / p_s
    e_s, var_s, log_mass = _truncated_moments(m_s, p_s)
    log_bf = 0.5 * np.log(prec_prior / p_s) + 0.5 * m_s**2 * p_s + _LOG2 + log_mass
    return log_bf, x, e_s, var_s, p_s >= min_information * prec_prior


def damage_hypotheses(weights, thetas, covariances, taus, noise_scales, theta0, information, *, prior, n_elements,
                      edges, zones, prior_damage=0.5, loss_log_std=0.5, min_information=2.0, keep=0.999,
                      max_components=300):
    """Extend a posterior mixture with damage hypotheses (see the module docstring).

    Parameters
    ----------
    weights, thetas, covariances, taus, noise_scales : the mixture's components (K,), (K, P), (K, P, P),
        (K,), (K,).
    theta0 : ndarray (P,)
        Prior mean (nominal log EI and log spring stiffnesses).
    information : ndarray (P, P)
        J^T J of the whitened data at the posterior mean (divided by alpha_k^2 per component): the
        precisions are rebuilt as J^T J / alpha_k^2 + Q rather than inverted from C_k, which loses
        accuracy when tau is large.
    prior : GMRFPrior
    n_elements : int
    edges : ndarray (n_elements + 1,)
        Element edges [m].
    zones : ndarray (H, 2)
        Candidate damaged zones [start, stop] [m].
    prior_damage : float
        Prior probability that some zone is damaged.
    loss_log_std : float
        Std of the half-normal prior of the loss's step in log EI.
    min_information : float
        A zone enters when the data make the precision of its step at least this multiple of the prior's.
    keep, max_components :
        Components are kept, largest weight first, up to this share of the total weight and at most this many.

    Returns
    -------
    (weights, thetas, covariances, component_index, zone_index, damage_probability)
        The extended mixture (component_index: the undamaged component each new component comes from;
        zone_index: -1 for the undamaged ones) and the posterior probability of a damaged zone.
    """
    n_params = thetas.shape[1]
    fractions = np.zeros((len(zones), n_params))
    fractions[:, :n_elements] = zone_fractions(edges, zones)
    fractions = fractions[fractions[:, :n_elements].sum(axis=1) > 0]
    log_w, comp, zone, steps = _hypotheses(weights, thetas, taus, noise_scales, theta0, information, prior=prior,
                                           n_elements=n_elements, fractions=fractions, prior_damage=prior_damage,
                                           loss_log_std=loss_log_std, min_information=min_information)
    w = np.exp(log_w - log_w.max())
    w /= w.sum()
    damage_probability = float(w[zone >= 0].sum())
    order = np.argsort(-w)
    n_keep = min(int(np.searchsorted(np.cumsum(w[order]), keep) + 1), max_components)
    chosen = np.sort(order[:n_keep])
    new_thetas, new_covs = _moment_matched(chosen, comp, zone, thetas, covariances, steps)
    w = w[chosen] / w[chosen].sum()
    return w, new_thetas, new_covs, comp[chosen], zone[chosen], damage_probability


def _hypotheses(weights, thetas, taus, noise_scales, theta0, information, *, prior, n_elements, fractions,
                prior_damage, loss_log_std, min_information):
    """Log weights, source component and zone (-1: undamaged) of every hypothesis, and each component's steps."""
    n_params = thetas.shape[1]
    n_zones = max(fractions.shape[0], 1)
    log_w, comp, zone, steps = [], [], [], {}
    roughness = np.zeros((n_params, n_params))
    roughness[:n_elements, :n_elements] = prior.structure(n_elements)
    fixed = prior.precision(n_elements, n_params - n_elements, tau=0.0)
    for k in range(weights.size):
        log_w.append(np.log(weights[k]) + np.log1p(-prior_damage))
        comp.append(k)
        zone.append(-1)
        if weights[k] < 1e-8 or not fractions.shape[0]:
            continue
        q_k = taus[k] * roughness + fixed  # prior.precision at tau_k
        log_bf, x, e_s, var_s, visible = step_evidence(information / noise_scales[k] ** 2, q_k, thetas[k], theta0,
                                                       fractions, loss_log_std, min_information)
        steps[k] = (x, e_s, var_s)
        seen = np.flatnonzero(visible)
        # zones the data do not see keep their prior mass in the undamaged component (see the docstring)
        log_w[-1] = np.logaddexp(log_w[-1], np.log(weights[k]) + np.log(prior_damage / n_zones)
                                 + np.log(max(n_zones - seen.size, 0)) if seen.size < n_zones else -np.inf)
        log_w.extend(np.log(weights[k]) + np.log(prior_damage / n_zones) + log_bf[seen])
        comp.extend([k] * seen.size)
        zone.extend(seen)
    return np.asarray(log_w), np.asarray(comp), np.asarray(zone), steps


def _moment_matched(chosen, comp, zone, thetas, covariances, steps):
    """Means and covariances of the ``chosen`` hypotheses (a damaged one: moment-matched over its step)."""
    k, h = comp[chosen], zone[chosen]
    new_thetas, new_covs = thetas[k], covariances[k]  # copies (fancy indexing); the undamaged ones stay as they are
    for source in np.unique(k[h >= 0]):  # the damaged ones, by the component they come from
        rows = np.flatnonzero((k == source) & (h >= 0))
        x, e_s, var_s = steps[source]
        step = x[:, h[rows]].T  # (n, P)
        new_thetas[rows] = thetas[source] + e_s[h[rows]][:, None] * step
        new_covs[rows] = covariances[source] + var_s[h[rows]][:, None, None] * (step[:, :, None] * step[:, None, :])
    return new_thetas, new_covs
