"""The forward model against closed-form results and an independent second formulation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from reference_dae import simulate_dae

from station.model.air import air_density, isa_pressure_hpa
from station.model.physics import Conditions, Params, StraightRun
from station.survey.track import Profile


def plane(deg: float) -> Profile:
    k = math.tan(math.radians(deg))
    return Profile(
        h=lambda x: -k * np.asarray(x, float),
        dh=lambda x: np.full_like(np.asarray(x, float), -k),
        d2h=lambda x: np.zeros_like(np.asarray(x, float)),
        x_min=-100.0,
        x_max=1000.0,
    )


def circle(radius: float, sign: float) -> Profile:
    """A dip (sign +1, centre above) or a crest (sign −1) of radius R, lowest/highest at x = 0."""
    r = radius

    def root(x):
        return np.sqrt(r * r - np.asarray(x, float) ** 2)

    return Profile(
        h=lambda x: sign * (r - root(x)),
        dh=lambda x: sign * np.asarray(x, float) / root(x),
        d2h=lambda x: sign * r * r / root(x) ** 3,
        x_min=-0.9 * r,
        x_max=0.9 * r,
    )


def closed_form_plane_times(s, deg, m, rho, cda, mu, v0, g):
    """friction-physics.md §5.1: t(s) = [arccosh(cosh c · e^{ks}) − c] / √(a0·k)."""
    a = math.radians(deg)
    a0 = g * (math.sin(a) - mu * math.cos(a))
    k = rho * cda / (2 * m)
    c = math.atanh(v0 / math.sqrt(a0 / k))
    return (np.arccosh(np.cosh(c) * np.exp(k * np.asarray(s))) - c) / math.sqrt(a0 * k)


def test_plane_with_drag_matches_the_published_closed_form_times():
    s = np.array([0.0, 10.0, 50.0, 100.0, 150.0])
    xs = s * math.cos(math.radians(15))
    run = StraightRun(plane(15), xs)
    d = run.solve(Params(0.22, 0.0085, 3.4), Conditions(75.0, 1.0, g=9.81))
    assert d.t[1:] == pytest.approx([1.79429, 5.22416, 7.96905, 10.16585], abs=6e-6)
    exact = closed_form_plane_times(s, 15, 75, 1.0, 0.22, 0.0085, 3.4, 9.81)
    assert np.max(np.abs(d.t - exact)) < 1e-8


@pytest.mark.parametrize(("cda", "mu", "v0"), [(0.4, 0.04, 8.0), (0.15, 0.002, 0.5)])
def test_plane_closed_form_other_parameters(cda, mu, v0):
    s = np.linspace(0, 300, 7)
    xs = s * math.cos(math.radians(20))
    d = StraightRun(plane(20), xs).solve(Params(cda, mu, v0), Conditions(90.0, 1.1))
    exact = closed_form_plane_times(s, 20, 90, 1.1, cda, mu, v0, 9.80665)
    assert np.max(np.abs(d.t - exact)) < 1e-7


def test_energy_is_conserved_without_friction_and_drag(demo_track, demo_xs):
    g = 9.80665
    d = StraightRun(demo_track.profile, demo_xs).solve(Params(0.0, 0.0, 2.0), Conditions(80, 1.0))
    h = demo_track.profile.h(demo_xs)
    v_energy = np.sqrt(2.0**2 + 2 * g * (h[0] - h))
    assert d.v == pytest.approx(v_energy, rel=1e-9)


def test_normal_force_at_the_bottom_of_a_dip_and_on_a_crest():
    m, r, g = 80.0, 20.0, 9.80665
    for sign, x0, v0 in ((+1.0, -15.0, 5.0), (-1.0, -12.0, 10.0)):
        prof = circle(r, sign)
        xs = np.array([x0, 0.0, 12.0])
        d = StraightRun(prof, xs).solve(Params(0.0, 0.0, v0), Conditions(m, 1.0))
        v2 = v0**2 + 2 * g * float(prof.h(np.array([x0]))[0])  # bottom/top at height 0
        i = int(np.argmin(np.abs(d.x)))
        assert d.x[i] == 0.0
        assert d.speed[i] ** 2 == pytest.approx(v2, rel=1e-9)
        expected = m * (g + sign * v2 / r)  # dip: g + v²/R, crest: g − v²/R
        assert d.normal_force_n[i] == pytest.approx(expected, rel=1e-9)
    # the dip at 15 m/s of the notes: N = m(g + 11.25)
    prof = circle(20.0, +1.0)
    v0 = math.sqrt(15.0**2 - 2 * g * float(prof.h(np.array([-15.0]))[0]))
    d = StraightRun(prof, np.array([-15.0, 0.0, 5.0])).solve(Params(0, 0, v0), Conditions(m, 1.0))
    i = int(np.argmin(np.abs(d.x)))
    assert d.normal_force_n[i] == pytest.approx(m * (g + 11.25), rel=1e-9)


def wave(amplitude: float, length: float) -> Profile:
    """h = A·cos(2πx/L): a crest at x = 0 between valleys at ±L/2."""
    w = 2 * math.pi / length
    return Profile(
        h=lambda x: amplitude * np.cos(w * np.asarray(x, float)),
        dh=lambda x: -amplitude * w * np.sin(w * np.asarray(x, float)),
        d2h=lambda x: -amplitude * w * w * np.cos(w * np.asarray(x, float)),
        x_min=-length,
        x_max=length,
    )


def test_lift_off_on_a_crest_is_detected_where_the_dae_finds_it():
    prof = wave(2.0, 60.0)  # crest radius 45.6 m; lift-off needs about 21 m/s at the top
    xs = np.array([-30.0, 0.0, 30.0])
    c = Conditions(80.0, 1.0)
    p = Params(0.0, 0.0, 24.0)
    d = StraightRun(prof, xs).solve(p, c)
    ref = simulate_dae(prof, xs, p, c)
    assert d.liftoff_x is not None and ref.liftoff_x is not None
    assert -30.0 < d.liftoff_x < 0.0
    assert d.liftoff_x == pytest.approx(ref.liftoff_x, abs=0.05)
    assert d.min_normal_force_n < 0
    slow = StraightRun(prof, xs).solve(Params(0.0, 0.0, 15.0), c)
    assert slow.liftoff_x is None and slow.min_normal_force_n > 0


def test_a_skier_who_stops_is_reported():
    deg, mu, v0, g = 3.0, 0.1, 3.0, 9.80665
    a = math.radians(deg)
    s_stop = v0**2 / (2 * g * (mu * math.cos(a) - math.sin(a)))
    xs = np.array([0.0, 20.0, 40.0])
    d = StraightRun(plane(deg), xs).solve(Params(0.0, mu, v0), Conditions(80, 1.0))
    assert d.stopped_x == pytest.approx(s_stop * math.cos(a), abs=0.3)
    ref = simulate_dae(plane(deg), xs, Params(0.0, mu, v0), Conditions(80, 1.0))
    assert ref.stopped_x == pytest.approx(s_stop * math.cos(a), abs=0.05)


@pytest.mark.parametrize(
    ("p", "wind"),
    [
        (Params(0.22, 0.0085, 3.4), 0.0),
        (Params(0.35, 0.05, 8.0), 0.0),
        (Params(0.22, 0.0081, 3.1, mu1=8.3e-5), 0.0),
        (Params(0.25, 0.02, 5.0), -2.5),
        (Params(0.25, 0.02, 5.0, mu1=2e-4), 1.5),
    ],
)
def test_arc_length_model_agrees_with_the_cartesian_dae(demo_track, demo_xs, p, wind):
    c = Conditions(88.0, 1.04, wind_ms=wind)
    d = StraightRun(demo_track.profile, demo_xs).solve(p, c, n_params=4)
    ref = simulate_dae(demo_track.profile, demo_xs, p, c)
    assert np.max(np.abs(d.t - ref.t)) < 1e-6
    assert np.max(np.abs(d.v - ref.v)) < 1e-6
    assert d.converged


def test_headwind_slows_and_tailwind_speeds_up(demo_track, demo_xs):
    run = StraightRun(demo_track.profile, demo_xs)
    p = Params(0.22, 0.0085, 3.4)
    t = {w: run.solve(p, Conditions(88, 1.04, wind_ms=w)).t[-1] for w in (-2.0, 0.0, 2.0)}
    assert t[-2.0] > t[0.0] > t[2.0]


def test_sensitivities_match_central_differences(demo_track, demo_xs):
    run = StraightRun(demo_track.profile, demo_xs)
    base = {"cda": 0.25, "mu": 0.02, "v0": 5.0, "mu1": 1e-4}
    c = Conditions(88.0, 1.04, wind_ms=-1.0)
    d = run.solve(Params(**base), c, n_params=4)
    for j, name in enumerate(("cda", "mu", "v0", "mu1")):
        eps = 1e-6 * max(abs(base[name]), 1e-3)
        hi = run.solve(Params(**{**base, name: base[name] + eps}), c, 4, False).t
        lo = run.solve(Params(**{**base, name: base[name] - eps}), c, 4, False).t
        fd = (hi - lo) / (2 * eps)
        assert np.max(np.abs(fd - d.dt_dp[:, j])) < 1e-5 * np.max(np.abs(fd))


@pytest.mark.parametrize(
    ("p", "wind"),
    [
        (Params(0.22, 0.0085, 3.4), 0.0),  # linear: one pass
        (Params(0.25, 0.02, 5.0), -2.5),  # iterated
        (Params(0.25, 0.02, 0.5, mu1=2e-4), 1.5),  # iterated, a slow start
    ],
)
def test_a_batch_of_tracks_is_solved_row_by_row_as_each_track_alone(demo_track, demo_xs, p, wind):
    """The survey's finite differences solve some 60 perturbed profiles as one batch: each row
    must be the very number the lone track gives (differences of 1e-6 s are taken of them)."""
    from scipy.interpolate import BSpline

    from station.model.physics import grid_nodes, grid_on_nodes, make_grid, solve_grid
    from station.survey.track import spline_profile

    unc = demo_track.uncertainty
    rng = np.random.default_rng(3)
    draws = [unc.coef + unc.factor @ rng.standard_normal(unc.factor.shape[1]) * k for k in (1, 30)]
    # a gentler run (the heights scaled by 0.3) needs one iteration more than the others
    coefs = [unc.coef, *draws, 0.3 * unc.coef]
    c = Conditions(88.0, 1.04, wind_ms=wind)
    x, idx = grid_nodes(demo_xs, 0.5)
    xm = 0.5 * (x[1:] + x[:-1])
    spl = BSpline(unc.knots, np.array(coefs).T, 3)
    d1, d2 = spl.derivative(1), spl.derivative(2)
    slopes = [np.ascontiguousarray(f(at).T) for f, at in ((d1, x), (d2, x), (d1, xm))]
    batch = solve_grid(grid_on_nodes(x, idx, *slopes), p, c, 3, sensitivities=False)
    assert batch.converged and batch.time.shape == (len(coefs), len(x))
    for row, coef in enumerate(coefs):
        alone_grid = make_grid(spline_profile(BSpline(unc.knots, coef, 3), 0.0, 1e3), demo_xs, 0.5)
        alone = solve_grid(alone_grid, p, c, 3, sensitivities=False)
        assert np.array_equal(batch.time[row], alone.time)
        assert np.array_equal(batch.energy[row], alone.energy)
    with pytest.raises(ValueError, match="one track"):
        solve_grid(grid_on_nodes(x, idx, *slopes), p, c, 3)


@pytest.mark.parametrize(
    ("p_hpa", "t_c", "rh", "rho"),
    [
        (1013.25, 15, 0, 1.225),
        (1013.25, 0, 80, 1.290),
        (900, -5, 80, 1.168),
        (800, -5, 80, 1.038),
        (700, -10, 70, 0.926),
    ],
)
def test_air_density_table(p_hpa, t_c, rh, rho):
    assert air_density(p_hpa, t_c, rh) == pytest.approx(rho, abs=6e-4)


def test_isa_pressure():
    assert isa_pressure_hpa(0.0) == pytest.approx(1013.25)
    assert air_density(isa_pressure_hpa(2000.0), -5, 80) == pytest.approx(1.031, abs=1e-3)


def test_local_gravity_matches_published_normal_gravity():
    """GRS80 normal gravity (Moritz, Geodetic Reference System 1980, table): equator
    9.7803267715, pole 9.8321863685, 45° 9.8061992; free air −0.3086 mGal/m."""
    from station.model.physics import local_gravity

    assert local_gravity(0.0) == pytest.approx(9.7803267715, abs=1e-9)
    assert local_gravity(90.0) == pytest.approx(9.8321863685, abs=1e-9)
    assert local_gravity(-90.0) == pytest.approx(9.8321863685, abs=1e-9)
    assert local_gravity(45.0) == pytest.approx(9.80620, abs=5e-6)
    # an alpine site: 47° N, 1700 m
    assert local_gravity(47.0, 1700.0) == pytest.approx(9.80799 - 3.086e-6 * 1700, abs=2e-5)
    assert local_gravity(45.0, 1000.0) - local_gravity(45.0) == pytest.approx(-3.086e-3)
    for bad in (91.0, float("nan")):
        with pytest.raises(ValueError):
            local_gravity(bad)
