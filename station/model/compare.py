"""Test-day analysis: which ski or wax glides better, by how much, and how sure.

One joint fit over the valid descents of a session, a model of how test days vary:

- μ per test item (ski or pair id and wax), optionally μ1 per item;
- per descent, its own drag area CdA_k = CdA_skier·exp(u_k) around the skier's mean: a real
  tuck varies from descent to descent, and u_k is a *random effect*, u_k ~ N(0, s²), with the
  posture scatter s estimated from the day (one CdA per skier with no scatter made the Δμ
  interval far too narrow: 34–44 % coverage at 0.5–2 % scatter, issue 12);
- per descent, v0 at the first photocell and a time offset there (the first time is data with
  the timer's noise, not an exact zero);
- a linear drift of μ over the time of day, shared by all items, μ = μ_item + drift·(t − t̄),
  when the reference item recurs (the comparison is corrected for it).

Why this estimator. The variance of the posture effect is estimated by restricted maximum
likelihood (REML) of the model linearised at the current estimate (Laplace / penalised
quasi-likelihood): given γ = s²/σ², the fit is penalised least squares, Σ r² + Σ u_k²/γ, and
−2·log L_REML = (n − p)·log PRSS(γ) + q·log γ + log det M(γ) with M the penalised normal matrix,
n time rows, p fixed effects (items, skiers' CdA, drift, v0 and offset per descent), q descents.
REML rather than plain maximum likelihood because every descent spends two degrees of freedom
on its own v0 and offset: ML would count them as information about s and σ and shrink both
(with 9 photocells, by about a quarter). The alternative the issue names, per-descent CdA as free
parameters, cannot separate a descent's posture from its item's μ when an item has few descents;
the random effect borrows strength across the day in exactly the proportion the data support
(s → 0 gives back one CdA per skier, s large gives free CdA per descent). γ and the parameters
are updated together: each outer iteration linearises the model once (one batch solve of all
descents, :mod:`station.model.batch`), finds γ by a one-dimensional search of the REML
criterion of that linearisation, and takes the Gauss-Newton step at that γ.

Scale. Each descent's own parameters (u_k, v0_k, offset_k) touch only its own rows, so the
normal equations are block-arrow shaped: 3×3 blocks per descent are eliminated (Schur
complement) and only the few global parameters are solved densely. Time and memory grow
linearly in the number of descents; BLAS threads are capped at one (station.runtime) since the
dense parts are tiny and a pool of threads on a shared 2-core machine costs far more than it
saves (50 descents took 3.7 s instead of 0.19 s with the default pool).

Uncertainty. Given the scatter γ, the global parameters are Student t around their
estimate with the scale σ̂²·S⁻¹ (S the Schur complement: the fixed-effect block of the
mixed-model equations' inverse). The scatter is itself estimated, and on small days poorly (2
descents an item: at 0 on one day in ten at 0.5 % scatter), so every interval, P(a faster),
P(best) and the items' covariance come from that t integrated over γ's posterior (its REML
likelihood, a prior flat in the scatter), each scale with Kenward-Roger's correction for the
scatter being estimated: :class:`_Inference`. Where the day pins the scatter
(ABBAABBA with nine photocells) this is the plug-in answer; where it does not, the answer keeps
the scatters the day cannot rule out (benchmarks/compare_small_days.py).

Goodness of fit. The residual standard deviation is compared with the timer's precision
(χ² test of PRSS/σ_timer² on n − p degrees of freedom): a day whose residuals the timer cannot
explain is flagged ``poor-fit``, not "ok".

Use. :func:`joint_fit` is the day model: inputs in, an immutable :class:`JointResult` out, no
I/O. Its inputs are :class:`DescentData` records, which :func:`collect` makes from a day's
results (a planner may make them from simulated descents instead)::

    day = collect(results)                       # DayInputs(data, excluded, wind_flagged)
    res = joint_fit(track, day.data, reference="A / blue", excluded=day.excluded,
                    wind_flagged=day.wind_flagged, wind_limit_ms=1.0)
    res.comparisons[0].ci90, res.item("A / blue").p_best, res.to_dict()

:mod:`station.session.comparison` is that glue for the recorded sessions.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, replace
from enum import StrEnum
from itertools import combinations
from typing import Any, NamedTuple

import numpy as np
from scipy.optimize import brentq, minimize_scalar
from scipy.special import chdtrc, stdtr, stdtrit  # χ² survival, Student t (no scipy.stats)

from station import runtime
from station.model.batch import Rows, solve_rows
from station.model.estimate import Estimate
from station.model.physics import G_STANDARD, Conditions, Params, StraightRun
from station.model.timer import POOR_FIT_P, TIMER_PRECISION_S
from station.survey.track import Track

US_PER_HOUR = 3.6e9
#: search range of log γ, γ = s²/σ² (s posture scatter, relative; σ timing noise, s)
LOG_GAMMA = (-14.0, 22.0)


class ComparisonStatus(StrEnum):
    """The verdict of the day's joint fit (the strings earlier versions wrote)."""

    OK = "ok"
    POOR_FIT = "poor-fit"  # residuals the timer's precision cannot explain (χ² test)
    NOT_CONVERGED = "not-converged"


@dataclass(frozen=True)
class DescentData:
    """What the joint fit needs of one descent."""

    number: int
    item: str
    group: str  # who skied it: one mean CdA per group
    photocells: tuple[str, ...]
    times_s: np.ndarray  # relative to the first photocell
    start_hours: float  # time of day of the start, hours (unwrapped)
    mass_kg: float
    air_density: float
    wind_ms: float
    start_guess: tuple[float, float, float]  # (cda, mu, v0) from the single fit
    #: the timer's precision its single fit was judged against (station.model.timer)
    timer_sd_s: float = TIMER_PRECISION_S
    #: the gravity its single fit used (the site's: station.model.physics.gravity_for), so
    #: that the day model's μ and the descents' own agree (standard gravity here moved every
    #: item's μ by 1.8e-4 at 47° N, 1700 m)
    gravity_ms2: float = G_STANDARD


class DayInputs(NamedTuple):
    """A day's descents as the comparison sees them (:func:`collect`)."""

    data: list[DescentData]  # those that enter the joint fit, in order
    excluded: list[tuple[int, str]]  # those left out, with why
    wind_flagged: list[int]  # those with more along-track wind than the limit

    def items(self) -> list[str]:
        """The test items that enter the fit, sorted (for ``--reference`` prefixes)."""
        return sorted({d.item for d in self.data})


@dataclass(frozen=True)
class ItemResult:
    item: str
    descents: tuple[int, ...]
    mu: float
    ci90: tuple[float, float]
    stderr: float
    mu1: float | None = None
    mu1_ci90: tuple[float, float] | None = None
    p_best: float | None = None  # P(this item has the lowest μ); None: not comparable


@dataclass(frozen=True)
class Comparison:
    a: str
    b: str
    delta_mu: float  # μ_a − μ_b
    ci90: tuple[float, float] | None  # None: no comparison possible (see note)
    p_a_faster: float | None  # P(μ_a < μ_b)
    delta_t_s: float  # time a takes minus time b takes over the run
    #: of the Student t that stands for the interval and its tail beyond (the sequential
    #: rule's): the one as wide at 90 %, capped by Satterthwaite's count (_Inference)
    dof: float | None = None
    note: str = ""
    #: whether the run order tells the day's drift from this pair's difference (the items
    #: interleave in time and Δμ is not nearly a multiple of the drift): a pair is judged on
    #: its own, so an item skied once at the end does not make A vs B "not separable"
    drift_separable: bool = True
    #: why the interval is not to be trusted for a decision ("": nothing known against it):
    #: the drift cannot be told from this difference, or the joint fit is poor or did not
    #: converge. The sequential decision reads it (station.model.sequential), so the
    #: console, the UI, ``station compare`` and the report give one answer.
    caveat: str = ""


@dataclass(frozen=True)
class DescentEffect:
    """What the day's fit says of one descent."""

    number: int
    cda: float
    v0: float
    dt0_s: float


