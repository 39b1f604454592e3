"""The acquisition layer: from a data logger's continuous record to crossings.

Each candidate event is tested: does the case's vehicle (entry time and speed
searched, load factor free) explain it significantly better than wander +
noise under the noise model in time, at a stated false-event rate?  Bursts
are masked first; accepted events are refined (entry time, speed, 95 %
intervals) and written as readings against load position.

Owns: :func:`extract_crossings`, :class:`ExtractedCrossings`, :class:`CrossingEvent`, the test
(:func:`assess_record`) and its parts.
May import: the foundations and model (never inference, design, io or anything above).
"""

from .extract import extract_crossings
from .fit import Template
from .glr import Policy, RecordTest, assess_record
from .results import REASONS, CrossingEvent, ExtractedCrossings

__all__ = ["extract_crossings", "ExtractedCrossings", "CrossingEvent", "REASONS", "Template",
           "Policy", "RecordTest", "assess_record"]
