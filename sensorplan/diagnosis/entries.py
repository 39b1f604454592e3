"""The diagnosis's findings from its fits: each candidate's entry and the corrected model.

Owns: :func:`effect_entry`, :func:`corrected_model`.  May import: the diagnosis's results.
"""

import math

import numpy as np

from .results import CorrectedModel, EffectFit

__all__ = ["corrected_model", "effect_entry"]


def effect_entry(name, candidate, base, ei_base):
    """The :class:`EffectFit` of effect ``name`` fitted alone (``candidate``) against the ``base`` candidate."""
    fit, held = candidate.fit, candidate.held
    if fit is None:
        return EffectFit(name, log_bayes_factor=math.nan, heldout_score_gain=None, rms_after=math.nan,
                         heldout_rms_after=None, parameters={}, ei_shift=(), max_ei_shift=math.nan, converged=False)
    problem = fit.problem
    block, sl = problem.block(name)
    std = np.sqrt(np.clip(np.diag(fit.covariance)[sl], 0, None))
    shift = np.exp(fit.theta[:problem.n_elements]) / ei_base - 1.0
    gain = None if held is None or base.held is None else float(np.sum(held.log_density - base.held.log_density))
    res = np.concatenate([r.ravel() for r in problem.residuals(fit.theta)])
    return EffectFit(
        name, log_bayes_factor=float(fit.log_evidence - base.fit.log_evidence), heldout_score_gain=gain,
        rms_after=float(math.sqrt(np.mean(res**2))), heldout_rms_after=None if held is None else held.rms,
        parameters={n: {"map": float(v), "std": float(s)} for n, v, s in zip(block.names, fit.theta[sl], std)},
        ei_shift=tuple(shift.tolist()), max_ei_shift=float(np.max(np.abs(shift))), converged=fit.converged,
        abandoned=fit.abandoned, findings=tuple(block.effect.describe(block, problem, fit.theta[sl], std)))


def corrected_model(problem, theta, std):
    """The :class:`CorrectedModel` of ``problem`` at ``theta`` (posterior std ``std``).

    Every block changes the model state as a corrected case holds it
    (:meth:`~.effects.base.Effect.apply_corrected`: a support-spring effect
    frees every support of its kind, and supports the data did not inform
    keep the case's value).
    """
    state = problem.initial_state()
    for b, sl in zip(problem.blocks, problem.slices):
        b.effect.apply_corrected(b, state, theta[sl], std[sl], problem.case)
    bridge = state.bridge
    return CorrectedModel(
        rotational_springs=tuple(float(k) for k in bridge.rotational_springs),
        vertical_springs=tuple(float(k) for k in bridge.vertical_springs),
        sensor_positions=tuple(float(x) for x in state.sensor_positions),
        axle_loads=tuple(float(w) for w in np.asarray(problem.case.vehicle.axle_loads) * state.axle_factors),
        not_in_case=tuple(b.name for b in problem.blocks if not b.effect.in_case))
