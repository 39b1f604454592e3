"""Optimal sensor placement: criteria, the placement problem, relaxations, integer layouts.

:mod:`.criteria` (one class per criterion behind one protocol, a registry
and one module per criterion family), :mod:`.problem` (candidates, blocks,
constraints, the linear oracle), :mod:`.candidates` and :mod:`.feasibility`
(what may be placed where), :mod:`.detect_problem` (the information of the
detect criterion), :mod:`.relaxation` (result type, solver registry, one
module per solver), :mod:`.selection` (greedy, exchange, rounding, the best
of several starts), :mod:`.baselines` (registry and the built-in rules),
:mod:`.recommend` and :mod:`.results`; :mod:`.supports` (the support margin,
what a sensor on a support reads); design to a required detection power:
:mod:`.target` (:func:`~.target.design_for_target`), :mod:`.target_levels`,
:mod:`.target_results` and :mod:`.exact` (the exact search that proves a
count too small).

Owns: everything about choosing a layout.
May import: model, detection and the foundations.
"""
