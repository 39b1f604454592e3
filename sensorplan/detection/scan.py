"""A damage detector with a controlled false-alarm rate: a scan over local losses.

Null hypothesis: the undamaged bridge under the nuisance (by default a
smooth within-span variation log EI = log EI_nominal + a + b x + c x^2 per
span, and the log stiffness of every elastic spring), fitted to the data by
Gauss-Newton (:class:`sensorplan.inference.detector.NullProblem`, which
passes the fit to :func:`scan_null_fit`).  Alternatives: a loss of relative compliance r > 0 over a zone
[c - l/2, c + l/2] for centres c and lengths l scanned over the bridge
(several lengths).  For each zone h the one-sided score

    z_h = u_h^T e / (alpha ||u_h||),

with e the whitened residual of the null fit, u_h the whitened compliance
signature of the zone projected off the nuisance columns (all at the null
fit) and alpha the noise scale of the null fit, is the locally most powerful
test of that zone; the scan statistic is max_h z_h.  Under the null, z is
Gaussian with the correlation of the projected signatures (exactly so for
the model linearised at the null fit), so the threshold for a false-alarm
rate q is the (1 - q) quantile of the maximum of that Gaussian vector,
computed by simulation with an explicit rng.  The noise scale alpha is
estimated from the nu = N - rank(J) residual degrees of freedom of the null
fit (floored at half the configured noise), so the simulation draws it too:
alpha^2 = (||g||^2 + chi^2_(nu - r)) / nu with g the r normals that make up
the scores; the threshold is then exact for the linearised model however
few readings there are (a t-like maximum, not a Gaussian one).

Testable zones.  A zone can be tested only when its compliance signature
is not in the span of the nuisance columns (its projected norm is at least
:data:`TESTABLE_RATIO` of its raw norm) and the fit leaves residual degrees
of freedom.  A few static readings under the full nuisance often leave no
such zone; the result then says so (:attr:`DamageDetection.testable` false,
no statistic) instead of testing nothing.

When the statistic exceeds the threshold, the zone, its length and the loss
are estimated by Bayesian model averaging over the zones, with proper priors
on everything that is averaged: every scanned length has the same prior
mass, spread evenly over its centres (so that short zones, which are more
numerous, are not favoured), and the lost fraction s = r / (1 + r) is
uniform on (0, ``max_loss``).  In the model linearised at the null fit the
likelihood of r in zone h is exp(b_h r - a_h r^2 / 2) with
b_h = u_h^T e / alpha^2 and a_h = ||u_h||^2 / alpha^2; it is integrated
over s on a fine grid, which gives each zone's marginal likelihood and its
posterior of s.  A shorter, deeper loss often explains the data as well as
the true one (only about r times the length is well determined), so the
95 % interval of s is taken from the mixture over all zones and lengths
(its 2.5 and 97.5 % quantiles), which carries that ambiguity.

Owns: the scan of a fitted null model, the threshold, the estimates (the result:
:class:`~.results.DamageDetection`).
May import: model and the foundations.
"""

import functools
import math

import numpy as np

from .._errors import ConfigError
from .results import DamageDetection

__all__ = ["DamageDetection", "scan_lengths", "zone_lengths", "check_scan_options", "scan_null_fit",
           "TESTABLE_RATIO"]

_MIN_LENGTH = 0.5  # m, shortest zone scanned
#: a zone is testable when its signature, projected off the nuisance, keeps at least this share of its norm
#: (far above the round-off of the projection, ~1e-8; below it the loss is indistinguishable from the nuisance)
TESTABLE_RATIO = 1e-6
_NOISE_FLOOR = 0.5  # the estimated noise scale is floored at half the configured noise


def scan_lengths(bridge, mesh):
    """Zone lengths scanned: from max(0.5 m, shortest element), growing by sqrt(2), up to a third of the shortest span."""
    spans = np.diff(bridge.support_positions)
    first = max(_MIN_LENGTH, float(np.min(mesh.lengths)))
    out = [first]
    while out[-1] * math.sqrt(2.0) <= spans.min() / 3 + 1e-9:
        out.append(out[-1] * math.sqrt(2.0))
    return tuple(out)


