"""The whitened problem: a case's crossings as whitened data, and the model's linearisation at theta.

:class:`WhitenedProblem` owns what every whitened least-squares problem of
the package shares: the case, the crossings (rows selected by masks), the
sensors and noise model of the data's columns, the whitened data, the data
count and noise log-determinant of the evidence, the crossings grouped by
what their model depends on (positions, load factors, rows), ONE value-keyed
:class:`~sensorplan._cache.Cache` and the assembly of the normal equations.
A subclass gives its parameters and, per group, the whitened predictions and
Jacobian (:meth:`WhitenedProblem.whitened_model`); or it overrides
:meth:`WhitenedProblem.linearise` and accumulates through
:class:`~.normal.NormalEquations` itself.  What a problem must offer to the
steps (:mod:`.steps`) and to the hyperparameter methods is
:class:`LinearisedProblem`.

Owns: the whitened data, the crossing groups, the problem's cache, the
grouped normal equations.  May import: model, the foundations.
"""

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..._cache import Cache, value_key
from ..._errors import ConfigError
from ...model.noise import NoiseModel
from .normal import Linearisation, NormalEquations

__all__ = ["LinearisedProblem", "StackedProblem", "Stacked", "CrossingGroup", "WhitenedProblem", "crossing_groups",
           "rows_of", "data_sensors", "DEFAULT_STD"]

DEFAULT_STD = {"rotation": 1e-6, "deflection": 1e-4}  # noise std [rad, m] of data sensors without one


class LinearisedProblem(Protocol):
    """What :func:`~.steps.solve_map`, :func:`~.steps.log_evidence` and the hyperparameter methods ask of a problem.

    ``evaluate(theta, jacobian=True)`` returns the :class:`~.normal.Linearisation`
    of the whitened misfit at ``theta`` (``jtj`` and ``jtr`` None without the
    Jacobian), or None where the model is undefined (a rejected trial point);
    ``n_data`` is the number of whitened rows that carry information (less one per marginalised offset of
    a wandering sensor) and ``log_det_noise`` the log
    determinant of the noise covariance of the data (for the evidence).
    """

    n_data: int
    log_det_noise: float

    def evaluate(self, theta: np.ndarray, *, jacobian: bool = True) -> Linearisation | None: ...


@dataclass(frozen=True, eq=False)
class Stacked:
    """A problem's whitened residual (N,) and Jacobian dF/dtheta (N, P) stacked over its rows.

    ``extra``: further columns a problem returns with them (None if none).
    """

    residual: np.ndarray
    jacobian: np.ndarray
    extra: np.ndarray | None = None


class StackedProblem(Protocol):
    """What :func:`~.steps.ridge_gauss_newton` asks of a problem: its :class:`Stacked` rows at ``theta``.

    ``stacked`` raises ConfigError where the model is undefined.
    """

    def stacked(self, theta: np.ndarray) -> Stacked: ...


def data_sensors(case, names):
    """The case's sensors ``names`` (in that order) and their noise model: the one rule for a missing noise level.

    The case's noise model of those sensors; a case without one gets
    ``DEFAULT_STD`` of each sensor's kind with independent noise, and every
    problem built on the data (the EI inversion, the diagnosis's joint
    model, the detector's null model) estimates the common noise scale
    alpha from the data.  (New sensors of a design take the median noise of
    the case's sensors of their kind instead: :meth:`~sensorplan.model.case.Case.noise_std_for`.)
    """
    index = [case.sensors.names.index(n) for n in names]
    sensors = case.sensors.subset(index)
    if case.noise is not None:
        return sensors, case.noise.subset(index)
    return sensors, NoiseModel([DEFAULT_STD[k] for k in sensors.kinds])


@dataclass(frozen=True, eq=False)
class CrossingGroup:
    """Crossings whose model is one and the same: equal positions, load factors and selected rows.

    ``members`` are the crossings' indices (in the data's order);
    ``position_set`` indexes the distinct position arrays
    (:attr:`WhitenedProblem.position_sets`), on which the lines are computed;
    ``times`` the readings' times when the crossings carry them (equal in a
    group: the noise model in time whitens with them).
    """

    members: tuple
    positions: np.ndarray
    load_factor: np.ndarray
    mask: np.ndarray
    position_set: int
    times: np.ndarray | None = None

    @property
    def rows(self):
        """The load positions of the selected rows."""
        return self.positions[self.mask]


def rows_of(times, mask):
    """The selected rows of a crossing's reading ``times`` (None when the crossing has none)."""
    return None if times is None else np.asarray(times)[mask]


def crossing_groups(crossings, masks):
    """The groups of ``crossings`` (rows ``masks``) sharing their model, each crossing's group, the position sets.

    Groups and position sets are in the order of first appearance.
    """
    sets, groups, group_of = {}, {}, []
    for c, (crossing, mask) in enumerate(zip(crossings, masks)):
        set_index = sets.setdefault(value_key(crossing.positions), len(sets))
        key = value_key(crossing.positions, crossing.load_factor, mask, crossing.times)
        if key not in groups:
            groups[key] = (len(groups), [c], crossing, mask, set_index)
        else:
            groups[key][1].append(c)
        group_of.append(groups[key][0])
    ordered = tuple(CrossingGroup(tuple(members), crossing.positions, crossing.load_factor, mask, set_index,
                                  crossing.times) for _, members, crossing, mask, set_index in groups.values())
    firsts = {}
    for crossing in crossings:
        firsts.setdefault(value_key(crossing.positions), crossing.positions)
    return ordered, tuple(group_of), tuple(firsts.values())


