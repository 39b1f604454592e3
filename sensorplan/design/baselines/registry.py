"""The registry of baselines: the rules a recommendation is compared with, by label.

Owns: BaselineRule, BaselineContext, BASELINES, register_baseline, baselines.
May import: nothing of the package.
"""

from collections.abc import Callable
from dataclasses import KW_ONLY, dataclass
from typing import Protocol

__all__ = ["BaselineRule", "BaselineContext", "BASELINES", "register_baseline", "baselines"]


@dataclass(frozen=True)
class BaselineContext:
    """What baselines may use besides the problem: the bridge and the random baseline's settings."""

    length: float
    support_positions: tuple
    _: KW_ONLY
    n_random: int = 100
    rng: object = 0


class BaselineRule(Protocol):
    """A baseline: ``rule(problem, context) -> candidate indices or None``.

    Contract: the indices are a layout of ``problem.count`` candidates of the
    placement problem that meets its constraints (``problem.feasible``), or
    None when the rule cannot meet them.  ``context`` is a
    :class:`BaselineContext`.  The label it is registered under may contain
    ``{n_random}``.
    """

    def __call__(self, problem, context: BaselineContext) -> list | None: ...


BASELINES: dict[str, BaselineRule] = {}


def register_baseline(label) -> Callable[[BaselineRule], BaselineRule]:
    """Register ``function(problem, context)`` under ``label`` (may contain ``{n_random}``)."""
    def decorator(function):
        BASELINES[label] = function
        return function
    return decorator


def baselines(problem, *, length, support_positions, n_random=100, rng=0):
    """Baseline layouts (candidate indices) by name; None where one cannot satisfy the constraints."""
    context = BaselineContext(float(length), tuple(support_positions), n_random=int(n_random), rng=rng)
    return {label.format(n_random=n_random): function(problem, context) for label, function in BASELINES.items()}
