"""Fit of (CdA, μ, v0[, μ1]) to the photocell times of one descent (Kaps et al. 1996, eq. 29).

Least squares of computed against measured crossing times, Σ(p) = Σ_i (t(x_i, p) + δ − t_i)²,
over every photocell including the first: the time at the first photocell is a measurement with
the same noise as the others, so a free offset δ (``dt0``, seconds) carries it; treating it as
exact made the v0 intervals too narrow (83–88 % coverage instead of 90 %). What makes it
reliable (numerics.md):

- bounds instead of the paper's square roots: ∂r/∂√μ = 2√μ·∂r/∂μ vanishes at μ = 0, a
  stationary point that attracts Gauss-Newton; a dogbox trust-region search (rectangular
  regions, made for simple bounds; 6 model evaluations on the demo descent where trust-region
  reflective needs 16) with CdA, μ, v0 (and μ1) ≥ 0 has no such point;
- exact sensitivities from the variational equations (:mod:`station.model.physics`) on a fixed grid,
  so the Jacobian is smooth, not finite-difference noise of an adaptive solver;
- a start computed from the data, not from the user: speeds at the photocells from local
  quadratics of s(t), then the energy balance of each interval, which is linear in μ and CdA,
  solved by non-negative least squares;
- a trial point where the skier stops gives finite, huge residuals (speed floored at 1 cm/s),
  so the trust region rejects it instead of failing; if the first search does not end at a
  verified minimum, a small grid of further starts is tried and the best minimum kept;
- speed: a bounded Gauss-Newton iteration (:func:`gauss_newton`) that stops as soon as a
  Gauss-Newton step could gain nothing more, so no model solve is spent past the minimum (some
  four solves per fit); the dogbox search is the fallback when it does not get there.

Uncertainty: linearised (Wald) 90 % intervals with Student's t on the residual degrees of
freedom, σ² = Σ/dof, Cov = σ²(JᵀJ)⁻¹. A parameter whose interval is wider than itself is
reported as not identifiable (status ``ill-conditioned``) rather than as a number.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np
from scipy.optimize import least_squares, nnls
from scipy.special import stdtrit  # Student-t quantile, without loading scipy.stats

from station.model.physics import PARAM_NAMES, Conditions, Params, StraightRun
from station.model.track_error import (
    DEFAULT_TIMER_PRECISION_S,
    SurveyError,
    add_survey_uncertainty,
    judge_goodness,
    survey_time_covariance,
)
from station.survey.track import Profile

#: typical magnitudes of (CdA, μ, v0, μ1), used to scale the search
SCALE = np.array([0.1, 0.01, 1.0, 1e-4])
UPPER = np.array([5.0, 1.0, 60.0, 0.05])
#: the time offset at the first photocell: name, typical magnitude (s), bound (s)
OFFSET_NAME, OFFSET_SCALE, OFFSET_BOUND = "dt0", 1e-3, 1.0
CI_METHOD = "linearised (Wald) interval, Student t on the residual degrees of freedom"
#: stopping tolerances of every least-squares search in station (one descent, a traverse, a day)
TOLERANCES = {"ftol": 1e-12, "xtol": 1e-12, "gtol": 1e-12}


@dataclass
class FitResult:
    """Everything a user needs to judge a fit: estimates, intervals, residuals and a status."""

    status: str
    model: str
    photocells: list[str]
    estimates: dict[str, float | None]
    ci90: dict[str, tuple[float, float] | None]
    stderr: dict[str, float | None]
    corr_mu_cda: float | None
    covariance: list[list[float]] | None
    sigma_s2: float | None
    grad_norm2: float | None
    dof: int
    residuals_s: dict[str, float]
    message: str = ""
    not_identifiable: list[str] = field(default_factory=list)
    liftoff_x: float | None = None
    stopped_x: float | None = None
    min_normal_force_n: float | None = None
    nfev: int = 0
    starts: int = 0
    speeds_ms: dict[str, float] = field(default_factory=dict)
    #: parameters (μ1) whose 90 % interval includes 0: shown, with this flag, not hidden
    consistent_with_zero: list[str] = field(default_factory=list)
    # goodness of fit and the survey's part in the intervals (station.model.track_error)
    timer_precision_s: float | None = None
    chi2: float | None = None
    chi2_p: float | None = None
    ci90_timing: dict[str, tuple[float, float] | None] | None = None
    stderr_timing: dict[str, float | None] | None = None
    survey_share: dict[str, float | None] | None = None
    #: the survey's covariance (s²) of the computed times t_i − t_1 used, for reuse by later
    #: fits on the same photocells (not part of the JSON)
    survey_time_cov: np.ndarray | None = field(default=None, repr=False, compare=False)

    def to_dict(self) -> dict[str, Any]:
        """The JSON form documented in the README."""
        e = self.estimates
        out: dict[str, Any] = {
            "cda": e.get("cda"),
            "mu": e.get("mu"),
            "v0": e.get("v0"),
        }
        if self.model == "velocity":
            out["mu1"] = e.get("mu1")
        out.update(
            {
                "ci90": {k: (list(v) if v is not None else None) for k, v in self.ci90.items()},
                "ci_method": CI_METHOD,
                "stderr": self.stderr,
                "corr_mu_cda": self.corr_mu_cda,
                "sigma_s2": self.sigma_s2,
                "grad_norm2": self.grad_norm2,
                "dof": self.dof,
                "residuals_s": self.residuals_s,
                "speeds_ms": self.speeds_ms,
                "status": self.status,
                "message": self.message,
                "not_identifiable": self.not_identifiable,
                "consistent_with_zero": self.consistent_with_zero,
                "model": self.model,
                "photocells": self.photocells,
                "v0_at": self.photocells[0] if self.photocells else None,
                "liftoff_x": self.liftoff_x,
                "stopped_x": self.stopped_x,
                "min_normal_force_n": self.min_normal_force_n,
                "nfev": self.nfev,
                "starts": self.starts,
                "timer_precision_s": self.timer_precision_s,
                "chi2": self.chi2,
                "chi2_p": self.chi2_p,
                "ci90_timing": (
                    None
                    if self.ci90_timing is None
                    else {
                        k: (list(v) if v is not None else None) for k, v in self.ci90_timing.items()
                    }
                ),
                "stderr_timing": self.stderr_timing,
                "survey_share": self.survey_share,
            }
        )
        return out


@dataclass
class Uncertainty:
    """Linearised uncertainty of a least-squares solution."""

    covariance: list[list[float]] | None
    stderr: dict[str, float | None]
    ci90: dict[str, tuple[float, float] | None]
    corr_mu_cda: float | None
    not_identifiable: list[str]
    consistent_with_zero: list[str] = field(default_factory=list)


@lru_cache(maxsize=256)
def t95(dof: int) -> float:
    """Student's t 0.95 quantile (cached; scipy.special, not scipy.stats, which costs start-up)."""
    return float(stdtrit(dof, 0.95))


