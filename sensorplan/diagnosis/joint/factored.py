"""The log-EI block of binned crossings kept as a product of two factors, and its normal equations.

The log-EI columns of a binned crossing are R T: R its interpolation
weights mapped onto its bins (bins x table rows, sparse), T the line
interpolant's element kernel of the table rows (table rows x sensors x
elements), each sensor's rows times a scale.  Formed, they are the largest
array of an evaluation (bins x sensors x elements per crossing, formed,
scaled and copied at every evaluation with a Jacobian); their share of the normal
equations needs only R^T R, R^T r and R^T B (B the effects' columns), all
of the table's size.  :class:`~.problem.JointProblem` uses this whenever every
crossing is binned; the explicit blocks (:func:`.lines.log_ei_blocks`) remain
for the rows of the held-out folds.

Owns: the factored log-EI normal equations.  May import: the diagnosis's lines.
"""

import numpy as np

from ..._cache import value_key
from .lines import mapped_groups

__all__ = ["LogEIFactor", "add_factored_terms", "log_ei_factors"]


class LogEIFactor:
    """A binned crossing's dy/dlog EI on its bins, kept as the product of its two factors (never formed).

    ``mapped[rows]``: the crossing's interpolation weights mapped onto its
    bins (bins x table rows, sparse; a dense array under the noise model in
    time, whose bin maps are dense; ``mapped`` holds every crossing of one
    interpolant); ``table``: the interpolant's element kernel of the table
    rows times -1/EI, (table rows, S, E), shared by those crossings;
    ``scale`` (S,): the factor of each sensor (1 / the readings' noise std,
    times the gains and amplifications acting on the response).  The block
    is ``scale[s] * (mapped[rows] @ table[:, s, :])``; its share of J^T J
    is table_s^T (R^T R) table_s summed over the sensors with their squared
    scales: products of the table's size instead of bins x elements
    (:meth:`~.problem.JointProblem.evaluate`).  ``mapped_key``: the values
    ``mapped`` was built from (crossings with one key share it).
    """

    def __init__(self, mapped, rows, table, scale, *, mapped_key):
        self.mapped, self.rows, self.table, self.scale = mapped, rows, table, scale
        self.mapped_key = mapped_key


def log_ei_factors(items, cache):
    """:class:`LogEIFactor` of every (lines, load factor, binned) item, all binned (see :func:`.lines.log_ei_blocks`)."""
    out = [None] * len(items)
    for members, lines, mapped, offsets, key in mapped_groups(items, cache):
        interpolant = lines.interpolant
        table = (interpolant.kernel_table.reshape(-1, interpolant.n_sensors, interpolant.n_elements)
                 * (-1.0 / lines.ei))
        for j, k in enumerate(members):
            out[k] = LogEIFactor(mapped, slice(offsets[j], offsets[j + 1]), table, 1.0 / items[k][2].noise.std,
                                 mapped_key=key)
    return out


def add_factored_terms(terms, jtj, jtr, cache):
    """Add the log-EI rows and columns of J^T J and J^T r of the factored crossings ``terms``.

    With A = diag(scale) (R T) of a crossing (R its weights on the bins,
    T the table): A^T A = sum_s scale_s^2 T_s^T (R^T R) T_s, A^T r and
    A^T B through R^T [r | B] (B the effects' columns), all on the table
    rows.  The crossings of one interpolant share T, and when their
    scales factor into a crossing's times a sensor's (the noise std and
    gains per sensor, amplifications per crossing) R^T R of all of them is
    one weighted product (kept in ``cache``, a :class:`~sensorplan._cache.Cache`).
    """
    n_el = terms[0][0].table.shape[2]
    groups = {}
    for term in terms:
        groups.setdefault(term[0].mapped_key, []).append(term)
    for members in groups.values():
        mapped, table = members[0][0].mapped, members[0][0].table
        n_rows, n_sensors = table.shape[:2]
        dense = mapped if isinstance(mapped, np.ndarray) else mapped.toarray()
        scales = np.array([factor.scale for factor, *_ in members])  # (crossings, S)
        weights = np.zeros(mapped.shape[0])  # a crossing's squared factor on its fitted bins
        residuals = np.zeros((mapped.shape[0], n_sensors))  # scale x r, bin-major, zero off the fitted bins
        projected, places = [], []  # R^T (scale x B) per crossing, and its columns
        sensor = scales[0]
        factors = scales[:, 0] / sensor[0] if sensor[0] else np.zeros(len(members))
        rank_one = bool(np.all(np.abs(scales - np.outer(factors, sensor)) <= 1e-13 * np.abs(scales)))
        for (factor, m, r, jac, cols), scale, a in zip(members, scales, factors):
            at = factor.rows if m.all() else np.flatnonzero(m) + factor.rows.start
            weights[at] = a * a
            residuals[at] = r.reshape(n_sensors, -1).T * scale
            if cols.size:  # R^T B with B's rows taken bin-major, times each sensor's scale
                b = jac.transpose(1, 0, 2)
                b = (b if m.all() else b[m]).reshape(-1, n_sensors * cols.size)
                part = (dense[at].T @ b).reshape(n_rows, n_sensors, cols.size)
                projected.append(part * scale[None, :, None])
                places.append(cols)
        if projected:  # the cross terms of every crossing in one product: sum_s T_s^T (R^T B_s)
            cross = np.tensordot(table, np.concatenate(projected, axis=2), axes=([0, 1], [0, 1]))
            start = 0
            for cols in places:
                block = cross[:, start:start + cols.size]
                start += cols.size
                jtj[:n_el, cols] += block
                jtj[cols, :n_el] += block.T
        jtr[:n_el] += np.einsum("lse,ls->e", table, dense.T @ residuals)
        flat = table.reshape(n_rows, -1)  # (L, S E)
        if rank_one:  # sum_s sensor_s^2 T_s^T G T_s with one G: two products
            product = _weighted_gram(members[0][0], weights, cache) @ flat
            weighted = (table * (sensor**2)[None, :, None]).reshape(-1, n_el)
            jtj[:n_el, :n_el] += weighted.T @ product.reshape(-1, n_el)
        else:  # scales that do not factor: per sensor, every crossing's R^T R with its own weight
            grams = np.zeros((n_sensors, n_rows, n_rows))
            for (factor, m, *_), scale in zip(members, scales):
                rows = dense[factor.rows][m]
                grams += scale[:, None, None] ** 2 * (rows.T @ rows)[None]
            for s in range(n_sensors):
                jtj[:n_el, :n_el] += table[:, s, :].T @ (grams[s] @ table[:, s, :])


def _weighted_gram(factor, weights, cache):
    """R^T diag(weights) R of ``factor.mapped`` (a dense array), kept in ``cache`` under its key and ``weights``."""
    def gram():
        mapped = factor.mapped
        if isinstance(mapped, np.ndarray):  # dense maps (noise in time)
            scaled = mapped * np.sqrt(weights)[:, None]
            return scaled.T @ scaled
        scaled = mapped.copy()  # rows times sqrt(weights), in the sparse structure as it is
        scaled.data *= np.repeat(np.sqrt(weights), np.diff(mapped.indptr))
        return (scaled.T @ scaled).toarray()

    return cache.get((), gram, key=("gram", factor.mapped_key, value_key(weights)))
