"""Detectability: the physical limit of damage detection, before any inversion.

:mod:`.signatures` computes, per sensor, the whitened damage signature of a
local EI loss (exact forward difference) and the whitened columns of the
nuisance it competes with (smooth or per-span EI changes, elastic support
springs); :mod:`.detectability` turns them into a map of the optimal
detection power and the smallest detectable loss along the bridge;
:mod:`.results` holds the result type.  The per-sensor Gram matrices of
:meth:`.signatures.Signatures.grams` are what a design criterion sums over
a layout (:func:`.signatures.schur_d_squared`).

Owns: damage signatures, nuisance projection, detectability maps.
May import: model and the foundations.
"""
