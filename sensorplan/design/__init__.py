"""Optimal sensor placement: criteria, the placement problem, relaxations, integer layouts.

:mod:`.criteria` (one class per criterion behind one protocol, and a
registry), :mod:`.problem` (candidates, blocks, constraints, the linear
oracle), :mod:`.relaxation` (result type and solver registry) with one
module per solver (:mod:`.relax_cvxpy`, :mod:`.relax_ipm`,
:mod:`.relax_eigen`), :mod:`.selection` (greedy, exchange, rounding),
:mod:`.baselines` (registry), :mod:`.recommend` and :mod:`.results`.

Owns: everything about choosing a layout.
May import: model, detection and the foundations.
"""
