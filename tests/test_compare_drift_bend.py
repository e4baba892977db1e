"""A drift that bends (issue 24): the sun comes onto the track and μ rises faster and faster.
The day model tests whether the drift is straight, from the descents' own μ against the clock;
when it bends it follows it with a quadratic and says so; a straight drift stays unwarned."""

from __future__ import annotations

import numpy as np
import pytest

from station.model.compare import DescentData, joint_fit
from station.model.compare_drift import drift_bend
from station.model.fit import fit_descent
from station.model.physics import Conditions, Params, StraightRun

RHO, MASS = 1.079, 88.0


def _day(demo_track, seed: int, quad: float, mus=(0.009, 0.009), step_h=5 / 60, scatter=0.015):
    """Equal skis (unless ``mus`` differ), ABBAABBA, one descent every 5 minutes, μ drifting
    +0.02 per hour plus ``quad`` per hour² around the middle of the day; every descent fitted
    on its own first, as station compare does."""
    xs = np.array([pc.x for pc in demo_track.photocells])
    run = StraightRun(demo_track.profile, xs)
    rng = np.random.default_rng(seed)
    cond = Conditions(MASS, RHO)
    order = "ABBAABBA"
    mid = (len(order) - 1) * step_h / 2
    out = []
    for k, item in enumerate(order):
        dt = k * step_h - mid
        mu = mus[item == "B"] + 0.02 * dt + quad * dt * dt
        cda = 0.22 * float(np.exp(rng.normal(0.0, scatter)))
        t = run.solve(Params(cda, mu, rng.uniform(2.5, 4.5)), cond, sensitivities=False).t
        t = np.round(36000.0 + t + rng.normal(0.0, 5e-4, len(t)), 4)
        f = fit_descent(demo_track.profile, xs, t, cond, run=run)
        guess = (f.cda.value or 0.25, f.mu.value or 0.02, f.v0.value or 3.0)
        out.append(DescentData(k + 1, item, "skier", tuple(demo_track.photocell_ids), t - t[0],
                               10.0 + k * step_h, MASS, RHO, 0.0, guess))  # fmt: skip
    return out


def test_a_bent_drift_is_followed_and_named(demo_track):
    res = joint_fit(demo_track, _day(demo_track, 1, quad=0.03))
    assert res.drift_bend is not None
    b, (lo, hi) = res.drift_bend
    assert lo <= 0.03 <= hi
    assert any("not straight" in w and "quadratic" in w for w in res.warnings)
    assert res.to_dict()["drift"]["per_hour2"] == pytest.approx(b)
    c = res.comparisons[0]
    assert c.ci90[0] <= 0.0 <= c.ci90[1]  # equal skis: no winner made by the bend


def test_too_few_descents_for_the_test_say_so(demo_track):
    """ABBA: items + 2 drift terms leave no dof for the test; the answer says it cannot see a
    bend (a bent ABBA day held the truth on 5–22 % of days, silently)."""
    data = _day(demo_track, 2, quad=0.03)[:4]
    assert drift_bend(data) is None
    warnings = joint_fit(demo_track, data).warnings
    assert not any("not straight" in w for w in warnings)
    assert any(w.startswith("drift:") and "cannot be seen" in w for w in warnings), warnings


@pytest.mark.slow  # 48 simulated days, each descent fitted
def test_bent_days_warn_or_hold_zero_and_straight_days_stay_unwarned(demo_track):
    """The issue's bar: on bent-drift days (4 a ski) the interval holds 0 on ≥ 19 of 24 or the
    answer warns of the drift on ≥ 20; straight-drift days stay unwarned."""
    holds = warned = 0
    for seed in range(24):
        res = joint_fit(demo_track, _day(demo_track, 100 + seed, quad=0.03))
        lo, hi = res.comparisons[0].ci90
        holds += lo <= 0.0 <= hi
        warned += any("not straight" in w for w in res.warnings)
    assert holds >= 19 or warned >= 20, (holds, warned)
    assert holds >= 19 and warned >= 20, (holds, warned)  # this day model does both
    false = sum(
        any("drift" in w for w in joint_fit(demo_track, _day(demo_track, s, 0.0)).warnings)
        for s in range(200, 224)
    )
    assert false <= 1, false  # the test's level is 1 %: one day in 24 is already unlucky
