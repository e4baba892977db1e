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
- speed: a bounded Gauss-Newton iteration (:func:`station.model.fit_search.gauss_newton`) that
  stops as soon as a Gauss-Newton step could gain nothing more, so no model solve is spent past
  the minimum (some four solves per fit); the dogbox search is the fallback when it does not get
  there.

Uncertainty: linearised (Wald) 90 % intervals with Student's t on the residual degrees of
freedom, σ² = Σ/dof, Cov = σ²(JᵀJ)⁻¹. A parameter whose interval is wider than itself is
reported as not identifiable (status ``ill-conditioned``) rather than as a number.

Here: the fit of one descent and its verdict; the search is :mod:`station.model.fit_search`, the
uncertainty and the result's type :mod:`station.model.fit_result`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from station.model.estimate import MISSING, Estimate, FitStatus
from station.model.fit_result import OFFSET_NAME, FitResult, Uncertainty, uncertainty
from station.model.fit_search import Problem, initial_guess, model_solver, with_offset
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

    run = run or StraightRun(profile, xs, step)
    fit_names, scale, upper, bounded = with_offset(names, n_params)
    problem = Problem(model_solver(run, conditions, n_params), t, scale, upper, bounded)
    x0 = initial_guess(run, t, conditions, n_params)
    best, nfev, starts = problem.minimise(x0, n_params)
    return _result(
        problem, best, nfev, starts, run=run, conditions=conditions, ids=ids, model=model,
        names=fit_names, n_cells=len(xs), dof=dof, step=step,
        timer_precision_s=timer_precision_s, survey=survey, survey_time_cov=survey_time_cov,
    )  # fmt: skip


def _result(
    problem: Problem,
    best: Any,
    nfev: int,
    starts: int,
    *,
    run: StraightRun,
    conditions: Conditions,
    ids: list[str],
    model: str,
    names: list[str],
    n_cells: int,
    dof: int,
    step: float,
    timer_precision_s: float,
    survey: SurveyError | None,
    survey_time_cov: np.ndarray | None,
) -> FitResult:
    """The result at the search's best point: residuals, linearised uncertainty (with the
    survey's share), the verdict and the χ² test. ``names``: the physical parameters and the
    offset, in the order of the search's vector."""
    fit_names, scale, n_params = names, problem.scale, len(names) - 1
    p = best.x
    desc = problem.solve(p)
    r, jm = problem.fun(p), problem.jac(p)
    values: dict[str, float | None] = {k: float(v) for k, v in zip(fit_names, p, strict=True)}
    unc = uncertainty(jm, r, p, fit_names, dof, scale)
    status, message = _verdict(
        n_cells, n_params, dof, desc, problem.verified(best) and desc.converged, best.message,
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
