"""Baseline layouts a recommendation is compared with, behind one registry.

A baseline is a rule ``(problem, context) -> candidate indices or None``
(:class:`~.registry.BaselineRule`) registered under a label (formatted with
the context's fields); None means the baseline cannot satisfy the
constraints.  :mod:`.registry` holds the registry and :func:`baselines`,
:mod:`.rules` the built-in rules; importing this package loads them.

Owns: the baselines.  May import: design.problem.
"""

from .registry import BASELINES, BaselineContext, BaselineRule, baselines, register_baseline
from .rules import best_random, effective_independence, equally_spaced, rule_of_thumb  # noqa: F401  (register)

__all__ = ["BASELINES", "BaselineContext", "BaselineRule", "register_baseline", "baselines"]
