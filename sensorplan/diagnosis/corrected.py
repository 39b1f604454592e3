"""The case corrected by a diagnosis: identified springs, sensor positions and axle loads written in.

Owns: corrected cases.  May import: model and the foundations.
"""

from dataclasses import replace

from ..model.loads import Vehicle
from ..model.sensors import SensorLayout
from ..model.structure import Bridge

__all__ = ["corrected_case"]


def corrected_case(case, diagnosis):
    """``case`` with the structural effects of ``diagnosis`` at their final MAP (springs, sensors, axles).

    Effects on the readings (offsets, drift, gains, amplification) and on the
    load positions or load levels are properties of the data, not of the
    case; they are listed in ``diagnosis.corrected_model.not_in_case``.
    """
    m = diagnosis.corrected_model
    if m is None:
        return case
    bridge = Bridge(case.bridge.spans, tuple(m.rotational_springs), tuple(m.vertical_springs))
    s = case.sensors
    sensors = SensorLayout(list(m.sensor_positions), s.kinds, s.names, s.noise_std)
    vehicle = Vehicle(case.vehicle.axle_offsets, tuple(m.axle_loads))
    return replace(case, bridge=bridge, sensors=sensors, vehicle=vehicle)
