"""Damage detection: what a layout can detect, and a detector that reaches it.

:mod:`.nuisance` (what an undamaged bridge may do), :mod:`.scan` (the scan
test with a calibrated false-alarm rate and the estimates of the zone and the
loss).

Owns: detectability and damage detection.
May import: model and the foundations.
"""