@dataclass(frozen=True)
class JointResult:
    """The day's comparison: built once by :func:`joint_fit`, never changed after (hand it to
    the UI thread, the report and the season store as it is)."""

    items: tuple[ItemResult, ...]
    #: skier (group) -> mean CdA with its 90 % interval (interval None: fixed by ``--cda``)
    cda: dict[str, Estimate]
    drift_per_hour: tuple[float, tuple[float, float]] | None
    drift_separable: bool
    comparisons: tuple[Comparison, ...]
    ranking: tuple[str, ...]
    reference: str | None
    dof: int
    sigma_s: float
    typical_v0: float
    posture_sd: float = 0.0  # between-descent SD of CdA, relative (0.01 = 1 %)
    posture_ci90: tuple[float, float] | None = None
    timer_sd_s: float = TIMER_PRECISION_S
    chi2_p: float | None = None
    descents: tuple[DescentEffect, ...] = ()
    excluded: tuple[tuple[int, str], ...] = ()
    wind_flagged: tuple[int, ...] = ()
    warnings: tuple[str, ...] = ()
    status: ComparisonStatus = ComparisonStatus.OK
    message: str = ""
    #: covariance of the items' μ, in the order of ``items`` (the season store joins the days
    #: by it: station.model.season)
    item_cov: tuple[tuple[float, ...], ...] = ()
    #: the gravity the day was computed with (m/s²): its descents' (the median, when they
    #: differ, which a warning then says)
    gravity_ms2: float = G_STANDARD
    #: the drift's curvature (μ per hour², with its 90 % interval) when the day's drift bends
    #: and is followed by a quadratic (:func:`drift_bend`); None: straight
    drift_bend: tuple[float, tuple[float, float]] | None = None

    def item(self, name: str) -> ItemResult:
        """The result of the item called ``name``."""
        return next(i for i in self.items if i.item == name)

    def to_dict(self) -> dict[str, Any]:
        return {
            "status": self.status.value,
            "message": self.message,
            "items": [
                {
                    "item": i.item,
                    "descents": list(i.descents),
                    "mu": i.mu,
                    "ci90": list(i.ci90),
                    "stderr": i.stderr,
                    "p_best": i.p_best,
                    **({"mu1": i.mu1} if i.mu1 is not None else {}),
                    **({"mu1_ci90": list(i.mu1_ci90)} if i.mu1_ci90 is not None else {}),
                }
                for i in self.items
            ],
            "cda": {
                g: {"value": e.value, "ci90": list(e.ci90) if e.ci90 else None}
                for g, e in self.cda.items()
            },
            "posture_sd_pct": 100.0 * self.posture_sd,
            "posture_ci90_pct": (
                [100.0 * self.posture_ci90[0], 100.0 * self.posture_ci90[1]]
                if self.posture_ci90
                else None
            ),
            "drift": (
                {
                    "mu_per_hour": self.drift_per_hour[0],
                    "ci90": list(self.drift_per_hour[1]),
                    "separable": self.drift_separable,
                    **(
                        {
                            "per_hour2": self.drift_bend[0],
                            "per_hour2_ci90": list(self.drift_bend[1]),
                        }
                        if self.drift_bend
                        else {}
                    ),
                }
                if self.drift_per_hour
                else None
            ),
            "comparisons": [
                {
                    "a": c.a,
                    "b": c.b,
                    "delta_mu": c.delta_mu,
                    "ci90": list(c.ci90) if c.ci90 else None,
                    "p_a_faster": c.p_a_faster,
                    "delta_t_s": c.delta_t_s,
                    "dof": c.dof,
                    "note": c.note,
                    "drift_separable": c.drift_separable,
                    "caveat": c.caveat,
                }
                for c in self.comparisons
            ],
            "ranking": list(self.ranking),
            "reference": self.reference,
            "dof": self.dof,
            "sigma_s": self.sigma_s,
            "timer_sd_s": self.timer_sd_s,
            "chi2_p": self.chi2_p,
            "typical_v0": self.typical_v0,
            "gravity_ms2": self.gravity_ms2,
            "descents": [
                {"descent": d.number, "cda": d.cda, "v0": d.v0, "dt0_s": d.dt0_s}
                for d in self.descents
            ],
            "excluded": [{"descent": n, "reason": r} for n, r in self.excluded],
            "wind_flagged": list(self.wind_flagged),
            "warnings": list(self.warnings),
        }


class CompareError(ValueError):
    """Not enough of the right data to compare."""


@dataclass
class _Pieces:
    """Normal-equation pieces of the linearised day at one point (global columns scaled)."""

    bb: np.ndarray  # (D, 3, 3)
    ab: np.ndarray  # (D, G, 3)
    aa: np.ndarray  # (G, G)
    br: np.ndarray  # (D, 3)
    ar: np.ndarray  # (G,)
    a: np.ndarray  # (D, n, G)
    b: np.ndarray  # (D, n, 3)
    r: np.ndarray  # (D, n)
    u: np.ndarray  # (D,)


@dataclass
class _Step:
    dg: np.ndarray  # scaled global step
    dl: np.ndarray  # (D, 3) local step
    prss: float
    logdet: float
    s_inv: np.ndarray  # (G, G) scaled


def _linear_step(pc: _Pieces, wu: float, lam: float = 0.0) -> _Step:
    """Penalised Gauss-Newton step with the local blocks eliminated (Schur complement)."""
    hll = pc.bb.copy()
    hll[:, 0, 0] += wu
    gl = pc.br.copy()
    gl[:, 0] += wu * pc.u
    aa = pc.aa
    if lam > 0:
        idx = np.arange(3)
        hll[:, idx, idx] *= 1.0 + lam
        aa = aa + lam * np.diag(np.diag(aa))
    hinv = np.linalg.inv(hll)
    k = np.einsum("dgi,dij->dgj", pc.ab, hinv)
    s = aa - np.einsum("dgi,dhi->gh", k, pc.ab)
    rhs = pc.ar - np.einsum("dgi,di->g", k, gl)
    if s.size:
        s_inv = np.linalg.inv(s)
        dg = -s_inv @ rhs
        logdet_s = float(np.linalg.slogdet(s)[1])
    else:
        s_inv, dg, logdet_s = np.zeros((0, 0)), np.zeros(0), 0.0
    dl = -np.einsum("dij,dj->di", hinv, gl + np.einsum("dgi,g->di", pc.ab, dg))
    lin = pc.r + np.einsum("dng,g->dn", pc.a, dg) + np.einsum("dni,di->dn", pc.b, dl)
    prss = float(np.sum(lin * lin) + wu * np.sum((pc.u + dl[:, 0]) ** 2))
    logdet = float(np.sum(np.linalg.slogdet(hll)[1])) + logdet_s
    return _Step(dg, dl, prss, logdet, s_inv)


def joint_fit(
    track: Track,
    data: list[DescentData],
    *,
    cda_fixed: float | None = None,
    model: str = "constant",
    drift: str = "auto",
    reference: str | None = None,
    timer_sd_s: float | None = None,
    excluded: Iterable[tuple[int, str]] = (),
    wind_flagged: Iterable[int] = (),
    wind_limit_ms: float | None = None,
) -> JointResult:
    """The day model: all descents of a day at once, inputs in, an immutable result out.

    ``data``: the descents that enter (:func:`collect` makes them from a day's results, with
    ``excluded`` and ``wind_flagged``, which the result carries; ``wind_limit_ms`` given, the
    flagged descents are also a warning). ``cda_fixed``: one CdA for all (m²) instead of a
    skier's mean and the posture scatter around it. ``model``: ``constant`` μ per item, or
    ``velocity`` (μ + μ1·v). ``drift``: a linear drift of μ over the day, ``auto`` (when the
    reference recurs), ``on`` or ``off``. ``reference``: the item every other is compared with
    (default: the one skied most). ``timer_sd_s``: the timer's precision the residuals are
    judged against (default: the one the descents' single fits used, see
    :mod:`station.model.timer`). Raises :class:`CompareError` when the data cannot answer.
    Pure: no I/O; BLAS is held to one thread while it runs."""
    if timer_sd_s is None:
        timer_sd_s = day_timer_sd(data)
    bent = drift_bend(data) if drift != "off" else None
    follow = bent is not None and bent.p < BEND_P
    with runtime.blas_on_one_thread():
        try:
            res = _joint_fit(track, data, cda_fixed, model, drift, reference, timer_sd_s, follow)
        except CompareError:  # too few times for the quadratic: the straight drift, warned
            if not follow:
                raise
            res = _joint_fit(track, data, cda_fixed, model, drift, reference, timer_sd_s)
    if bent is not None and bent.p < BEND_P:
        res = replace(res, warnings=(*res.warnings, _bend_warning(bent, res)))
    elif bent is None and res.drift_per_hour is not None and _bend_unseen(data):
        res = replace(res, warnings=(*res.warnings, _unseen_bend_warning(data)))
    flagged = tuple(wind_flagged)
    warnings = res.warnings
    if flagged and wind_limit_ms is not None:
        warnings += (
            f"descents {', '.join(map(str, flagged))} had more than {wind_limit_ms:g} m/s of "
            "along-track wind: check them, or mark them invalid",
        )
    return replace(res, excluded=tuple(excluded), wind_flagged=flagged, warnings=warnings)


