"""The candidates of one step fitted in passes: every one briefly, then only those that may still matter.

Every candidate gets ``first_pass`` Levenberg-Marquardt steps; those not
converged are continued only while they may still reach the level a
decision needs (the best candidate's evidence less ``bf_threshold``, and
the current model's plus ``bf_threshold``).  A candidate that misses what
the data show fits slowly (large residuals, curved valleys) and cannot be
chosen: it is left *abandoned* (not converged, flagged).  In a selection
step only a candidate that reaches the current model's evidence plus
``bf_threshold`` can matter, so there a fit gives up during its first pass
as soon as it cannot reach that; in this process (no executor) the
candidates are fitted in the order given and each later one gives up once
it cannot come within ``bf_threshold`` of an earlier one that passes the
step's tests.  Should those leaders fail the tests, the ones given up below
them are continued (:func:`revive`).

Owns: :func:`fit_models`, :func:`revive`.  May import: the executors, the selection's candidates.
"""

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from ..._executors import map_ordered
from .candidate import Candidate, SelectionContext

__all__ = ["FitTask", "ResumeTask", "fit_models", "revive"]


@dataclass(frozen=True)
class FitTask:
    """Fit the model ``names`` from ``blocks`` for ``max_iter`` steps, giving up below ``floor`` (a worker's job)."""

    ctx: SelectionContext
    names: Sequence[str]
    blocks: Mapping | None
    floor: float | None
    max_iter: int

    def run(self) -> Candidate:
        return self.ctx.fit(self.names, self.blocks, max_iter=self.max_iter, floor=self.floor)


@dataclass(frozen=True)
class ResumeTask:
    """Continue ``candidate`` for ``max_iter`` steps, giving up below ``floor`` (a worker's job)."""

    ctx: SelectionContext
    candidate: Candidate
    floor: float | None
    max_iter: int

    def run(self) -> Candidate:
        return self.ctx.resume(self.candidate, max_iter=self.max_iter, floor=self.floor)


def _run(task):
    """``task`` run, its problem's caches dropped (module level: pickled to worker processes)."""
    return task.run().light()


def fit_models(ctx, models, level, *, policy, runner, say, label, strict=False, eligible=None):
    """{name: Candidate} of ``models`` ({name: (effect names, warm-start blocks or None)}), in passes.

    ``level``: the log evidence a candidate needs to be chosen.  ``runner``:
    an executor or None (this process).  ``strict``: only a candidate that
    reaches ``level`` matters (a selection step, where an alternative must
    be eligible itself), so a fit gives up as soon as its ceiling is below
    it; otherwise (the screening, whose table reports every effect) the
    first pass runs its full budget.  ``eligible(name, candidate)``: whether
    a fitted candidate passes the step's tests (see the module docstring).
    """
    names = list(models)
    prefix = f"{label}: " if label else ""
    early = level if strict else None
    floors = {}
    if strict and runner is None and eligible is not None:
        first, best = [], -math.inf
        for k, n in enumerate(names):
            floors[n] = max(early, best - policy.bf_threshold)
            first.append(_run(FitTask(ctx, models[n][0], models[n][1], floors[n], policy.first_pass)))
            say(f"{prefix}effect {k + 1} of {len(names)}: {n}")
            best = max(best, first[-1].reached)
    else:
        tasks = [FitTask(ctx, models[n][0], models[n][1], early, policy.first_pass) for n in names]
        first = map_ordered(runner, _run, tasks, chunksize=1,
                            progress=lambda k, n: say(f"{prefix}effect {k} of {n}: {names[k - 1]}"))
    out = _continue_slow(ctx, dict(zip(names, first)), level, policy=policy, runner=runner, say=say, prefix=prefix)
    if floors:
        out = revive(ctx, out, floors, early, eligible, policy=policy, say=say, prefix=prefix)
    return out


def revive(ctx, out, floors, level, eligible, *, policy, say, prefix):
    """``out`` with the candidates given up below a leader that then failed the step's tests continued.

    A candidate needs only come within ``bf_threshold`` of the best one that
    passes the tests (and reach ``level``); one given up against a higher
    floor (``floors``) that could still reach this gets a first pass's
    budget more.
    """
    best = max((c.fit.log_evidence for n, c in out.items() if eligible(n, c)), default=-math.inf)
    need = max(level, best - policy.bf_threshold)
    back = [n for n, c in out.items()
            if c.fit is not None and c.fit.abandoned and floors[n] > need and c.fit.ceiling >= need]
    out = dict(out)
    for k, n in enumerate(back):
        say(f"{prefix}continued below a failed leader {k + 1} of {len(back)}: {n}")
        out[n] = _run(ResumeTask(ctx, out[n], need, policy.first_pass))
    return out


def _continue_slow(ctx, out, level, *, policy, runner, say, prefix):
    """``out`` with the second (and third) passes of the candidates not converged that may still matter."""
    reached = [c.fit.log_evidence for c in out.values() if c.fit is not None and math.isfinite(c.fit.log_evidence)]
    if not reached:
        return out
    floor = max(max(reached) - policy.bf_threshold, level)
    slow = [n for n, c in out.items() if c.fit is not None and not c.fit.converged]
    todo = [n for n in slow if out[n].fit.ceiling >= floor]
    out = {n: c.given_up() if n in slow and n not in todo else c for n, c in out.items()}
    if not todo:
        return out
    again = map_ordered(runner, _run, [ResumeTask(ctx, out[n], floor, policy.second_pass) for n in todo], chunksize=1,
                        progress=lambda k, n: say(f"{prefix}continued {k} of {n}: {todo[k - 1]}"))
    out.update(zip(todo, again))
    # the leader still crawling (a strongly nonlinear effect on precise data) gets one more pass, as it alone
    # can decide the step
    done = [c.fit.log_evidence for c in out.values() if c.fit is not None and c.fit.converged]
    best = max(todo, key=lambda n: -math.inf if out[n].fit is None else out[n].fit.log_evidence)
    fit = out[best].fit
    if (fit is not None and not fit.converged and not fit.abandoned and math.isfinite(fit.log_evidence)
            and fit.log_evidence >= max(done, default=-math.inf) + policy.bf_threshold):
        say(f"{prefix}continued further: {best}")
        out[best] = _run(ResumeTask(ctx, out[best], floor, policy.third_pass))
    return out
