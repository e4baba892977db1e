"""The paper's formulation: Cartesian DAE with a Lagrange multiplier, integrated in time.

Kaps et al. (1996) eq. 11-21: M·ẍ = F_a + F_r, g(x) = y − h(x) = 0, F_r = −Gᵀλ, G = (−h′, 1),
and N = −λ / cos α. Differentiating the constraint twice (index reduction) gives λ in closed
form; the photocell times are the roots of x(t) = x_i, found by the integrator's event location
("a root finding algorithm is necessary", §6.1).

This is deliberately a *different* formulation from :mod:`station.model.physics` (time
instead of arc length, Cartesian position and velocity instead of energy, an adaptive
Runge-Kutta integrator instead of a fixed grid). It lives with the tests because it is their
independent reference, not part of the station: the tests check that both agree to 1e-6 s;
``benchmarks/fit_speed.py`` uses it, at scipy's default tolerances, as "the straightforward
way".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from station.model.physics import Conditions, Params
from station.survey.track import Profile


@dataclass
class DaeResult:
    """Crossing times and speeds at the photocells (NaN where not reached)."""

    t: np.ndarray
    v: np.ndarray
    liftoff_x: float | None
    stopped_x: float | None
    min_normal_force_n: float
    nfev: int


def _scalar(f, x: float) -> float:
    return float(np.asarray(f(np.array([x])))[0])


def simulate_dae(
    profile: Profile,
    xs: np.ndarray,
    p: Params,
    c: Conditions,
    rtol: float = 1e-12,
    atol: float = 1e-12,
    method: str = "DOP853",
    t_max: float = 600.0,
) -> DaeResult:
    """Integrate (x, y, ẋ, ẏ) from the first photocell with speed v0 along the track."""
    m, g = c.mass_kg, c.g
    xs = np.asarray(xs, dtype=float)
    min_n = [math.inf]

    def forces(state: np.ndarray) -> tuple[float, float, float, float]:
        x, _, vx, vy = state
        hp = _scalar(profile.dh, x)
        hpp = _scalar(profile.d2h, x)
        cos_a = 1.0 / math.sqrt(1.0 + hp * hp)
        sin_a = hp * cos_a
        v = vx * cos_a + vy * sin_a  # speed along the tangent
        # constraint acceleration ÿ = h′ẍ + h″ẋ²; the tangential forces drop out of λ
        lam = (-m * g - m * hpp * vx * vx) / (1.0 + hp * hp)
        normal = -lam / cos_a
        vr = v - c.wind_ms
        drag = 0.5 * c.air_density * p.cda * vr * abs(vr)
        friction = (p.mu + p.mu1 * v) * normal
        fx = -(drag + friction) * cos_a + hp * lam
        fy = -m * g - (drag + friction) * sin_a - lam
        return fx / m, fy / m, normal, v

    def rhs(_t: float, state: np.ndarray) -> list[float]:
        ax, ay, normal, _ = forces(state)
        min_n[0] = min(min_n[0], normal)
        return [state[2], state[3], ax, ay]

    events = []
    for xi in xs[1:]:

        def crossing(_t, state, xi=xi):
            return state[0] - xi

        crossing.direction = 1.0
        events.append(crossing)

    def liftoff(_t, state):
        return forces(state)[2]

    liftoff.terminal = True
    liftoff.direction = -1.0

    def stop(_t, state):
        return forces(state)[3] - 1e-3

    stop.terminal = True
    stop.direction = -1.0

    def last(_t, state):
        return state[0] - xs[-1]

    last.terminal = True
    last.direction = 1.0

    x0 = xs[0]
    hp0 = _scalar(profile.dh, x0)
    ca = 1.0 / math.sqrt(1.0 + hp0 * hp0)
    state0 = [x0, _scalar(profile.h, x0), p.v0 * ca, p.v0 * hp0 * ca]
    sol = solve_ivp(
        rhs,
        (0.0, t_max),
        state0,
        method=method,
        rtol=rtol,
        atol=atol,
        events=[*events, liftoff, stop, last],
    )
    t = np.full(len(xs), np.nan)
    v = np.full(len(xs), np.nan)
    t[0], v[0] = 0.0, p.v0
    for i in range(len(xs) - 1):
        if sol.t_events[i].size:
            t[i + 1] = sol.t_events[i][0]
            st = sol.y_events[i][0]
            v[i + 1] = forces(st)[3]
    lift = sol.t_events[-3]
    stopped = sol.t_events[-2]
    return DaeResult(
        t=t,
        v=v,
        liftoff_x=float(sol.y_events[-3][0][0]) if lift.size else None,
        stopped_x=float(sol.y_events[-2][0][0]) if stopped.size else None,
        min_normal_force_n=min_n[0],
        nfev=sol.nfev,
    )
