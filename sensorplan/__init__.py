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
    "Support": "model.structure", "Bridge": "model.structure", "Mesh": "model.structure",
    "Vehicle": "model.loads", "LoadSweep": "model.loads",
    "SensorLayout": "model.sensors",
    "NoiseModel": "model.noise",
    "GMRFPrior": "model.prior", "HyperPrior": "model.prior",
    "Case": "model.case",
    "InfluenceLines": "model.forward", "influence_lines": "model.forward", "bending_moments": "model.forward",
    "support_reactions": "model.forward", "expand_ei": "model.forward",
    "load_case": "io.config", "example_case": "io.config", "EXAMPLES": "io.config",
    "Crossing": "model.crossings", "Crossings": "model.crossings",
    "read_crossings": "io.csvio", "write_crossings": "io.csvio",
    "simulate_crossings": "model.simulate",
    "TimeSeries": "model.timeseries", "LoggerFormat": "model.timeseries", "read_timeseries": "io.logger",
    "extract_crossings": "acquisition.extract", "ExtractedCrossings": "acquisition.results",
    "CrossingEvent": "acquisition.results",
    "FisherBlocks": "model.fisher", "fisher_blocks": "model.fisher",
    "Identifiability": "model.fisher", "identifiability": "model.fisher",
    "Informativeness": "model.fisher", "informativeness": "model.fisher",
    "DetectabilityMap": "detection.results", "detectability": "detection.detectability",
    "DamageDetection": "detection.scan", "detect_damage": "inference.detector",
    "PosteriorResult": "inference.posterior", "CrossingFit": "inference.posterior", "invert": "inference.inversion",
    "GaussianMixture": "inference.mixture",
    "DesignResult": "design.results", "Baseline": "design.results", "SolverStats": "design.results",
    "CurvePoint": "design.results", "recommend": "design.recommend", "CandidateGrid": "design.recommend",
    "Constraints": "design.recommend", "DetectionTarget": "design.recommend", "Criterion": "design.criteria", "register_criterion": "design.criteria",
    "CRITERIA": "design.criteria", "design_for_target": "design.target",
    "crossing_trade": "design.crossing_trade", "CrossingTrade": "design.crossing_trade",
    "TargetDesign": "design.target_results", "TargetAnswer": "design.target_results", "CountTrial": "design.target_results",
    "VerificationResult": "verification.results", "LayoutScore": "verification.results",
    "Metric": "verification.results", "Scenario": "verification.scenarios", "Analysis": "analysis", "analyse": "analysis", "verify_layouts": "verification.verify",
    "GapDiagnosis": "diagnosis.results", "EffectFit": "diagnosis.results", "Gap": "diagnosis.results",
    "Confounding": "diagnosis.results", "diagnose": "diagnosis.diagnose",
    "design_study": "verification.study", "DesignStudy": "verification.study", "StudyRow": "verification.study",
    "ExecutorError": "_errors", "keep_freed_memory": "_allocator",
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