def _zones(bridge, mesh, lengths, per_length=4):
    """Zones [a, b] inside the bridge: centres every 1/per_length of a length (scan: at least half an element apart)."""
    total = bridge.length
    zones = []
    for length in lengths:
        step = length / per_length if per_length > 4 else max(length / 4, float(np.min(mesh.lengths)) / 2)
        n = max(1, int(math.floor((total - length) / step + 1e-9)) + 1)
        centres = length / 2 + (total - length) * (np.arange(n) / max(n - 1, 1) if n > 1 else np.array([0.5]))
        zones += [(c - length / 2, c + length / 2) for c in centres]
    return np.array(zones)


def _estimate_zones(bridge, mesh, lengths):
    """The finer family of zones of the estimates: lengths growing by 2^(1/4) over the scanned range, centres l/8 apart."""
    lo, hi = min(lengths), max(lengths)
    n = int(math.floor(4 * math.log2(hi / lo) + 1e-9)) + 1
    return _zones(bridge, mesh, lo * 2.0 ** (np.arange(n) / 4), per_length=8)


def _overlap(mesh, zones):
    """Fraction of each element inside each zone, shape (H, n_elements)."""
    lo = np.maximum(zones[:, :1], mesh.edges[None, :-1])
    hi = np.minimum(zones[:, 1:], mesh.edges[None, 1:])
    return np.clip(hi - lo, 0.0, None) / mesh.lengths[None, :]


def check_scan_options(*, false_alarm, max_loss):
    """Refuse a false-alarm rate outside (0, 0.5) or a largest loss outside (0, 1]."""
    if not 0.0 < max_loss <= 1.0:
        raise ConfigError(f"The 'max_loss' parameter must be in (0, 1]. Got {max_loss!r} instead.")
    if not 0.0 < false_alarm < 0.5:
        raise ConfigError(f"The 'false_alarm' rate must be in (0, 0.5). Got {false_alarm!r} instead.")


def zone_lengths(case, lengths=None):
    """The zone lengths scanned: ``lengths`` checked to lie inside the bridge, or :func:`scan_lengths`."""
    lengths = scan_lengths(case.bridge, case.mesh) if lengths is None else tuple(float(x) for x in lengths)
    if any(not 0.0 < x < case.bridge.length for x in lengths):
        raise ConfigError(f"Zone lengths must be in (0, {case.bridge.length:g}) m. Got {lengths!r}.")
    return lengths


def scan_null_fit(case, residual, jacobian, compliance, *, false_alarm, nuisance, lengths, n_null, rng, max_loss):
    """The scan test on a fitted null model (see the module docstring); returns a :class:`DamageDetection`.

    ``residual`` (N,), ``jacobian`` (N, P) and ``compliance`` (N, n_elements):
    the whitened residual, nuisance columns and compliance columns at the
    null fit; ``rng`` a Generator.
    """
    basis = _column_basis(jacobian)
    dof = residual.size - basis.shape[1]
    # noise scale of the null fit from its residual degrees of freedom; floored at half the configured
    # noise so that noise-free (simulated) data give finite scores (a larger alpha lowers them)
    alpha = max(math.sqrt(float(residual @ residual) / max(dof, 1)), _NOISE_FLOOR)
    # Everything the scan needs lives in the element space: with C_p = (I - P) C the whitened compliance
    # columns projected off the nuisance (P the projector onto its columns), K = C_p^T C_p and
    # c = C_p^T e, a zone with element fractions o has ||u||^2 = o^T K o and u^T e = o^T c.
    projected = compliance - basis @ (basis.T @ compliance)
    gram, raw_gram = projected.T @ projected, compliance.T @ compliance
    c_res = projected.T @ residual
    all_zones = _zones(case.bridge, case.mesh, lengths)
    zones, norms, proj, untestable = _signatures(case.mesh, all_zones, gram, raw_gram, c_res, dof)
    common = dict(nuisance=nuisance, noise_scale=float(alpha), untestable=untestable, dof=int(dof),
                  n_nuisance=int(jacobian.shape[1]))
    if not zones.size:
        empty = np.zeros((0, 2))
        return DamageDetection(False, float(false_alarm), math.nan, math.nan, math.nan, None, None, None, None,
                               None, empty, np.zeros(0), (np.zeros(0), empty), **common)
    scores = proj / (alpha * norms)
    statistic = float(scores.max())
    threshold, p_value = _calibration(_NullMaxima(_overlap(case.mesh, zones) / norms[:, None], gram, n_null, rng,
                                                  dof=dof), 1.0 - false_alarm, statistic)
    detected = statistic > threshold
    estimates = (None,) * 5
    if detected:
        estimates = _fine_estimates(case, lengths, gram, raw_gram, c_res, dof, alpha, max_loss)
    return DamageDetection(bool(detected), float(false_alarm), statistic, threshold, p_value, *estimates,
                           zones, scores, functools.partial(_zone_moments, proj, norms, alpha, zones, max_loss),
                           **common)


