"""Sim-to-real gap diagnosis: candidate effects, joint refits, verdicts.

:mod:`.effects` (the library of parametric model extensions),
:mod:`.joint` (the case's model extended by effects, on the shared
inference base), :mod:`.diagnose` (gap, Bayes factors, held-out scores,
selection, confounding).

Owns: effects, joint fits, verdicts.
May import: inference, design, model and the foundations.
"""
