"""The quiet parts of a logger record: no vehicle, no burst, no gap; long enough to see the wander.

Three robust masks, joined over the channels (a vehicle seen on one channel
is activity on all):

* **bursts**: a first difference beyond ``burst_k`` times the robust std of
  the differences (1.4826 MAD; white noise has almost all of it), widened by
  ``margin_s`` on both sides (a burst's decay and the logger's settling);
* **activity** (vehicles, load steps): the 1 s block means against their
  running median over ``baseline_s``; a block whose deviation exceeds
  ``activity_k`` times the robust std of those deviations is active, widened
  by ``margin_s``.  Slow wander moves the running median along and stays
  quiet; a vehicle's seconds-long signal does not;
* **gaps**: a step over 1.5 times the median sample interval ends a segment.

What is left is cut into runs of at least ``min_segment_s``; shorter quiet
runs are dropped (they cannot show minutes of wander).
"""

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import median_filter

__all__ = ["QuietParts", "quiet_parts"]

ROBUST = 1.4826  # MAD -> std for Gaussian data


@dataclass(frozen=True, eq=False)
class QuietParts:
    """The quiet segments of a record.

    Attributes
    ----------
    segments : tuple of (start, stop)
        Sample index ranges [start, stop) of the quiet segments used.
    mask : ndarray of bool (n_samples,)
        True on the samples of the segments.
    bursts, active : int
        Samples flagged as burst and as activity.
    """

    segments: tuple
    mask: np.ndarray
    bursts: int
    active: int

    @property
    def fraction(self):
        """Share of the record's samples in the quiet segments."""
        return float(self.mask.mean()) if self.mask.size else 0.0


def _robust_std(x):
    x = np.asarray(x, dtype=float)
    return float(ROBUST * np.median(np.abs(x - np.median(x)))) if x.size else 0.0


def _widen(flags, width):
    """``flags`` widened by ``width`` samples on both sides."""
    if width <= 0 or not flags.any():
        return flags
    kernel = np.ones(2 * width + 1)
    return np.convolve(flags.astype(float), kernel, mode="same") > 0.5


def _burst_flags(values, k, width):
    flags = np.zeros(values.shape[1], dtype=bool)
    for row in values:
        d = np.diff(row)
        scale = _robust_std(d)
        if scale <= 0.0:
            continue
        jump = np.abs(d - np.median(d)) > k * scale
        flags[1:] |= jump
        flags[:-1] |= jump
    return _widen(flags, width)


def _activity_flags(values, block, baseline_blocks, k, width):
    n = values.shape[1]
    n_blocks = n // block
    flags = np.zeros(n, dtype=bool)
    if n_blocks < 3:
        return flags
    for row in values:
        means = row[:n_blocks * block].reshape(n_blocks, block).mean(axis=1)
        dev = means - median_filter(means, size=min(baseline_blocks, n_blocks) | 1, mode="nearest")
        scale = _robust_std(dev)
        if scale <= 0.0:
            continue
        active = np.abs(dev - np.median(dev)) > k * scale
        flags[:n_blocks * block] |= np.repeat(active, block)
        if n > n_blocks * block:
            flags[n_blocks * block:] |= active[-1]
    return _widen(flags, width)


def quiet_parts(time, values, *, min_segment_s=60.0, margin_s=2.0, baseline_s=60.0, burst_k=7.0, activity_k=5.0):
    """The :class:`QuietParts` of a record (``values`` (n_channels, n_samples), ``time`` [s])."""
    time = np.asarray(time, dtype=float)
    values = np.atleast_2d(np.asarray(values, dtype=float))
    step = np.diff(time)
    dt = float(np.median(step))
    width = max(int(round(margin_s / dt)), 1)
    block = max(int(round(1.0 / dt)), 1)
    bursts = _burst_flags(values, burst_k, width)
    active = _activity_flags(values, block, max(int(round(baseline_s / (block * dt))), 3), activity_k, width)
    bad = bursts | active
    breaks = np.flatnonzero(step > 1.5 * dt) + 1  # a gap ends a run
    good = ~bad
    edges = np.flatnonzero(np.diff(np.concatenate([[0], good.astype(int), [0]])))
    segments = []
    min_len = int(np.ceil(min_segment_s / dt))
    for start, stop in zip(edges[::2], edges[1::2]):
        cuts = [start] + [int(b) for b in breaks if start < b < stop] + [stop]
        segments += [(a, b) for a, b in zip(cuts[:-1], cuts[1:]) if b - a >= min_len]
    mask = np.zeros(time.size, dtype=bool)
    for a, b in segments:
        mask[a:b] = True
    return QuietParts(tuple(segments), mask, int(bursts.sum()), int((active & ~bursts).sum()))
