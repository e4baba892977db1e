"""The search of one descent's fit: the start computed from the data, the bounded Gauss-Newton
iteration that stops at a verified minimum, and scipy's dogbox where it gives up (why each, in
:mod:`station.model.fit`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import least_squares, nnls

from station.model.fit_result import OFFSET_BOUND, OFFSET_NAME, OFFSET_SCALE
from station.model.physics import Conditions, Params, StraightRun

#: typical magnitudes of (CdA, μ, v0, μ1), used to scale the search
SCALE = np.array([0.1, 0.01, 1.0, 1e-4])
UPPER = np.array([5.0, 1.0, 60.0, 0.05])
#: stopping tolerances of every least-squares search in station (one descent, a traverse, a day)
TOLERANCES = {"ftol": 1e-12, "xtol": 1e-12, "gtol": 1e-12}


def speed_estimates(s: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Speed at each photocell from the quadratic s(t) through it and its neighbours (the
    derivative of the Lagrange polynomial, for all photocells at once)."""
    n = len(s)
    if n < 3:
        v = np.full(n, (s[-1] - s[0]) / (t[-1] - t[0]) if n == 2 and t[-1] != t[0] else 0.1)
        return np.maximum(v, 0.1)
    j = np.clip(np.arange(n) - 1, 0, n - 3)
    t0, t1, t2 = t[j], t[j + 1], t[j + 2]
    s0, s1, s2 = s[j], s[j + 1], s[j + 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        v = (
            s0 * (2 * t - t1 - t2) / ((t0 - t1) * (t0 - t2))
            + s1 * (2 * t - t0 - t2) / ((t1 - t0) * (t1 - t2))
            + s2 * (2 * t - t0 - t1) / ((t2 - t0) * (t2 - t1))
        )
    return np.maximum(np.nan_to_num(v, nan=0.1, posinf=0.1, neginf=0.1), 0.1)


def initial_guess(run: StraightRun, t: np.ndarray, c: Conditions, n_params: int) -> np.ndarray:
    """(CdA, μ, v0[, μ1]) from the energy balance of each interval; linear in μ and CdA."""
    grid = run.fine
    idx = grid.cell_index
    s = grid.s[idx]
    v = speed_estimates(s, t)
    energy = 0.5 * v * v
    y = run.profile.h(run.xs)
    alpha = np.arctan(run.profile.dh(run.xs))
    k = c.air_density / c.mass_kg
    e_mean = 0.5 * (energy[1:] + energy[:-1])
    rows = np.column_stack(
        [
            -(c.g * np.diff(run.xs) + 2.0 * e_mean * np.diff(alpha)),  # ∂/∂μ
            -k * e_mean * np.diff(s),  # ∂/∂CdA
        ]
    )
    rhs = np.diff(energy) + c.g * np.diff(y)
    try:
        sol, _ = nnls(rows / SCALE[[1, 0]], rhs)
        mu, cda = sol * SCALE[[1, 0]]
    except (ValueError, RuntimeError):
        mu, cda = 0.02, 0.3
    if not np.isfinite(mu) or not np.isfinite(cda) or len(t) < 4:
        mu, cda = 0.02, 0.3
    x0 = [min(max(cda, 0.02), 2.0), min(max(mu, 1e-3), 0.5), float(v[0])]
    if n_params == 4:
        x0.append(0.0)
    return np.array(x0)


def _predicted_decrease(
    jac: np.ndarray,
    r: np.ndarray,
    x: np.ndarray,
    scale: np.ndarray,
    bounded: np.ndarray | None = None,
) -> float:
    """What one more feasible Gauss-Newton step could still gain in Σ.

    Parameters at their lower bound 0 whose step points outward are held there; the step of the
    others is shortened so that none crosses 0. A verified minimum gains (almost) nothing.
    ``bounded`` marks the parameters with that bound (default: all; a time offset has none).
    """
    return _feasible_step(jac, r, x, scale, bounded)[0]


def _feasible_step(jac, r, x, scale, bounded=None) -> tuple[float, np.ndarray]:
    """The feasible Gauss-Newton step of :func:`_predicted_decrease` and what it would gain."""
    bounded = np.ones(len(x), dtype=bool) if bounded is None else bounded
    free = np.ones(len(x), dtype=bool)
    for _ in range(len(x)):
        if not free.any():
            return 0.0, np.zeros(len(x))
        step = np.zeros(len(x))
        step[free], *_ = np.linalg.lstsq(jac[:, free], -r, rcond=None)
        blocked = free & bounded & (x <= 1e-6 * scale) & (step < 0)
        if not blocked.any():
            break
        free &= ~blocked
    neg = bounded & (step < 0)
    frac = min(1.0, float(np.min(x[neg] / -step[neg]))) if neg.any() else 1.0
    return float(np.sum(r**2) - np.sum((r + frac * (jac @ step)) ** 2)), frac * step


@dataclass
class Search:
    """The outcome of a least-squares search, in the fields of scipy's ``OptimizeResult`` that
    the fit reads (so that either search can be used)."""

    x: np.ndarray
    fun: np.ndarray
    jac: np.ndarray
    cost: float
    nfev: int
    status: int
    message: str


def gauss_newton(
    evaluate,
    x0: np.ndarray,
    upper: np.ndarray,
    scale: np.ndarray,
    bounded: np.ndarray,
    max_iter: int = 25,
) -> Search:
    """Bounded Gauss-Newton with Levenberg-Marquardt damping when a step fails.

    ``evaluate(x) -> (r, J)`` costs one model solve; the iteration stops *before* solving again
    once the feasible Gauss-Newton step predicts a gain ≤ 1e-6·Σ (the test of a verified
    minimum), so no solve is spent past the minimum. Bounds: 0 ≤ x for ``bounded`` parameters,
    |x| ≤ upper for all; a step is projected onto them. ``status`` 0 means it gave up (then the
    caller falls back to scipy's dogbox).
    """
    lower = np.where(bounded, 0.0, -upper)
    x = np.minimum(np.maximum(x0, lower), upper)
    r, jac = evaluate(x)
    cost = float(r @ r)
    nfev, lam = 1, 0.0
    for _ in range(max_iter):
        if not np.isfinite(cost):
            break
        gain, step = _feasible_step(jac, r, x, scale, bounded)
        if gain <= 1e-6 * cost + 1e-18:
            return Search(x, r, jac, 0.5 * cost, nfev, 1, "predicted gain below 1e-6 of Σ")
        if lam > 0:  # the full step failed: a damped one, in scaled parameters
            js = jac * scale
            hold = bounded & (x <= 1e-6 * scale) & (js.T @ r > 0)  # at 0 and pushed outward
            free = ~hold
            a = js[:, free]
            damp = np.sqrt(lam * np.sum(a * a, axis=0))
            a = np.vstack([a, np.diag(damp)])
            rhs = np.concatenate([-r, np.zeros(int(free.sum()))])
            step = np.zeros(len(x))
            step[free] = np.linalg.lstsq(a, rhs, rcond=None)[0] * scale[free]
        x_new = np.minimum(np.maximum(x + step, lower), upper)
        r_new, jac_new = evaluate(x_new)
        nfev += 1
        cost_new = float(r_new @ r_new)
        if np.isfinite(cost_new) and cost_new < cost:
            x, r, jac, cost = x_new, r_new, jac_new, cost_new
            lam = 0.0 if lam <= 1e-3 else lam / 10.0
        else:
            lam = 1e-3 if lam == 0.0 else lam * 10.0
            if lam > 1e8:
                break
    return Search(x, r, jac, 0.5 * cost, nfev, 0, "Gauss-Newton gave up")


def with_offset(names: list[str], n_params: int):
    """Names, scales, upper bounds and the lower-bound-0 mask of the physical parameters
    followed by the time offset at the first photocell (unbounded but for ±1 s)."""
    scale = np.append(SCALE[:n_params], OFFSET_SCALE)
    upper = np.append(UPPER[:n_params], OFFSET_BOUND)
    bounded = np.append(np.ones(n_params, dtype=bool), False)
    return [*names, OFFSET_NAME], scale, upper, bounded


def model_solver(run: StraightRun, conditions: Conditions, n_params: int):
    """The model solve of a parameter vector (physical parameters, then the offset), keeping
    the last few: the search, its check and the result ask for the same points."""
    cache: dict[bytes, Any] = {}

    def solve(p: np.ndarray):
        key = p[:n_params].tobytes()
        if key not in cache:
            if len(cache) >= 4:
                cache.pop(next(iter(cache)))
            par = Params(p[0], p[1], p[2], mu1=p[3] if n_params == 4 else 0.0)
            cache[key] = run.solve(par, conditions, n_params)
        return cache[key]

    return solve


@dataclass
class Problem:
    """The least-squares problem of one descent: the residuals and Jacobian of (physical
    parameters, offset), the bounded search and the test of a verified minimum."""

    solve: Callable[[np.ndarray], Any]
    t: np.ndarray
    scale: np.ndarray
    upper: np.ndarray
    bounded: np.ndarray

    def fun(self, p: np.ndarray) -> np.ndarray:
        return self.solve(p).t + p[-1] - self.t

    def jac(self, p: np.ndarray) -> np.ndarray:
        return np.column_stack([self.solve(p).dt_dp, np.ones(len(self.t))])

    def search(self, x0: np.ndarray):
        """Gauss-Newton from ``x0`` (offset 0), scipy's dogbox where it gives up."""
        x0 = np.append(x0, 0.0)
        upper, bounded = self.upper, self.bounded
        res = gauss_newton(lambda p: (self.fun(p), self.jac(p)), x0, upper, self.scale, bounded)
        if res.status > 0 and self.solve(res.x).stopped_x is None:
            return res
        out = least_squares(
            self.fun,
            np.clip(x0, np.where(bounded, 0.0, -upper), upper),
            jac=self.jac,
            bounds=(np.where(bounded, 0.0, -upper), upper),
            method="dogbox",
            x_scale=self.scale,
            max_nfev=200,
            **TOLERANCES,
        )
        out.nfev += res.nfev
        return out

    def verified(self, res) -> bool:
        """A minimum only if Gauss-Newton can gain nothing more and the skier reaches every
        photocell (a point where the model skier stops has a flat, huge Σ)."""
        if self.solve(res.x).stopped_x is not None:
            return False
        if isinstance(res, Search):
            return res.status > 0  # gauss_newton stops only on this very test
        r = res.fun
        sigma = float(r @ r)
        gain = _predicted_decrease(res.jac, r, res.x, self.scale, self.bounded)
        return bool(np.isfinite(sigma)) and gain <= 1e-6 * sigma + 1e-18

    def minimise(self, x0: np.ndarray, n_params: int) -> tuple[Any, int, int]:
        """The search from the data's start, then from a small grid of starts until one ends
        at a verified minimum; the best search, model evaluations and starts."""
        best = self.search(x0)
        nfev, starts = best.nfev, 1
        if not self.verified(best):
            for cda0 in (0.1, 0.4, 1.0):
                for mu0 in (0.005, 0.03, 0.1):
                    start = np.array([cda0, mu0, x0[2], 0.0][:n_params])
                    res = self.search(start)
                    nfev += res.nfev
                    starts += 1
                    if res.cost < best.cost or (not self.verified(best) and self.verified(res)):
                        best = res
                    if self.verified(best):
                        break
                if self.verified(best):
                    break
        return best, nfev, starts
