"""The library of candidate effects: parametric extensions of the forward model, and their registry.

Each effect owns a block of parameters with an independent Gaussian prior,
changes the model state (bridge springs, sensor or load positions, axle
loads: :class:`~.base.StructuralEffect`) or the readings (offsets, drift,
gains, amplification: :class:`~.base.OutputEffect`), returns the exact
derivative of the predictions with respect to its parameters
(sensor-position derivatives by a central difference of the exact lines;
load-position derivatives exact, from the piecewise-cubic lines) and states
what it found in engineering terms.  Importing this package registers the
library (:mod:`.registry`) in the order ``diagnose`` screens it.

Owns: the effects and their registry.  May import: the model layer, the diagnosis's results and column blocks.
"""

from .amplification import DynamicAmplification
from .base import Effect, EffectBlock, OutputEffect, State, StructuralEffect
from .loads import AxleLoads, PositionOffset
from .offsets import SensorOffset, ThermalDrift
from .registry import EFFECTS, effect_names, make_effect, register_effect, unregister_effect
from .sensors import SensorGain, SensorPosition
from .springs import CaseSprings, SupportRotationalSpring, VerticalSupportSpring
from .stiffness import LoadDependentStiffness

__all__ = ["EFFECTS", "CaseSprings", "Effect", "EffectBlock", "OutputEffect", "State", "StructuralEffect",
           "effect_names", "make_effect", "register_effect", "unregister_effect"]

for _library_effect in (SupportRotationalSpring, VerticalSupportSpring, SensorOffset, ThermalDrift, PositionOffset,
                        AxleLoads, SensorPosition, DynamicAmplification, SensorGain, LoadDependentStiffness):
    register_effect(_library_effect)
