"""The matched-filter scan: a vehicle's test statistic at every entry time and speed of a grid.

For a vehicle entering at sample k with speed v, every channel c reads
``a * IL_c(v (t - t_k))`` (a >= 0 the unknown load factor, IL_c the case's
influence line of the case's vehicle) on top of the noise.  With the
whitened record r_c and the whitened template m_c of that (k, v), the
generalised likelihood ratio against "noise only" (wander + OU + white,
both under the same model) is, maximised over a >= 0,

    GLR(k, v) = z(k, v)_+^2,     z(k, v) = sum_c r_c . m_c / sqrt(sum_c |m_c|^2),

and z(k, v) is exactly standard normal for each (k, v) when there is no
vehicle.  The whitening is a time-invariant filter (:mod:`.whitening`), so
m_c at entry k is the template's whitened column shifted by k and every
r . m over k is one correlation (FFT).  The scan keeps, per sample, the
largest z over the speed grid and the speed that gave it.
"""

from dataclasses import dataclass

import numpy as np

from .._cache import value_key

__all__ = ["Templates", "whitened_templates", "ScanResult", "scan", "upcrossings", "candidates", "speed_grid"]

# Geometric speed grid step: adjacent templates correlate above about 0.98 (a grid loss of a few % of z).
SPEED_STEP = 1.03
# A whitened column is kept until it decays to this fraction of its peak.
TAIL_TOLERANCE = 1e-4


def speed_grid(speed_range, fixed_speed=None):
    """Speeds [m/s] of the scan: ``fixed_speed`` alone, or a geometric grid over ``speed_range``."""
    if fixed_speed is not None:
        return np.array([float(fixed_speed)])
    lo, hi = speed_range
    return np.geomspace(lo, hi, int(np.ceil(np.log(hi / lo) / np.log(SPEED_STEP))) + 1)


@dataclass(frozen=True, eq=False)
class Templates:
    """Whitened templates of one vehicle at each speed of the grid, on the record's sample grid.

    Attributes
    ----------
    speeds : ndarray (n_speeds,)
        [m/s]
    columns : tuple of ndarray (n_channels, n_k)
        Whitened template at entry sample 0 (its tail included).
    norms : ndarray (n_speeds,)
        sqrt(sum_c |m_c|^2) of each.
    durations : ndarray (n_speeds,)
        Samples the vehicle is on the bridge at each speed.
    """

    speeds: np.ndarray
    columns: tuple
    norms: np.ndarray
    durations: np.ndarray

    @property
    def cache_key(self):
        return ("Templates", value_key(self.speeds, *self.columns))


def whitened_templates(template, whiteners, dt, speeds, *, max_samples=None):
    """:class:`Templates` of ``template`` (a :class:`~.fit.Template`) whitened per channel on step ``dt``.

    The whitened column runs on after the vehicle until it has decayed (the filter's tail), but never beyond
    ``max_samples`` (the record's length): a nearly unit pole (a very weak walk) would otherwise ask for
    millions of samples no record holds.
    """
    tail = max(w.tail(TAIL_TOLERANCE) for w in whiteners)
    if max_samples is not None:
        tail = min(tail, int(max_samples))
    columns, norms, durations = [], [], []
    for v in speeds:
        on = int(np.ceil(template.length / (v * dt)))
        z = v * dt * np.arange(on + tail)
        raw = template.predict(z)
        col = np.stack([w.apply(row) for w, row in zip(whiteners, raw)])
        columns.append(col)
        norms.append(float(np.sqrt(np.sum(col**2))))
        durations.append(on)
    return Templates(np.asarray(speeds, float), tuple(columns), np.array(norms), np.array(durations))


@dataclass(frozen=True, eq=False)
class ScanResult:
    """Per entry sample: the largest z over the speeds and the index of that speed."""

    z: np.ndarray
    speed_index: np.ndarray


def _correlate(r, column):
    """sum_c sum_j r_c[k + j] column_c[j] for every k (n,), the column cut at the record's end."""
    from scipy.signal import fftconvolve

    n = r.shape[1]
    full = sum(fftconvolve(rc, cc[::-1], mode="full") for rc, cc in zip(r, column))
    return full[column.shape[1] - 1: column.shape[1] - 1 + n]


def _norms_cut(column, n):
    """|m| at every entry sample k < n of a record of n samples (the column cut at the end)."""
    energy = np.cumsum(np.sum(column**2, axis=0))
    room = np.minimum(n - np.arange(n), column.shape[1])  # samples of the column inside the record
    return np.sqrt(energy[room - 1])


def _offset_share(ones, column):
    """sum_c (u_c . m_c)^2 / |u_c|^2 at every entry sample: the part of |m|^2 the offset takes."""
    n = ones.shape[1]
    out = np.zeros(n)
    for u, col in zip(ones, column):
        uu = float(u @ u)
        if uu <= 0.0:
            continue
        live = np.flatnonzero(np.abs(u) > 1e-9 * np.max(np.abs(u)))
        reach = min(n, int(live[-1]) + 1)  # u is negligible after the record's first seconds
        part = _correlate(u[None, :reach], col[None, :])
        out[:reach] += part**2 / uu
    return out


def scan(r, templates, *, ones=None):
    """:class:`ScanResult` of the whitened record ``r`` (n_channels, n) against ``templates``.

    ``ones`` (n_channels, n), the whitened constants of :meth:`~.whitening.Whitener.record`,
    corrects the norms near the record's start for the marginalised offset.
    """
    n = r.shape[1]
    best = np.full(n, -np.inf)
    index = np.zeros(n, dtype=int)
    for i, column in enumerate(templates.columns):
        norm2 = _norms_cut(column, n) ** 2
        if ones is not None:
            norm2 = norm2 - _offset_share(ones, column)
        z = _correlate(r, column) / np.sqrt(np.maximum(norm2, 1e-300))
        z[max(0, n - int(templates.durations[i])):] = -np.inf  # the vehicle would still be on the bridge at the end
        better = z > best
        best[better] = z[better]
        index[better] = i
    return ScanResult(best, index)


def upcrossings(z, levels):
    """Number of upcrossings of each level by the sequence ``z``."""
    z = np.asarray(z)
    return np.array([int(np.sum((z[:-1] < u) & (z[1:] >= u))) for u in levels])


def candidates(result, durations, level, *, limit=None):
    """Entry samples of separated local maxima of ``result.z`` above ``level``, strongest first.

    A maximum suppresses every weaker one whose vehicle would be on the bridge
    at the same time (one vehicle per event).
    """
    z = result.z
    above = np.flatnonzero(z > level)
    if above.size == 0:
        return []
    keep = above[(z[above] >= z[np.maximum(above - 1, 0)]) & (z[above] >= z[np.minimum(above + 1, z.size - 1)])]
    order = keep[np.argsort(-z[keep], kind="stable")]
    chosen: list[int] = []
    reach: list[int] = []
    for k in order:
        end = int(k) + int(durations[result.speed_index[k]])
        if any(int(k) < e and c < end for c, e in zip(chosen, reach)):
            continue
        chosen.append(int(k))
        reach.append(end)
        if limit is not None and len(chosen) >= limit:
            break
    return chosen
