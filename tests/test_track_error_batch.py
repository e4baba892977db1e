"""The survey's time covariance solves its perturbed tracks in batches: the numbers must be
those of one lone solve per perturbation (its finite differences are taken of them)."""

from __future__ import annotations

import numpy as np
import pytest

from station.model.physics import Conditions, Params, grid_nodes, make_grid, solve_grid
from station.model.track_error import (
    H_STEP_M,
    X_STEP_M,
    SurveyError,
    survey_error,
    survey_time_covariance,
)


def covariance_one_track_at_a_time(survey, xs, p, c, step=0.5):
    """The covariance as first written: one grid and one solve per perturbed track."""
    unc = survey.profile

    def times(profile, x):
        grid = make_grid(profile, x, step)
        return solve_grid(grid, p, c, 3, False).time[grid.cell_index][1:]

    base = times(unc.profile(), xs)
    m = len(unc.coef)
    support = [j for j in range(m) if unc.knots[j + 4] > xs[0] and unc.knots[j] < xs[-1]]
    a_h = np.empty((len(base), len(support)))
    for col, j in enumerate(support):
        delta = np.zeros(m)
        delta[j] = H_STEP_M
        a_h[:, col] = (times(unc.profile(delta), xs) - base) / H_STEP_M
    s_h = a_h @ unc.factor[support, :]
    cov = s_h @ s_h.T
    for k, sx in enumerate(survey.sigma_x):
        moved = xs.copy()
        moved[k] += X_STEP_M
        if sx <= 0 or (k + 1 < len(xs) and moved[k] >= xs[k + 1]):
            continue
        a_k = (times(unc.profile(), moved) - base) / X_STEP_M
        cov += sx * sx * np.outer(a_k, a_k)
    return cov


@pytest.mark.parametrize(
    ("p", "wind"),
    [(Params(0.22, 0.0085, 3.4), 0.0), (Params(0.25, 0.02, 0.8, mu1=3e-4), -2.0)],
)
def test_the_batched_covariance_is_that_of_one_solve_per_track(demo_track, demo_xs, p, wind):
    c = Conditions(88.0, 1.04, wind_ms=wind)
    se = survey_error(demo_track, demo_track.photocell_ids)
    assert np.array_equal(
        survey_time_covariance(se, demo_xs, p, c), covariance_one_track_at_a_time(se, demo_xs, p, c)
    )


def test_photocell_moves_that_add_a_grid_node(demo_track):
    """Photocells 29.9996 m apart: a 1 mm move lengthens an interval past 60 grid steps, so
    the moved tracks do not all share the nodes of the unmoved one (a batch of them could not
    be stacked); a photocell with σ 0 is not moved."""
    xs = demo_track.photocells[0].x + 29.9996 * np.arange(9)
    xs[5:] += 0.3
    layouts = set()
    for k in range(len(xs)):
        moved = xs.copy()
        moved[k] += X_STEP_M
        layouts.add(grid_nodes(moved, 0.5)[1].tobytes())
    assert len(layouts) > 2
    sigma = np.full(len(xs), 0.002)
    sigma[2] = 0.0
    se = SurveyError(demo_track.uncertainty, sigma)
    p, c = Params(0.22, 0.0085, 3.4), Conditions(88.0, 1.04)
    assert np.array_equal(
        survey_time_covariance(se, xs, p, c), covariance_one_track_at_a_time(se, xs, p, c)
    )
