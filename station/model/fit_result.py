"""What a fit gives: the linearised uncertainty at a least-squares solution (one descent's fit
and the traverse's share it) and one descent's result with its JSON form."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np
from scipy.special import stdtrit  # Student-t quantile, without loading scipy.stats

from station.model.estimate import Estimate, FitStatus

#: the time offset at the first photocell: name, typical magnitude (s), bound (s)
OFFSET_NAME, OFFSET_SCALE, OFFSET_BOUND = "dt0", 1e-3, 1.0
CI_METHOD = "linearised (Wald) interval, Student t on the residual degrees of freedom"


@dataclass(frozen=True)
class FitResult:
    """Everything a user needs to judge a fit: estimates with their intervals, residuals and a
    status. Built once, at the end of :func:`station.model.fit.fit_descent`; never changed after."""

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
