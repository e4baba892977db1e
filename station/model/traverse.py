"""Traversing on an inclined plane (Kaps et al. 1996, §5.2, eq. 22-28).

On a plane of inclination A, travelling at an angle B to the fall line, the arc length obeys

    s̈ = a − k·ṡ²,   a = g·sin A·cos B − μ·g·cos A,   k = ρ·CdA / (2m)

(the paper's eq. 22 with b = −k; normal force m·g·cos A). Positions s_i at times t_i, e.g. from
film analysis, are fitted for (CdA, μ, v0) and the position offset s0, with the sensitivities
from the variational equations (eq. 27) integrated alongside, as the paper did. The paper found
μ well determined and CdA not (CdA → 0 with an infinite interval): this fit says so through the
status ``ill-conditioned`` instead of printing a number.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import least_squares

from station.errors import InputError
from station.files import MAX_TIMES, read_text
from station.model.estimate import Estimate, FitStatus
from station.model.fit_result import CI_METHOD, uncertainty
from station.model.fit_search import TOLERANCES
from station.model.physics import G_STANDARD

NAMES = ["cda", "mu", "v0", "s0"]
SCALE = np.array([0.1, 0.01, 1.0, 0.1])
LOWER = np.array([0.0, 0.0, 0.0, -np.inf])
UPPER = np.array([5.0, 1.0, 60.0, np.inf])


@dataclass(frozen=True)
class TraverseResult:
    """The fit of a traverse: each parameter with its interval, the residuals and a status."""

    status: FitStatus
    cda: Estimate
    mu: Estimate
    v0: Estimate
    s0: Estimate  # the position at t = 0 (m)
    corr_mu_cda: float | None
    sigma_m2: float
    dof: int
    residuals_m: list[float]
    v_final: float
    message: str = ""

    def parameters(self) -> list[tuple[str, Estimate]]:
        """The parameters in the order of the JSON (:data:`NAMES`)."""
        return [("cda", self.cda), ("mu", self.mu), ("v0", self.v0), ("s0", self.s0)]

    @property
    def not_identifiable(self) -> list[str]:
        return [k for k, e in self.parameters() if e.not_identifiable]

    def to_dict(self) -> dict[str, Any]:
        params = self.parameters()
        return {
            **{k: e.value for k, e in params},
            "ci90": {k: (list(e.ci90) if e.ci90 is not None else None) for k, e in params},
            "ci_method": CI_METHOD,
            "stderr": {k: e.stderr for k, e in params},
            "corr_mu_cda": self.corr_mu_cda,
            "sigma_m2": self.sigma_m2,
            "dof": self.dof,
            "v_final": self.v_final,
            "residuals_m": self.residuals_m,
            "status": self.status.value,
            "message": self.message,
            "not_identifiable": self.not_identifiable,
        }


def simulate_traverse(
    t: np.ndarray,
    cda: float,
    mu: float,
    v0: float,
    slope_deg: float,
    traverse_deg: float,
    mass_kg: float,
    air_density: float,
    g: float = G_STANDARD,
    s0: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """s(t), ṡ(t) and ∂s/∂(CdA, μ, v0, s0) at the times t (t[0] is the start)."""
    alpha, beta = math.radians(slope_deg), math.radians(traverse_deg)
    a = g * math.sin(alpha) * math.cos(beta) - mu * g * math.cos(alpha)
    k = air_density * cda / (2.0 * mass_kg)
    dk = air_density / (2.0 * mass_kg)
    da_mu = -g * math.cos(alpha)

    def rhs(_t: float, y: np.ndarray) -> list[float]:
        s, v, s_c, v_c, s_m, v_m, s_v, v_v = y
        acc_v = -2.0 * k * abs(v)
        return [
            v,
            a - k * v * abs(v),
            v_c,
            -dk * v * abs(v) + acc_v * v_c,
            v_m,
            da_mu + acc_v * v_m,
            v_v,
            acc_v * v_v,
        ]

    t = np.asarray(t, dtype=float)
    t_rel = t - t[0]
    sol = solve_ivp(
        rhs,
        (0.0, float(t_rel[-1]) if t_rel[-1] > 0 else 1e-9),
        [0.0, v0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
        method="DOP853",
        t_eval=t_rel,
        rtol=1e-11,
        atol=1e-12,
    )
    y = sol.y
    jac = np.column_stack([y[2], y[4], y[6], np.ones_like(t_rel)])
    return s0 + y[0], y[1], jac


def read_traverse_data(path: str) -> tuple[np.ndarray, np.ndarray]:
    """(t, s) columns from a CSV with a header ``t,s`` (or ``time,position``)."""

    text = read_text(path, MAX_TIMES, "data file")
    try:
        reader = csv.reader(io.StringIO(text, newline=""))
        rows = [(i, r) for i, r in enumerate(reader, start=1) if r and r[0].strip()]
    except csv.Error as exc:
        raise InputError(f"not a CSV file: {exc}", path=path) from None
    rows = [(i, r) for i, r in rows if not r[0].lstrip().startswith("#")]
    if not rows:
        raise InputError("empty data file; expected columns t,s", path=path)
    line, header = rows[0]
    cols = [c.strip().lower() for c in header]
    it = next((cols.index(c) for c in ("t", "time") if c in cols), None)
    is_ = next((cols.index(c) for c in ("s", "position") if c in cols), None)
    if it is None or is_ is None:
        raise InputError(
            f"expected columns t and s, header is {','.join(header)!r}",
            path=path,
            line=line,
            field="header",
        )
    t: list[float] = []
    s: list[float] = []
    for line, row in rows[1:]:
        for col, name, out in ((it, "t", t), (is_, "s", s)):
            try:
                value = float(row[col])
            except (ValueError, IndexError):
                cell = row[col] if col < len(row) else ""
                raise InputError(
                    f"{cell!r} is not a number", path=path, line=line, field=name
                ) from None
            if not math.isfinite(value):
                raise InputError(f"{value!r} is not finite", path=path, line=line, field=name)
            out.append(value)
        if len(t) > 1 and t[-1] <= t[-2]:
            raise InputError("times must increase", path=path, line=line, field="t")
    if len(t) < 6:
        raise InputError(f"{len(t)} data rows; at least 6 are needed", path=path)
    return np.array(t), np.array(s)


def _start(
    t: np.ndarray,
    s: np.ndarray,
    slope_deg: float,
    traverse_deg: float,
    mass_kg: float,
    air_density: float,
    g: float,
) -> np.ndarray:
    """The search's start (CdA, μ, v0, s0): a quadratic s(t) gives v0 and the mean
    acceleration; CdA 0.3 m² accounts for drag."""
    tr = t - t[0]
    c2, c1, c0 = np.polyfit(tr, s, 2)
    v0 = max(c1, 0.0)
    k0 = air_density * 0.3 / (2.0 * mass_kg)
    vbar = max((s[-1] - s[0]) / max(tr[-1], 1e-9), 0.0)
    alpha, beta = math.radians(slope_deg), math.radians(traverse_deg)
    mu0 = (g * math.sin(alpha) * math.cos(beta) - 2 * c2 - k0 * vbar**2) / (g * math.cos(alpha))
    return np.array([0.3, min(max(mu0, 1e-3), 0.9), min(v0, 59.0), c0])


def fit_traverse(
    t: np.ndarray,
    s: np.ndarray,
    slope_deg: float,
    traverse_deg: float,
    mass_kg: float,
    air_density: float,
    g: float = G_STANDARD,
) -> TraverseResult:
    """Least squares of computed against measured positions (the paper's eq. 30)."""
    t = np.asarray(t, dtype=float)
    s = np.asarray(s, dtype=float)
    dof = len(t) - 4

    def model(p: np.ndarray):
        return simulate_traverse(t, *p[:3], slope_deg, traverse_deg, mass_kg, air_density, g, p[3])  # type: ignore[call-arg]

    x0 = _start(t, s, slope_deg, traverse_deg, mass_kg, air_density, g)
    cache: dict[bytes, Any] = {}

    def solve(p):
        key = p.tobytes()
        if key not in cache:
            cache.clear()
            cache[key] = model(p)
        return cache[key]

    res = least_squares(
        lambda p: solve(p)[0] - s,
        x0,
        jac=lambda p: solve(p)[2],
        bounds=(LOWER, UPPER),
        method="trf",
        x_scale=SCALE,
        **TOLERANCES,
    )
    p = res.x
    s_fit, v_fit, jac = model(p)
    r = s_fit - s
    unc = uncertainty(jac, r, p, NAMES, dof, SCALE)
    estimates: dict[str, float | None] = {k: float(v) for k, v in zip(NAMES, p, strict=True)}
    status, message = FitStatus.OK, ""
    if dof < 1:
        status, message = FitStatus.TOO_FEW_PHOTOCELLS, "fewer data points than unknowns + 1"
    elif res.status <= 0:
        status = FitStatus.NOT_CONVERGED
        message = f"the search ended without a minimum: {res.message}"
    elif unc.not_identifiable:
        status = FitStatus.ILL_CONDITIONED
        which = ", ".join(unc.not_identifiable)
        message = (
            f"{which} not identifiable from these positions: the 90 % interval is wider than "
            "the estimate itself (the paper's traversing runs gave CdA = 0 with an infinite "
            "interval)"
        )
        for k in unc.not_identifiable:
            estimates[k] = None
            unc.ci90[k] = None

    def estimate(k: str) -> Estimate:
        return Estimate(
            estimates[k], unc.ci90[k], unc.stderr[k], not_identifiable=k in unc.not_identifiable
        )

    return TraverseResult(
        status=status,
        cda=estimate("cda"),
        mu=estimate("mu"),
        v0=estimate("v0"),
        s0=estimate("s0"),
        corr_mu_cda=unc.corr_mu_cda,
        sigma_m2=float(r @ r),
        dof=max(dof, 0),
        residuals_m=[float(x) for x in r],
        v_final=float(v_fit[-1]),
        message=message,
    )
