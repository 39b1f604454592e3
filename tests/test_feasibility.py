"""The packing that bounds how many sensors fit, against brute force, and the messages naming the options."""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sensorplan import ConfigError
from sensorplan.design.feasibility import check_feasible, packing


def brute_force_max(positions, spans, min_spacing, span_max):
    """Largest subset keeping the spacing and the per-span caps, by enumerating every subset (reference)."""
    n = len(positions)
    for size in range(n, 0, -1):
        for subset in itertools.combinations(range(n), size):
            x = np.sort(positions[list(subset)])
            if min_spacing > 0 and np.any(np.diff(x) < min_spacing - 1e-9):
                continue
            counts = np.bincount(spans[list(subset)], minlength=len(span_max) if span_max is not None else 1)
            if span_max is not None and np.any(counts > span_max):
                continue
            return size
    return 0


@settings(max_examples=150, deadline=None)
@given(st.lists(st.integers(0, 40), min_size=1, max_size=9), st.sampled_from([0.0, 1.0, 2.5, 4.0, 7.0]),
       st.one_of(st.none(), st.tuples(st.integers(0, 3), st.integers(0, 3))))
def test_packing_is_the_largest_feasible_layout(grid, min_spacing, span_max):
    positions = np.array(grid, dtype=float) * 0.5  # repeated positions: two kinds at one place
    spans = (positions > 10.0).astype(int)
    caps = None if span_max is None else np.array(span_max)
    taken = packing(positions, spans, min_spacing, caps)
    assert taken.size == brute_force_max(positions, spans, min_spacing, caps)
    x = np.sort(positions[taken])
    assert min_spacing == 0 or np.all(np.diff(x) >= min_spacing - 1e-9)


def test_a_count_that_does_not_fit_names_count_and_spacing():
    positions = np.arange(0.0, 30.5, 0.5)  # openlab-like grid: 61 candidates on 30 m
    with pytest.raises(ConfigError, match=r"'count' 61 with 'min_spacing' 10 m: at most 4 sensor\(s\) fit; "
                                          r"lower 'count' or 'min_spacing'"):
        check_feasible(positions, (positions > 15).astype(int), 61, min_spacing=10.0)
    check_feasible(positions, (positions > 15).astype(int), 4, min_spacing=10.0)  # 0, 10, 20, 30 m


def test_a_span_minimum_that_does_not_fit_names_the_span():
    positions = np.arange(0.0, 30.5, 0.5)
    with pytest.raises(ConfigError, match=r"'span_min' asks for 3 sensor\(s\) in span 1, but at most 2 fit"):
        check_feasible(positions, (positions > 15).astype(int), 3, min_spacing=8.0, span_min=[3, 0])


def test_a_budget_below_the_cheapest_layout_names_the_budget():
    with pytest.raises(ConfigError, match=r"'budget' 2 is below the cost of the 2 cheapest"):
        check_feasible(np.arange(5.0), np.zeros(5, int), 2, costs=np.full(5, 1.5), budget=2.0)
