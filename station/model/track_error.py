"""What the survey adds to a fit's uncertainty, and whether the times fit at all.

Every μ rests on the profile h(x) and the photocells' positions, and both are measured. A PC1
placed 5 cm off moves μ by −4.8e-4 and no residual shows it; the profile's own scatter moves it
by 1e-4 and more. Here both enter the fit's intervals by linearised propagation:

- the crossing times' sensitivity to the track, A = ∂t/∂θ, by forward differences of the
  forward model, for θ = the profile spline's coefficients (those whose support meets the timed
  section) and each photocell's x;
- the track's covariance: the spline coefficients' sampling covariance (from the smoothing
  fit, :class:`station.survey.track.ProfileUncertainty`) and each photocell's survey precision;
- the times' covariance from the survey, S = A Cov(θ) Aᵀ, mapped to the parameters as the
  least-squares estimate maps any error in the times: Cov_p += G S Gᵀ, G = (JᵀJ)⁻¹Jᵀ.

The total interval uses Student's t with the Welch–Satterthwaite degrees of freedom (the
timing variance is estimated from dof residuals, the survey's is known), and is never narrower
than the timing-only one. Both intervals are reported, and the survey's share of the variance.

Goodness of fit: the residuals against the timer's precision (χ² on the residual degrees of
freedom, with the first photocell's error common to every time difference). A fit far above
it (p < ``POOR_FIT_P``, :mod:`station.model.timer`) has status ``poor-fit``: the numbers are a
least-squares solution, but the model, the track or a photocell is wrong somewhere.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.interpolate import BSpline
from scipy.special import chdtrc, stdtrit  # χ² survival, Student t, without scipy.stats

from station.model.physics import (
    Conditions,
    Params,
    grid_nodes,
    grid_on_nodes,
    make_grid,
    solve_grid,
)
from station.model.timer import POOR_FIT_P

if TYPE_CHECKING:
    from station.survey.track import ProfileUncertainty, Track

#: forward-difference steps: profile coefficients (m) and photocell positions (m)
H_STEP_M = 1e-3
X_STEP_M = 1e-3


@dataclass(frozen=True)
class SurveyError:
    """The survey's uncertainty as a fit needs it: the profile's, and each used photocell's
    along-track position standard deviation (m), in the fit's photocell order."""

    profile: ProfileUncertainty
    sigma_x: np.ndarray


def survey_error(track: Track, ids: list[str]) -> SurveyError | None:
    """The survey error of ``track`` for the photocells ``ids``; None without one."""
    if track.uncertainty is None:
        return None
    return SurveyError(
        track.uncertainty, np.array([track.photocell(i).sigma_x_m for i in ids], dtype=float)
    )


def survey_time_covariance(
    survey: SurveyError,
    xs: np.ndarray,
    p: Params,
    conditions: Conditions,
    step: float = 0.5,
) -> np.ndarray:
    """Covariance (s²) of the computed times t_i − t_1 (i ≥ 2) that the survey's uncertainty
    causes, at parameters ``p``."""
    xs = np.asarray(xs, dtype=float)
    unc = survey.profile

    def times(profile, x) -> np.ndarray:
        # one grid, no Richardson step: the grid's own error is the same on the perturbed and
        # the unperturbed track, and cancels in the differences taken here
        grid = make_grid(profile, x, step)
        return solve_grid(grid, p, conditions, 3, False).time[grid.cell_index][1:]

    base_profile = unc.profile()
    knots = unc.knots
    m = len(unc.coef)
    support = [j for j in range(m) if knots[j + 4] > xs[0] and knots[j] < xs[-1]]
    profile_times = _perturbed_profile_times(unc, support, xs, p, conditions, step)
    base = profile_times[0]
    a_h = ((profile_times[1:] - base) / H_STEP_M).T
    lf = unc.factor[support, :]
    s_h = a_h @ lf
    cov = s_h @ s_h.T
    for k, sx in enumerate(survey.sigma_x):
        if sx <= 0:
            continue
        moved = xs.copy()
        moved[k] += X_STEP_M
        if k + 1 < len(xs) and moved[k] >= xs[k + 1]:
            continue
        a_k = (times(base_profile, moved) - base) / X_STEP_M
        cov += sx * sx * np.outer(a_k, a_k)
    return cov


def _perturbed_profile_times(
    unc: ProfileUncertainty,
    support: list[int],
    xs: np.ndarray,
    p: Params,
    conditions: Conditions,
    step: float,
) -> np.ndarray:
    """Times t_i − t_1 (i ≥ 2) on the unperturbed profile (row 0) and on the profile with each
    coefficient ``support[r]`` raised by H_STEP_M (row r + 1), all on one grid in x.

    One batched solve instead of one per coefficient (some 60 on a real run): every row is
    computed by the same operations as a lone profile, so the numbers are the same.
    """
    x, idx = grid_nodes(xs, step)
    xm = 0.5 * (x[1:] + x[:-1])
    # column 0: the coefficients as they are; column r + 1: coefficient support[r] + H_STEP_M
    bump = np.zeros((len(unc.coef), len(support) + 1))
    bump[support, np.arange(1, len(support) + 1)] = H_STEP_M
    spl = BSpline(unc.knots, unc.coef[:, None] + bump, 3, extrapolate=True)
    d1, d2 = spl.derivative(1), spl.derivative(2)
    slopes = [np.ascontiguousarray(f(at).T) for f, at in ((d1, x), (d2, x), (d1, xm))]
    grid = grid_on_nodes(x, idx, *slopes)
    return solve_grid(grid, p, conditions, 3, False).time[:, idx[1:]]