def _zone_moments(proj, norms, alpha, zones, max_loss):
    """The zones' posterior weights and the posterior mean and std of the lost fraction in each, (H,), (H, 2)."""
    weights, grid, density = _zone_posteriors(proj, norms, alpha, zones, max_loss)
    mean = density @ grid
    return weights, np.column_stack([mean, np.sqrt(np.clip(density @ grid**2 - mean**2, 0, None))])


def _column_basis(jacobian, rtol=1e-10):
    """Orthonormal basis (N, rank) of the span of the nuisance columns (rank-revealing: an SVD, not a QR).

    Columns the data cannot tell apart (more nuisance parameters than informative readings, an
    unobservable spring) give a rank below P; a QR would then add arbitrary directions and project
    off part of the data's own space.
    """
    if jacobian.shape[1] == 0:
        return np.zeros((jacobian.shape[0], 0))
    u, s, _ = np.linalg.svd(jacobian, full_matrices=False)
    rank = int(np.sum(s > rtol * max(float(s[0]), 1e-300) * max(jacobian.shape))) if s.size else 0
    return u[:, :rank]


def _fine_estimates(case, lengths, gram, raw_gram, c_res, dof, alpha, max_loss):
    """Centre, length, centre interval, loss and loss interval on the finer family of zones (edges off the grid)."""
    fine, n_fine, p_fine, _ = _signatures(case.mesh, _estimate_zones(case.bridge, case.mesh, lengths), gram,
                                          raw_gram, c_res, dof)
    log_prior = _log_prior(fine)
    keep = _plausible(p_fine, n_fine, alpha, log_prior, max_loss)  # the rest carry < e^-40 of the weight
    return _estimates(fine[keep], *_zone_posteriors(p_fine[keep], n_fine[keep], alpha, fine[keep], max_loss,
                                                     log_prior[keep]),
                      half=float(np.min(fine[:, 1] - fine[:, 0])))


def _signatures(mesh, zones, gram, raw_gram, c_res, dof):
    """The testable zones, their projected norms ||u_h||, the projections u_h^T e, and the untestable zones.

    A zone is testable when the fit leaves residual degrees of freedom and its projected signature keeps
    at least :data:`TESTABLE_RATIO` of its raw norm.
    """
    overlap = _overlap(mesh, zones)
    norms = np.sqrt(np.clip(np.einsum("he,ef,hf->h", overlap, gram, overlap), 0.0, None))
    raw = np.sqrt(np.clip(np.einsum("he,ef,hf->h", overlap, raw_gram, overlap), 0.0, None))
    keep = (norms > TESTABLE_RATIO * raw) & (raw > 0.0) & (dof > 0)
    return zones[keep], norms[keep], overlap[keep] @ c_res, zones[~keep]


