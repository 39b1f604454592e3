"""Synthetic crossings from the forward model."""

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from .._errors import ConfigError
from .crossings import Crossing, Crossings

if TYPE_CHECKING:
    from .case import Case
    from .structure import Bridge

__all__ = ["simulate_crossings"]


def simulate_crossings(case: "Case", n_crossings: int = 1, *, noise: bool = False,
                       rng: "np.random.Generator | int | None" = None, ei: "ArrayLike | None" = None,
                       bridge: "Bridge | None" = None, positions: "ArrayLike | None" = None) -> Crossings:
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
    noise_model = case.noise
    if noise and noise_model is None:
        raise ConfigError("Noise was requested but the case has no noise_std; add "
                          "noise_std to [sensors].")
    if noise and rng is None:
        raise ConfigError("A seed (rng) is required for noisy simulations.")
    pos = case.sweep.positions if positions is None else np.asarray(positions, dtype=float)
    clean = case.influence_lines(ei, positions=pos, bridge=bridge).predictions
    draws = noise_model.sample(pos, rng, n_crossings) if noise and noise_model is not None else np.zeros((n_crossings,) + clean.shape)
    ones = np.ones(pos.size)
    return Crossings(case.sensors.names, tuple(
        Crossing(str(i + 1), pos, clean + draws[i], ones) for i in range(n_crossings)))