@dataclass(frozen=True)
class SurveyIntervals:
    """A fit's uncertainty with the survey's in it (:func:`add_survey_uncertainty`), and the
    timing-only one it was built from; each a mapping of the fit's parameter names."""

    covariance: list[list[float]]
    ci90: dict[str, tuple[float, float] | None]
    stderr: dict[str, float | None]
    ci90_timing: dict[str, tuple[float, float] | None]
    stderr_timing: dict[str, float | None]
    survey_share: dict[str, float | None]


#: residual degrees of freedom a fit needs before it says the survey's share of the variance
MIN_DOF_SHARE = 3


def add_survey_uncertainty(
    values: Mapping[str, float | None],
    ci90: Mapping[str, tuple[float, float] | None],
    stderr: Mapping[str, float | None],
    dof: int,
    jac: np.ndarray,
    residuals: np.ndarray,
    survey_cov: np.ndarray,
) -> SurveyIntervals:
    """A fit's timing-only intervals (``ci90``, ``stderr``; ``values`` None where there is no
    estimate) widened by the survey's time covariance; the timing-only ones kept beside them.

    The timing variance in the total is estimated from the residuals *less* what the survey
    alone leaves in them, E[rᵀr] = σ_t²·dof + tr((I − P) S (I − P)) with P the least-squares
    projection: otherwise the survey would be counted twice, once through the residuals and
    once through S (measured: 95 % coverage of the "90 %" intervals instead of 92 %). The
    estimate is floored at a tenth of the raw one, so the timing never vanishes.
    """
    names = list(ci90)
    jtj_inv = np.linalg.inv(jac.T @ jac)
    g = jtj_inv @ jac.T
    r = np.asarray(residuals, dtype=float)
    raw = float(r @ r) / dof
    q_perp = np.eye(len(r)) - jac @ g
    survey_in_residuals = float(np.trace(q_perp @ survey_cov @ q_perp.T)) / dof
    sigma2 = max(raw - survey_in_residuals, 0.1 * raw)
    cov_t = sigma2 * jtj_inv
    cov_s = g @ survey_cov @ g.T
    cov = cov_t + cov_s
    out = SurveyIntervals(cov.tolist(), dict(ci90), dict(stderr), dict(ci90), dict(stderr), {})
    for i, k in enumerate(names):
        est = values.get(k)
        vt, vs = float(cov_t[i, i]), float(cov_s[i, i])
        vtot = vt + vs
        # with fewer than MIN_DOF_SHARE residual degrees of freedom the timing variance is one
        # or two squared residuals: a split of the variance on it said "survey 100 %"
        out.survey_share[k] = vs / vtot if vtot > 0 and dof >= MIN_DOF_SHARE else None
        if est is None or ci90[k] is None:
            continue
        # Welch-Satterthwaite: only the timing part is estimated (from dof residuals)
        dof_eff = dof * (vtot / vt) ** 2 if vt > 0 else math.inf
        q = float(stdtrit(min(dof_eff, 1e6), 0.95))
        sd = math.sqrt(vtot)
        lo, hi = est - q * sd, est + q * sd
        if k in ("cda", "mu", "v0", "mu1"):
            lo = max(lo, 0.0)
        # never narrower than the timing-only interval: the survey cannot make a fit surer
        tlo, thi = out.ci90_timing[k] or (lo, hi)
        out.ci90[k] = (float(min(lo, tlo)), float(max(hi, thi)))
        out.stderr[k] = max(sd, out.stderr_timing.get(k) or 0.0)
    return out


@dataclass(frozen=True)
class Goodness:
    """The χ² test of a fit's residuals against the timer's precision."""

    chi2: float
    p: float
    rms_s: float  # root mean square of the residuals

    @property
    def poor(self) -> bool:
        return self.p < POOR_FIT_P


def judge_goodness(
    residuals: np.ndarray,
    dof: int,
    timer_precision_s: float,
    survey_cov: np.ndarray | None = None,
) -> Goodness | None:
    """χ² of the residuals against the timer precision (and the survey's share of the times'
    covariance, so that an honest rough survey is not called a poor fit); None without a
    degree of freedom or a precision."""
    if dof < 1 or not timer_precision_s > 0:
        return None
    r = np.asarray(residuals, dtype=float)
    # every crossing time is data with its own timer error (the fit's free offset takes the
    # first photocell's): Cov = σ²·I
    n = len(r)
    cov = timer_precision_s**2 * np.eye(n)
    if survey_cov is not None:
        cov = cov + survey_cov
    q = float(r @ np.linalg.solve(cov, r))
    p = float(chdtrc(dof, q))
    return Goodness(q, p, math.sqrt(float(r @ r) / len(r)))
