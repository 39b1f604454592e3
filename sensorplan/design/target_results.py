"""Result types of the design to a required detection power: TargetAnswer, CountTrial, TargetDesign.

Owns: the answer (what the ``target`` key of ``design.json`` holds), the
per-count record of the search and their text.  May import: errors, design, detection.
"""

import math
from dataclasses import dataclass

__all__ = ["TargetAnswer", "CountTrial", "TargetDesign", "MINIMALITY"]

# how it was established that no smaller count (cheaper layout) reaches the power, or, when none does,
# that no allowed count reaches it
MINIMALITY = ("trivial", "relaxation bound", "exhaustive", "not proven")


def floor3(value):
    """``value`` rounded down to 3 decimals (a power is never shown higher than it is)."""
    return math.floor(value * 1000.0 + 1e-9) / 1000.0


@dataclass(frozen=True)
class TargetAnswer:
    """Whether the required worst-case power is reached, with how many sensors, and the crossings needed.

    Attributes
    ----------
    power : float
        The required worst-case power P.
    met : bool
        Whether an allowed count (layout within the budget) reaches it.
    count : int
        Sensors of the layout returned: the smallest count that reaches P, or the cap when none does.
    worst_case_power : float
        That layout's worst-case power over the damage centres, as ``detectability`` computes it.
    crossings_needed : int or None
        When not met: the smallest number of crossings with which that layout reaches P (checked with
        ``detectability``), None when no number does (a centre the layout does not see at all); None when met.
    minimality : str
        One of :data:`MINIMALITY`: how it was established that no smaller count (no cheaper level with
        costs) reaches P, or, when not met, that no allowed count does: ``"trivial"`` (the smallest allowed
        count reaches it), ``"relaxation bound"`` (the certified bound of the detect relaxation is below the
        required d^2), ``"exhaustive"`` (an exact search over every layout, :mod:`.exact`) or ``"not proven"``.
    cost : float or None
        The layout's cost (with a budget).
    """

    power: float
    met: bool
    count: int
    worst_case_power: float
    crossings_needed: int | None
    minimality: str
    cost: float | None = None

    def to_dict(self):
        out = {"power": self.power, "met": self.met, "count": self.count,
               "worst_case_power": self.worst_case_power, "crossings_needed": self.crossings_needed,
               "minimality": self.minimality}
        if self.cost is not None:
            out["cost"] = self.cost
        return out


@dataclass(frozen=True)
class CountTrial:
    """One count (and budget level) tried: the best layout found, its worst-case power and the bound.

    ``outcome`` is ``"reached"``, or how it is known that no layout of this level reaches the power:
    ``"relaxation bound"``, ``"exhaustive"``, ``"implied"`` (a larger count does not reach it either and
    adding a sensor never lowers the power), ``"infeasible"`` (no layout meets the constraints) or
    ``"not proven"``.  ``bound_power`` is the power of the certified relaxation bound (no layout of this
    level does better); ``method`` how the layout was found; ``note`` why an exact search did not settle it.
    """

    count: int
    budget: float | None
    layout_m: tuple
    worst_case_power: float | None
    bound_power: float | None
    outcome: str
    method: str
    time_s: float
    note: str = ""

    def to_dict(self):
        out = {"count": self.count, "budget": self.budget, "layout_m": list(self.layout_m),
               "worst_case_power": self.worst_case_power, "bound_power": self.bound_power,
               "outcome": self.outcome, "method": self.method, "time_s": self.time_s}
        if self.note:
            out["note"] = self.note
        return out

    def line(self, power):
        """One line of the summary's table, for the required ``power``."""
        budget = "" if self.budget is None else f" (cost <= {self.budget:g})"
        head = f"{self.count:3d} sensor(s){budget}: "
        if self.worst_case_power is None:
            return head + _OUTCOMES[self.outcome].format(power=power)
        return (head + f"worst-case power {floor3(self.worst_case_power):.3f}, at most {floor3(self.bound_power):.3f} "
                f"for any layout: {_OUTCOMES[self.outcome].format(power=power)} ({self.method}, {self.time_s:.1f} s)"
                + (f"; {self.note}" if self.note else ""))


