"""Entry time, speed and load factor of one significant vehicle, refined off the scan's grid.

The scan gives the entry sample and grid speed of the largest whitened
matched-filter statistic; here the same statistic (the template sampled at
the record's times for any real ``t0`` and ``v``, whitened by the channel's
filter, the marginalised offset's share taken off its norm) is maximised
continuously by Nelder-Mead.  The load factor is then the whitened least-
squares one (non-negative), and the 95 % half-widths of ``t0`` and ``v`` come
from the Fisher information of (a, t0, v) in the whitened domain (central
differences), inflated by the residual rms when it exceeds one.
"""

from dataclasses import dataclass

import numpy as np

from .scan import TAIL_TOLERANCE

__all__ = ["VehicleEstimate", "refine"]

PRE = 2.0  # s of record before the grid entry the refinement may move the entry to
SLOWER = 0.9  # the window holds the vehicle at down to this fraction of the grid speed


@dataclass(frozen=True, eq=False, kw_only=True)
class VehicleEstimate:
    """A refined vehicle: see :class:`~.glr.Candidate` for the fields; ``whitened`` is a m on the window."""

    entry_time: float
    speed: float
    entry_ci95: float
    speed_ci95: float
    load_factor: float
    rms: float
    window: slice
    signal: np.ndarray
    whitened: np.ndarray


class _Column:
    """The whitened template on a window of the record for any (t0, v), and the statistic there."""

    def __init__(self, ctx, window):
        self.ctx = ctx
        self.time = ctx.time[window]
        self.r = ctx.r[:, window]
        self.u = ctx.ones[:, window]
        self.uu = np.sum(ctx.ones**2, axis=1)

    def raw(self, t0, v):
        return self.ctx.template.predict(v * (self.time - t0))

    def whitened(self, t0, v):
        """The template's whitened column, the offset's direction projected out."""
        m = np.stack([w.apply(row) for w, row in zip(self.ctx.whiteners, self.raw(t0, v))])
        share = np.where(self.uu > 0.0, np.sum(self.u * m, axis=1) / np.where(self.uu > 0.0, self.uu, 1.0), 0.0)
        return m - share[:, None] * self.u

    def z(self, t0, v):
        m = self.whitened(t0, v)
        norm = float(np.sqrt(np.sum(m**2)))
        return float(np.sum(self.r * m)) / norm if norm > 0.0 else 0.0


def _window(ctx, k, v0):
    dt = float(ctx.time[1] - ctx.time[0])
    tail = min(max(w.tail(TAIL_TOLERANCE) for w in ctx.whiteners), ctx.time.size)
    on = int(np.ceil(ctx.template.length / (SLOWER * v0 * dt)))
    return slice(max(0, k - int(PRE / dt)), min(ctx.time.size, k + on + tail))


def _maximise(column, t0, v0, ctx, fixed_entry):
    """(t0, v) maximising the statistic from the grid's (t0, v0); the known ones stay fixed."""
    from scipy.optimize import minimize

    dt = float(ctx.time[1] - ctx.time[0])
    free = np.array([fixed_entry is None, ctx.fixed_speed is None])
    if not free.any():
        return t0, v0
    lo, hi = ctx.speed_range

    def unpack(x):
        full = np.zeros(2)
        full[free] = x
        speed = v0 if not free[1] else float(np.clip(v0 * np.exp(0.01 * full[1]), lo, hi))
        return t0 + 0.1 * full[0], speed

    def cost(x):
        return -column.z(*unpack(x))

    x0 = np.zeros(int(free.sum()))
    steps = np.array([max(dt, 0.02) / 0.1, 2.0])[free]
    simplex = np.vstack([x0] + [x0 + step for step in np.diag(steps)])
    sol = minimize(cost, x0, method="Nelder-Mead", options=dict(initial_simplex=simplex, xatol=1e-3, fatol=1e-6,
                                                                  maxiter=400))
    best = sol.x if sol.fun <= cost(x0) else x0
    return unpack(best)


def _intervals(column, t0, v, a, rms, free):
    """95 % half-widths of t0 and v (0 when known) from the whitened Fisher information of (a, t0, v)."""
    h_t, h_v = 1e-3 * max(column.ctx.template.length / v, 1.0), 1e-4 * v
    cols = [column.whitened(t0, v).ravel()]
    if free[0]:
        cols.append(a * (column.whitened(t0 + h_t, v) - column.whitened(t0 - h_t, v)).ravel() / (2.0 * h_t))
    if free[1]:
        cols.append(a * (column.whitened(t0, v + h_v) - column.whitened(t0, v - h_v)).ravel() / (2.0 * h_v))
    jac = np.column_stack(cols)
    info = jac.T @ jac
    half = np.zeros(2)
    if a <= 0.0 or not np.all(np.isfinite(info)) or np.linalg.matrix_rank(info) < info.shape[0]:
        half[free] = np.inf
    else:
        half[free] = 1.96 * np.sqrt(np.clip(np.diag(np.linalg.inv(info)), 0.0, None))[1:] * max(1.0, rms)
    return float(half[0]), float(half[1])


def refine(ctx, k, v0, *, entry=None):
    """The :class:`VehicleEstimate` of the scan maximum at entry sample ``k`` and grid speed ``v0``.

    ``entry`` [s], when known (an axle detector), replaces the entry time and stays fixed.
    """
    if entry is not None:
        k = int(np.clip(np.searchsorted(ctx.time, entry), 0, ctx.time.size - 1))
    window = _window(ctx, k, v0)
    column = _Column(ctx, window)
    start = float(ctx.time[k]) if entry is None else float(entry)
    t0, v = _maximise(column, start, float(v0), ctx, entry)
    m = column.whitened(t0, v)
    norm2 = float(np.sum(m**2))
    a = max(0.0, float(np.sum(column.r * m)) / norm2) if norm2 > 0.0 else 0.0
    on = (column.time >= t0) & (column.time <= t0 + ctx.template.length / v)
    residual = (column.r - a * m)[:, on]
    rms = float(np.sqrt(np.mean(residual**2))) if residual.size else np.inf
    entry_ci, speed_ci = _intervals(column, t0, v, a, rms, (entry is None, ctx.fixed_speed is None))
    return VehicleEstimate(entry_time=t0, speed=v, entry_ci95=entry_ci, speed_ci95=speed_ci, load_factor=a, rms=rms,
                           window=window, signal=a * column.raw(t0, v), whitened=a * m)
