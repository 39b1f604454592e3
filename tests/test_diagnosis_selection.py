"""Stepwise selection of the diagnosis (forward, noise rescale, backward test, swap) on a table of models.

The fits are stand-ins with a log evidence and per-fold held-out log
densities chosen by hand, so that each rule of :mod:`sensorplan.diagnosis.selection`
is exercised alone; the numbers are not from data.
"""

from dataclasses import replace

import numpy as np

import sensorplan as sp
from sensorplan import diagnose, example_case, simulate_crossings
from sensorplan.diagnosis.refit import Heldout
from sensorplan.diagnosis.selection import select
from sensorplan.diagnosis.summary import summary_lines


class _Problem:
    n_elements, effects, slices, n_data = 1, [], [], 100

    def evaluate(self, theta, jacobian=True):
        return None  # no noise rescale in these tables


class _Fit:
    def __init__(self, evidence):
        self.log_evidence, self.converged = float(evidence), True
        self.problem, self.theta = _Problem(), np.zeros(1)


def _held(total):
    return Heldout(np.full(4, total / 4.0), 1.0, np.ones(1), 1.0)


class _Table:
    """ctx.fit stand-in: (fit, held-out) of every model (frozenset of effect names)."""

    def __init__(self, models):
        self.models = models
        self.calls = []

    def fit(self, names, blocks=None, *, initial=True):
        self.calls.append(tuple(names))
        evidence, held = self.models[frozenset(names)]
        return _Fit(evidence), _held(held)


def _run(models, names=("O", "G", "S")):
    ctx = _Table(models)
    screened = {n: ctx.fit([n]) for n in names}
    base = _Fit(models[frozenset()][0])
    selected, alternatives, current, _ = select(ctx, list(names), screened, base, _held(models[frozenset()][1]),
                                                bf_threshold=3.0, gain_threshold=3.0, max_rounds=3, folds=True,
                                                say=lambda text: None)
    return selected, alternatives, current, ctx


def test_forward_selection_stops_when_nothing_is_gained():
    models = {frozenset(): (0, 0), frozenset("O"): (100, 200), frozenset("G"): (2, 1), frozenset("S"): (50, 80),
              frozenset("OG"): (101, 201), frozenset("OS"): (101, 201)}
    selected, _, current, _ = _run(models)
    assert selected == ["O"] and current.log_evidence == 100


def test_backward_test_drops_a_pick_the_later_one_makes_redundant():
    # O first; G next (it mimics part of S); S then adds 10 given O and G, but given O and S, G adds
    # 15 in evidence and only 2 held out: G is dropped, and O + S + G is not visited again
    models = {frozenset(): (0, 0), frozenset("O"): (1000, 2000), frozenset("G"): (500, 900),
              frozenset("S"): (100, 150), frozenset("OG"): (1050, 2100), frozenset("OS"): (1045, 2108),
              frozenset("OGS"): (1060, 2110), frozenset("GS"): (600, 1000)}
    selected, _, current, _ = _run(models)
    assert selected == ["O", "S"] and current.log_evidence == 1045
    # without the backward test G would stay: it adds 15 > 3 in evidence given O and S
    assert models[frozenset("OGS")][0] - models[frozenset("OS")][0] > 3


def test_backward_test_keeps_picks_that_still_earn_their_place():
    models = {frozenset(): (0, 0), frozenset("O"): (1000, 2000), frozenset("G"): (500, 900),
              frozenset("S"): (100, 150), frozenset("OG"): (1050, 2100), frozenset("OS"): (1045, 2090),
              frozenset("OGS"): (1060, 2120), frozenset("GS"): (600, 1000)}
    selected, _, _, _ = _run(models)
    assert selected == ["O", "G", "S"]


def test_swap_only_tries_effects_that_explain_part_of_the_gap_alone():
    models = {frozenset(): (0, 0), frozenset("O"): (1000, 2000), frozenset("G"): (-5, -3),
              frozenset("S"): (100, 150), frozenset("OS"): (1045, 2090), frozenset("OG"): (990, 1990),
              frozenset("OGS"): (1040, 2080), frozenset("GS"): (90, 140)}
    selected, _, _, ctx = _run(models)
    assert selected == ["O", "S"]
    swaps = [c for c in ctx.calls if len(c) == 2 and "G" in c]
    assert ("O", "G") in ctx.calls  # the forward step tried G given O ...
    assert ("S", "G") not in swaps  # ... the swap pass did not try G for O


def test_summary_without_a_significant_gap_does_not_list_confounded_effects():
    case = example_case("openlab-like")  # on 8 elements with a 1 m sweep, as in test_diagnosis.py
    case = replace(case.with_mesh(sp.Mesh.uniform(case.bridge, 8)), sweep=sp.LoadSweep.from_range(0.0, 32.0, 1.0))
    d = diagnose(case, simulate_crossings(case, 3, noise=True, rng=11))
    assert not d.gap.significant and d.causes == ()
    assert d.confounded, "this layout cannot separate some effects from EI (the case the rule is for)"
    lines = summary_lines(d)
    assert not any(line.lstrip().startswith("confounded:") for line in lines)
    assert any("confounded alternatives are not listed" in line for line in lines)
    assert "confounded" not in d.verdict