#: the drift is taken to bend when a curvature this unlikely under a straight drift is seen
#: (so a straight-drift day is warned on about one day in a hundred)
BEND_P = 0.01


class DriftBend(NamedTuple):
    """The curvature of μ over the day seen in the descents' own μ (per hour²)."""

    per_hour2: float
    stderr: float
    p: float  # two-sided, against a straight drift
    dof: int


def drift_bend(data: list[DescentData]) -> DriftBend | None:
    """Does μ drift straight? The single fits' μ of the day's descents, regressed on the items
    and a straight and a quadratic drift over the time of day: the quadratic's t-test, its
    variance from the scatter of the descents about that curve (posture and timer both in
    it). None when the day has no degrees of freedom for it (fewer than items + 4 descents)
    or does not span time.

    Why a test of its own, not the joint fit's residuals: a bend of μ is absorbed by each
    descent's own CdA and v0 in the times, so the times' residuals barely show it, while the
    descents' μ line it up against the clock (the sun coming onto the track, μ +0.02/h
    +0.03/h², made the interval miss 0 on 13 of 24 equal-ski days with a straight drift)."""
    items = sorted({d.item for d in data})
    n = len(data)
    dof = n - len(items) - 2
    if dof < 2:
        return None
    t = np.array([d.start_hours for d in data])
    t = t - t.mean()
    if np.ptp(t) <= 0:
        return None
    x = np.zeros((n, len(items) + 2))
    for k, d in enumerate(data):
        x[k, items.index(d.item)] = 1.0
    x[:, -2], x[:, -1] = t, t * t
    y = np.array([d.start_guess[1] for d in data])
    coef, _res, rank, _sv = np.linalg.lstsq(x, y, rcond=None)
    if rank < x.shape[1]:
        return None
    resid = y - x @ coef
    s2 = float(resid @ resid) / dof
    se = math.sqrt(max(float(s2 * np.linalg.inv(x.T @ x)[-1, -1]), 0.0))
    if se <= 0:
        return None
    tval = float(coef[-1]) / se
    return DriftBend(float(coef[-1]), se, float(2.0 * stdtr(dof, -abs(tval))), dof)


def _bend_unseen(data: list[DescentData]) -> bool:
    """Too few descents to test the drift's straightness (:func:`drift_bend`), over a day that
    spans time."""
    n_items = len({d.item for d in data})
    return len(data) - n_items - 2 < 2 and len({d.start_hours for d in data}) > 1


def _unseen_bend_warning(data: list[DescentData]) -> str:
    """Why a small day is warned although its drift may well be straight: on ABBA the
    items and a straight drift leave no degrees of freedom for the drift's shape, so a bend
    (the sun coming onto the track) goes straight into Δμ, and the interval then held the
    truth on 5–22 % of such days (benchmarks/compare_small_days.py). A straight day and a
    bent one cannot be told apart, so every such day says it."""
    counts = sorted({sum(d.item == it for d in data) for it in {d.item for d in data}})
    n_items = len({d.item for d in data})
    how = (
        f"{counts[0]} descents an item"
        if len(counts) == 1
        else f"{len(data)} descents of {_count(n_items, 'item')}"
    )
    return (
        f"drift: with {how} a bend in the drift of μ cannot be seen (that takes "
        f"{n_items + 4} descents); the intervals assume a straight drift"
    )


def _bend_warning(bent: DriftBend, res: JointResult) -> str:
    what = (
        "followed by a quadratic drift (the drift line gives its slope at the day's mean time)"
        if res.drift_bend is not None
        else "the comparison assumes a straight drift, so its intervals may miss; ski the "
        "reference more often (ABBA through the day) or compare the parts of the day apart"
    )
    return (
        f"the drift of μ is not straight: it bends by {bent.per_hour2:+.4f} per hour² over "
        f"the day (p = {bent.p:.2g}, from the descents' own μ): {what}"
    )


def day_timer_sd(data: Iterable[DescentData]) -> float:
    """The timer's precision of a day: the coarsest its descents' single fits were judged
    against (they share one timer, so all are the same unless a config changed)."""
    return max((d.timer_sd_s for d in data), default=TIMER_PRECISION_S)


@dataclass(frozen=True)
class _Layout:
    """Who is in the day and where each global parameter sits: the skiers' mean CdA, μ (and
    μ1) per item, the drift; v0 and the offset per descent are local."""

    items: list[str]
    groups: list[str]
    counts: dict[str, int]
    ref: str | None
    use_drift: bool
    drift: str
    t_mean: float
    #: the drift bends: a quadratic term after the linear one (column i_drift + 1)
    bend: bool
    n_g: int
    per_item: int
    i_mu: int
    i_drift: int
    n_glob: int
    dof: int

    @classmethod
    def of(cls, data, cda_fixed, model, drift, reference, bend: bool = False) -> _Layout:
        if not data:
            raise CompareError("no valid descent to compare")
        items = sorted(
            {d.item for d in data}, key=lambda it: min(x.number for x in data if x.item == it)
        )
        groups = sorted({d.group for d in data})
        if reference is not None and reference not in items:
            raise CompareError(f"reference item {reference!r} is not among {', '.join(items)}")
        counts = {it: sum(d.item == it for d in data) for it in items}
        recurring = [it for it in items if counts[it] >= 2]
        ref = reference or (max(items, key=lambda it: counts[it]) if items else None)
        use_drift = drift == "on" or (drift == "auto" and ref in recurring and len(data) >= 4)
        t_mean = float(np.mean([d.start_hours for d in data]))
        n_d = len(data)
        n_g = 0 if cda_fixed is not None else len(groups)
        per_item = 2 if model == "velocity" else 1
        i_drift = n_g + len(items) * per_item
        bend = bend and use_drift
        n_glob = i_drift + (1 if use_drift else 0) + (1 if bend else 0)
        n_cells = np.array([len(d.times_s) for d in data])
        n_res = int(n_cells.sum())
        n_fixed = n_glob + 2 * n_d  # v0 and offset per descent are fixed effects too
        dof = n_res - n_fixed
        if dof < 1 or np.any(n_cells < 3):
            raise CompareError(
                f"{n_res} times for {n_fixed} unknowns: too few photocells or descents"
            )
        return cls(items, groups, counts, ref, use_drift, drift, t_mean, bend, n_g, per_item,
                   n_g, i_drift, n_glob, dof)  # fmt: skip

    def mu_index(self, item: str) -> int:
        return self.i_mu + self.items.index(item) * self.per_item


