"""Which effects explain the gap: the stepwise selection and the policy that tunes it.

:mod:`.policy` (every knob with its reason), :mod:`.candidate` (the
:class:`~.candidate.Candidate` compared and the context protocol the
selection needs), :mod:`.context` (the diagnosis's context), :mod:`.refit`
(quick fits at fixed hyperparameters), :mod:`.heldout` (folds and held-out
scores), :mod:`.passes` (the candidates of a step fitted in passes),
:mod:`.select` (the decision), :mod:`.state` and :mod:`.revisions`
(backward test and swaps).

Owns: the selection.  May import: the joint model, inference and the foundations.
"""
