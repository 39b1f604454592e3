"""sensorplan: where to put tiltmeters so that EI(x) of a bridge can be identified.

The public API is re-exported here; modules with a leading underscore are
private.  Importing sensorplan never imports matplotlib.
"""

from ._errors import ConfigError, DataError, SensorplanError, SensorplanWarning, SolverError
from ._forward import InfluenceLines, bending_moments, expand_ei, influence_lines, support_reactions
from ._loads import LoadSweep, Vehicle
from ._sensors import SensorLayout
from ._structure import Bridge, Mesh, Support

__version__ = "0.1.0"

__all__ = [
    "Bridge",
    "ConfigError",
    "DataError",
    "InfluenceLines",
    "LoadSweep",
    "Mesh",
    "SensorLayout",
    "SensorplanError",
    "SensorplanWarning",
    "SolverError",
    "Support",
    "Vehicle",
    "bending_moments",
    "expand_ei",
    "influence_lines",
    "support_reactions",
]
