"""Fit of (CdA, μ, v0[, μ1]) to the photocell times of one descent (Kaps et al. 1996, eq. 29).

Least squares of computed against measured crossing times, Σ(p) = Σ_i (t(x_i, p) − t_i)²,
with the times relative to the first photocell used. What makes it reliable (numerics.md):

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
  verified minimum, a small grid of further starts is tried and the best minimum kept.

Uncertainty: linearised (Wald) 90 % intervals with Student's t on the residual degrees of
freedom, σ² = Σ/dof, Cov = σ²(JᵀJ)⁻¹. A parameter whose interval is wider than itself is
reported as not identifiable (status ``ill-conditioned``) rather than as a number.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import least_squares, nnls
from scipy.stats import t as student_t

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
    # goodness of fit and the survey's part in the intervals (station.model.track_error)
    timer_precision_s: float | None = None
    chi2: float | None = None
    chi2_p: float | None = None
    ci90_timing: dict[str, tuple[float, float] | None] | None = None
    stderr_timing: dict[str, float | None] | None = None
    survey_share: dict[str, float | None] | None = None

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


def uncertainty(
    jac: np.ndarray,
    r: np.ndarray,
    p: np.ndarray,
    names: list[str],
    dof: int,
    scale: np.ndarray,
    nuisance: tuple[str, ...] = ("v0", "s0"),
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
    q = float(student_t.ppf(0.95, dof))
    out.covariance = cov.tolist()
    for i, k in enumerate(names):
        out.stderr[k] = float(sd[i])
        lo = p[i] - q * sd[i]
        if k not in nuisance or k == "v0":
            lo = max(lo, 0.0)
        out.ci90[k] = (float(lo), float(p[i] + q * sd[i]))
        if k not in nuisance and q * sd[i] > abs(p[i]):
            out.not_identifiable.append(k)
    if "cda" in names and "mu" in names:
        i, j = names.index("cda"), names.index("mu")
        if sd[i] > 0 and sd[j] > 0:
            out.corr_mu_cda = float(cov[i, j] / (sd[i] * sd[j]))
    return out


def speed_estimates(s: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Speed at each photocell from the quadratic s(t) through it and its neighbours."""
    n = len(s)
    v = np.empty(n)
    for i in range(n):
        j = min(max(i - 1, 0), n - 3) if n >= 3 else 0
        idx = slice(j, j + 3) if n >= 3 else slice(0, n)
        tt, ss = t[idx], s[idx]
        deg = min(2, len(tt) - 1)
        coef = np.polyfit(tt - t[i], ss, deg)
        v[i] = coef[-2]
    return np.maximum(v, 0.1)


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


def _predicted_decrease(jac: np.ndarray, r: np.ndarray, x: np.ndarray, scale: np.ndarray) -> float:
    """What one more feasible Gauss-Newton step could still gain in Σ.

    Parameters at their lower bound 0 whose step points outward are held there; the step of the
    others is shortened so that none crosses 0. A verified minimum gains (almost) nothing.
    """
    free = np.ones(len(x), dtype=bool)
    for _ in range(len(x)):
        if not free.any():
            return 0.0
        step = np.zeros(len(x))
        step[free], *_ = np.linalg.lstsq(jac[:, free], -r, rcond=None)
        blocked = free & (x <= 1e-6 * scale) & (step < 0)
        if not blocked.any():
            break
        free &= ~blocked
    neg = step < 0
    frac = min(1.0, float(np.min(x[neg] / -step[neg]))) if neg.any() else 1.0
    return float(np.sum(r**2) - np.sum((r + frac * (jac @ step)) ** 2))


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
) -> FitResult:
    """Fit one descent. ``xs`` and ``times`` are the photocells used, in order down the run;
    times may be on any clock (only differences to the first are used).

    ``timer_precision_s``: standard deviation of one crossing time, for the goodness-of-fit
    test (default 0.5 ms: a 1 ms timer resolution and typical photocell jitter, see
    :data:`station.model.track_error.DEFAULT_TIMER_PRECISION_S`). ``survey``: the track's
    uncertainty (:func:`station.model.track_error.survey_error`); with it the 90 % intervals
    carry the survey too, and the timing-only ones are kept beside them."""
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
    scale = SCALE[:n_params]
    upper = UPPER[:n_params]

    cache: dict[bytes, Any] = {}

    def solve(p: np.ndarray):
        key = p.tobytes()
        if key not in cache:
            cache.clear()
            par = Params(*p[:3], mu1=p[3] if n_params == 4 else 0.0)
            cache[key] = run.solve(par, conditions, n_params)
        return cache[key]

    def fun(p: np.ndarray) -> np.ndarray:
        return solve(p).t[1:] - t[1:]

    def jac(p: np.ndarray) -> np.ndarray:
        return solve(p).dt_dp[1:, :]

    def search(x0: np.ndarray):
        return least_squares(
            fun,
            np.clip(x0, 0.0, upper),
            jac=jac,
            bounds=(np.zeros(n_params), upper),
            method="dogbox",
            x_scale=scale,
            max_nfev=200,
            **TOLERANCES,
        )

    def verified(res) -> bool:
        """A minimum only if Gauss-Newton can gain nothing more and the skier reaches every
        photocell (a point where the model skier stops has a flat, huge Σ)."""
        if solve(res.x).stopped_x is not None:
            return False
        r = res.fun
        sigma = float(r @ r)
        gain = _predicted_decrease(res.jac, r, res.x, scale)
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
    r = desc.t[1:] - t[1:]
    jm = desc.dt_dp[1:, :]
    sigma_s2 = float(r @ r)
    grad = 2.0 * jm.T @ r
    estimates = {k: float(v) for k, v in zip(names, p, strict=True)}
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
        residuals_s={ids[0]: 0.0, **{i: float(v) for i, v in zip(ids[1:], r, strict=True)}},
        liftoff_x=desc.liftoff_x,
        stopped_x=desc.stopped_x,
        min_normal_force_n=desc.min_normal_force_n,
        nfev=nfev,
        starts=starts,
        speeds_ms={i: float(v) for i, v in zip(ids, desc.v, strict=True)},
    )

    unc = uncertainty(jm, r, p, names, dof, scale)
    result.covariance, result.stderr, result.ci90 = unc.covariance, unc.stderr, unc.ci90
    result.corr_mu_cda, result.not_identifiable = unc.corr_mu_cda, unc.not_identifiable

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
    _survey_and_goodness(result, run, p, conditions, jm, r, step, timer_precision_s, survey)
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
) -> None:
    """The survey's share of the intervals, then the χ² test (station.model.track_error)."""
    survey_cov = None
    if survey is not None and result.covariance is not None:
        survey_cov = survey_time_covariance(survey, run.xs, Params(*p), conditions, step)
        add_survey_uncertainty(result, jm, r, survey_cov)
    judge_goodness(result, r, timer_precision_s, survey_cov)
