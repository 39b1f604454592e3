"""Every knob of the selection, with the reason for its value.

Owns: :class:`SelectionPolicy`.  May import: nothing.
"""

from dataclasses import dataclass

__all__ = ["DEFAULT_POLICY", "SelectionPolicy"]


@dataclass(frozen=True)
class SelectionPolicy:
    """The thresholds and budgets of the stepwise selection (:func:`~.select.select`), one reason each.

    ``bf_threshold``, ``gain_threshold`` and ``max_rounds`` are
    :func:`~sensorplan.diagnosis.diagnose.diagnose`'s options; the others
    are fixed by the validation studies (studies/diagnosis).
    """

    # a pick needs a log Bayes factor this high ("strong" on Jeffreys' scale); also the margin within which
    # other candidates are its alternatives and below which a later fit may give up
    bf_threshold: float = 3.0
    # a pick needs this total held-out log predictive gain, not bought by losses in the other folds
    gain_threshold: float = 3.0
    # the largest number of selected effects (a gap explained by more is not identified)
    max_rounds: int = 3
    # whether picks that leave a significant gap are still named as causes (:func:`~.select.named_causes`).  No:
    # effects that absorb part of a gap they cannot remove are not identified causes, and a reader told "partly
    # explained by A, B, C; unexplained" reads three causes.  Effects outside the library (a bearing that lifts
    # off, the deck's shear deformation) were "partly explained" by up to three library effects at once; the
    # gap that remains is what says the cause is elsewhere.  The picks are reported as partial.
    name_partial: bool = False
    # a later pick with this many alternatives within bf_threshold is not made: three effects that explain the
    # remainder about equally are no identified cause
    ambiguous: int = 2
    # Levenberg-Marquardt steps every candidate gets: most converge within them from a warm start
    first_pass: int = 15
    # further steps of the candidates not converged that may still reach the level a decision needs
    second_pass: int = 40
    # further steps of a leader still crawling after the second pass: a strongly nonlinear effect on precise data
    # can decide a step alone
    third_pass: int = 60
    # steps of the refit at a re-estimated noise scale (the model is already near its optimum)
    rescale_max_iter: int = 40
    # rounds of the noise-scale fixed point (refit, re-estimate): one step from a fit at an inflated scale stops
    # short of the fixed point
    rescale_rounds: int = 5
    # the fixed point is reached once the noise scale moves by less than this fraction
    rescale_rtol: float = 0.01
    # a candidate that fails the held-out test but cuts the held-out rms to this fraction may be the first of two
    # missing effects: it is taken tentatively and the next one fitted given it (look-ahead)
    look_ahead_ratio: float = 0.8
    # a base noise scale above this means EI twisted to mimic the gap: support springs are also fitted from the
    # nominal EI and springs
    distorted: float = 3.0
    # a fit not converged could still gain this many Newton decrements plus ``ceiling_margin`` in log evidence:
    # on slow fits the objective fell by 0.4-2 decrements after the point where it was measured
    ceiling_decrements: float = 2.0
    ceiling_margin: float = 3.0
    # a fit that counts only if it converges within its steps gives up once this many times the larger of its
    # last two gains, in every step left, would not reach its floor (far from the optimum the ceiling is no guide)
    budget_pace: float = 2.0
    # Levenberg-Marquardt steps of a fit that must decide alone (the backward test, a screening refit at the end)
    max_iter: int = 40


DEFAULT_POLICY = SelectionPolicy()