class _NullMaxima:
    """Null draws of max_h z_h with z = W C_p^T e / alpha, e ~ N(0, I), alpha estimated as the data's is.

    W C_p^T e ~ N(0, W K W^T) is drawn through a factor of K from r normals g; the residual's other
    dof - r directions add a chi^2 to ||g||^2 in the estimated scale alpha^2 (floored as in the scan).
    The normals are drawn first, in the same order as without the scale, then the chi^2 terms.

    The maxima are computed in single precision with a bound on their error (:attr:`low`,
    :attr:`high`); :meth:`exact` gives the double-precision maxima of the draws a calibration needs
    (the few near the quantile or the statistic), so that the threshold and p-value are those of the
    maxima of all draws in double precision at about half the cost of the products.
    """

    def __init__(self, weights, gram, n, rng, *, dof, chunk=2000):
        vals, vecs = np.linalg.eigh(0.5 * (gram + gram.T))
        keep = vals > 1e-12 * max(float(vals.max()), 1e-300)
        self.factor = weights @ (vecs[:, keep] * np.sqrt(vals[keep]))
        factor32 = self.factor.astype(np.float32)  # (H, r): the maxima reduce over rows, contiguous ones
        r = self.factor.shape[1]
        self.normals = np.empty((int(n), r))
        approx = np.empty(int(n))
        square = np.empty(int(n))
        for start in range(0, approx.size, chunk):
            k = min(chunk, approx.size - start)
            g = self.normals[start:start + k] = rng.standard_normal((k, r))
            approx[start:start + k] = (factor32 @ g.T.astype(np.float32)).max(axis=0)
            square[start:start + k] = np.einsum("ij,ij->i", g, g)
        # |z_h - fl32(z_h)| <= (r + 2) u sum_i |g_i f_hi| <= (r + 2) u ||g|| ||f_h|| (rounding g and f to single
        # precision, then r products and sums; u = 2^-24), doubled for the rounding of the bound itself
        error = 2.0 * (r + 2) * 2.0**-24 * float(np.sqrt(np.einsum("hi,hi->h", self.factor, self.factor)).max(
            initial=0.0)) * np.sqrt(square) + 1e-300
        rest = max(int(dof) - r, 0)
        if rest:
            square += rng.chisquare(rest, size=approx.size)
        self.alpha = np.maximum(np.sqrt(square / max(int(dof), 1)), _NOISE_FLOOR)
        self.low, self.high = (approx - error) / self.alpha, (approx + error) / self.alpha

    def exact(self, rows):
        """The double-precision maxima of the draws ``rows``."""
        return (self.normals[rows] @ self.factor.T).max(axis=1) / self.alpha[rows]


def _calibration(null, level, statistic):
    """The ``level`` quantile of the null maxima (numpy's linear interpolation) and the p-value of ``statistic``.

    Only draws whose error interval does not settle their side are computed in double precision: a draw
    entirely below the lower bound of order statistic j (or above the upper bound of j + 1) is below
    (above) both order statistics that the quantile interpolates.
    """
    low, high, n = null.low, null.high, null.low.size
    j = int(math.floor(level * (n - 1)))
    k = min(j + 1, n - 1)
    below = high < np.partition(low, j)[j]
    above = low > np.partition(high, k)[k]
    rows = np.flatnonzero(~(below | above))
    exact = null.exact(rows)
    n_below = int(below.sum())
    lo, hi = float(exact.min()), float(exact.max())  # stand-ins of the settled draws keep every order statistic
    threshold = float(np.quantile(np.concatenate([np.full(n_below, lo), exact, np.full(n - n_below - rows.size, hi)]),
                                  level))
    open_rows = np.flatnonzero((high >= statistic) & (low < statistic))
    count = int(np.sum(low >= statistic)) + int(np.sum(null.exact(open_rows) >= statistic))
    return threshold, float((1 + count) / (1 + n))


_N_GRID = 2000  # midpoints of the grid over the lost fraction


def _log_prior(zones):
    """log prior mass of each zone up to a constant: equal mass per length, even over its centres."""
    lengths = np.round(zones[:, 1] - zones[:, 0], 9)
    _, group, counts = np.unique(lengths, return_inverse=True, return_counts=True)
    return -np.log(counts[group])


