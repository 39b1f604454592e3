"""The diagnosis's selection context: refits of the joint model shared by every step (:class:`SelectionContext`).

Owns: :class:`DiagnosisContext`.  May import: the joint model, the selection's refits and held-out scores.
"""

import math
from collections.abc import Mapping
from dataclasses import KW_ONLY, dataclass, replace
from typing import Any

import numpy as np

from ..joint.fits import warm_start
from ..joint.problem import JointProblem
from .candidate import Candidate
from .heldout import heldout
from .policy import DEFAULT_POLICY, SelectionPolicy
from .refit import quick_fit

__all__ = ["DiagnosisContext"]


@dataclass(frozen=True, eq=False)
class DiagnosisContext:
    """What every refit shares: the data, the candidate effects, the base fit's hyperparameters and blocks, the folds.

    ``effects``: effect name -> effect object (the candidates);
    ``noise_scale``, ``tau``: the hyperparameters the fits are made at;
    ``blocks``: the base fit's parameters by block (the default warm
    start); ``test_masks``: the folds' held-out rows; ``predictions``: the
    nominal model's per crossing (for the effects' moment estimates).
    """

    case: Any
    crossings: Any
    _: KW_ONLY
    prior: Any
    effects: Mapping
    estimate_springs: bool
    noise_scale: float
    tau: float
    blocks: Mapping
    test_masks: list
    predictions: list
    policy: SelectionPolicy = DEFAULT_POLICY

    def problem(self, names):
        """The joint problem of the model ``names`` on the context's data."""
        return JointProblem(self.case, self.crossings, [self.effects[n] for n in names], self.prior,
                            estimate_springs=self.estimate_springs)

    def fit(self, names, blocks=None, *, initial=True, max_iter=40, floor=None, budget=False):
        problem = self.problem(names)
        start = warm_start(problem, self.blocks if blocks is None else blocks)
        block, sl = problem.block(names[-1])
        init = block.effect.initial(block, problem, self.predictions) if initial else None
        if init is not None:
            # a moment estimate against the nominal model (a sign flip, a unit slip): the base MAP is
            # distorted by exactly what the effect explains, so this fit starts from the nominal EI
            start = warm_start(problem, {"log_ei": problem.theta0[:problem.n_elements]} if blocks is None
                               else blocks)
            start[sl] = init
        options = dict(max_iter=max_iter, floor=floor, budget=budget, policy=self.policy)
        fit = quick_fit(problem, start, self.noise_scale, self.tau, **options)
        distorted = self.noise_scale > self.policy.distorted  # the noise scale of the model the fit starts from
        if block.effect.frees and initial and distorted and (fit is None or not (fit.converged or fit.abandoned)):
            fit = self._nominal_start(problem, start, fit, options)
        return self.score(fit)

    def _nominal_start(self, problem, start, fit, options):
        """The better of ``fit`` and a fit from the nominal EI and springs (the output effects' blocks kept).

        A support that settles or restrains is what a distorted base EI
        twisted to mimic: from there the spring's fit crawls or stops in a
        worse optimum.
        """
        nominal = problem.theta0.copy()
        for b, s in zip(problem.blocks, problem.slices):
            nominal[s] = b.effect.restart(b, start[s])
        cold = quick_fit(problem, nominal, self.noise_scale, self.tau, **options)
        if cold is not None and (fit is None or (cold.converged, cold.log_evidence) > (fit.converged,
                                                                                         fit.log_evidence)):
            return cold
        return fit

    def resume(self, candidate, *, max_iter=40, floor=None):
        fit = candidate.fit
        return self.score(quick_fit(fit.problem, fit.theta, self.noise_scale, self.tau, max_iter=max_iter, floor=floor,
                                    policy=self.policy))

    def score(self, fit):
        """The :class:`Candidate` of ``fit``: scored on the folds when it converged."""
        return Candidate(fit, heldout(fit, self.test_masks) if fit is not None and fit.converged else None)

    def rescaled(self, candidate):
        """The context at the noise scale re-estimated at ``candidate``'s MAP, and the candidate refitted there.

        MacKay's fixed point alpha^2 = |r|^2 / (N - gamma) is iterated
        (refit, re-estimate) until the scale moves by less than
        ``policy.rescale_rtol``: one step from a fit made at the inflated
        scale of the model before a pick stops short.  The scale only
        shrinks (the base fit's bounds it).  A refit that does not converge
        at the smaller scale (EI twisting to absorb what the model misses) is
        kept there with the evidence it could still reach (its ceiling), so
        that the next pick must beat an optimistic bound of it.  Returns
        (context, refitted candidate or None: keep ``candidate``).
        """
        ctx, current, held = self, candidate.fit, None
        for _ in range(self.policy.rescale_rounds):
            alpha = _evidence_noise_scale(current)
            if alpha is None or not alpha < ctx.noise_scale:
                break
            fit = quick_fit(current.problem, current.theta, alpha, ctx.tau, max_iter=self.policy.rescale_max_iter,
                            policy=self.policy)
            if fit is None or not math.isfinite(fit.ceiling):
                break
            step = 1.0 - alpha / ctx.noise_scale
            ctx = replace(ctx, noise_scale=alpha)
            if not fit.converged:
                held = heldout(fit, ctx.test_masks)
                return ctx, None if held is None else Candidate(replace(fit, log_evidence=fit.ceiling), held)
            current, held = fit, heldout(fit, ctx.test_masks)
            if step < self.policy.rescale_rtol:
                break
        return ctx, None if held is None else Candidate(current, held)


def _evidence_noise_scale(fit):
    """alpha = sqrt(|r|^2 / (N - gamma)) at ``fit``'s MAP (None when it cannot be formed).

    gamma = tr(H^-1 J^T J) / alpha^2 is the effective number of parameters
    the data determine (the maximum-likelihood |r|^2 / N would be biased low
    by them).
    """
    lin = fit.problem.evaluate(fit.theta)
    if lin is None or lin.jtj is None:
        return None
    gamma = float(np.trace(np.linalg.solve(fit.hessian, lin.jtj))) / fit.noise_scale**2
    dof = fit.problem.n_data - gamma
    if dof <= 1.0:
        return None
    return math.sqrt(max(lin.rr / dof, 1e-300))
