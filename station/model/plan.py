"""Planning a test day: how many descents per item resolve a difference Δμ, in which order.

The answer comes from the day model of :mod:`station.model.compare`, not from a rule of thumb:
μ per item, the skier's mean CdA, a linear drift of μ over the day, and per descent its own v0,
a time offset at the first photocell and a posture effect u_k ~ N(0, s²) on log CdA, with the
timer's noise σ on every time. For a design (the run order, the minutes between descents, the
skier, the air, the track) the times and their sensitivities are computed by the same batch
solver the joint fit uses (:func:`station.model.batch.solve_rows`); the covariance of the fixed
effects is then the inverse Fisher information of that linear mixed model,

    I = Σ_k A_kᵀ P_k A_k,  V_k = σ²·1 + s² z_k z_kᵀ,  P_k = W_k − W_k F_k (F_kᵀ W_k F_k)⁻¹ F_kᵀ W_k

with W_k = V_k⁻¹, A_k the descent's sensitivities to the globals (CdA, μ per item, drift), F_k
those to its own v0 and offset (fixed effects, eliminated), and z_k = ∂t/∂u_k. This is the
covariance the joint fit reports, σ̂²·S⁻¹ from its mixed-model equations, evaluated at the
planned values instead of the estimated ones (the mixed-model equations and generalised least
squares are the same estimator). Whether the plan keeps its promise is checked by simulating
days and fitting them with the real joint fit (benchmarks/plan_power.py, tests/test_plan.py).

Power: the day is "resolved" when the 90 % interval of Δμ excludes 0 on the right side. With
standard error ``se``, Satterthwaite's degrees of freedom ν of its estimate
(:func:`evaluate_design`) and the t quantile q, the power is P(T'_ν(|Δ|/se) > q), T' the
noncentral t (the far side adds a negligible amount).
"""

from __future__ import annotations

import math
from collections.abc import Collection, Sequence
from dataclasses import dataclass, field, replace
from enum import StrEnum
from itertools import combinations
from typing import TYPE_CHECKING, Any

import numpy as np

from station.model.batch import Rows, solve_rows
from station.model.physics import G_STANDARD, Conditions, Params, StraightRun
from station.survey.track import Track

if TYPE_CHECKING:
    from station.model.compare import JointResult

#: the smallest day the planner plans, descents per item. The joint fit compares two (one
#: descent's glide cannot be told from its posture), but its interval does not keep its 90 %
#: there when the scatter is small (83.5 % at 0.5 %, benchmarks/compare_small_days.py: four
#: descents cannot tell the scatter from none), and on few photocells the power the plan
#: promises is not what such days give (0.963 stated, 0.88 over 100 simulated days at Δμ
#: 0.002, 1 % on four photocells: their intervals rest on one or two degrees of freedom, and the
#: estimate's spread is 43 % above the known-scatter one). Three per item, as the README
#: advises "when the numbers must be trusted": at most one more than a day needs.
MIN_PER_ITEM = 3
#: the largest day the planner considers, descents per item
MAX_PER_ITEM = 60
#: the interval's level: 90 %, two-sided, as ``station compare`` reports
LEVEL = 0.90
#: the posture scatter a plan assumes when a past session could not estimate it (estimated at 0,
#: or with no interval): field tests give 0.6-2.2 % per run, the tuck's drag area 1-2 %
DEFAULT_POSTURE = 0.01
#: below this a session's estimate is "no scatter seen", not a measured one (REML puts the
#: scatter at 0 when a few descents cannot tell it from the timing noise)
MIN_POSTURE = 0.001


@dataclass(frozen=True)
class DayAssumptions:
    """What a plan assumes of the day (all of it printed with the plan)."""

    mass_kg: float
    air_density: float
    cda: float  # the skier's mean drag area, m²
    v0: float  # typical speed at the first photocell, m/s
    mu: float  # typical μ of the items (the sensitivities depend on it a little)
    timer_sd_s: float  # SD of one recorded time
    posture_sd: float  # SD of log CdA between descents (0.015 = 1.5 %)
    drift_per_hour: float  # expected drift of μ per hour (the fit estimates it)
    minutes_between: float  # from one descent's start to the next
    g: float = G_STANDARD


