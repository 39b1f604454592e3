"""The effect protocol: what a candidate effect declares, and what the joint model offers it.

An effect is a named block of parameters phi with an independent Gaussian
prior that extends the case's model.  It describes itself: which data it
can act on (:meth:`Effect.applicable`), its parameters and prior for a
given model (:meth:`Effect.configure`, which returns a frozen
:class:`EffectBlock` and leaves the effect as it was), which parameters act
on a crossing (:meth:`Effect.columns`), its exact derivatives, and its
engineering statement (:meth:`Effect.describe`).

Two kinds, one hook each for the two phases of an evaluation of the joint
model (:class:`~sensorplan.diagnosis.joint.problem.JointProblem`):

* :class:`StructuralEffect` changes the model state before the forward
  solve (springs, sensor or load positions, axle loads, a crossing's EI
  factor): :meth:`~StructuralEffect.apply` and
  :meth:`~StructuralEffect.jacobian`;
* :class:`OutputEffect` acts on the predicted readings (gains and
  amplifications on the response, then offsets and drift added):
  :meth:`~OutputEffect.output`.

Every hook of the other kind is a no-op, so the joint model calls both
phases on every block and never asks which kind an effect is.  The model
passes itself as ``ctx``: :class:`EffectContext` lists what an effect may
use of it.

Owns: the effect protocol, :class:`EffectBlock`, :class:`State`.  May import: numpy.
"""

from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import KW_ONLY, dataclass, field
from typing import Any, ClassVar, Protocol

import numpy as np

__all__ = ["Effect", "EffectBlock", "EffectContext", "OutputEffect", "State", "StructuralEffect"]


@dataclass
class State:
    """The model state one parameter vector sets (the structural effects change it in place, in order).

    ``positions``: the load positions of every crossing [m];
    ``ei_log_scale``: a log EI factor per crossing.  ``keys``: the joint
    model's cache keys of each crossing at this state, formed once the
    effects have set it (:class:`~sensorplan.diagnosis.joint.source.LineSource`).
    """

    bridge: Any
    sensor_positions: np.ndarray
    positions: list
    axle_factors: np.ndarray
    ei_log_scale: np.ndarray
    keys: dict = field(default_factory=dict, repr=False, compare=False)


@dataclass(frozen=True, eq=False)
class EffectBlock:
    """An effect configured for one model: its parameter names and prior, and what it derived from the data.

    ``detail``: values the effect's own methods need and computed once in
    :meth:`Effect.configure` (a sensor's sign, the crossings' load levels,
    the springs it estimates); None when there are none.
    ``log_prior_constant``: the log prior of the effect's discrete choices
    (added to the evidence).
    """

    effect: "Effect"
    names: tuple
    mean: np.ndarray
    std: np.ndarray
    _: KW_ONLY
    log_prior_constant: float = 0.0
    detail: Any = None

    @property
    def name(self) -> str:
        return self.effect.name

    @property
    def n_params(self) -> int:
        return len(self.names)


class EffectContext(Protocol):
    """What the joint model offers an effect (``ctx`` in the hooks).

    The data: ``case``, ``crossings``, ``prior``, ``sensors`` (the data's
    sensor layout), ``sensor_names``, ``n_sensors``, ``n_crossings``,
    ``labels`` (of the crossings), ``offset_scale`` (a typical reading per
    sensor, the scale of offset priors), ``model_positions`` (per crossing,
    the load positions at which the model is evaluated).  The lines
    (``lines``: readings, spring and log-EI terms of crossing ``c`` at a
    model state; ``line_slopes``: their slope in the load position;
    ``axle_lines``: one axle's response), each crossing's ``load_factor(c)``
    and ``to_bins(c, y)`` (a model at the readings as it enters the fit).
    """

    case: Any
    crossings: Any
    prior: Any
    sensors: Any
    sensor_names: Sequence[str]
    n_sensors: int
    n_crossings: int
    labels: Sequence[str]
    offset_scale: np.ndarray
    model_positions: list

    def load_factor(self, c: int) -> np.ndarray: ...

    def to_bins(self, c: int, y: np.ndarray) -> np.ndarray: ...

    def lines(self, state: State, c: int, *, positions=None, sensor_positions=None) -> Any: ...

    def line_slopes(self, state: State, c: int) -> np.ndarray: ...

    def axle_lines(self, state: State, c: int, axle: int) -> np.ndarray: ...


