"""Synthetic crossings from the forward model."""

import numpy as np

from .._errors import ConfigError
from .crossings import Crossing, Crossings

__all__ = ["simulate_crossings"]


def simulate_crossings(case, n_crossings=1, *, noise=False, rng=None, ei=None, bridge=None,
                       positions=None):
    """Predicted (``noise=False``) or noisy synthetic crossings of ``case``.

    Parameters
    ----------
    case : Case
    n_crossings : int
    noise : bool
        Add noise drawn from ``case.noise`` (AR(1) included).
    rng : numpy.random.Generator or int, optional
        Required when ``noise`` is True.
    ei : array_like, optional
        EI per element of ``case.mesh`` to simulate instead of the nominal.
    bridge : Bridge, optional
        Bridge to simulate (e.g. with other springs).
    positions : array_like, optional
        Reference-axle positions; defaults to ``case.sweep``.
    """
    if int(n_crossings) != n_crossings or n_crossings < 1:
        raise ConfigError(f"The 'crossings' parameter must be a positive integer. "
                          f"Got {n_crossings!r} instead.")
    if noise and case.noise is None:
        raise ConfigError("Noise was requested but the case has no noise_std; add "
                          "noise_std to [sensors].")
    if noise and rng is None:
        raise ConfigError("A seed (rng) is required for noisy simulations.")
    pos = case.sweep.positions if positions is None else np.asarray(positions, dtype=float)
    clean = case.influence_lines(ei, positions=pos, bridge=bridge).predictions
    draws = case.noise.sample(pos, rng, n_crossings) if noise else np.zeros((n_crossings,) + clean.shape)
    ones = np.ones(pos.size)
    return Crossings(case.sensors.names, tuple(
        Crossing(str(i + 1), pos, clean + draws[i], ones) for i in range(n_crossings)))