@dataclass(frozen=True)
class Plan:
    descents_per_item: int
    order: str  # one letter per descent, items A, B, C, … in turn
    items: tuple[str, ...]
    minutes: float
    power: float  # for the weakest pair of items
    halfwidth_mu: float  # expected half-width of the 90 % interval of Δμ
    delta_mu: float
    target_power: float
    se_mu: float  # standard error of Δμ (weakest pair)
    dof: float  # Satterthwaite's degrees of freedom of that standard error
    assumptions: DayAssumptions
    power_by_n: dict[int, float] = field(default_factory=dict)
    #: the power when the day is watched after every descent with the rule of
    #: :mod:`station.model.sequential` (horizon: this plan's descents per item)
    power_watched: float | None = None

    @property
    def reached(self) -> bool:
        """Whether the power asked for is reached within :data:`MAX_PER_ITEM` per item."""
        return self.power >= self.target_power

    def to_dict(self) -> dict[str, Any]:
        a = self.assumptions
        return {
            "descents_per_item": self.descents_per_item,
            "order": self.order,
            "minutes": self.minutes,
            "power": self.power,
            "halfwidth_mu": self.halfwidth_mu,
            "reached": self.reached,
            "power_watched": self.power_watched,
            "assumptions": {
                "delta_mu": self.delta_mu,
                "target_power": self.target_power,
                "level": LEVEL,
                "items": len(self.items),
                "mass_kg": a.mass_kg,
                "air_density": a.air_density,
                "cda": a.cda,
                "v0": a.v0,
                "mu": a.mu,
                "timer_ms": a.timer_sd_s * 1e3,
                "posture_scatter_pct": a.posture_sd * 100.0,
                "drift_per_hour": a.drift_per_hour,
                "minutes_between": a.minutes_between,
                "se_mu": self.se_mu,
                "dof": self.dof,
            },
        }


def item_letters(n_items: int) -> tuple[str, ...]:
    """A, B, C, … (AA, AB, … beyond Z)."""
    out = []
    for k in range(n_items):
        s, k1 = "", k
        while True:
            s = chr(ord("A") + k1 % 26) + s
            k1 = k1 // 26 - 1
            if k1 < 0:
                break
        out.append(s)
    return tuple(out)


def run_order(n_items: int, per_item: int) -> list[int]:
    """The order of the descents, as item indices: rounds of all items, every second round
    reversed (AB BA AB BA… = ABBA ABBA for two items, ABC CBA ABC… for three). Each pair of
    rounds gives every item the same mean position, so a linear drift of the snow cancels in
    every comparison and the fit can tell drift from item."""
    order: list[int] = []
    for r in range(per_item):
        rnd = list(range(n_items))
        order.extend(rnd if r % 2 == 0 else rnd[::-1])
    return order


def _pair_contrasts(n_items: int, n_glob: int, i_mu: int) -> list[np.ndarray]:
    out = []
    for a, b in combinations(range(n_items), 2):
        c = np.zeros(n_glob)
        c[i_mu + a], c[i_mu + b] = 1.0, -1.0
        out.append(c)
    return out