#: parameters that are always reported with their interval, flagged when it includes 0
SIGNED_EFFECTS = ("mu1",)


def uncertainty(
    jac: np.ndarray,
    r: np.ndarray,
    p: np.ndarray,
    names: list[str],
    dof: int,
    scale: np.ndarray,
    nuisance: tuple[str, ...] = ("v0", "s0", OFFSET_NAME),
) -> Uncertainty:
    """Cov = σ²(JᵀJ)⁻¹ with σ² = Σ/dof; 90 % intervals p ± t(0.95, dof)·sd, clipped at the
    lower bound 0 of the physical parameters. A parameter (other than the nuisance ones) whose
    half-width exceeds its own value, or a singular JᵀJ, makes it not identifiable."""
    out = Uncertainty(None, {k: None for k in names}, {k: None for k in names}, None, [])
    if dof < 1:
        return out
    js = jac * scale
    cond = np.linalg.cond(js) if np.all(np.isfinite(js)) else math.inf
    if not cond < 1e12:
        out.not_identifiable = [k for k in names if k not in nuisance]
        return out
    sigma2 = float(r @ r) / dof
    cov = np.linalg.inv(jac.T @ jac) * sigma2
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    q = t95(dof)
    out.covariance = cov.tolist()
    for i, k in enumerate(names):
        out.stderr[k] = float(sd[i])
        lo = p[i] - q * sd[i]
        if k not in nuisance or k == "v0":
            lo = max(lo, 0.0)
        out.ci90[k] = (float(lo), float(p[i] + q * sd[i]))
        if k in SIGNED_EFFECTS:
            if lo <= 0.0:
                out.consistent_with_zero.append(k)
        elif k not in nuisance and q * sd[i] > abs(p[i]):
            out.not_identifiable.append(k)
    if "cda" in names and "mu" in names:
        i, j = names.index("cda"), names.index("mu")
        if sd[i] > 0 and sd[j] > 0:
            out.corr_mu_cda = float(cov[i, j] / (sd[i] * sd[j]))
    return out


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