class _DayModel:
    """The day's descents as arrays (one row per descent, padded to the most photocells) and
    the forward model of all of them at once (:mod:`station.model.batch`)."""

    def __init__(self, track: Track, data: list[DescentData], lay: _Layout, cda_fixed) -> None:
        self.data, self.lay, self.cda_fixed = data, lay, cda_fixed
        n_d = self.n_d = len(data)
        n_cells = np.array([len(d.times_s) for d in data])
        n_max = self.n_max = int(n_cells.max())
        self.mask = np.arange(n_max)[None, :] < n_cells[:, None]
        self.times = np.zeros((n_d, n_max))
        for k, d in enumerate(data):
            self.times[k, : n_cells[k]] = d.times_s
        self.col_g = np.array([lay.groups.index(d.group) for d in data])
        self.col_mu = np.array([lay.mu_index(d.item) for d in data])
        self.dth = np.array([d.start_hours - lay.t_mean for d in data])
        self.kk = np.array([d.air_density / d.mass_kg for d in data])
        self.wind = np.array([d.wind_ms for d in data])
        self.grav = np.array([d.gravity_ms2 for d in data])
        self.runs: dict[tuple[str, ...], tuple[StraightRun, np.ndarray]] = {}
        for pcs in {d.photocells for d in data}:
            xs = np.array([track.photocell(p).x for p in pcs])
            idx = np.array([k for k, d in enumerate(data) if d.photocells == pcs])
            self.runs[pcs] = (StraightRun(track.profile, xs), idx)

    def base_cda(self, glob: np.ndarray) -> np.ndarray:
        """Each descent's skier's mean CdA (or the fixed one)."""
        if self.cda_fixed is not None:
            return np.full(self.n_d, self.cda_fixed)
        return glob[self.col_g]

    def evaluate(self, glob: np.ndarray, loc: np.ndarray):
        """Residuals (D, n) and Jacobians of the globals (D, n, G) and locals (D, n, 3)."""
        lay, n_d, n_max = self.lay, self.n_d, self.n_max
        col_g, col_mu, dth, per_item = self.col_g, self.col_mu, self.dth, lay.per_item
        cda = self.base_cda(glob) * np.exp(loc[:, 0])
        mu = glob[col_mu] + (glob[lay.i_drift] * dth if lay.use_drift else 0.0)
        if lay.bend:
            mu = mu + glob[lay.i_drift + 1] * dth * dth
        mu1 = glob[col_mu + 1] if per_item == 2 else np.zeros(n_d)
        r = np.zeros((n_d, n_max))
        a = np.zeros((n_d, n_max, lay.n_glob))
        b = np.zeros((n_d, n_max, 3))
        stopped = np.zeros(n_d, dtype=bool)
        converged = True
        for run, idx in self.runs.values():
            sol = solve_rows(
                run,
                Rows(cda[idx], mu[idx], loc[idx, 1], mu1[idx], self.kk[idx], self.wind[idx],
                     self.grav[idx]),
                n_params=3 + (per_item - 1),
            )  # fmt: skip
            m = sol.t.shape[1]
            r[idx, :m] = sol.t + loc[idx, 2:3] - self.times[idx, :m]
            dt = sol.dt_dp
            if self.cda_fixed is None:
                a[idx, :m, col_g[idx]] = dt[:, :, 0] * np.exp(loc[idx, 0:1])
            a[idx, :m, col_mu[idx]] = dt[:, :, 1]
            if per_item == 2:
                a[idx, :m, col_mu[idx] + 1] = dt[:, :, 3]
            if lay.use_drift:
                a[idx, :m, lay.i_drift] = dt[:, :, 1] * dth[idx, None]
            if lay.bend:
                a[idx, :m, lay.i_drift + 1] = dt[:, :, 1] * (dth[idx] ** 2)[:, None]
            b[idx, :m, 0] = dt[:, :, 0] * cda[idx, None]
            b[idx, :m, 1] = dt[:, :, 2]
            b[idx, :m, 2] = 1.0
            stopped[idx] = sol.stopped
            converged = converged and bool(sol.converged.all())
        r *= self.mask
        a *= self.mask[:, :, None]
        b *= self.mask[:, :, None]
        return r, a, b, stopped, converged

    def start(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The single fits' medians as the start; the lower bounds of the globals."""
        lay, data = self.lay, self.data
        glob = np.zeros(lay.n_glob)
        for g_i, g in enumerate(lay.groups[: lay.n_g]):
            glob[g_i] = np.median([d.start_guess[0] for d in data if d.group == g])
        for ii, it in enumerate(lay.items):
            glob[lay.i_mu + ii * lay.per_item] = np.median(
                [d.start_guess[1] for d in data if d.item == it]
            )
        loc = np.zeros((self.n_d, 3))
        loc[:, 1] = [d.start_guess[2] for d in data]
        lower = np.full(lay.n_glob, -np.inf)
        lower[: lay.n_g] = 1e-3
        lower[lay.i_mu : lay.i_drift] = 0.0
        return glob, loc, lower


@dataclass
class _Solution:
    """Where the REML / Gauss-Newton iteration ended."""

    glob: np.ndarray
    loc: np.ndarray
    pc: _Pieces  # the normal-equation pieces there
    cs: np.ndarray  # column scales of the globals
    lg: float  # log γ
    stopped: np.ndarray
    converged: bool  # every model solve converged
    converged_outer: bool  # the iteration itself


def _solve(day: _DayModel) -> _Solution:
    """γ and the parameters updated together: each outer iteration linearises the model once,
    finds γ by a one-dimensional search of the REML criterion of that linearisation, and takes
    the (damped where needed) Gauss-Newton step at that γ."""
    dof, n_d = day.lay.dof, day.n_d
    glob, loc, lower = day.start()
    r, a, b, stopped, converged = day.evaluate(glob, loc)
    cs = 1.0 / np.maximum(np.sqrt(np.sum(a * a, axis=(0, 1))), 1e-300)  # column scales

    def pieces(r, a, b, loc) -> _Pieces:
        a_s = a * cs
        return _Pieces(
            bb=np.einsum("dni,dnj->dij", b, b),
            ab=np.einsum("dng,dni->dgi", a_s, b),
            aa=np.einsum("dng,dnh->gh", a_s, a_s),
            br=np.einsum("dni,dn->di", b, r),
            ar=np.einsum("dng,dn->g", a_s, r),
            a=a_s,
            b=b,
            r=r,
            u=loc[:, 0].copy(),
        )

    def reml(lg: float, pc: _Pieces) -> tuple[float, _Step]:
        st = _linear_step(pc, math.exp(-lg))
        return (dof * math.log(max(st.prss, 1e-300)) + n_d * lg + st.logdet), st

    pc = pieces(r, a, b, loc)
    lg = 2.0 * math.log(0.01 / 5e-4)
    converged_outer = False
    for _ in range(60):
        lg_prev = lg
        opt = minimize_scalar(
            lambda x, pc=pc: reml(x, pc)[0],
            bounds=LOG_GAMMA,
            method="bounded",
            options={"xatol": 1e-3},
        )
        lg = float(opt.x)
        wu = math.exp(-lg)
        st = _linear_step(pc, wu)
        cost = float(np.sum(pc.r**2) + wu * np.sum(pc.u**2))
        if cost - st.prss <= 1e-9 * cost + 1e-24 and abs(lg - lg_prev) < 1e-2:
            converged_outer = True
            break
        lam = 0.0
        for _ in range(12):
            g_new = np.maximum(glob + st.dg * cs, lower)
            l_new = loc + st.dl
            l_new[:, 1] = np.maximum(l_new[:, 1], 0.0)
            r2, a2, b2, stopped2, conv2 = day.evaluate(g_new, l_new)
            cost2 = float(np.sum(r2**2) + wu * np.sum(l_new[:, 0] ** 2))
            if np.isfinite(cost2) and cost2 <= cost:
                glob, loc, r, a, b, stopped, converged = g_new, l_new, r2, a2, b2, stopped2, conv2
                break
            lam = 1e-3 if lam == 0 else lam * 10
            st = _linear_step(pc, wu, lam)
        else:
            break
        pc = pieces(r, a, b, loc)
    return _Solution(glob, loc, pc, cs, lg, stopped, converged, converged_outer)


#: the posterior of log γ is integrated where its log density is within this of its peak
POST_DROP = 16.0
#: steps of log γ: the widest of the walk that finds where the posterior lies, and the widest
#: of the grid that integrates it (at least POST_POINTS points over where it lies)
POST_SEARCH, POST_STEP, POST_POINTS = 0.5, 0.25, 41
#: the largest posture scatter the prior allows (relative SD of CdA between descents of a
#: skier): beyond it the single fits would show another position, not a tuck's scatter; a
#: bound makes the posterior proper on days with as few descents as skiers + 1
POSTURE_MAX = 0.2


class _Inference:
    """At the solution: σ̂², the posture scatter, and the distribution of the globals with the
    uncertainty of the estimated scatter in it.

    Why a posterior over γ, not γ̂ plugged in. Plugged in, the intervals are as narrow as if
    the scatter were known; on small days (2 descents an item) REML puts it at 0 on about one
    day in ten at 0.5 % scatter, Δμ̂ at γ = 0 can be far from Δμ̂ at the true γ, and on those
    days the interval held the truth two times in three (83.5 % in all with the
    Kackar-Harville term and Satterthwaite's degrees of freedom, which both vanish or mislead
    at the boundary, issue 24). Instead the globals' distribution is integrated over γ: given
    γ, with flat priors on the fixed effects and 1/σ² on σ², the globals are exactly Student
    t on n − p degrees of freedom around β̂(γ) with scale PRSS(γ)/(n − p)·S⁻¹(γ) (of the model
    linearised at the solution), and γ's posterior is its REML likelihood,
    exp(−½[(n − p)·log PRSS(γ) + q·log γ + log det M(γ)]), times a prior. The prior is flat
    in the scatter s itself (the usual choice for a scale with few groups, Gelman 2006): it
    keeps what the day cannot rule out, and where the day pins γ the posterior is narrow and
    the answer is the plug-in one. Measured, 200 simulated days a cell
    (benchmarks/compare_small_days.py, straight drift): 2 a ski at 0.5 % scatter 88.5 %
    (83.5 % plugged in), at 3 % 89 %; 3, 4 and 6 a ski at 0.5 % 91.5, 90 and 88.5 %.
    Jeffreys' prior for γ (from REML's expected information) gave 85.5 % at 2 a ski: it
    falls to 0 with γ as fast as γ itself and so keeps too much of the scatter-free answer;
    a prior flat in γ gave 90 %, but is known to over-widen where the day says little. The
    integral is a sum over a grid in log γ: a walk out from γ̂ to where the posterior ends,
    then at least 41 points over it; each point is one linear solve of the day (no new model
    solves).

    Kenward-Roger's correction. Each component's scale σ̂²(γ)·S⁻¹(γ) is that of a day whose
    scatter is known; estimated, the scatter moves the estimates (the spread of the centres
    over the posterior, Λ, Kackar-Harville's term) and the scales themselves come out low by
    about as much: for a covariance linear in its parameters (σ² and s², as here) E[φ(θ̂)] ≈
    φ(θ) − Λ, so the variance is φ + 2Λ (Kenward & Roger 1997). Without it the components'
    mean scale was 2-8 % below the variance at the true scatter on the demo run (nine
    photocells) and about as much as Λ below on four photocells (benchmarks/
    compare_se_oracle.py), and equal skis were declared different after every descent on
    10.4-11.7 % (nine photocells) and 16.8 % (four) of simulated days (issue 21). So every
    component's scale gets Λ added: the variance is then the mean scale plus 2Λ, and every
    interval widens by what the day does not know of its scatter (nothing where the day
    pins it). The degrees of freedom of a comparison count that uncertainty too
    (:meth:`satterthwaite_dof`).

    Every number about the globals comes from that one mixture of t distributions:
    intervals (its quantiles), P(a faster), P(best), the covariance (the mixture's scale:
    mean of the scales plus the spread of the centres) and the standard errors from it, and
    the estimates themselves (μ, μ1, the drift, Δμ): the mixture's mean ``centre``, not the
    solution at γ̂. At γ̂ on the boundary (the scatter estimated at 0) the solution can lie
    outside its own interval (Δμ̂ 2.0 half-widths from the interval's middle on a 2-a-ski day,
    tests/test_compare_small_days.py), and z = Δμ̂/se spread 1.13–1.16 at 2 a ski where the
    mixture's centre spreads 1.09 (issue 21, benchmarks/compare_se_oracle.py). The skiers'
    mean CdA stay at γ̂ with their plug-in intervals (:meth:`plugin_interval`)."""

    H = 0.05  # step in log γ of the curvature's differences (the posture's interval)
    scale: np.ndarray  # (K, G, G) the components' scale matrices (set by _mixture, corrected)

    def __init__(self, sol: _Solution, dof: int) -> None:
        self.sol, self.dof = sol, dof
        pc, lg, h = sol.pc, sol.lg, self.H
        wu = math.exp(-lg)
        st = self.st = _linear_step(pc, wu)
        prss = self.prss = float(np.sum(pc.r**2) + wu * np.sum(pc.u**2))
        sigma2 = self.sigma2 = prss / dof
        self.posture = math.sqrt(math.exp(lg) * sigma2)
        probe = {dx: _linear_step(pc, math.exp(-(lg + dx))) for dx in (-h, h)}
        p_m, p_p = probe[-h].prss, probe[h].prss
        l0, l_m, l_p = st.logdet, probe[-h].logdet, probe[h].logdet
        d1p = (p_p - p_m) / (2 * h)
        d2p = (p_p - 2 * prss + p_m) / h**2
        d2l = (l_p - 2 * l0 + l_m) / h**2
        hess = np.array([[prss / sigma2, -d1p / sigma2], [-d1p / sigma2, d2p / sigma2 + d2l]])
        vcov: np.ndarray | None
        try:
            vcov = 2.0 * np.linalg.inv(hess)
            if not (np.all(np.isfinite(vcov)) and vcov[0, 0] > 0 and vcov[1, 1] > 0):
                vcov = None
        except np.linalg.LinAlgError:
            vcov = None
        self.vcov = vcov
        cs = sol.cs
        self.plugin_sd = np.sqrt(np.maximum(sigma2 * cs * cs * np.diag(st.s_inv), 0.0))
        self._mixture(pc, lg)
        mean = self.centre = self.w @ self.beta
        spread = self.beta - mean
        #: the components' own scales, before the correction below (the degrees of freedom
        #: of a contrast are counted from them: equivalent_dof)
        self.scale0 = self.scale
        lam = (spread.T * self.w) @ spread  # the spread of the centres: Kackar-Harville's Λ
        self.scale = self.scale0 + lam[None, :, :]
        self.cov = np.einsum("k,kij->ij", self.w, self.scale) + lam
        self.sd = np.sqrt(np.maximum(np.diag(self.cov), 0.0))

    def _mixture(self, pc: _Pieces, lg_hat: float) -> None:
        """The posterior of log γ on a grid: weights ``w``, and at each point the globals'
        centre ``beta`` and scale matrix ``scale`` (unscaled columns)."""
        dof, n_d, cs, glob = self.dof, len(pc.u), self.sol.cs, self.sol.glob

        def at(lgs: np.ndarray) -> tuple[list[_Step], np.ndarray]:
            sts = [_linear_step(pc, math.exp(-x)) for x in lgs]
            ld = np.array([n_d * x + s.logdet for x, s in zip(lgs, sts, strict=True)])
            prss = np.array([max(s.prss, 1e-300) for s in sts])
            # REML likelihood, times the prior flat in s = √γ·σ (per unit log γ: √γ)
            return sts, -0.5 * (dof * np.log(prss) + ld) + 0.5 * lgs

        # γ up to the largest scatter a skier's tuck can have (POSTURE_MAX)
        lo_b = LOG_GAMMA[0]
        hi_b = min(LOG_GAMMA[1], math.log(POSTURE_MAX**2 / max(self.sigma2, 1e-300)))
        hi_b = max(hi_b, lg_hat + POST_SEARCH)
        # the search step: the posterior's SD in log γ from its curvature at γ̂ (narrow on
        # big days), at most POST_SEARCH
        _sts, lp3 = at(np.array([lg_hat - self.H, lg_hat, lg_hat + self.H]))
        curv = (lp3[0] - 2 * lp3[1] + lp3[2]) / self.H**2
        step = POST_SEARCH if not curv < -1.0 / POST_SEARCH**2 else 1.0 / math.sqrt(-curv)
        top = float(lp3[1])
        lo = hi = lg_hat
        for sign in (1.0, -1.0):  # walk out from γ̂ until the posterior is negligible
            x = lg_hat
            while lo_b < x + sign * step < hi_b:
                x += sign * step
                lp_x = float(at(np.array([x]))[1][0])
                top = max(top, lp_x)
                if lp_x < top - POST_DROP:
                    break
            lo, hi = min(lo, x), max(hi, x)
        lo, hi = max(lo - step, lo_b), min(hi + step, hi_b)
        n = max(POST_POINTS, math.ceil((hi - lo) / POST_STEP) + 1)
        grid = np.linspace(lo, hi, n)
        sts, lp = at(grid)
        w = np.exp(lp - lp.max())
        w[[0, -1]] *= 0.5  # trapezoid
        use = w > 1e-12 * w.max()
        w = w[use] / w[use].sum()
        sts = [s for s, u in zip(sts, use, strict=True) if u]
        self.w = w
        self.grid = grid[use]
        self.beta = np.array([glob + s.dg * cs for s in sts])
        self.scale = np.array(
            [max(s.prss, 0.0) / dof * (cs[:, None] * s.s_inv * cs[None, :]) for s in sts]
        )

    def parts(self, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Centres and scales of c·globals in the mixture's components."""
        m = self.beta @ c
        s = np.sqrt(np.maximum(np.einsum("i,kij,j->k", c, self.scale, c), 1e-300))
        return m, s

    def cdf(self, c: np.ndarray, x: float) -> float:
        """P(c·globals ≤ x) (within [0, 1]: the weights' rounding gave 1.0000000000000002,
        which the report showed as a P(faster) of −0.000)."""
        m, s = self.parts(c)
        return min(max(float(self.w @ stdtr(self.dof, (x - m) / s)), 0.0), 1.0)

    def quantile(self, c: np.ndarray, p: float) -> float:
        m, s = self.parts(c)
        q = float(stdtrit(self.dof, p))
        lo, hi = float(np.min(m + q * s)), float(np.max(m + q * s))
        if hi - lo <= 1e-15 * max(abs(lo), abs(hi), 1e-300):
            return lo

        def f(x: float) -> float:
            return float(self.w @ stdtr(self.dof, (x - m) / s)) - p

        return float(brentq(f, lo, hi, xtol=1e-14 * max(abs(lo), abs(hi), 1e-12), rtol=1e-12))

    def interval_of(self, c: np.ndarray) -> tuple[float, float]:
        """The 90 % interval of c·globals."""
        return self.quantile(c, 0.05), self.quantile(c, 0.95)

    def interval(self, j: int) -> tuple[float, float]:
        """The 90 % interval of global parameter ``j``."""
        c = np.zeros(len(self.sol.glob))
        c[j] = 1.0
        return self.interval_of(c)

    def plugin_interval(self, j: int) -> tuple[float, float]:
        """The 90 % interval of global parameter ``j`` at the estimated scatter: for a
        skier's mean CdA, the mean over the day's descents. Why not the mixture: the mean
        of a skier's posture distribution is what the scatter's posterior makes uncertain,
        without bound on a day of 2 descents (a skier's CdA 0.2200 [0.1807, 0.2593] on two
        identical descents); the mean of the descents the day has is pinned by their
        times whatever the scatter. The comparisons of items are not affected by the
        scatter's tail: free CdA per descent still gives each μ its interval."""
        q = float(stdtrit(self.dof, 0.95)) * float(self.plugin_sd[j])
        g = float(self.sol.glob[j])
        return g - q, g + q

    def equivalent_dof(self, c: np.ndarray, ci: tuple[float, float]) -> float:
        """The degrees of freedom of the Student t that stands for the mixture of c·globals
        beyond its 90 % interval (the sequential rule's boundaries lie there: z 1.9 to 4.4):
        the t with the scale √(c·cov·c) whose 90 % interval is as wide as the mixture's, and
        no more than Satterthwaite's count for that variance (:meth:`satterthwaite_dof`). A
        caller that rebuilds a standard error from the interval and the degrees of freedom
        (station.model.sequential) gets the interval back at 90 % and the heavier tail
        beyond."""
        se = math.sqrt(max(float(c @ self.cov @ c), 0.0))
        ratio = (ci[1] - ci[0]) / 2 / se if se > 0 else 0.0
        if not ratio > float(stdtrit(self.dof, 0.95)):
            nu = float(self.dof)
        elif ratio >= float(stdtrit(1.0, 0.95)):
            nu = 1.0
        else:
            nu = float(brentq(lambda v: float(stdtrit(v, 0.95)) - ratio, 1.0, float(self.dof)))
        return max(1.0, min(nu, self.satterthwaite_dof(c)))

    def satterthwaite_dof(self, c: np.ndarray) -> float:
        """Degrees of freedom of the variance of c·globals counted as Satterthwaite does:
        that variance is the components' mean scale E[φ] plus twice the spread of their
        centres Λ (Kenward-Roger), and each part is uncertain: φ by the timing noise's χ² (2/ν
        in log) and by how it varies over the scatter's posterior (Var log φ), Λ as one χ²
        degree of freedom (the centres move along one direction, the scatter). Where the day
        pins the scatter (nine photocells) this is the timing noise's ν; where it does not
        (four photocells, two descents an item) it is a handful, and the decision's tail is
        that heavy: with the t at the interval's own degrees of freedom, equal skis were
        declared different on 16.8 % of simulated four-photocell days (issue 21)."""
        m = self.beta @ c
        phi = np.maximum(np.einsum("i,kij,j->k", c, self.scale0, c), 1e-300)
        lam = float(self.w @ (m - self.w @ m) ** 2)
        e_phi = float(self.w @ phi)
        log_phi = np.log(phi)
        var_log = float(self.w @ (log_phi - self.w @ log_phi) ** 2)
        tot = e_phi + 2.0 * lam
        den = e_phi**2 * (var_log + 2.0 / self.dof) / 2.0 + (2.0 * lam) ** 2
        return float(tot**2 / den) if den > 0 else float(self.dof)

    def draws(self, cols: list[int], n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` draws of the globals ``cols`` from the mixture (seeded by the caller)."""
        k = rng.choice(len(self.w), size=n, p=self.w)
        out = np.empty((n, len(cols)))
        for i in np.unique(k):
            sel = np.flatnonzero(k == i)
            sub = self.scale[i][np.ix_(cols, cols)]
            z = rng.multivariate_normal(np.zeros(len(cols)), sub, size=len(sel), method="eigh")
            chi = np.sqrt(rng.chisquare(self.dof, size=len(sel)) / self.dof)
            out[sel] = self.beta[i][cols][None, :] + z / chi[:, None]
        return out

    def posture_ci(self) -> tuple[float, float] | None:
        """The posture scatter's 90 % interval, where the day says enough about it."""
        posture, vcov = self.posture, self.vcov
        if vcov is None or not posture > 0 or not self.sol.lg > LOG_GAMMA[0] + 2.0:
            return None
        se = math.sqrt(max(float(np.ones(2) @ vcov @ np.ones(2)), 0.0))
        if not se < 10.0:  # the day says next to nothing about it
            return None
        return posture * math.exp(-1.645 * se / 2), posture * math.exp(1.645 * se / 2)


def _joint_fit(
    track, data, cda_fixed, model, drift, reference, timer_sd_s, bend: bool = False
) -> JointResult:
    lay = _Layout.of(data, cda_fixed, model, drift, reference, bend)
    day = _DayModel(track, data, lay, cda_fixed)
    sol = _solve(day)
    inf = _Inference(sol, lay.dof)
    glob = sol.glob

    cda_out: dict[str, Estimate] = {}
    for g_i, g in enumerate(lay.groups):
        cda_out[g] = Estimate(cda_fixed) if cda_fixed is not None else Estimate(
            float(glob[g_i]), inf.plugin_interval(g_i), float(inf.plugin_sd[g_i])
        )  # fmt: skip
    drift_out, apart, warnings = _drift(data, lay, inf)
    separable = all(apart.values())
    gravities = sorted({d.gravity_ms2 for d in data})
    if gravities[-1] - gravities[0] > 1e-6:
        warnings.append(
            f"the descents were fitted with different gravity ({gravities[0]:.5f} to "
            f"{gravities[-1]:.5f} m/s²): each is used with its own; were they on one site?"
        )
    typical_v0 = float(np.median(sol.loc[:, 1]))
    run_time = _run_time(track, day, data, cda_out, typical_v0)
    centre = inf.centre  # μ, μ1, drift and Δμ: the centres of their own intervals (_Inference)
    mus = {it: float(centre[lay.mu_index(it)]) for it in lay.items}
    comparisons = _comparisons(lay, inf, mus, {it: run_time(mus[it]) for it in lay.items})
    p_best = _p_best(lay, inf)
    out_items = []
    for it in lay.items:
        j = lay.mu_index(it)
        velocity = lay.per_item == 2
        out_items.append(
            ItemResult(
                item=it,
                descents=tuple(d.number for d in data if d.item == it),
                mu=mus[it],
                ci90=inf.interval(j),
                stderr=float(inf.sd[j]),
                mu1=float(centre[j + 1]) if velocity else None,
                mu1_ci90=inf.interval(j + 1) if velocity else None,
                p_best=p_best.get(it),
            )
        )
    status, message, chi2_p = _status(data, sol, inf, timer_sd_s)
    comparisons = [_with_caveat(c, apart, status) for c in comparisons]
    base = day.base_cda(glob)
    loc = sol.loc
    effects = tuple(
        DescentEffect(
            d.number, float(base[k] * math.exp(loc[k, 0])), float(loc[k, 1]), float(loc[k, 2])
        )  # fmt: skip
        for k, d in enumerate(data)
    )
    return JointResult(
        items=tuple(out_items),
        cda=cda_out,
        drift_per_hour=drift_out,
        drift_bend=(
            (float(centre[lay.i_drift + 1]), inf.interval(lay.i_drift + 1)) if lay.bend else None
        ),
        drift_separable=separable,
        comparisons=tuple(comparisons),
        ranking=tuple(it.item for it in sorted(out_items, key=lambda i: i.mu)),
        reference=lay.ref,
        dof=lay.dof,
        sigma_s=math.sqrt(inf.sigma2),
        typical_v0=typical_v0,
        posture_sd=inf.posture,
        posture_ci90=inf.posture_ci(),
        timer_sd_s=timer_sd_s,
        chi2_p=chi2_p,
        descents=effects,
        warnings=tuple(warnings),
        status=status,
        message=message,
        item_cov=_item_cov(lay, inf),
        gravity_ms2=float(np.median([d.gravity_ms2 for d in data])),
    )


def _item_cov(lay: _Layout, inf: _Inference) -> tuple[tuple[float, ...], ...]:
    cols = [lay.mu_index(it) for it in lay.items]
    sub = inf.cov[np.ix_(cols, cols)]
    return tuple(tuple(float(x) for x in row) for row in sub)


def _drift(data, lay: _Layout, inf: _Inference):
    """The drift of μ per hour with its interval (None: not fitted), whether the run order
    separates it from each comparable pair's difference (pair -> bool), and the warnings
    about the design of the day.

    Per pair, not per day: an item skied once, last, has a μ that the drift and its one
    descent explain alike, yet A and B skied ABBA before it are told from the drift as well
    as ever. A pair is not separable when its items do not overlap in time (AAABBB) or its
    Δμ correlates with the drift beyond 0.9."""
    items, glob, cov, sd = lay.items, inf.centre, inf.cov, inf.sd
    warnings: list[str] = []
    drift_out = None
    i_drift = lay.i_drift
    comparable = [it for it in items if lay.counts[it] >= 2]
    apart = {pair: True for pair in combinations(comparable, 2)}
    if lay.use_drift:
        drift_out = (float(glob[i_drift]), inf.interval(i_drift))
        spans = {it: [d.start_hours for d in data if d.item == it] for it in comparable}
        for ia, ib in apart:
            c = np.zeros(len(glob))
            c[lay.mu_index(ia)], c[lay.mu_index(ib)] = 1.0, -1.0
            sd_c = math.sqrt(max(float(c @ cov @ c), 0.0))
            corr = float(c @ cov[:, i_drift]) / (sd_c * sd[i_drift]) if sd_c > 0 and sd[
                i_drift] > 0 else 1.0  # fmt: skip
            disjoint = max(spans[ia]) < min(spans[ib]) or max(spans[ib]) < min(spans[ia])
            apart[(ia, ib)] = bool(not disjoint and abs(corr) <= 0.9)
        tangled = [f"{a} and {b}" for (a, b), ok in apart.items() if not ok]
        if tangled:
            warnings.append(
                f"the run order cannot separate drift from item for {'; '.join(tangled)} (e.g. "
                "all of one item before the other): the difference between the items and the "
                "drift explain the times equally well; interleave the items (ABBA) and repeat "
                "the reference through the day"
            )
    elif len(items) >= 2 and lay.drift != "off":
        warnings.append(
            f"no drift estimated: the reference item {lay.ref!r} does not recur; a change of the "
            "snow during the session would show as a difference between items"
        )
    single = [it for it in items if lay.counts[it] < 2]
    if single:
        each, it = ("", "it") if len(single) == 1 else (" each", "them")
        warnings.append(
            f"{', '.join(single)}: one descent{each}, so no comparison is possible for {it}: "
            "one descent's glide cannot be told from that descent's posture; ski every item at "
            "least twice (ABBA)"
        )
    return drift_out, apart, warnings


def _with_caveat(
    c: Comparison, apart: dict[tuple[str, str], bool], status: ComparisonStatus
) -> Comparison:
    """The comparison with its per-pair separability and why a decision on it is not to be
    trusted (poor or unconverged fit, drift not separable), for the sequential decision."""
    if c.ci90 is None:
        return c
    ok = apart.get((c.a, c.b), apart.get((c.b, c.a), True))
    why = []
    if status == ComparisonStatus.POOR_FIT:
        why.append("the joint fit is a poor fit (its intervals are not to be trusted)")
    elif status == ComparisonStatus.NOT_CONVERGED:
        why.append("the joint fit did not converge")
    if not ok:
        why.append(f"the drift is not separable from {c.a} vs {c.b} (interleave them, ABBA)")
    return replace(c, drift_separable=ok, caveat="; ".join(why))


def _run_time(track: Track, day: _DayModel, data, cda_out: dict[str, Estimate], v0: float):
    """What a μ means in time over the whole run, for the day's typical skier, air and v0."""
    full_ids = tuple(track.photocell_ids)
    run_full = (
        day.runs[full_ids][0]
        if full_ids in day.runs
        else StraightRun(track.profile, np.array([pc.x for pc in track.photocells]))
    )
    mass = float(np.median([d.mass_kg for d in data]))
    rho = float(np.median([d.air_density for d in data]))
    grav = float(np.median([d.gravity_ms2 for d in data]))
    cda_typ = float(np.median([e.value for e in cda_out.values() if e.value is not None]))

    def run_time(mu: float) -> float:
        sol = run_full.solve(
            Params(cda_typ, mu, v0), Conditions(mass, rho, g=grav), sensitivities=False
        )
        return float(sol.t[-1])

    return run_time


def _comparisons(lay: _Layout, inf: _Inference, mus: dict[str, float], run_times):
    """Every pair of items, the reference first: Δμ with its interval, P(a faster) and Δt
    over the run (and the degrees of freedom of the Student t that interval is equivalent to,
    :meth:`_Inference.equivalent_dof`)."""
    glob, counts, ref = inf.centre, lay.counts, lay.ref
    comparisons = []
    order = [ref] + [it for it in lay.items if it != ref] if ref else lay.items
    for ia, ib in combinations(order, 2):
        ja, jb = lay.mu_index(ia), lay.mu_index(ib)
        delta = float(glob[ja] - glob[jb])
        dts = run_times[ia] - run_times[ib]
        few = [x for x in (ia, ib) if counts[x] < 2]
        if few:
            note = (
                f"no comparison possible: {' and '.join(few)} "
                f"{'has' if len(few) == 1 else 'have'} one descent"
            )
            comparisons.append(Comparison(ia, ib, delta, None, None, dts, None, note))
            continue
        c = np.zeros(lay.n_glob)
        c[ja], c[jb] = 1.0, -1.0
        ci = inf.interval_of(c)
        nu = inf.equivalent_dof(c, ci)
        prob = inf.cdf(c, 0.0)
        comparisons.append(Comparison(ia, ib, delta, ci, prob, dts, nu))
    return comparisons


def _p_best(lay: _Layout, inf: _Inference) -> dict[str, float]:
    """P(this item has the lowest μ) of the items skied at least twice, by simulation from the
    day's distribution of their μ (:class:`_Inference`: the scatter's uncertainty in it, as in
    the Δμ intervals; seeded: the same day gives the same numbers)."""
    comparable = [ii for ii, it in enumerate(lay.items) if lay.counts[it] >= 2]
    out: dict[str, float] = {}
    if len(comparable) >= 2:
        cols = [lay.i_mu + ii * lay.per_item for ii in comparable]
        best = np.argmin(inf.draws(cols, 20000, np.random.default_rng(0)), axis=1)
        for n, ii in enumerate(comparable):
            out[lay.items[ii]] = float(np.mean(best == n))
    elif len(comparable) == 1 and len(lay.items) == 1:
        out[lay.items[comparable[0]]] = 1.0
    return out


def _status(data, sol: _Solution, inf: _Inference, timer_sd_s: float):
    """The day's verdict and why, and the χ² p of its residuals against the timer."""
    dof = inf.dof
    chi2_stat = inf.prss / timer_sd_s**2
    chi2_p = float(chdtrc(dof, chi2_stat))
    stopped = sol.stopped
    if not sol.converged_outer or not sol.converged or stopped.any():
        where = ""
        if stopped.any():
            which = ", ".join(str(data[k].number) for k in np.arange(len(data))[stopped])
            where = f" (descents {which} stop before the last photocell)"
        why = f"the joint fit did not reach a verified minimum{where}: the numbers are not a "
        return ComparisonStatus.NOT_CONVERGED, why + "least-squares solution", chi2_p
    if chi2_p < POOR_FIT_P:
        sigma_ms = math.sqrt(inf.sigma2) * 1e3
        why = (
            f"the timing residual {sigma_ms:.2f} ms is more than the timer's precision "
            f"{timer_sd_s * 1e3:.2f} ms explains (χ² {chi2_stat:.0f} on {dof} dof, "
            f"p = {chi2_p:.1e}): the model does not describe these descents (wind, edging, a "
            "photocell or survey error, a wrong item); the intervals are not to be trusted"
        )
        return ComparisonStatus.POOR_FIT, why, chi2_p
    return ComparisonStatus.OK, "", chi2_p


def _count(n: int, word: str) -> str:
    """``1 item``, ``2 items`` (as station.report.text.count, which the model does not import)."""
    return f"{n} {word}{'s' * (n != 1)}"


def chi2_p_words(p: float) -> str:
    """``p = 0.36``, or ``p > 0.99`` / ``p < 0.001`` at the ends: two significant figures
    round 0.996 up to "p = 1", which reads as a certainty no test gives."""
    if p > 0.99:
        return "p > 0.99"
    if p < 1e-3:
        return "p < 0.001"
    return f"p = {p:.2g}"


def posture_words(res: JointResult) -> str:
    """The posture scatter as the text, the report and the UI say it: "1.08 % [0.69, 1.68] %",
    or "0.00 % (none seen beyond the timing noise)" when no interval and below 0.1 %."""
    words = f"{res.posture_sd * 100:.2f} %"
    if res.posture_ci90:
        return words + f" [{res.posture_ci90[0] * 100:.2f}, {res.posture_ci90[1] * 100:.2f}] %"
    if res.posture_sd < 1e-3:
        return words + " (none seen beyond the timing noise)"
    return words


def format_comparison(res: JointResult, n_desc: int) -> str:
    """The comparison as the terminal shows it (CLI and UI)."""
    verdict = {
        ComparisonStatus.OK: "ok",
        ComparisonStatus.POOR_FIT: "POOR FIT",
        ComparisonStatus.NOT_CONVERGED: "NOT CONVERGED",
    }
    lines = [
        f"joint fit of {_count(n_desc, 'descent')}, {_count(len(res.items), 'item')}, "
        f"{res.dof} dof, timing "
        f"residual {res.sigma_s * 1000:.2f} ms against a timer of {res.timer_sd_s * 1000:.2f} ms"
        + (f" (χ² {chi2_p_words(res.chi2_p)})" if res.chi2_p is not None else "")
        + f": {verdict[res.status]}"
    ]
    if res.message:
        lines.append(f"  {res.message}")
    for g, est in res.cda.items():
        c = est.ci90
        rng = f"[{c[0]:.4f}, {c[1]:.4f}]" if c else "(fixed)"
        lines.append(f"  CdA {g}: {est.value:.4f} m² {rng} (mean over the skier's descents)")
    lines.append(f"  posture scatter (CdA between descents of a skier): {posture_words(res)}")
    if res.drift_per_hour:
        d, (lo, hi) = res.drift_per_hour
        sep = "" if res.drift_separable else "  NOT SEPARABLE FROM ITEM"
        lines.append(f"  drift of μ: {d:+.5f} per hour [{lo:+.5f}, {hi:+.5f}]{sep}")
        if res.drift_bend:
            b, (blo, bhi) = res.drift_bend
            lines.append(f"  bending by {b:+.5f} per hour² [{blo:+.5f}, {bhi:+.5f}]")
    lines.append("")
    # the item column as wide as the names (at most the 28 of long names): the table fits an
    # 80-column terminal and the UI's comparison dialog with the names people use
    w = min(28, max([6, *(len(i.item) + 2 for i in res.items)]))
    lines.append(f"{'rank':<5}{'item':<{w}}{'descents':>9}{'μ':>10}   90 % CI{'':<14}P(best)")
    for k, name in enumerate(res.ranking, start=1):
        it = res.item(name)
        pb = f"{it.p_best:.3f}" if it.p_best is not None else "—"
        ci = f"[{it.ci90[0]:.5f}, {it.ci90[1]:.5f}]"
        lines.append(f"{k:<5}{it.item:<{w}}{len(it.descents):>9}{it.mu:>10.5f}   {ci:<21}{pb}")
        if it.mu1 is not None and it.mu1_ci90 is not None:
            flag = "  (not distinguishable from 0)" if it.mu1_ci90[0] <= 0 <= it.mu1_ci90[1] else ""
            lines.append(f"{'':<5}  μ1 {it.mu1:.2e} s/m [{it.mu1_ci90[0]:.2e}, "
                         f"{it.mu1_ci90[1]:.2e}]{flag}")  # fmt: skip
    lines.append("")
    for c in res.comparisons:
        if c.ci90 is None or c.p_a_faster is None:
            lines.append(f"{c.a} − {c.b}: {c.note}")
            continue
        lines.append(
            f"{c.a} − {c.b}: Δμ {c.delta_mu:+.5f} [{c.ci90[0]:+.5f}, {c.ci90[1]:+.5f}], "
            f"P({c.a} faster) = {c.p_a_faster:.3f}, "
            f"{c.delta_t_s * 1000:+.1f} ms over the run at v0 {res.typical_v0:.1f} m/s"
        )
    for n, why in res.excluded:
        lines.append(f"  descent {n} left out: {why}")
    return "\n".join(lines)


def item_of(row: Any) -> str:
    """The test item of a descent: ski (or pair id) and wax, as the engineer entered them
    (``row`` is a :class:`station.session.records.ResultRow`)."""
    return item_name(row.ski, row.wax)


def item_name(ski: str | None, wax: str | None) -> str:
    """A test item's name from its ski (or pair id) and wax."""
    ski = str(ski or "").strip()
    wax = str(wax or "").strip()
    if ski and wax:
        return f"{ski} / {wax}"
    return ski or wax or "(no item)"


#: the fit statuses of a descent that enters a day's comparison (:func:`collect`). One rule:
#: the season store's query of the items a day fit could take (station.store.queries) reads
#: it and :data:`DAY_FIT_MIN_PHOTOCELLS`, so the items `station season compare` names as left
#: out are those the day fit left out, not a copy of its rule that could drift from it
DAY_FIT_STATUSES: tuple[str, ...] = ("ok", "ill-conditioned")
#: the fewest photocells of a descent that enters a day's comparison (two intervals)
DAY_FIT_MIN_PHOTOCELLS = 3


def collect(results: Iterable[Any], wind_limit_ms: float = 1.0) -> DayInputs:
    """The descents that enter the comparison, those left out (with why) and those flagged for
    wind, from a day's results (:class:`station.session.analysis.DescentResult`, in order)."""
    data: list[DescentData] = []
    excluded: list[tuple[int, str]] = []
    windy: list[int] = []
    for res in results:
        # the fit's values are the row's: a fit kept in the session's store is not read back
        row, d = res.row, res.descent
        n = row.descent
        if row.invalid_reason:
            excluded.append((n, f"marked invalid: {row.invalid_reason}"))
            continue
        if not res.has_fit:
            why = "; ".join(row.flags[-1:]) if row.status == "error" else ""
            excluded.append((n, f"{row.status}: {why}" if why else str(row.status)))
            continue
        if row.status not in DAY_FIT_STATUSES:
            excluded.append((n, str(row.status)))
            continue
        if len(d.photocells) < DAY_FIT_MIN_PHOTOCELLS:
            excluded.append((n, f"fewer than {DAY_FIT_MIN_PHOTOCELLS} photocells"))
            continue
        wind = float(row.wind_ms or 0.0)
        if abs(wind) > wind_limit_ms:
            windy.append(n)
        guess = (row.cda or 0.25, row.mu or 0.02, row.v0 or 3.0)
        data.append(
            DescentData(
                number=n,
                item=item_of(row),
                group=str(row.skier or "skier"),
                photocells=tuple(d.photocells),
                times_s=(np.array(d.times_us) - d.times_us[0]) / 1e6,
                start_hours=d.times_us[0] / US_PER_HOUR,
                mass_kg=float(row.mass_kg),
                air_density=float(row.air_density),
                wind_ms=wind,
                start_guess=(float(guess[0]), float(guess[1]), float(guess[2])),
                timer_sd_s=res.fit_timer_precision_s or TIMER_PRECISION_S,
                gravity_ms2=float(row.gravity) if row.gravity else G_STANDARD,
            )
        )
    return DayInputs(data, excluded, windy)