def design_covariance(
    track: Track, order: list[int], mus: list[float], a: DayAssumptions
) -> Design:
    """The joint fit of a day run in ``order`` (item indices) with true friction ``mus`` per
    item, as a linear mixed model: the covariance of its globals (CdA, μ per item, drift) and
    what the degrees of freedom need. The day model of :mod:`station.model.compare` at known
    scatter and noise."""
    n_items = len(mus)
    n_d = len(order)
    xs = np.array([pc.x for pc in track.photocells])
    run = StraightRun(track.profile, xs)
    hours = np.arange(n_d) * a.minutes_between / 60.0
    dth = hours - hours.mean()
    mu = np.array([mus[i] for i in order]) + a.drift_per_hour * dth
    sol = solve_rows(
        run,
        Rows(
            np.full(n_d, a.cda),
            mu,
            np.full(n_d, a.v0),
            np.zeros(n_d),
            np.full(n_d, a.air_density / a.mass_kg),
            np.zeros(n_d),
            a.g,
        ),
        n_params=3,
    )
    if sol.stopped.any():
        raise ValueError(
            f"the skier stops before the last photocell (μ {max(mus):.4f}, v0 {a.v0:g} m/s)"
        )
    dt = sol.dt_dp  # (D, n, 3): cda, mu, v0
    n = dt.shape[1]
    use_drift = n_d >= 4
    n_glob = 1 + n_items + (1 if use_drift else 0)
    s2, sig2 = a.posture_sd**2, a.timer_sd_s**2
    # the day's design, dense: globals, then v0 and offset per descent (fixed effects), and
    # the posture effects' columns z_k = ∂t/∂u_k (random)
    n_all = n_d * n
    xmat = np.zeros((n_all, n_glob + 2 * n_d))
    zmat = np.zeros((n_all, n_d))
    vinv = np.zeros((n_all, n_all))
    for k in range(n_d):
        rows = slice(k * n, (k + 1) * n)
        xmat[rows, 0] = dt[k, :, 0]
        xmat[rows, 1 + order[k]] = dt[k, :, 1]
        if use_drift:
            xmat[rows, n_glob - 1] = dt[k, :, 1] * dth[k]
        xmat[rows, n_glob + 2 * k] = dt[k, :, 2]
        xmat[rows, n_glob + 2 * k + 1] = 1.0
        z = dt[k, :, 0] * a.cda
        zmat[rows, k] = z
        # V⁻¹ of the descent's block (Sherman–Morrison)
        vinv[rows, rows] = (np.eye(n) - s2 * np.outer(z, z) / (sig2 + s2 * float(z @ z))) / sig2
    dof = n_all - (n_glob + 2 * n_d)
    scale = 1.0 / np.sqrt(np.maximum(np.sum(xmat * xmat, axis=0), 1e-300))
    xs_ = xmat * scale
    info = xs_.T @ vinv @ xs_
    if dof < 1 or np.linalg.cond(info) > 1e12:
        raise ValueError(
            f"{n_d} descents on {n} photocells cannot separate the items from the posture and "
            "the drift: more photocells or more descents"
        )
    minv = np.linalg.inv(info) * scale[:, None] * scale[None, :]
    return Design(minv, xmat, zmat, vinv, n_glob, dof)


@dataclass(frozen=True)
class Design:
    """A planned day as the linear mixed model sees it (:func:`design_covariance`)."""

    minv: np.ndarray  # inverse information of all fixed effects (globals first)
    xmat: np.ndarray  # fixed-effect columns, time rows
    zmat: np.ndarray  # posture-effect columns
    vinv: np.ndarray  # inverse covariance of the times
    n_glob: int
    dof: int  # residual degrees of freedom of the fit

    @property
    def cov(self) -> np.ndarray:
        """Covariance of the globals (CdA, μ per item, drift)."""
        return self.minv[: self.n_glob, : self.n_glob]

    def satterthwaite(self, c: np.ndarray) -> float:
        """Degrees of freedom of the estimated variance of c·globals, from the REML
        information of the two variance components (posture s², timing σ²), as the joint fit
        computes them from its REML curvature: ν = 2·var² / (gᵀ I⁻¹ g)."""
        cf = np.zeros(len(self.minv))
        cf[: self.n_glob] = c
        var = float(cf @ self.minv @ cf)
        w = self.vinv @ (self.xmat @ (self.minv @ cf))  # V⁻¹ X M⁻¹ c
        p_mat = self.vinv - (self.vinv @ self.xmat) @ self.minv @ (self.xmat.T @ self.vinv)
        pz = p_mat @ self.zmat
        # derivatives of var by s² (V_s = Z Zᵀ) and by σ² (V_σ = 1)
        g = np.array([float(np.sum((self.zmat.T @ w) ** 2)), float(w @ w)])
        pp = np.sum(p_mat * p_mat.T)  # tr(P P)
        ii = (
            np.array(
                [
                    [float(np.sum((self.zmat.T @ pz) ** 2)), float(np.sum(pz * pz))],
                    [float(np.sum(pz * pz)), float(pp)],
                ]
            )
            / 2.0
        )
        try:
            q = float(g @ np.linalg.solve(ii, g))
        except np.linalg.LinAlgError:
            return float(self.dof)
        if not math.isfinite(q) or q <= 0:
            return float(self.dof)
        return float(min(max(2.0 * var * var / q, 1.0), self.dof))


