"""The acquisition layer: from a data logger's continuous record to crossings.

Event detection against a robust noise floor, removal of each event's
offset and drift, and the fit of entry time and constant speed per crossing
with the model's influence lines.

Owns: :func:`extract_crossings`, :class:`ExtractedCrossings`, :class:`CrossingEvent`.
May import: the foundations and model (never inference, design, io or anything above).
"""

from .extract import extract_crossings
from .fit import Template, VehicleFit, fit_vehicles
from .results import REASONS, CrossingEvent, ExtractedCrossings

__all__ = ["extract_crossings", "ExtractedCrossings", "CrossingEvent", "REASONS", "Template", "VehicleFit",
           "fit_vehicles"]
