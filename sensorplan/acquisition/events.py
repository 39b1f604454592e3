"""Where in a continuous record something crosses the bridge.

The noise floor of each channel is the median absolute deviation of its
first differences (robust to the events and to slow drift: for white noise
of std s the differences have std s sqrt 2).  The signal, smoothed over
``smooth`` seconds, is compared with a baseline through the quiet samples;
samples more than ``threshold`` noise standard deviations (of the smoothed
signal) away from it on any channel are active.  The first quiet set is
the blocks of ``2 quiet_gap`` seconds without a significant slope; the
baseline and the active set are then refined a few times.  Active runs closer than
``quiet_gap`` seconds are one event.
"""

import numpy as np

__all__ = ["noise_floor", "find_events"]

_MAD_TO_STD = 1.482602218505602  # 1 / Phi^-1(3/4): MAD of a normal sample to its std


def noise_floor(values):
    """Noise standard deviation of each channel (rows of ``values``) from its first differences."""
    diff = np.diff(values, axis=1)
    mad = np.median(np.abs(diff - np.median(diff, axis=1, keepdims=True)), axis=1)
    return _MAD_TO_STD * mad / np.sqrt(2.0)


def _moving_average(values, k):
    if k <= 1:
        return values.copy()
    kernel = np.ones(k) / k
    padded = np.pad(values, ((0, 0), (k // 2, k - 1 - k // 2)), mode="edge")
    return np.array([np.convolve(row, kernel, mode="valid") for row in padded])


def _baseline(time, smooth, quiet, block):
    """Per channel: block medians of the quiet samples, linearly interpolated in time."""
    n = time.size
    starts = np.arange(0, n, block)
    centres, medians = [], []
    for s in starts:
        sel = slice(s, min(s + block, n))
        q = quiet[sel]
        if q.sum() >= max(1, q.size // 4):
            centres.append(float(np.mean(time[sel][q])))
            medians.append(np.median(smooth[:, sel][:, q], axis=1))
    if len(centres) < 2:
        return np.repeat(np.median(smooth, axis=1, keepdims=True), n, axis=1)
    medians = np.array(medians).T
    return np.array([np.interp(time, centres, m) for m in medians])


def _flat_blocks(time, values, noise_std, block):
    """Samples in blocks whose least-squares slope is within noise on every channel (a first quiet set)."""
    quiet = np.zeros(time.size, bool)
    for s in range(0, time.size, block):
        sel = slice(s, min(s + block, time.size))
        t = time[sel] - time[sel].mean()
        if t.size < 3:
            continue
        rise = np.abs(values[:, sel] @ t) / (t @ t) * np.ptp(t)  # fitted change over the block
        # the fitted change of white noise has std sigma sqrt(12 / n) (least-squares slope)
        quiet[sel] = bool(np.all(rise < 4.0 * noise_std * np.sqrt(12.0 / t.size)))
    return quiet if quiet.any() else np.ones(time.size, bool)


def _runs(mask):
    """(start, stop) index pairs of the True runs of ``mask`` (stop exclusive)."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)))


def find_events(time, values, noise_std, *, smooth, quiet_gap, threshold=6.0, iterations=4):
    """Active segments of a record.

    Parameters
    ----------
    time : ndarray (n_samples,)
        [s], increasing.
    values : ndarray (n_channels, n_samples)
    noise_std : ndarray (n_channels,)
        Noise floor per channel.
    smooth : float
        Width of the moving average [s].
    quiet_gap : float
        Active runs separated by less than this [s] are one event.
    threshold : float
        Detection threshold in noise standard deviations of the smoothed signal.

    Returns
    -------
    segments : list of (int, int)
        Start and stop (exclusive) sample indices of each event.
    activity : ndarray (n_samples,)
        Largest deviation from the baseline over the channels, in noise std of the smoothed signal.
    """
    dt = float(np.median(np.diff(time)))
    k = max(1, int(round(smooth / dt)))
    smoothed = _moving_average(values, k)
    scale = np.maximum(noise_std, 1e-300)[:, None] / np.sqrt(k)
    pad = max(1, int(round(quiet_gap / dt)))
    block = max(k, int(round(2 * quiet_gap / dt)))
    quiet = _flat_blocks(time, values, noise_std, block)
    for _ in range(iterations):
        baseline = _baseline(time, smoothed, quiet, block)
        activity = np.max(np.abs(smoothed - baseline) / scale, axis=0)
        active = activity > threshold
        quiet = ~(np.convolve(active, np.ones(2 * pad + 1), mode="same") > 0)
    segments = []
    for a, b in _runs(active):
        if segments and time[a] - time[segments[-1][1] - 1] < quiet_gap:
            segments[-1] = (segments[-1][0], b)
        else:
            segments.append((a, b))
    return segments, activity