def _t_quantile(dof: float) -> float:
    from scipy.special import stdtrit

    return float(stdtrit(max(dof, 1), 0.5 + LEVEL / 2))


def power_of(delta: float, se: float, dof: float) -> float:
    """P(the 90 % interval excludes 0 on the side of the truth) for a true difference
    ``delta`` estimated with standard error ``se`` whose estimate has ``dof`` degrees of
    freedom: the noncentral t distribution of the estimate over its estimated error."""
    from scipy.special import nctdtr

    if se <= 0:
        return 1.0
    return float(1.0 - nctdtr(max(dof, 1.0), abs(delta) / se, _t_quantile(dof)))


def evaluate_design(
    track: Track, n_items: int, per_item: int, delta_mu: float, a: DayAssumptions
) -> tuple[float, float, float]:
    """(power, se of Δμ, dof) of a day with ``per_item`` descents per item, weakest pair.

    The degrees of freedom are Satterthwaite's, from the REML information of the posture
    scatter and the timing noise (:meth:`Design.satterthwaite`), as the joint fit computes
    them: on a small day with few photocells the scatter is poorly known, the interval wider
    than a known-scatter one and the power lower (four descents on four photocells: the
    residual degrees of freedom promised 0.91 where simulated days gave 0.73)."""
    mus = [a.mu + (delta_mu if i % 2 else 0.0) for i in range(n_items)]
    design = design_covariance(track, run_order(n_items, per_item), mus, a)
    cov = design.cov
    worst = max(_pair_contrasts(n_items, len(cov), 1), key=lambda c: float(c @ cov @ c))
    se = math.sqrt(max(float(worst @ cov @ worst), 0.0))
    dof = design.satterthwaite(worst)
    return power_of(delta_mu, se, dof), se, dof


def delta_mu_of_ms(track: Track, delta_ms: float, a: DayAssumptions) -> float:
    """The Δμ that changes the time over the run (first to last photocell) by ``delta_ms``."""
    xs = np.array([pc.x for pc in track.photocells])
    sol = StraightRun(track.profile, xs).solve(
        Params(a.cda, a.mu, a.v0), Conditions(a.mass_kg, a.air_density, g=a.g)
    )
    assert sol.dt_dp is not None
    dtdmu = float(sol.dt_dp[-1, 1])
    if not math.isfinite(dtdmu) or dtdmu <= 0:
        raise ValueError("the run's time does not depend on μ at these values")
    return delta_ms * 1e-3 / dtdmu


def plan_day(
    track: Track,
    delta_mu: float,
    a: DayAssumptions,
    *,
    n_items: int = 2,
    target_power: float = 0.9,
) -> Plan:
    """The smallest number of descents per item whose day resolves ``delta_mu`` with
    ``target_power`` (the weakest pair of items), its order, length and expected interval."""
    if delta_mu <= 0:
        raise ValueError("the difference to resolve must be greater than 0")
    if n_items < 2:
        raise ValueError("a comparison needs at least two items")
    power_by_n: dict[int, float] = {}
    found: dict[int, tuple[float, float, float]] = {}

    def at(per: int) -> float:
        if per not in found:
            try:
                found[per] = evaluate_design(track, n_items, per, delta_mu, a)
            except ValueError:
                found[per] = (0.0, math.inf, 0.0)
            power_by_n[per] = found[per][0]
        return found[per][0]

    # the power grows with the day: double until it is reached, then bisect
    lo, hi = MIN_PER_ITEM - 1, MIN_PER_ITEM
    while at(hi) < target_power and hi < MAX_PER_ITEM:
        lo, hi = hi, min(2 * hi, MAX_PER_ITEM)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if at(mid) >= target_power:
            hi = mid
        else:
            lo = mid
    per = hi
    pw, se, dof = found[per]
    if not math.isfinite(se):
        raise ValueError(
            f"{per} descents per item on {len(track.photocells)} photocells cannot separate the "
            "items from the posture and the drift: more photocells are needed"
        )
    from station.model.sequential import power_watched

    letters = item_letters(n_items)
    order = "".join(letters[i] for i in run_order(n_items, per))
    watched = power_watched(delta_mu / se, order, letters[0], letters[1], per)
    return Plan(
        descents_per_item=per,
        order=order,
        items=letters,
        minutes=len(order) * a.minutes_between,
        power=pw,
        halfwidth_mu=_t_quantile(dof) * se,
        delta_mu=delta_mu,
        target_power=target_power,
        se_mu=se,
        dof=dof,
        assumptions=a,
        power_by_n=power_by_n,
        power_watched=watched,
    )


