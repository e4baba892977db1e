"""Decided or not after every descent: the group-sequential boundary, the decision, and (slow)
simulated days looked at after every descent."""

from __future__ import annotations

import math

import numpy as np
import pytest

from station.model.sequential import (
    Decision,
    boundaries,
    decide,
    describe,
    look_boundaries,
    pair_counts,
)


def test_the_boundaries_are_the_published_obrien_fleming_type_ones():
    """Lan–DeMets O'Brien–Fleming-type spending, five equally spaced looks, two-sided 0.05:
    4.877, 3.357, 2.680, 2.290, 2.031 (Jennison & Turnbull 2000, table 2.7; gsDesign)."""
    got = boundaries((0.2, 0.4, 0.6, 0.8, 1.0), 0.05)
    assert got == pytest.approx((4.877, 3.357, 2.680, 2.290, 2.031), abs=2e-3)


def test_looking_after_every_descent_declares_equal_items_different_at_most_alpha():
    """Brownian motion in information time, looked at on an ABBA day's schedule: the z
    statistic crosses a boundary at some look on 10 % of days; the 90 % interval looked at the
    same way would cross on far more."""
    counts = pair_counts("ABBAABBAABBAABBAABBA", "A", "B")
    c = np.array(look_boundaries(counts, 10))
    t = np.array([2 / (1 / a + 1 / b) / 10 for a, b in counts])
    rng = np.random.default_rng(0)
    b = np.cumsum(rng.normal(size=(200_000, len(t))) * np.sqrt(np.diff(t, prepend=0.0)), axis=1)
    z = np.abs(b / np.sqrt(t))
    assert np.mean((z >= c).any(axis=1)) == pytest.approx(0.10, abs=0.003)
    assert np.mean((z >= 1.645).any(axis=1)) > 0.25  # the naive rule
    assert c[-1] < 1.9 and c[0] > 4.0  # strict early, close to the fixed 1.645 at the horizon


def test_looks_count_only_descents_of_the_pair_once_both_have_two():
    assert pair_counts("ABCCBAABC", "A", "B") == [(2, 2), (3, 2), (3, 3)]
    assert pair_counts("AAB", "A", "B") == []


def test_beyond_the_horizon_the_last_boundary_is_kept():
    counts = pair_counts("AB" * 8, "A", "B")
    c = look_boundaries(counts, 4)
    assert c[-1] == c[-2] == c[-3]


def test_the_decision_states():
    run = "ABBAABBA"
    d = decide("A", "B", -0.001, 0.0001, 50, run)
    assert d.state == "decided" and d.faster == "A" and d.looks == 5
    lo, hi = d.interval
    assert hi < 0 and lo < -0.001 < hi
    assert describe(d).startswith("decided: A faster by Δμ 0.00100 [")
    assert decide("A", "B", 0.001, 0.0001, 50, run).faster == "B"
    d = decide("A", "B", 0.00005, 0.0001, 50, run, margin=0.001)
    assert d.state == "equivalent" and d.faster is None
    assert "no difference that matters" in describe(d)
    d = decide("A", "B", 0.0002, 0.0001, 50, run)
    assert d.state == "undecided" and d.more_descents_per_item is not None
    assert describe(d) == (
        f"not yet: about {d.more_descents_per_item} more descents per item at today's scatter"
    )
    d = decide("A", "B", 0.0, 0.0001, 50, run)
    assert d.more_descents_per_item is None and "no difference in sight" in describe(d)
    d = decide("A", "B", 0.0, None, None, "AB")
    assert d.state == "undecided" and d.looks == 0 and "before a comparison" in describe(d)
    assert Decision.to_dict(decide("A", "B", -0.001, 0.0001, 50, run))["faster"] == "A"


def test_the_projection_of_more_descents_comes_true_when_the_estimate_stays():
    """The projection "about k more descents per item": with k more of each, the same estimate and the
    standard error shrunk as the information grows, the rule decides; with k − 1 it does not."""
    run = "ABBAAB"
    delta, se = 0.0003, 0.00015
    d = decide("A", "B", delta, se, None, run)
    k = d.more_descents_per_item
    assert d.state == "undecided" and k is not None and k >= 2

    def later(m: int) -> Decision:
        na, nb = 3, 3
        h0, h1 = 2 / (1 / na + 1 / nb), 2 / (1 / (na + m) + 1 / (nb + m))
        return decide("A", "B", delta, se * math.sqrt(h0 / h1), None, run + "AB" * m)

    assert later(k).state == "decided" and later(k - 1).state == "undecided"