def _zone_posteriors(proj, norms, alpha, zones, max_loss, log_prior=None):
    """Posterior zone weights and, per zone, the posterior of the lost fraction on a grid (see the docstring).

    ``log_prior`` (default :func:`_log_prior` of ``zones``) is given when ``zones`` is a subset of a family.

    Returns (weights (H,), grid (G,), density (H, G)); each row of density sums to 1.
    """
    grid, r = _loss_grid(max_loss)
    log_like = (proj / alpha**2)[:, None] * r[None] - 0.5 * (norms**2 / alpha**2)[:, None] * r[None] ** 2
    peak = log_like.max(axis=1)
    density = np.exp(log_like - peak[:, None])
    total = density.sum(axis=1)
    density /= total[:, None]
    log_evidence = peak + np.log(total)  # uniform prior: the grid's mean, up to a constant
    log_post = log_evidence + (_log_prior(zones) if log_prior is None else log_prior)
    weights = np.exp(log_post - log_post.max())
    return weights / weights.sum(), grid, density


def _plausible(proj, norms, alpha, log_prior, max_loss, margin=40.0):
    """Zones whose posterior weight can be within e^-margin of the largest (a bound, not an estimate).

    A zone's evidence (the grid mean of its likelihood) is at most the likelihood's maximum over the
    grid's range of r = f / (1 - f), which is closed-form; a zone whose maximum is ``margin`` below
    the exact evidence of the zone with the largest maximum cannot matter.
    """
    _, r = _loss_grid(max_loss)
    a, b = proj / alpha**2, norms**2 / alpha**2
    r_star = np.clip(a / b, r[0], r[-1])
    bound = a * r_star - 0.5 * b * r_star**2 + log_prior
    best = int(np.argmax(bound))
    log_like = a[best] * r - 0.5 * b[best] * r**2
    exact = float(log_like.max() + np.log(np.mean(np.exp(log_like - log_like.max()))) + log_prior[best])
    return bound >= exact - margin


def _loss_grid(max_loss):
    """Midpoints of the grid over the lost fraction f in (0, max_loss) and r = f / (1 - f) there."""
    grid = max_loss * (np.arange(_N_GRID) + 0.5) / _N_GRID
    return grid, grid / (1.0 - grid)


def _estimates(zones, weights, grid, density, half=None):
    """Centre (most probable window) and its 95 % interval, most probable length, loss (median) and its 95 % interval.

    ``half``: half-width of the centre's window (default the shortest zone length).
    """
    spans = np.round(zones[:, 1] - zones[:, 0], 9)
    by_length = {x: float(weights[spans == x].sum()) for x in np.unique(spans)}
    length = float(max(by_length, key=by_length.get))
    centres = zones.mean(axis=1)
    order = np.argsort(centres)
    cdf = np.cumsum(weights[order])
    lo, hi = (float(centres[order][min(np.searchsorted(cdf, p), cdf.size - 1)]) for p in (0.025, 0.975))
    # the centre: the most probable window of +- the shortest length (a median can fall between two modes)
    sorted_centres, half = centres[order], float(spans.min() if half is None else half)
    mass = (np.interp(sorted_centres + half, sorted_centres, cdf, right=1.0)
            - np.interp(sorted_centres - half, sorted_centres, cdf, left=0.0))
    window = np.abs(sorted_centres - sorted_centres[int(np.argmax(mass))]) <= half
    centre = float(np.average(sorted_centres[window], weights=weights[order][window] + 1e-300))
    loss_cdf = np.cumsum(weights @ density)
    loss_lo, loss, loss_hi = (_grid_quantile(grid, loss_cdf, p) for p in (0.025, 0.5, 0.975))
    return centre, length, (lo, hi), loss, (loss_lo, loss_hi)


def _grid_quantile(grid, cdf, p):
    """Quantile p of the distribution with mass cdf[i] - cdf[i - 1] in the grid cell around grid[i] (even cells)."""
    half = 0.5 * (grid[1] - grid[0])
    return float(np.interp(p * cdf[-1], np.concatenate([[0.0], cdf]), np.concatenate([[grid[0] - half], grid + half])))
