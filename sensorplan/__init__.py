"""sensorplan: where to put tiltmeters so that EI(x) of a bridge can be identified.

The public API is listed in ``__all__`` and loaded lazily (PEP 562), so that
``import sensorplan`` is cheap and the command line can configure the
numerical libraries before they load.  Modules with a leading underscore
are private.  Importing sensorplan never imports matplotlib; figures live in
:mod:`sensorplan.plotting`.
"""

import importlib

__version__ = "0.1.0"

_EXPORTS = {
    "SensorplanError": "_errors", "ConfigError": "_errors", "DataError": "_errors",
    "SolverError": "_errors", "SensorplanWarning": "_errors",
    "Support": "_structure", "Bridge": "_structure", "Mesh": "_structure",
    "Vehicle": "_loads", "LoadSweep": "_loads",
    "SensorLayout": "_sensors",
    "NoiseModel": "_noise",
    "GMRFPrior": "_prior",
    "Case": "_case",
    "InfluenceLines": "_forward", "influence_lines": "_forward", "bending_moments": "_forward",
    "support_reactions": "_forward", "expand_ei": "_forward",
    "load_case": "_config", "example_case": "_config", "EXAMPLES": "_config",
    "Crossing": "_crossings", "Crossings": "_crossings",
    "read_crossings": "_csvio", "write_crossings": "_csvio",
    "simulate_crossings": "_simulate",
    "FisherBlocks": "_fisher", "fisher_blocks": "_fisher",
    "Identifiability": "_fisher", "identifiability": "_fisher",
    "PosteriorResult": "_posterior", "invert": "_inversion",
    "DesignResult": "_design", "recommend": "_design",
    "VerificationResult": "_verification", "verify_layouts": "_verification",
    "GapDiagnosis": "_diagnosis", "diagnose": "_diagnosis",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name):
    try:
        module = _EXPORTS[name]
    except KeyError:
        raise AttributeError(f"module 'sensorplan' has no attribute {name!r}") from None
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