class Effect(ABC):
    """A candidate effect (subclass :class:`StructuralEffect` or :class:`OutputEffect`).

    Declared data: ``name`` (unique; the registry's key), ``contains``
    (library effects it holds as a special case: once it is in the model the
    data cannot tell them apart), ``in_case`` (its state is a property of
    the case -- springs, sensor positions, axle loads -- that a corrected
    case holds), ``per_sensor`` (its parameters belong to the data's
    sensors: a sensor added elsewhere cannot separate it from an EI
    change), and what a structural effect asks of the model
    (:class:`StructuralEffect`: ``frees``, ``moves_loads``,
    ``needs_axle_lines``; none for an output effect).
    """

    name: ClassVar[str] = ""
    contains: ClassVar[tuple] = ()
    in_case: ClassVar[bool] = False
    per_sensor: ClassVar[bool] = False
    frees: ClassVar[tuple] = ()
    moves_loads: ClassVar[bool] = False
    needs_axle_lines: ClassVar[bool] = False

    def applicable(self, crossings) -> "str | None":
        """Why the effect cannot act on these data (None: it can)."""
        return None

    @abstractmethod
    def configure(self, ctx: EffectContext) -> EffectBlock:
        """The effect's parameters and prior for the model ``ctx`` (the effect itself is not changed)."""

    def initial(self, block: EffectBlock, ctx: EffectContext, predictions) -> "np.ndarray | None":
        """Start values from the nominal model's ``predictions`` per crossing (None: the prior mean)."""
        return None

    def columns(self, block: EffectBlock, ctx: EffectContext, c: int) -> "np.ndarray | None":
        """Indices of the parameters that can act on crossing ``c`` (None: all of them).

        The Jacobian of crossing ``c`` holds these columns only: a parameter
        of one crossing (an offset, a shift) is zero in the others.
        """
        return None

    @abstractmethod
    def describe(self, block: EffectBlock, ctx: EffectContext, mean, std) -> list:
        """Findings (:class:`~sensorplan.diagnosis.results.Finding`) at parameter MAP ``mean`` and std ``std``."""

    def restart(self, block: EffectBlock, values: np.ndarray) -> np.ndarray:
        """The block's values in a restart from the nominal model, given its ``values`` in the current start."""
        return values

    # -- phase 1: the model state (structural effects) ---------------------------------------------------
    def apply(self, block: EffectBlock, state: State, phi: np.ndarray) -> None:
        """Change ``state`` in place (structural effects; nothing for output effects)."""

    def apply_corrected(self, block: EffectBlock, state: State, phi, std, case) -> None:
        """Change ``state`` as a corrected case holds it (posterior std ``std``); default :meth:`apply`."""
        self.apply(block, state, phi)

    def jacobian(self, block: EffectBlock, ctx: EffectContext, state: State, phi, c: int, y):
        """dy/dphi of crossing ``c`` at the readings before the outputs act (None for output effects)."""
        return None

    # -- phase 2: the readings (output effects) ----------------------------------------------------------
    def output_order(self) -> int:
        """When :meth:`output` acts among the effects' outputs (0: it does nothing)."""
        return 0

    def output(self, block: EffectBlock, ctx: EffectContext, state: State, phi, c: int, y):
        """(y', dy'/dphi or None, multiplier of the earlier columns) of crossing ``c`` (identity by default)."""
        return y, None, 1.0


class StructuralEffect(Effect):
    """An effect on the model state: :meth:`apply` changes it, :meth:`jacobian` gives dy/dphi.

    Declared data: ``frees`` (spring kinds whose stiffness the effect sets:
    the case's springs of that kind step aside, and a model distorted by the
    gap is also fitted from the nominal start); ``moves_loads`` (the load
    positions are parameters: the lines then need their slopes and a
    continuous entry onto the bridge); ``needs_axle_lines`` (the Jacobian
    needs each axle's response alone).

    :meth:`jacobian` returns an array (S, K, n) over ``columns(ctx, c)`` or
    a column block of :mod:`sensorplan.diagnosis.joint.columns`.
    """

    @abstractmethod
    def apply(self, block: EffectBlock, state: State, phi: np.ndarray) -> None:
        """Change ``state`` in place."""

    @abstractmethod
    def jacobian(self, block: EffectBlock, ctx: EffectContext, state: State, phi, c: int, y):
        """dy/dphi of crossing ``c`` (S, K, n) at the readings, or a column block."""

    def restart(self, block: EffectBlock, values: np.ndarray) -> np.ndarray:
        """The prior mean: a restart from the nominal model starts from the nominal state."""
        return block.mean


class OutputEffect(Effect):
    """An effect on the predicted readings: :meth:`output` maps y to y'.

    Declared data: ``additive`` (an output term added to the reading:
    applied after the effects that scale the response, whatever order the
    effects were selected in -- a gain applied after a drift scales the
    drift too).  :meth:`output` returns (y', dy'/dphi over
    ``columns(ctx, c)`` as an array (S, K, n) or a column block, the
    multiplier (scalar or per sensor) by which the effect scales the
    columns of the effects before it).
    """

    additive: ClassVar[bool] = False

    def output_order(self) -> int:
        """1: acts on the response (scales it); 2: adds to the reading (after every scaling)."""
        return 2 if self.additive else 1

    @abstractmethod
    def output(self, block: EffectBlock, ctx: EffectContext, state: State, phi, c: int, y):
        """(y', dy'/dphi, multiplier) of crossing ``c``."""
