"""Result types of the placement: the design, its baselines, solver statistics, the curve.

Owns: DesignResult, Baseline, SolverStats, CurvePoint.  May import: model, errors.
"""

from dataclasses import dataclass, field

import numpy as np

__all__ = ["DesignResult", "Baseline", "SolverStats", "CurvePoint"]


def _jsonable(v):
    return isinstance(v, (str, int, float, bool, type(None)))


@dataclass(frozen=True)
class Baseline:
    """A baseline layout, its criterion value and its efficiency relative to the recommended layout.

    ``layout_m`` is None when the baseline cannot meet the constraints;
    ``layout_kind`` is the kind of each sensor, ``cost`` the layout's total cost (with a budget).
    """

    name: str
    layout_m: tuple | None
    value: float | None
    relative: float | None = None
    layout_kind: tuple = ()
    cost: float | None = None

    @property
    def feasible(self) -> bool:
        return self.layout_m is not None

    def to_dict(self):
        if not self.feasible:
            return None
        out = {"layout_m": list(self.layout_m), "layout_kind": list(self.layout_kind), "value": self.value}
        if self.cost is not None:
            out["cost"] = self.cost
        return out


@dataclass(frozen=True)
class SolverStats:
    """How the relaxation was solved.

    Attributes
    ----------
    solver : str
    status : str
        "optimal" when the certified gap met the tolerance.
    relative_gap : float
        (bound - utility) / max(1, |bound|) of the relaxation.
    time_s : float
    method : str
        Solver path ("fast" or "cvxpy-clarabel").
    details : dict
        Solver-specific counters (rounds, working set, iterations, fallbacks, warnings).
    """

    solver: str
    status: str
    relative_gap: float
    time_s: float
    method: str
    details: dict = field(default_factory=dict)

    @property
    def optimal(self) -> bool:
        return self.status == "optimal"

    def to_dict(self):
        out = {k: v for k, v in self.details.items() if _jsonable(v)}
        out.update(solver=self.solver, status=self.status, relative_gap=self.relative_gap, time_s=self.time_s,
                   relaxation_method=self.method)
        return out


@dataclass(frozen=True)
class CurvePoint:
    """Criterion of the best layout found and the relaxation bound for ``count`` sensors.

    ``value`` and ``bound`` are None when that count failed (``reason`` says why).
    """

    count: int
    value: float | None
    bound: float | None
    reason: str = ""

    @property
    def failed(self) -> bool:
        return self.value is None

    def to_dict(self):
        out = {"count": self.count, "value": self.value, "bound": self.bound}
        if self.failed:
            out["failed"] = self.reason
        return out