_OUTCOMES = {"reached": "reaches {power:g}",
             "relaxation bound": "no layout reaches {power:g} (certified by the relaxation bound)",
             "exhaustive": "no layout reaches {power:g} (exhaustive search)",
             "implied": "no layout reaches {power:g} (implied: more sensors do not either)",
             "infeasible": "no layout meets the constraints",
             "not proven": "short; whether another layout reaches {power:g} is not proven",
             "pending": "short (proven later if needed)"}


@dataclass(frozen=True, eq=False)
class TargetDesign:
    """A layout designed to reach a required worst-case detection power (:func:`design_for_target`).

    Attributes
    ----------
    design : DesignResult
        The detect-optimal layout returned (the answer's count), as :func:`recommend` reports a layout.
    answer : TargetAnswer
    trials : tuple of CountTrial
        Every count (budget level) tried, smallest first.
    detectability : DetectabilityMap
        The map of the layout returned (and the existing sensors), at the design's crossings.
    region : tuple of float or None
        The damage centres the worst case runs over (None: the whole bridge).
    """

    design: object
    answer: TargetAnswer
    trials: tuple
    detectability: object
    region: tuple | None = None

    def headline(self):
        """One sentence: sufficient or not, for which loss, and what would make it sufficient."""
        a, m = self.answer, self.detectability
        where = ("anywhere on the bridge" if self.region is None
                 else f"centred anywhere in {self.region[0]:g}-{self.region[1]:g} m")
        loss = (f"a {100 * m.severity:g} % EI loss over {m.length_m:g} m {where} ({m.n_crossings} crossing(s), "
                f"false-alarm rate {100 * m.false_alarm_rate:g} %)")
        sensors = _sensors(a.count, self.design.layout_kind, len(self.design.fixed_m)) + (
            "" if a.cost is None else f" (cost {a.cost:g})")
        if a.met:
            return (f"Sufficient: {sensors} reach a worst-case power of {floor3(a.worst_case_power):.3f} >= "
                    f"{a.power:g} for {loss}{_fewer(a)}.")
        more = (f"{a.crossings_needed} crossings would reach {a.power:g} with that layout"
                if a.crossings_needed is not None else
                "no number of crossings reaches it with that layout (it does not see a loss at every centre)")
        return (f"Not sufficient: with the cap of {sensors} the worst-case power is "
                f"{floor3(a.worst_case_power):.3f} < {a.power:g} for {loss}{_none(a)}; {more}.")

    def summary(self):
        lines = [self.headline(), "  counts tried:"] + ["    " + t.line(self.answer.power) for t in self.trials]
        return "\n".join(lines + [self.design.summary()])

    def to_dict(self):
        target = self.answer.to_dict()
        target["tried"] = [t.to_dict() for t in self.trials]
        return {**self.design.to_dict(), "target": target}


def _sensors(count, kinds, existing=0):
    """"3 rotation sensor(s)", or "3 sensors (2 rotation, 1 deflection)" when the kinds differ; with existing
    sensors "3 new rotation sensor(s) and the 2 existing"."""
    names = sorted(set(kinds))
    new = "new " if existing else ""
    text = (f"{count} {new}{names[0]} sensor(s)" if len(names) == 1 else
            f"{count} {new}sensors (" + ", ".join(f"{list(kinds).count(k)} {k}" for k in names) + ")")
    return text + (f" and the {existing} existing" if existing else "")


_HOW = {"relaxation bound": "certified by the relaxation bound", "exhaustive": "exhaustive search over every layout"}


def _fewer(answer):
    """What is known of fewer sensors (a cheaper layout) when the answer is met."""
    fewer = "fewer sensors" if answer.cost is None else "a cheaper layout"
    if answer.minimality == "trivial":
        return ""
    if answer.minimality in _HOW:
        return f"; {fewer} cannot ({_HOW[answer.minimality]})"
    return f"; whether {fewer} could is not proven (the bound is not conclusive and an exhaustive search too long)"


def _none(answer):
    """What is known of the other allowed counts when the answer is not met."""
    if answer.minimality in _HOW:
        return f"; no allowed layout reaches it ({_HOW[answer.minimality]})"
    return "; whether another allowed layout reaches it is not proven"
