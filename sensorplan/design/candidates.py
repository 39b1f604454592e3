"""Candidate sensors of one or several kinds, their noise and cost, and the existing sensors.

Every candidate position is offered once per kind (kind-major order: all
positions of the first kind, then of the second, ...); each candidate has
the noise std of its kind (whitening is per sensor, so Fisher blocks of
different kinds are in the same dimensionless units) and the cost of its
kind.  Existing (fixed) sensors keep their own kind and noise.

Spacing rule: a minimum spacing applies between any two sensors whatever
their kinds; with no minimum spacing two sensors of different kinds may
share a position, and a candidate identical to an existing sensor (same
position and kind) is dropped.

Owns: kinds, per-kind noise and cost, fixed sensors.  May import: model, errors.
"""

from collections.abc import Mapping

import numpy as np

from .._errors import ConfigError
from ..model.sensors import SENSOR_KINDS, SensorLayout

__all__ = ["as_kinds", "kind_noise", "kind_costs", "fixed_layout", "sensor_layout", "CandidateSet",
           "candidate_set"]


def as_kinds(kind):
    """A kind or a sequence of kinds as a tuple of distinct known kinds."""
    kinds = (kind,) if isinstance(kind, str) else tuple(kind)
    if not kinds or any(k not in SENSOR_KINDS for k in kinds) or len(set(kinds)) != len(kinds):
        raise ConfigError(f"The 'kind' parameter must be one or more distinct sensor kinds out of "
                          f"{', '.join(SENSOR_KINDS)}. Got {kind!r} instead.")
    return kinds


def kind_noise(case, kinds, noise_std=None):
    """Noise std [rad or m] of new sensors of each kind, as a dict.

    ``noise_std`` is None (the case's sensors of each kind,
    :meth:`Case.noise_std_for`), one number (only with one kind) or a mapping
    kind -> std (kinds missing from it take the case's value).
    """
    if noise_std is None or isinstance(noise_std, Mapping):
        given = dict(noise_std or {})
        unknown = sorted(set(given) - set(kinds))
        if unknown:
            raise ConfigError(f"The 'noise_std' parameter names kind(s) {', '.join(map(str, unknown))} that are not "
                              f"among the candidate kinds ({', '.join(kinds)}).")
        return {k: case.noise_std_for(k, given.get(k)) for k in kinds}
    if len(kinds) > 1:
        raise ConfigError(f"The 'noise_std' parameter must give one noise std per kind when the candidates are of "
                          f"several kinds, e.g. rotation=5e-6,deflection=1e-4. Got {noise_std!r} instead.")
    return {kinds[0]: case.noise_std_for(kinds[0], noise_std)}


def kind_costs(costs, candidate_kinds, kinds):
    """Cost of each candidate: None (1 each), one number, one per candidate, or a mapping kind -> cost (default 1)."""
    n_candidates = len(candidate_kinds)
    if costs is None:
        out = np.ones(n_candidates)
    elif isinstance(costs, Mapping):
        unknown = sorted(set(costs) - set(kinds))
        if unknown:
            raise ConfigError(f"The 'costs' parameter names kind(s) {', '.join(map(str, unknown))} that are not "
                              f"among the candidate kinds ({', '.join(kinds)}).")
        out = np.array([float(costs.get(k, 1.0)) for k in candidate_kinds])
    else:
        try:
            out = np.broadcast_to(np.asarray(costs, dtype=float), (n_candidates,)).copy()
        except ValueError:
            raise ConfigError(f"The 'costs' parameter must be one number, one per candidate ({n_candidates}) or "
                              f"a mapping kind -> cost. Got {np.size(costs)} values instead.") from None
    if not np.all(np.isfinite(out) & (out >= 0)):
        raise ConfigError(f"The 'costs' parameter must hold non-negative costs. Got {sorted(set(out.tolist()))} "
                          "instead.")
    return out


def sensor_layout(positions, kinds, noise_std):
    """A layout of sensors with distinct names (position, plus the kind where two share a position)."""
    positions = np.atleast_1d(np.asarray(positions, dtype=float))
    names = [f"{x:.6g}" for x in positions]
    if len(set(names)) != len(names):
        names = [f"{n}:{k}" for n, k in zip(names, kinds)]
    return SensorLayout(positions, tuple(kinds), tuple(names), tuple(float(s) for s in noise_std))


def fixed_layout(case, fixed, kind, noise):
    """Existing sensors as a SensorLayout with their noise (None when there are none).

    ``fixed`` is a sequence of positions [m] (sensors of ``kind`` with the
    noise of new sensors of that kind, ``noise`` dict) or a SensorLayout: its
    kinds, and its noise std if set, else the case's noise model when it is
    the case's own layout, else the case's sensors of its kind
    (:meth:`Case.noise_std_for`; the new sensors' noise if the case has none).
    """
    if fixed is None:
        return None
    if isinstance(fixed, SensorLayout):
        if fixed.noise_std is not None:
            stds = fixed.noise_std
        elif fixed is case.sensors and case.noise is not None:
            stds = tuple(case.noise.std)
        else:
            stds = tuple(_case_noise(case, k, noise) for k in fixed.kinds)
        return sensor_layout(fixed.positions, fixed.kinds, stds)
    x = np.asarray(list(fixed), dtype=float)
    if x.size == 0:
        return None
    return sensor_layout(x, (kind,) * x.size, (noise[kind],) * x.size)


def _case_noise(case, kind, noise):
    if case.noise is not None and kind in case.sensors.kinds:
        return case.noise_std_for(kind)
    if kind in noise:
        return noise[kind]
    return case.noise_std_for(kind)  # the error that names the missing noise


class CandidateSet:
    """Candidates (positions, kinds, noise std) and the existing sensors of a placement problem."""

    def __init__(self, positions, kinds, noise_std, fixed):
        self.positions = positions  # (C,) [m]
        self.kinds = kinds  # (C,) tuple of str
        self.noise_std = noise_std  # (C,) [rad or m]
        self.fixed = fixed  # SensorLayout or None

    @property
    def n_candidates(self):
        return self.positions.size

    def layout(self, index=None):
        """Candidates (those at ``index``, default all) then existing sensors, as one SensorLayout."""
        index = np.arange(self.positions.size) if index is None else np.asarray(list(index), dtype=int)
        positions, kinds = self.positions[index], tuple(self.kinds[i] for i in index)
        noise = tuple(np.asarray(self.noise_std)[index])
        if self.fixed is None:
            return sensor_layout(positions, kinds, noise)
        return sensor_layout(np.concatenate([positions, self.fixed.positions]), kinds + self.fixed.kinds,
                             noise + tuple(self.fixed.noise_std or ()))


def candidate_set(case, positions, kinds, noise, fixed, min_spacing):
    """Every position once per kind, minus those too close to (or identical with) an existing sensor."""
    positions = np.asarray(positions, dtype=float)
    x = np.tile(positions, len(kinds))
    k = np.repeat(np.array(kinds, dtype=object), positions.size)
    keep = np.ones(x.size, dtype=bool)
    for fx, fk in ([] if fixed is None else zip(fixed.positions, fixed.kinds)):
        dist = np.abs(x - fx)
        keep &= ~((dist < min_spacing) | ((dist < 1e-9) & (k == fk)))
    if not keep.any():
        raise ConfigError("The 'fixed' sensors and 'min_spacing' leave no candidate position; lower 'min_spacing' "
                          "or move the 'fixed' sensors.")
    kinds_kept = tuple(str(v) for v in k[keep])
    return CandidateSet(x[keep], kinds_kept, np.array([noise[v] for v in kinds_kept]), fixed)
