"""The model across days (station.model.season), on days whose answers are known: effects
recovered through the network, gaps named, slopes in a condition, no ranking where an item was
never tested, heterogeneity in the intervals. Its coverage over many simulated seasons is
checked by benchmarks/season_coverage.py."""

from __future__ import annotations

import numpy as np
import pytest

from station.model.season import DayEffects, SeasonError, compare_season

SE = 1e-6  # within-day standard error: the answers are the truth to a few 1e-6


def day(name, effects: dict[str, float], temp=-5.0, level=0.02, rng=None, se=SE):
    items = tuple(effects)
    k = len(items)
    cov = se**2 * (0.5 * np.eye(k) + 0.5)
    mu = level + np.array([effects[i] for i in items])
    if rng is not None:
        mu = mu + rng.multivariate_normal(np.zeros(k), cov)
    return DayEffects(name, items, mu, cov, (6,) * k, {"snow_temperature_c": temp})


def item(res, name):
    return next(i for i in res.items if i.item == name)


def test_items_that_never_met_are_compared_through_the_network():
    rng = np.random.default_rng(1)
    theta = {"A": 0.0, "B": 0.001, "C": -0.0005, "D": 0.0002}
    days = [
        day("d1", {"A": 0, "B": 0.001}, level=0.012, rng=rng),
        day("d2", {"B": 0.001, "C": -0.0005}, level=0.031, rng=rng),  # A and C never met
        day("d3", {"C": -0.0005, "D": 0.0002}, level=0.020, rng=rng),
        day("d4", {"A": 0, "B": 0.001, "D": 0.0002}, level=0.009, rng=rng),
    ]
    res = compare_season(days, "A")
    for name, t in theta.items():
        assert item(res, name).delta_mu == pytest.approx(t, abs=1e-5)
        lo, hi = item(res, name).ci90
        assert lo <= t + 1e-12 and t - 1e-12 <= hi
    assert item(res, "C").p_best > 0.99 and item(res, "C").p_faster > 0.99
    assert res.days == 4 and res.descents == 6 * 9


def test_a_gap_in_the_network_is_named_and_not_bridged():
    days = [day("d1", {"A": 0, "B": 0.001}), day("d2", {"C": 0, "D": 0.002})]
    res = compare_season(days, "A")
    assert item(res, "C").delta_mu is None and item(res, "D").delta_mu is None
    assert any("C, D: not connected to A" in w for w in res.warnings)
    with pytest.raises(SeasonError, match="reference 'X'"):
        compare_season(days, "X")


def test_a_condition_no_day_has_is_named_in_the_error():
    """`season compare --at snow_temperature_c=-12` on days nobody measured the snow of: the
    error names the condition and the days, not just 'no day left'."""
    days = [day("d1", {"A": 0, "B": 0.001}, temp=float("nan"))]
    with pytest.raises(SeasonError, match=r"1 day\(s\) without snow_temperature_c .*: d1"):
        compare_season(days, "A", {"snow_temperature_c": -12.0})


def test_an_effect_linear_in_snow_temperature_is_reported_where_asked():
    # B loses 0.0001 per °C warmer than A: at −12 °C it is 0.0004 faster, at −2 °C 0.0006 slower
    days = [
        day(f"d{t}", {"A": 0.0, "B": 0.0001 * (t + 8)}, temp=float(t)) for t in (-14, -10, -6, -2)
    ]  # noqa: E501
    days += [
        day("e", {"A": 0.0, "C": 0.0003}, temp=-9.0),
        day("f", {"A": 0.0, "C": 0.0003}, temp=-3),
    ]
    res = compare_season(days, "A", {"snow_temperature_c": -12.0})
    b = item(res, "B")
    assert b.delta_mu == pytest.approx(-0.0004, abs=1e-5)
    assert b.slopes["snow_temperature_c"][0] == pytest.approx(0.0001, abs=1e-6)
    assert b.tested["snow_temperature_c"] == (-14.0, -2.0)
    assert b.p_best is not None and b.p_best > 0.99
    warm = compare_season(days, "A", {"snow_temperature_c": -2.0})
    assert item(warm, "B").delta_mu == pytest.approx(0.0006, abs=1e-5)


def test_an_item_never_tested_near_a_condition_is_not_ranked_there():
    # W was only tested warm, where it was best by far: in the cold nobody knows
    days = [day(f"c{t}", {"A": 0.0, "B": 0.0002}, temp=float(t)) for t in (-16, -13, -10)]
    days += [day(f"w{t}", {"A": 0.0, "W": -0.003}, temp=float(t)) for t in (-3, -2, -1)]
    res = compare_season(days, "A", {"snow_temperature_c": -15.0})
    w = item(res, "W")
    assert w.p_best is None and "not tested near" in w.note
    assert any("W was not tested near snow_temperature_c=-15" in x for x in res.warnings)
    assert item(res, "A").p_best is not None  # the others are ranked


def test_heterogeneity_between_days_widens_the_intervals():
    rng = np.random.default_rng(4)
    same = [day(f"d{k}", {"A": 0.0, "B": 0.001}, rng=rng, se=1e-4) for k in range(12)]
    differ = [
        day(f"d{k}", {"A": 0.0, "B": 0.001 + (0.0006 if k % 2 else -0.0006)}, rng=rng, se=1e-4)
        for k in range(12)
    ]  # fmt: skip
    a, b = compare_season(same, "A"), compare_season(differ, "A")
    assert a.tau < 1e-4 < 4e-4 < b.tau
    wa, wb = (np.diff(item(r, "B").ci90)[0] for r in (a, b))
    assert wb > 3 * wa
    assert b.q_p is not None and b.q_p < 1e-6
