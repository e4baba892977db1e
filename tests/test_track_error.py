"""The survey's part in a fit's intervals, and the goodness-of-fit test."""

from __future__ import annotations

import numpy as np
import pytest

from station.model.fit import fit_descent
from station.model.physics import Conditions, Params, StraightRun
from station.model.track_error import survey_error, survey_time_covariance

COND = Conditions(88.0, 1.04)
TRUTH = Params(0.22, 0.0085, 3.4)


def test_linearised_survey_covariance_matches_redrawn_profiles(demo_track, demo_xs):
    """Redraw the profile from its posterior (coefficients + L·e) and move the photocells by
    their σ: the empirical covariance of the computed times is the linearised one."""
    se = survey_error(demo_track, demo_track.photocell_ids)
    lin = survey_time_covariance(se, demo_xs, TRUTH, COND)
    unc = se.profile
    rng = np.random.default_rng(5)
    draws = []
    for _ in range(300):
        prof = unc.profile(unc.factor @ rng.standard_normal(unc.factor.shape[1]))
        xs = demo_xs + rng.standard_normal(len(demo_xs)) * se.sigma_x
        draws.append(StraightRun(prof, xs).solve(TRUTH, COND, sensitivities=False).t[1:])
    emp = np.cov(np.array(draws).T)
    sd_lin, sd_emp = np.sqrt(np.diag(lin)), np.sqrt(np.diag(emp))
    # 300 draws: a standard deviation to ±4 % (1σ); the survey moves PC9's time by ~1 ms
    assert sd_emp == pytest.approx(sd_lin, rel=0.15)
    assert 2e-4 < sd_lin[-1] < 5e-3


def _times(demo_track, demo_xs, noise_s, seed):
    t = StraightRun(demo_track.profile, demo_xs).solve(TRUTH, COND, sensitivities=False).t
    rng = np.random.default_rng(seed)
    return t + rng.normal(0, noise_s, len(t))  # every crossing, the first one too


def test_intervals_carry_the_survey(demo_track, demo_xs):
    ids = demo_track.photocell_ids
    t = _times(demo_track, demo_xs, 1e-4, 1)
    plain = fit_descent(demo_track.profile, demo_xs, t, COND, ids)
    with_survey = fit_descent(
        demo_track.profile, demo_xs, t, COND, ids, survey=survey_error(demo_track, ids)
    )
    assert not plain.survey_in_intervals and with_survey.survey_in_intervals
    for k in ("mu", "cda", "v0"):
        alone, est = getattr(plain, k), getattr(with_survey, k)
        assert alone.ci90_timing is None and alone.survey_share is None
        assert est.ci90_timing == alone.ci90
        lo, hi = est.ci90
        tlo, thi = est.ci90_timing
        assert hi - lo > thi - tlo
        assert 0.0 < est.survey_share < 1.0
    # with 0.1 ms timing the survey dominates μ's uncertainty
    assert with_survey.mu.survey_share > 0.5
    out = with_survey.to_dict()
    assert out["ci90_timing"]["mu"] == list(with_survey.mu.ci90_timing)


@pytest.mark.parametrize(("noise_ms", "status"), [(0.3, "ok"), (2.0, "poor-fit")])
def test_residuals_far_above_the_timer_precision_are_a_poor_fit(
    demo_track, demo_xs, noise_ms, status
):
    t = _times(demo_track, demo_xs, noise_ms * 1e-3, 2)
    res = fit_descent(demo_track.profile, demo_xs, t, COND)
    assert res.status == status
    assert res.timer_precision_s == 0.5e-3
    if status == "poor-fit":
        assert res.chi2_p < 1e-3 and "timer precision 0.50 ms" in res.message
        assert res.mu.value is not None  # the numbers stay, the status warns
        relaxed = fit_descent(demo_track.profile, demo_xs, t, COND, timer_precision_s=2.5e-3)
        assert relaxed.status == "ok"


def test_chi2_is_calibrated_under_the_timer_precision(demo_track, demo_xs):
    """At exactly the declared precision the χ² p-value is uniform: poor-fit 0.1 % of the time,
    p < 0.1 10 % of the time (200 descents, a few seconds)."""
    ps = []
    for seed in range(200):
        t = _times(demo_track, demo_xs, 0.5e-3, 100 + seed)
        ps.append(fit_descent(demo_track.profile, demo_xs, t, COND).chi2_p)
    ps = np.array(ps)
    assert 0.04 < np.mean(ps < 0.1) < 0.17
    assert np.mean(ps < 1e-3) < 0.02
