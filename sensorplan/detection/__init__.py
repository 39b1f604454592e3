"""Damage detection: the physical limit of detection, and a detector that reaches it.

:mod:`.nuisance` says what an undamaged bridge may do (smooth or per-span EI
changes); :mod:`.signatures` computes, per sensor, the whitened damage
signature of a local EI loss (exact forward difference) and the whitened
columns of the nuisance it competes with (plus the elastic support springs);
:mod:`.detectability` turns them into a map of the optimal detection power
and the smallest detectable loss along the bridge (:mod:`.results` holds the
result type); :mod:`.scan` is the detector's test: a scan over zones of a fitted null
model with a calibrated false-alarm rate and the estimates of the zone and
the loss (the null fit itself is an engine problem,
:mod:`sensorplan.inference.detector`, which also holds ``detect_damage``).  The
per-sensor Gram matrices of :meth:`.signatures.Signatures.grams` are what a
design criterion sums over a layout (:func:`.signatures.schur_d_squared`).

Owns: damage signatures, nuisance projection, detectability maps, the detector's scan.
May import: model and the foundations.
"""
