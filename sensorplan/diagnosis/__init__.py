"""Sim-to-real gap diagnosis: candidate effects, joint refits, selection, verdicts.

Three rooms: :mod:`.effects` (the library of parametric model extensions
and its registry), :mod:`.joint` (the case's model extended by effects,
fitted jointly with log EI), :mod:`.selection` (which effects explain the
gap); :mod:`.diagnose` runs the diagnosis (gap, screening, selection, final
refit, confounding) into a :class:`~.results.GapDiagnosis`.

Owns: effects, joint fits, verdicts.
May import: inference, design, model and the foundations.
"""
