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
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np
from scipy.optimize import least_squares, nnls
from scipy.special import stdtrit  # Student-t quantile, without loading scipy.stats

from station.model.estimate import MISSING, Estimate, FitStatus
from station.model.physics import PARAM_NAMES, Conditions, Params, StraightRun
from station.model.timer import TIMER_PRECISION_S
from station.model.track_error import (
    Goodness,
    SurveyError,
    SurveyIntervals,
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


@dataclass(frozen=True)
class FitResult:
    """Everything a user needs to judge a fit: estimates with their intervals, residuals and a
    status. Built once, at the end of :func:`fit_descent`; never changed after."""

    status: FitStatus
    model: str
    photocells: list[str]
    cda: Estimate
    mu: Estimate
    v0: Estimate
    #: the time offset at the first photocell (that time is data too); None: not fitted
    dt0: Estimate | None
    corr_mu_cda: float | None
    covariance: list[list[float]] | None
    sigma_s2: float | None
    grad_norm2: float | None
    dof: int
    residuals_s: dict[str, float]
    #: velocity-dependent friction (s/m), only in the ``velocity`` model
    mu1: Estimate | None = None
    message: str = ""
    liftoff_x: float | None = None
    stopped_x: float | None = None
    min_normal_force_n: float | None = None
    nfev: int = 0
    starts: int = 0
    speeds_ms: dict[str, float] = field(default_factory=dict)
    # goodness of fit and the survey's part in the intervals (station.model.track_error)
    timer_precision_s: float | None = None
    chi2: float | None = None
    chi2_p: float | None = None
    #: the intervals carry the survey's uncertainty (each estimate keeps its timing-only one)
    survey_in_intervals: bool = False
    #: the survey's covariance (s²) of the computed times t_i − t_1 used, for reuse by later
    #: fits on the same photocells (not part of the JSON)
    survey_time_cov: np.ndarray | None = field(default=None, repr=False, compare=False)

    def parameters(self) -> list[tuple[str, Estimate]]:
        """The fitted parameters in the order of the JSON: cda, mu, v0, [mu1], [dt0]."""
        out = [("cda", self.cda), ("mu", self.mu), ("v0", self.v0)]
        if self.mu1 is not None:
            out.append(("mu1", self.mu1))
        if self.dt0 is not None:
            out.append((OFFSET_NAME, self.dt0))
        return out

    @property
    def not_identifiable(self) -> list[str]:
        """Names of the parameters the data do not determine."""
        return [k for k, e in self.parameters() if e.not_identifiable]

    @property
    def consistent_with_zero(self) -> list[str]:
        """Names of the signed effects (μ1) whose 90 % interval includes 0."""
        return [k for k, e in self.parameters() if e.consistent_with_zero]

    def to_dict(self) -> dict[str, Any]:
        """The JSON form documented in the README."""
        params = self.parameters()
        out: dict[str, Any] = {"cda": self.cda.value, "mu": self.mu.value, "v0": self.v0.value}
        if self.model == "velocity":
            out["mu1"] = self.mu1.value if self.mu1 is not None else None
        survey = self.survey_in_intervals
        out.update(
            {
                "ci90": {k: _pair(e.ci90) for k, e in params},
                "ci_method": CI_METHOD,
                "stderr": {k: e.stderr for k, e in params},
                "corr_mu_cda": self.corr_mu_cda,
                "sigma_s2": self.sigma_s2,
                "grad_norm2": self.grad_norm2,
                "dof": self.dof,
                "residuals_s": self.residuals_s,
                "speeds_ms": self.speeds_ms,
                "status": self.status.value,
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
                "ci90_timing": {k: _pair(e.ci90_timing) for k, e in params} if survey else None,
                "stderr_timing": {k: e.stderr_timing for k, e in params} if survey else None,
                "survey_share": {k: e.survey_share for k, e in params} if survey else None,
            }
        )
        return out


def _pair(ci: tuple[float, float] | None) -> list[float] | None:
    return list(ci) if ci is not None else None


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


@dataclass
class _Problem:
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


def fit_descent(
    profile: Profile,
    xs: np.ndarray,
    times: np.ndarray,
    conditions: Conditions,
    ids: list[str] | None = None,
    model: str = "constant",
    step: float = 0.5,
    run: StraightRun | None = None,
    timer_precision_s: float = TIMER_PRECISION_S,
    survey: SurveyError | None = None,
    survey_time_cov: np.ndarray | None = None,
) -> FitResult:
    """Fit one descent. ``xs`` and ``times`` are the photocells used, in order down the run;
    times may be on any clock (the offset ``dt0`` absorbs it and the noise of the first).

    ``timer_precision_s``: standard deviation of one crossing time, for the goodness-of-fit
    test (default :data:`station.model.timer.TIMER_PRECISION_S`, 0.5 ms). ``survey``: the
    track's uncertainty (:func:`station.model.track_error.survey_error`); with it the 90 %
    intervals carry the survey too, and the timing-only ones are kept beside them.
    ``survey_time_cov``: that survey's covariance of the times as an earlier fit on the same
    photocells returned it (``FitResult.survey_time_cov``), instead of ``survey``: its ~60
    model solves are then not repeated for every descent of a day."""
    if model not in ("constant", "velocity"):
        raise ValueError(f"unknown model {model!r}")
    n_params = 4 if model == "velocity" else 3
    names = list(PARAM_NAMES[:n_params])
    xs = np.asarray(xs, dtype=float)
    t = np.asarray(times, dtype=float) - float(times[0])
    ids = ids or [f"PC{i + 1}" for i in range(len(xs))]
    n_res = len(xs) - 1
    dof = n_res - n_params
    if n_res < n_params:
        return _no_fit(
            model, ids, names, max(dof, 0),
            f"{len(xs)} photocells give {n_res} time differences for {n_params} unknowns; "
            f"at least {n_params + 2} photocells are needed for a fit with uncertainty",
        )  # fmt: skip

    # the search
    run = run or StraightRun(profile, xs, step)
    fit_names, scale, upper, bounded = with_offset(names, n_params)
    problem = _Problem(_solver(run, conditions, n_params), t, scale, upper, bounded)
    x0 = initial_guess(run, t, conditions, n_params)
    best, nfev, starts = problem.minimise(x0, n_params)

    # at the solution: residuals, linearised uncertainty, the verdict
    p = best.x
    desc = problem.solve(p)
    r, jm = problem.fun(p), problem.jac(p)
    values: dict[str, float | None] = {k: float(v) for k, v in zip(fit_names, p, strict=True)}
    unc = uncertainty(jm, r, p, fit_names, dof, scale)
    status, message = _verdict(
        len(xs), n_params, dof, desc, problem.verified(best) and desc.converged, best.message,
        starts, unc.not_identifiable,
    )  # fmt: skip
    if status == FitStatus.ILL_CONDITIONED:
        for k in unc.not_identifiable:
            values[k] = None
            unc.ci90[k] = None

    # the survey's share of the intervals, then the χ² test (station.model.track_error)
    relative, survey_cov, widened = _survey_part(
        run, p, conditions, jm, r, step, dof, values, unc, survey, survey_time_cov
    )
    good = judge_goodness(r, dof, timer_precision_s, survey_cov)
    if good is not None and status == FitStatus.OK and good.poor:
        status, message = FitStatus.POOR_FIT, _poor_fit_message(good, timer_precision_s, dof)

    def estimate(k: str) -> Estimate:
        return _estimate(k, values[k], unc, widened)

    grad = 2.0 * jm.T @ r
    return FitResult(
        status=status,
        model=model,
        photocells=ids,
        cda=estimate("cda"),
        mu=estimate("mu"),
        v0=estimate("v0"),
        mu1=estimate("mu1") if n_params == 4 else None,
        dt0=estimate(OFFSET_NAME),
        corr_mu_cda=unc.corr_mu_cda,
        covariance=widened.covariance if widened else unc.covariance,
        sigma_s2=float(r @ r),
        grad_norm2=float(grad @ grad),
        dof=dof,
        residuals_s={i: float(v) for i, v in zip(ids, r, strict=True)},
        message=message,
        liftoff_x=desc.liftoff_x,
        stopped_x=desc.stopped_x,
        min_normal_force_n=desc.min_normal_force_n,
        nfev=nfev,
        starts=starts,
        speeds_ms={i: float(v) for i, v in zip(ids, desc.v, strict=True)},
        timer_precision_s=timer_precision_s,
        chi2=good.chi2 if good else None,
        chi2_p=good.p if good else None,
        survey_in_intervals=widened is not None,
        survey_time_cov=relative,
    )


def _poor_fit_message(good: Goodness, timer_precision_s: float, dof: int) -> str:
    return (
        f"the residuals (RMS {good.rms_s * 1000:.2f} ms) are far above the timer precision "
        f"{timer_precision_s * 1000:.2f} ms (χ² {good.chi2:.1f} on {dof} dof, "
        f"p = {good.p:.1e}): a photocell triggered by something else, a photocell position "
        "or a track that is wrong, or a descent the model does not describe; the numbers "
        "are not to be trusted"
    )


def _estimate(
    k: str, value: float | None, unc: Uncertainty, widened: SurveyIntervals | None
) -> Estimate:
    """Parameter ``k`` as the result gives it: its timing-only uncertainty, or the one widened
    by the survey with the timing-only one beside it."""
    return Estimate(
        value=value,
        ci90=widened.ci90[k] if widened else unc.ci90[k],
        stderr=widened.stderr[k] if widened else unc.stderr[k],
        ci90_timing=widened.ci90_timing[k] if widened else None,
        stderr_timing=widened.stderr_timing[k] if widened else None,
        survey_share=widened.survey_share[k] if widened else None,
        not_identifiable=k in unc.not_identifiable,
        consistent_with_zero=k in unc.consistent_with_zero,
    )


def _no_fit(model: str, ids: list[str], names: list[str], dof: int, message: str) -> FitResult:
    """Too few photocells for the unknowns: no search, no numbers, the reason."""
    return FitResult(
        status=FitStatus.TOO_FEW_PHOTOCELLS,
        model=model,
        photocells=ids,
        cda=MISSING,
        mu=MISSING,
        v0=MISSING,
        mu1=MISSING if "mu1" in names else None,
        dt0=None,
        corr_mu_cda=None,
        covariance=None,
        sigma_s2=None,
        grad_norm2=None,
        dof=dof,
        residuals_s={},
        message=message,
    )


def _verdict(
    n_cells: int,
    n_params: int,
    dof: int,
    desc: Any,
    verified: bool,
    search_message: str,
    starts: int,
    not_identifiable: list[str],
) -> tuple[FitStatus, str]:
    """The fit's status and why, most serious first (the χ² test comes after, on ``ok``)."""
    if dof < 1:
        return FitStatus.TOO_FEW_PHOTOCELLS, (
            f"{n_cells} photocells leave no degree of freedom for {n_params} unknowns: "
            "the fit passes through every time and has no uncertainty"
        )
    if desc.liftoff_x is not None:
        return FitStatus.LIFT_OFF, (
            f"the fitted skier leaves the snow at x = {desc.liftoff_x:.1f} m (normal force "
            "≤ 0); the particle-on-track model does not hold there"
        )
    if desc.stopped_x is not None:
        return FitStatus.STOPPED, (
            f"the fitted skier stops at x = {desc.stopped_x:.1f} m, before the last photocell"
        )
    if not verified:
        return FitStatus.NOT_CONVERGED, (
            f"the search ended ({search_message}) without a verified minimum after {starts} "
            "start(s); the numbers are not a least-squares solution"
        )
    if not_identifiable:
        which = ", ".join(not_identifiable)
        return FitStatus.ILL_CONDITIONED, (
            f"{which} not identifiable from these times: the 90 % interval is wider than the "
            "estimate itself"
        )
    return FitStatus.OK, ""


def _survey_part(
    run: StraightRun,
    p: np.ndarray,
    conditions: Conditions,
    jm: np.ndarray,
    r: np.ndarray,
    step: float,
    dof: int,
    values: dict[str, float | None],
    unc: Uncertainty,
    survey: SurveyError | None,
    relative: np.ndarray | None,
) -> tuple[np.ndarray | None, np.ndarray | None, SurveyIntervals | None]:
    """The survey's covariance of the times t_i − t_1 (given, or computed from ``survey``),
    padded for the fit, and the intervals widened by it; Nones without a survey or without an
    uncertainty to widen.

    The fit has every crossing time as data and a free offset (the last parameter), so the
    survey's covariance of the computed times t_i − t_1 is padded with a zero first row and
    column: the model's own first time is 0 whatever the track."""
    if unc.covariance is None:
        return None, None, None
    if relative is None and survey is not None:
        n_phys = len(p) - 1
        phys = Params(p[0], p[1], p[2], mu1=p[3] if n_phys == 4 else 0.0)
        relative = survey_time_covariance(survey, run.xs, phys, conditions, step)
    if relative is None:
        return None, None, None
    survey_cov = np.zeros((len(r), len(r)))
    survey_cov[1:, 1:] = relative
    if dof < 1:
        return relative, survey_cov, None
    widened = add_survey_uncertainty(values, unc.ci90, unc.stderr, dof, jm, r, survey_cov)
    return relative, survey_cov, widened