@dataclass(frozen=True, eq=False)
class DesignResult:
    """A recommended layout with its certificate and the baselines.

    Attributes
    ----------
    criterion : str
    description : str
        What the criterion measures.
    maximise : bool
        Whether larger criterion values are better.
    count : int
        Number of new sensors.
    n_params : int
        Dimension of the per-parameter efficiency.
    layout_m : tuple of float
        Sorted positions of the recommended sensors [m].
    value : float
        Criterion value of the layout.
    bound : float
        Relaxation bound on the criterion of every feasible layout (upper when
        maximised, lower otherwise), certified by a dual bound.
    efficiency : float
        Certified lower bound on the layout's efficiency against the best
        possible layout (not a proof of optimality unless it is 1).
    method : str
        How the layout was found.
    baselines : tuple of Baseline
    solver : SolverStats
    curve : tuple of CurvePoint
        Criterion versus number of sensors.
    informativeness : FisherBlocks
        Fisher blocks (EI parameters) of the recommended sensors.
    details, detail_line : dict, str
        Criterion-specific results of the layout (detect: worst centre, d, power) for the JSON and
        the summary; ``params_label`` says what ``n_params`` counts.
    layout_kind : tuple of str
        Kind of each recommended sensor (parallel to ``layout_m``).
    fixed_kind, fixed_noise_std : tuple
        Kind and noise std [rad or m] of each existing sensor (parallel to ``fixed_m``).
    noise_std : dict
        Noise std [rad or m] of new sensors of each candidate kind.
    cost, budget : float or None
        Total cost of the recommended sensors and the budget (None without a budget).
    support_notes : tuple of str
        One sentence per recommended sensor that sits on a support: where, and what it reads there.
    support_margin_m : float
        Smallest distance [m] of a new sensor from every support the candidates kept (0: none).
    """

    criterion: str
    description: str
    maximise: bool
    count: int
    n_params: int
    layout_m: tuple
    value: float
    bound: float
    efficiency: float
    method: str
    baselines: tuple
    solver: SolverStats
    candidates_m: np.ndarray
    weights: np.ndarray
    fixed_m: tuple = ()
    curve: tuple = ()
    kind: str = "rotation"
    layout_index: tuple = field(default=(), repr=False)
    edges: np.ndarray | None = None
    supports_m: tuple = ()
    posterior_std: dict = field(default_factory=dict)
    informativeness: object = field(default=None, repr=False)
    details: dict = field(default_factory=dict)
    detail_line: str = ""
    params_label: str = "parameters"
    layout_kind: tuple = ()
    fixed_kind: tuple = ()
    fixed_noise_std: tuple = ()
    noise_std: dict = field(default_factory=dict)
    cost: float | None = None
    budget: float | None = None
    support_notes: tuple = ()
    support_margin_m: float = 0.0

    @property
    def mixed(self) -> bool:
        """Whether the candidates or the existing sensors are of more than one kind."""
        return len(set(self.layout_kind) | set(self.fixed_kind) | set(self.kind.split("+"))) > 1

    def _positions(self, xs, kinds):
        if not self.mixed:
            return ", ".join(f"{x:.2f}" for x in xs)
        return ", ".join(f"{x:.2f} ({k})" for x, k in zip(xs, kinds))

    def baseline(self, name):
        """The baseline called ``name``."""
        for b in self.baselines:
            if b.name == name:
                return b
        raise KeyError(name)

    def summary(self):
        kind = self.kind.replace("+", " or ")
        lines = [f"Recommended {self.count} {kind} sensor(s), {self.criterion}-optimal "
                 f"({self.description}, {self.n_params} {self.params_label})",
                 "  positions [m]: " + self._positions(self.layout_m, self.layout_kind)]
        if self.fixed_m:
            lines.append("  existing sensors [m]: " + self._positions(self.fixed_m, self.fixed_kind))
        if self.budget is not None:
            lines.append(f"  cost {self.cost:g} of a budget of {self.budget:g}")
        if self.support_margin_m > 0:
            lines.append(f"  candidates kept at least {self.support_margin_m:g} m from every support")
        lines += [f"  {note}" for note in self.support_notes]
        gap = self.value - self.bound  # a maximised criterion sits below its bound, a minimised one above
        side = "below" if gap < 0 else "above"
        how = "relaxation" if self.solver.details.get("bound_method", "relaxation") == "relaxation" else "exact"
        lines.append(f"  criterion {self.value:.6g}; {how} bound {self.bound:.6g}, {abs(gap):.3g} {side} it; "
                     f"certified efficiency >= {100 * self.efficiency:.2f} %  (method: {self.method})")
        if how == "exact":
            lines.append(f"  bound: {self.solver.details['bound_method']}")
        if self.detail_line:
            lines.append(self.detail_line)
        s = self.solver
        lines.append(f"  relaxation: {s.solver}, status {s.status}, relative duality gap "
                     f"{s.relative_gap:.1e}, {s.time_s:.2f} s"
                     + ("" if s.optimal else "  <- NOT optimal: treat the bound with care"))
        lines.append(f"  {'baseline':28s} {'criterion':>12s} {'vs layout':>10s}  positions [m]")
        for b in self.baselines:
            if not b.feasible:
                lines.append(f"  {b.name:28s} {'infeasible':>12s}")
                continue
            lines.append(f"  {b.name:28s} {b.value:12.6g} {100 * b.relative:9.1f}%  "
                         + self._positions(b.layout_m, b.layout_kind))
        failed = [p for p in self.curve if p.failed]
        if failed:
            lines.append("  criterion vs R failed for R = " + ", ".join(_runs(failed)))
        return "\n".join(lines)

    def best_baseline(self):
        """Name of the best feasible baseline (None if none is feasible)."""
        sign = 1.0 if self.maximise else -1.0
        feasible = [b for b in self.baselines if b.feasible]
        return max(feasible, key=lambda b: sign * b.value).name if feasible else None

    def to_dict(self):
        return {
            "criterion": self.criterion,
            "count": self.count,
            "n_params": self.n_params,
            "layout_m": list(self.layout_m),
            "layout_kind": list(self.layout_kind),
            "value": self.value,
            "bound": self.bound,
            "efficiency": self.efficiency,
            "method": self.method,
            "baselines": {b.name: b.to_dict() for b in self.baselines},
            "fixed_m": list(self.fixed_m),
            "fixed_kind": list(self.fixed_kind),
            "fixed_noise_std": list(self.fixed_noise_std),
            "kind": self.kind,
            "noise_std": dict(self.noise_std),
            "cost": self.cost,
            "budget": self.budget,
            "solver": self.solver.to_dict(),
            "curve": [p.to_dict() for p in self.curve],
            **self.details,
            **({"support_margin_m": self.support_margin_m} if self.support_margin_m > 0 else {}),
        }


def _runs(points):
    """'a-b (reason)' for each run of consecutive counts that failed for the same reason ('a (reason)' alone)."""
    runs = []
    for p in points:
        if runs and runs[-1][2] == p.reason and runs[-1][1] == p.count - 1:
            runs[-1][1] = p.count
        else:
            runs.append([p.count, p.count, p.reason])
    return [(f"{a}" if a == b else f"{a}-{b}") + f" ({reason})" for a, b, reason in runs]
