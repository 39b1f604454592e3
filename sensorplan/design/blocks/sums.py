"""Suffix sums and sums by mask start: how the masked parts of structured blocks are summed over candidates.

Owns: suffix_sums, sums_by_start.  May import: nothing of the package.
"""

import numpy as np

__all__ = ["suffix_sums", "sums_by_start"]


def suffix_sums(values):
    """Suffix sums over the first axis with a trailing zero (a mask that starts past the last element):
    out[s] = sum_{j >= s} values[j], shape (n + 1, ...) for n rows, in ``values``' precision."""
    out = np.zeros((values.shape[0] + 1,) + values.shape[1:], dtype=values.dtype)
    out[:-1] = np.cumsum(values[::-1], axis=0)[::-1]
    return out


def sums_by_start(values, start, n):
    """S[j] = sum of the rows of ``values`` whose mask ``start`` is at or before j, shape (n, ...), in
    ``values``' precision (n the number of parameters)."""
    spread = np.zeros((n + 1,) + values.shape[1:], dtype=values.dtype)
    np.add.at(spread, start, values)
    return np.cumsum(spread, axis=0)[:n]