def _solver(run: StraightRun, conditions: Conditions, n_params: int):
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


def fit_descent(
    profile: Profile,
    xs: np.ndarray,
    times: np.ndarray,
    conditions: Conditions,
    ids: list[str] | None = None,
    model: str = "constant",
    step: float = 0.5,
    run: StraightRun | None = None,
    timer_precision_s: float = DEFAULT_TIMER_PRECISION_S,
    survey: SurveyError | None = None,
    survey_time_cov: np.ndarray | None = None,
) -> FitResult:
    """Fit one descent. ``xs`` and ``times`` are the photocells used, in order down the run;
    times may be on any clock (the offset ``dt0`` absorbs it and the noise of the first).

    ``timer_precision_s``: standard deviation of one crossing time, for the goodness-of-fit
    test (default 0.5 ms: a 1 ms timer resolution and typical photocell jitter, see
    :data:`station.model.track_error.DEFAULT_TIMER_PRECISION_S`). ``survey``: the track's
    uncertainty (:func:`station.model.track_error.survey_error`); with it the 90 % intervals
    carry the survey too, and the timing-only ones are kept beside them. ``survey_time_cov``:
    that survey's covariance of the times as an earlier fit on the same photocells returned it
    (``FitResult.survey_time_cov``), instead of ``survey``: its ~60 model solves are then not
    repeated for every descent of a day."""
    if model not in ("constant", "velocity"):
        raise ValueError(f"unknown model {model!r}")
    n_params = 4 if model == "velocity" else 3
    names = list(PARAM_NAMES[:n_params])
    xs = np.asarray(xs, dtype=float)
    t = np.asarray(times, dtype=float) - float(times[0])
    ids = ids or [f"PC{i + 1}" for i in range(len(xs))]
    n_res = len(xs) - 1
    dof = n_res - n_params

    def empty(status: str, message: str) -> FitResult:
        return FitResult(
            status=status,
            model=model,
            photocells=ids,
            estimates={k: None for k in names},
            ci90={k: None for k in names},
            stderr={k: None for k in names},
            corr_mu_cda=None,
            covariance=None,
            sigma_s2=None,
            grad_norm2=None,
            dof=max(dof, 0),
            residuals_s={},
            message=message,
        )

    if n_res < n_params:
        return empty(
            "too-few-photocells",
            f"{len(xs)} photocells give {n_res} time differences for {n_params} unknowns; "
            f"at least {n_params + 2} photocells are needed for a fit with uncertainty",
        )
    run = run or StraightRun(profile, xs, step)
    fit_names, scale, upper, bounded = with_offset(names, n_params)
    solve = _solver(run, conditions, n_params)

    def fun(p: np.ndarray) -> np.ndarray:
        return solve(p).t + p[-1] - t

    def jac(p: np.ndarray) -> np.ndarray:
        return np.column_stack([solve(p).dt_dp, np.ones(len(t))])

    def search(x0: np.ndarray):
        x0 = np.append(x0, 0.0)
        res = gauss_newton(lambda p: (fun(p), jac(p)), x0, upper, scale, bounded)
        if res.status > 0 and solve(res.x).stopped_x is None:
            return res
        out = least_squares(
            fun,
            np.clip(x0, np.where(bounded, 0.0, -upper), upper),
            jac=jac,
            bounds=(np.where(bounded, 0.0, -upper), upper),
            method="dogbox",
            x_scale=scale,
            max_nfev=200,
            **TOLERANCES,
        )
        out.nfev += res.nfev
        return out

    def verified(res) -> bool:
        """A minimum only if Gauss-Newton can gain nothing more and the skier reaches every
        photocell (a point where the model skier stops has a flat, huge Σ)."""
        if solve(res.x).stopped_x is not None:
            return False
        if isinstance(res, Search):
            return res.status > 0  # gauss_newton stops only on this very test
        r = res.fun
        sigma = float(r @ r)
        gain = _predicted_decrease(res.jac, r, res.x, scale, bounded)
        return bool(np.isfinite(sigma)) and gain <= 1e-6 * sigma + 1e-18

    x0 = initial_guess(run, t, conditions, n_params)
    best = search(x0)
    nfev, starts = best.nfev, 1
    if not verified(best):
        for cda0 in (0.1, 0.4, 1.0):
            for mu0 in (0.005, 0.03, 0.1):
                start = np.array([cda0, mu0, x0[2], 0.0][:n_params])
                res = search(start)
                nfev += res.nfev
                starts += 1
                if res.cost < best.cost or (not verified(best) and verified(res)):
                    best = res
                if verified(best):
                    break
            if verified(best):
                break

    p = best.x
    desc = solve(p)
    r, jm = fun(p), jac(p)
    sigma_s2 = float(r @ r)
    grad = 2.0 * jm.T @ r
    estimates = {k: float(v) for k, v in zip(fit_names, p, strict=True)}
    result = FitResult(
        status="ok",
        model=model,
        photocells=ids,
        estimates=estimates,  # type: ignore[arg-type]
        ci90={k: None for k in names},
        stderr={k: None for k in names},
        corr_mu_cda=None,
        covariance=None,
        sigma_s2=sigma_s2,
        grad_norm2=float(grad @ grad),
        dof=dof,
        residuals_s={i: float(v) for i, v in zip(ids, r, strict=True)},
        liftoff_x=desc.liftoff_x,
        stopped_x=desc.stopped_x,
        min_normal_force_n=desc.min_normal_force_n,
        nfev=nfev,
        starts=starts,
        speeds_ms={i: float(v) for i, v in zip(ids, desc.v, strict=True)},
    )

    unc = uncertainty(jm, r, p, fit_names, dof, scale)
    result.covariance, result.stderr, result.ci90 = unc.covariance, unc.stderr, unc.ci90
    result.corr_mu_cda, result.not_identifiable = unc.corr_mu_cda, unc.not_identifiable
    result.consistent_with_zero = unc.consistent_with_zero

    # status, most serious first
    if dof < 1:
        result.status = "too-few-photocells"
        result.message = (
            f"{len(xs)} photocells leave no degree of freedom for {n_params} unknowns: "
            "the fit passes through every time and has no uncertainty"
        )
    elif desc.liftoff_x is not None:
        result.status = "lift-off"
        result.message = (
            f"the fitted skier leaves the snow at x = {desc.liftoff_x:.1f} m (normal force "
            "≤ 0); the particle-on-track model does not hold there"
        )
    elif desc.stopped_x is not None:
        result.status = "stopped"
        result.message = (
            f"the fitted skier stops at x = {desc.stopped_x:.1f} m, before the last photocell"
        )
    elif not verified(best) or not desc.converged:
        result.status = "not-converged"
        result.message = (
            f"the search ended ({best.message}) without a verified minimum after {starts} "
            "start(s); the numbers are not a least-squares solution"
        )
    elif result.not_identifiable:
        result.status = "ill-conditioned"
        which = ", ".join(result.not_identifiable)
        result.message = (
            f"{which} not identifiable from these times: the 90 % interval is wider than the "
            "estimate itself"
        )
        for k in result.not_identifiable:
            result.estimates[k] = None
            result.ci90[k] = None
    _survey_and_goodness(
        result, run, p, conditions, jm, r, step, timer_precision_s, survey, survey_time_cov
    )
    return result


def _survey_and_goodness(
    result: FitResult,
    run: StraightRun,
    p: np.ndarray,
    conditions: Conditions,
    jm: np.ndarray,
    r: np.ndarray,
    step: float,
    timer_precision_s: float,
    survey: SurveyError | None,
    relative: np.ndarray | None = None,
) -> None:
    """The survey's share of the intervals, then the χ² test (station.model.track_error).

    The fit has every crossing time as data and a free offset (the last parameter), so the
    survey's covariance of the computed times t_i − t_1 is padded with a zero first row and
    column: the model's own first time is 0 whatever the track."""
    survey_cov = None
    if relative is None and survey is not None and result.covariance is not None:
        n_phys = len(p) - 1
        phys = Params(p[0], p[1], p[2], mu1=p[3] if n_phys == 4 else 0.0)
        relative = survey_time_covariance(survey, run.xs, phys, conditions, step)
    if relative is not None and result.covariance is not None:
        result.survey_time_cov = relative
        survey_cov = np.zeros((len(r), len(r)))
        survey_cov[1:, 1:] = relative
        add_survey_uncertainty(result, jm, r, survey_cov)
    judge_goodness(result, r, timer_precision_s, survey_cov)