# ----------------------------------------------------------------------------- a past day's prior


@dataclass(frozen=True)
class PastDay:
    """What a past day's joint fit says of the skier and the snow, for planning the next day:
    its posture scatter (with its interval, None when it could not be bounded), its drift of μ
    per hour, the median of the skiers' fitted CdA (None: none fitted), the typical v0, the
    median μ of its items, the descents compared and the median air density they were fitted
    with (the CdA was fitted in that air: another air would change the drag ρ·CdA)."""

    posture_sd: float
    posture_ci90: tuple[float, float] | None
    drift_per_hour: float | None
    cda: float | None
    v0: float
    mu: float
    descents: int
    air_density: float

    @classmethod
    def of(cls, result: JointResult, air_densities: Sequence[float]) -> PastDay:
        """From the day's joint fit and the air density of each descent it compared; a fit
        that is not ``ok`` is a :class:`ValueError` (its scatter is not to be trusted)."""
        if result.status != "ok":
            raise ValueError(
                f"the session's joint fit is {result.status} ({result.message}); its posture "
                "scatter is not to be trusted"
            )
        if not air_densities:
            raise ValueError("the session's joint fit compared no descent")
        cdas = sorted(e.value for e in result.cda.values() if e.value is not None)
        rhos = sorted(air_densities)
        return cls(
            posture_sd=result.posture_sd,
            posture_ci90=result.posture_ci90,
            drift_per_hour=result.drift_per_hour[0] if result.drift_per_hour is not None else None,
            cda=cdas[len(cdas) // 2] if cdas else None,
            v0=result.typical_v0,
            mu=sorted(i.mu for i in result.items)[len(result.items) // 2],
            descents=len(rhos),
            air_density=rhos[len(rhos) // 2],
        )


class Source(StrEnum):
    """Where an assumption of a plan comes from."""

    GIVEN = "given"
    DEFAULT = "default"
    PAST = "past"  # estimated from the past day


@dataclass(frozen=True)
class Prior:
    """A plan's assumptions, and where its posture scatter and drift came from."""

    assumptions: DayAssumptions
    posture: Source
    drift: Source
    past: PastDay | None = None


def prior(stated: DayAssumptions, given: Collection[str], past: PastDay | None) -> Prior:
    """The assumptions of a plan: ``stated`` (the options, their defaults where not given)
    with what ``past`` says where ``given`` (names of :class:`DayAssumptions` fields) does not
    name the field. A past scatter estimated below :data:`MIN_POSTURE`, or with no interval, is
    the silence of a few descents, not a steady skier: a plan on 0 % promises a power the day
    cannot keep, so it takes at least :data:`DEFAULT_POSTURE` (:attr:`Source.DEFAULT`)."""
    drift = Source.GIVEN if "drift_per_hour" in given else Source.DEFAULT
    if past is None:
        if "posture_sd" not in given:
            raise ValueError("a plan needs the posture scatter: given, or from a past day")
        return Prior(stated, Source.GIVEN, drift)
    taken: dict[str, float] = {}
    if drift is Source.DEFAULT and past.drift_per_hour is not None:
        taken["drift_per_hour"], drift = past.drift_per_hour, Source.PAST
    for name, value in (("cda", past.cda), ("v0", past.v0), ("mu", past.mu),
                        ("air_density", past.air_density)):  # fmt: skip
        if name not in given and value is not None:
            taken[name] = value
    if "posture_sd" in given:
        posture = Source.GIVEN
    elif past.posture_ci90 is not None and past.posture_sd >= MIN_POSTURE:
        taken["posture_sd"], posture = past.posture_sd, Source.PAST
    else:
        taken["posture_sd"], posture = max(past.posture_sd, DEFAULT_POSTURE), Source.DEFAULT
    return Prior(replace(stated, **taken), posture, drift, past)