class WhitenedProblem:
    """Sensors, noise and whitened data of ``crossings`` (rows selected by ``masks``), and their normal equations.

    Parameters
    ----------
    case : Case
        Sensors and noise model (sensors without one get ``DEFAULT_STD`` of
        their kind; the evidence then estimates the common scale).
    crossings : Crossings
    masks : list of bool arrays, optional
        Rows of each crossing that enter the likelihood (default all).

    Attributes set here: ``case``, ``crossings``, ``sensors``, ``noise``,
    ``masks``, ``white_data`` (per crossing, (S, selected rows)), ``n_data``,
    ``log_det_noise``, ``groups`` (:class:`CrossingGroup`), ``group_of``
    (each crossing's group), ``position_sets`` (the distinct position
    arrays) and ``cache`` (the problem's one :class:`~sensorplan._cache.Cache`,
    ``cache_size`` entries, emptied by :meth:`clear_cache`).  A subclass sets
    ``n_params`` and implements :meth:`whitened_model`, or overrides
    :meth:`linearise`.
    """

    cache_size: int | None = 8

    def __init__(self, case, crossings, *, masks=None):
        self.case = case
        self.crossings = crossings
        self.sensors, self.noise = data_sensors(case, crossings.sensor_names)
        self.masks = [np.ones(c.n_loads, bool) for c in crossings] if masks is None else masks
        self.white_data = [self.noise.whiten(c.values[:, m], c.positions[m], times=rows_of(c.times, m))
                           for c, m in zip(crossings, self.masks)]
        # readings that inform anything but the marginalised offsets of wandering sensors (all without wander)
        self.n_data = sum(self.noise.dof(m.sum()) for m in self.masks)
        self.log_det_noise = sum(self.noise.log_det(c.positions[m], times=rows_of(c.times, m))
                                 for c, m in zip(crossings, self.masks) if m.any())
        self.groups, self.group_of, self.position_sets = crossing_groups(crossings, self.masks)
        self.cache = Cache(maxsize=self.cache_size)

    n_params: int

    def clear_cache(self):
        """Forget every cached value (they are recomputed on demand)."""
        self.cache.clear()

    def whitened_model(self, theta, *, jacobian):
        """Per group (in ``self.groups``' order): whitened predictions (S, rows) and Jacobian (S rows, P) or None.

        Return None where the model is undefined at ``theta``; raising
        ConfigError (an unstable bridge, say) means the same.
        """
        raise NotImplementedError(f"{type(self).__name__} must implement whitened_model or evaluate")

    def evaluate(self, theta, *, jacobian=True):
        """Linearisation of the whitened misfit at ``theta`` (None: outside the model's domain).

        Kept in the cache by the value of ``theta``; an entry without the
        Jacobian serves only calls without it.
        """
        key = self.cache.key(("linearisation", theta))
        found, lin = self.cache.lookup((), key=key)
        if found and (lin.jtj is not None or not jacobian):
            return lin
        if not np.all(np.isfinite(theta)):
            return None
        try:
            lin = self.linearise(theta, jacobian=jacobian)
        except ConfigError:  # a trial step made the model invalid (e.g. an unstable bridge): reject it
            return None
        if lin is not None:
            self.cache.put((), lin, key=key)
        return lin

    def linearise(self, theta, *, jacobian=True):
        """The :class:`~.normal.Linearisation` at a finite ``theta``, uncached (None: outside the domain).

        By default :meth:`normal_equations` of :meth:`whitened_model`; a
        problem whose blocks are not groups of crossings (columns per
        crossing, factored terms) overrides this and accumulates through
        :class:`~.normal.NormalEquations` itself, keeping :meth:`evaluate`'s
        cache and domain checks.
        """
        model = self.whitened_model(theta, jacobian=jacobian)
        return None if model is None else self.normal_equations(model, jacobian=jacobian)

    def normal_equations(self, model, *, jacobian=True):
        """r.r, J^T J and J^T r from the groups' whitened predictions and Jacobians (``whitened_model``).

        Every crossing adds its residual r = white data - white prediction
        to r.r and J^T r; each group adds its Gram matrix J^T J once, times
        its number of crossings.
        """
        equations = NormalEquations(self.n_params, jacobian=jacobian)
        for c, white in enumerate(self.white_data):
            white_pred, white_jac = model[self.group_of[c]]
            equations.add_residual((white - white_pred).ravel(), white_jac)
        if jacobian:
            for group, (_, white_jac) in zip(self.groups, model):
                equations.add_gram(white_jac.T @ white_jac, count=len(group.members))
        return equations.linearisation()
