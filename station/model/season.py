"""Items compared across the days of a season: the second stage of a two-stage network
meta-analysis of the test days.

Stage one is each day's own joint fit (:mod:`station.model.compare`): its items' μ with their
covariance, the day's posture scatter and timing noise already in it. The absolute μ of a day
moves with its snow by far more than the items differ (0.005–0.02 against 0.001), so only
contrasts *within* a day carry information about the items: each day enters as the differences
of its items from its first item, with their covariance C·S_d·Cᵀ. Items that never met on one day
are compared through the items they met (a network, as treatments in a network meta-analysis
or players in paired comparisons).

Stage two, the model across days: for item i on day d,

    μ_di = α_d + θ_i + Σ_c β_ic·(x_dc − x*_c) + b_di + e_di,

α_d the day's level (removed by the contrasts), θ_i the item's effect against the reference at
the conditions x* asked for (``--at``), β_ic its slope in condition c (only with ``--at``, and
only for an item tested at two values of c or more), e_d ~ N(0, S_d) the day's own uncertainty,
and b_di ~ N(0, τ²/2) the heterogeneity: an item is not equally good on every day, beyond the
conditions given, so that a contrast between two items varies from day to day with variance τ².
τ² is estimated by restricted maximum likelihood (REML, as in metafor, mvmeta and netmeta):
maximum likelihood would count the fixed effects as information about τ² and shrink it. τ² is in
every interval: with τ² > 0 an interval that ignored it would be too narrow however many days
there are. Intervals are Knapp–Hartung's: the covariance (XᵀV⁻¹X)⁻¹ at τ̂² scaled by the
weighted residual sum over its degrees of freedom, rᵀV⁻¹r / (N − p), with Student's t on N − p
degrees of freedom (N contrasts, p fixed effects). It carries the uncertainty of τ̂² itself:
plain REML intervals held the truth 92–93 % of the time on seasons without heterogeneity (τ̂ is
never below 0, so it widens them there) and those with it near 90 %; the simulated seasons of
benchmarks/season_coverage.py check it (90 % intervals hold the truth 88–92 % of the time).

Why two stages and not one model of all descents: the day fit is already a mixed model with its
own posture random effect and REML; a one-stage model of every time of a season would refit all
of it for each question (``--by``, ``--where``, ``--at``), while stage two works on a handful of
numbers per day and answers in milliseconds. With a day's items estimated from tens of times
each, the two approaches agree closely (the within-day estimates are near normal).

An item is not ranked where it was never tested: evaluated at a condition outside the range of
its days (beyond a tenth of the season's range), its P(best) is not given and a warning says so.
Pure: numbers in, numbers out.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

#: how far beyond an item's tested range a condition may lie and still count as "near" it,
#: as a fraction of the season's range of that condition
NEAR_FRACTION = 0.1
#: … and at least this much in the condition's unit (°C, mm, %)
NEAR_MIN = 1.0
_P_BEST_DRAWS = 20000


@dataclass(frozen=True)
class DayEffects:
    """One day's items: μ, covariance and descents per item, and its conditions."""

    day: str
    items: tuple[str, ...]
    mu: np.ndarray  # (k,)
    cov: np.ndarray  # (k, k)
    descents: tuple[int, ...]  # per item
    conditions: Mapping[str, float] = field(default_factory=dict)


@dataclass
class SeasonItem:
    item: str
    delta_mu: float | None  # μ_item − μ_reference at the conditions asked for
    ci90: tuple[float, float] | None
    stderr: float | None
    p_faster: float | None  # P(μ_item < μ_reference)
    p_best: float | None  # P(lowest μ of the items ranked); None: not ranked there
    days: int
    descents: int
    tested: dict[str, tuple[float, float]] = field(default_factory=dict)
    slopes: dict[str, tuple[float, tuple[float, float]]] = field(default_factory=dict)
    note: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {
            "item": self.item,
            "delta_mu": self.delta_mu,
            "ci90": list(self.ci90) if self.ci90 else None,
            "p_faster": self.p_faster,
            "p_best": self.p_best,
            "days": self.days,
            "descents": self.descents,
            "stderr": self.stderr,
            "tested": {k: list(v) for k, v in self.tested.items()},
            "slopes": {k: {"per_unit": s, "ci90": list(c)} for k, (s, c) in self.slopes.items()},
            "note": self.note,
        }


@dataclass
class SeasonResult:
    reference: str
    at: dict[str, float]
    items: list[SeasonItem]
    tau: float  # between-day SD of a contrast beyond the conditions given (heterogeneity)
    q: float  # Cochran's generalised Q at τ = 0
    dof: int  # N contrasts − p fixed effects
    q_p: float | None
    days: int  # the days compared against the reference (connected to it, with the --at)
    descents: int
    warnings: list[str] = field(default_factory=list)
    #: every day with two items or more and its descents: what the items listed count, the
    #: unconnected ones too (a header of the compared days alone did not add up to the table)
    listed_days: int = 0
    listed_descents: int = 0

    def counts(self) -> str:
        """'3 days, 12 descents listed, 2 days, 8 descents compared': the days the items
        listed count, and those compared against the reference when that is fewer."""

        def text(days: int, descents: int) -> str:
            return f"{days} day{'s' * (days != 1)}, {descents} descents"

        if (self.listed_days, self.listed_descents) in ((0, 0), (self.days, self.descents)):
            return text(self.days, self.descents)
        return (
            f"{text(self.listed_days, self.listed_descents)} listed, "
            f"{text(self.days, self.descents)} compared"
        )

    def ranked(self) -> list[SeasonItem]:
        """The items from the lowest μ against the reference up (a name breaks a tie), those
        without a comparison last."""
        return sorted(self.items, key=lambda i: (i.delta_mu is None, i.delta_mu or 0.0, i.item))

    def heterogeneity(self) -> dict[str, Any]:
        return {"tau": self.tau, "q": self.q, "dof": self.dof, "p": self.q_p}


class SeasonError(ValueError):
    """Nothing to compare (no day with two items, an unknown reference)."""


def _components(days: Sequence[DayEffects]) -> dict[str, int]:
    """Each item's connected component in the network of days (union-find)."""
    parent: dict[str, str] = {}

    def find(x: str) -> str:
        while parent.setdefault(x, x) != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for d in days:
        for it in d.items:
            find(it)
        for it in d.items[1:]:
            parent[find(it)] = find(d.items[0])
    roots: dict[str, int] = {}
    return {it: roots.setdefault(find(it), len(roots)) for it in parent}


@dataclass(frozen=True)
class SeasonDays:
    """The days a season comparison may join (each with two items or more), the days left out
    with why, and every day's conditions by its name (for the report's pictures)."""

    days: list[DayEffects]
    left_out: list[str]
    conditions: dict[str, dict[str, Any]]

    def item_names(self) -> list[str]:
        """The items of the days, sorted (for matching a reference given by its beginning)."""
        return sorted({it for d in self.days for it in d.items})

    def compare(self, reference: str | None, at: Mapping[str, float]) -> SeasonComparison:
        """:func:`compare_season` of these days, the days left out first among its warnings."""
        res = compare_season(self.days, reference, at)
        said = [f"left out: {x}" for x in self.left_out]
        return SeasonComparison(replace(res, warnings=[*said, *res.warnings]), self)


@dataclass(frozen=True)
class SeasonComparison:
    """What ``season compare`` and ``season report`` show: the comparison and its days."""

    result: SeasonResult
    selected: SeasonDays


@dataclass
class _Network:
    """The days connected to the reference, and what every item was seen in."""

    days: list[DayEffects]
    reference: str
    all_items: list[str]  # most days first
    linked: list[str]  # connected to the reference
    apart: list[str]
    count_days: dict[str, int]
    count_desc: dict[str, int]
    warnings: list[str]


def _network(days: list[DayEffects], reference: str | None) -> _Network:
    """The reference (the item on most days, unless given) and the days connected to it."""
    count_days: dict[str, int] = {}
    count_desc: dict[str, int] = {}
    for d in days:
        for it, n in zip(d.items, d.descents, strict=True):
            count_days[it] = count_days.get(it, 0) + 1
            count_desc[it] = count_desc.get(it, 0) + n
    all_items = sorted(count_days, key=lambda it: (-count_days[it], it))
    if reference is None:
        reference = all_items[0]
    elif reference not in count_days:
        raise SeasonError(
            f"reference {reference!r} is on no day with another item "
            f"(items: {', '.join(all_items)})"
        )
    comp = _components(days)
    linked = [it for it in all_items if comp[it] == comp[reference]]
    apart = [it for it in all_items if comp[it] != comp[reference]]
    warnings: list[str] = []
    if apart:
        warnings.append(
            f"{', '.join(apart)}: not connected to {reference} (never met it, nor an item that "
            "met it, on any day): no comparison across that gap"
        )
    days = [d for d in days if comp[d.items[0]] == comp[reference]]
    return _Network(days, reference, all_items, linked, apart, count_days, count_desc, warnings)


def _with_conditions(
    days: list[DayEffects], at: Mapping[str, float], warnings: list[str]
) -> list[DayEffects]:
    """The days that have every condition of ``at``; those without are named in a warning."""
    left_out: list[str] = []
    for c in at:
        missing = [d.day for d in days if not math.isfinite(d.conditions.get(c, math.nan))]
        if missing:
            left_out.append(
                f"{len(missing)} day(s) without {c} left out of the comparison at {c}="
                f"{at[c]:g}: {', '.join(missing[:5])}{' …' if len(missing) > 5 else ''}"
            )
            days = [d for d in days if d.day not in missing]
    warnings.extend(left_out)
    if not days:
        # say which condition emptied the comparison: the warnings above die with the error
        raise SeasonError("no day left with the conditions asked for (" + "; ".join(left_out)
                          + ")")  # fmt: skip
    return days


def _slopes(
    days: list[DayEffects],
    net: _Network,
    tested: dict[str, dict[str, tuple[float, float]]],
    at: Mapping[str, float],
) -> tuple[list[str], list[tuple[str, str]]]:
    """The items with an effect of their own, and the (item, condition) pairs with a slope:
    an item tested at two values of a condition or more, while the days' differences can
    carry them."""
    conds = list(at)
    slope_of: list[tuple[str, str]] = []  # (item, condition) with a slope column
    for c in conds:
        for it in net.linked:
            if it == net.reference or c not in tested[it]:
                continue
            lo, hi = tested[it][c]
            if hi > lo:
                slope_of.append((it, c))
            else:
                net.warnings.append(
                    f"{it} was tested at one {c} only ({lo:g}): its effect is taken as the "
                    f"same at {at[c]:g}"
                )
    others = [it for it in net.linked if it != net.reference and any(it in d.items for d in days)]
    n_contrasts = sum(len(d.items) - 1 for d in days)
    if slope_of and n_contrasts <= len(others) + len(slope_of):
        net.warnings.append(
            f"{n_contrasts} within-day differences cannot carry {len(others)} effects and "
            f"{len(slope_of)} slopes: the effects are taken as the same at every "
            f"{', '.join(conds)} (more days, or no --at)"
        )
        slope_of = []
    return others, slope_of


@dataclass(frozen=True)
class _Stacks:
    """The days' contrasts against their first item, stacked by the number of items: each
    evaluation of the likelihood is a few batched solves."""

    groups: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]  # z, X, S, H
    n_obs: int
    p: int  # fixed effects
    scale: float  # a typical SD of a contrast
    spread: float  # the SD of all contrasts

    @classmethod
    def of(
        cls,
        days: list[DayEffects],
        col: dict[str, int],
        scol: dict[tuple[str, str], int],
        at: Mapping[str, float],
    ) -> _Stacks:
        p = len(col) + len(scol)
        z_all, x_all, s_all, h_all = [], [], [], []
        for d in days:
            k = len(d.items)
            cmat = np.hstack([-np.ones((k - 1, 1)), np.eye(k - 1)])
            z = cmat @ d.mu
            rows = np.zeros((k, p))
            for j, it in enumerate(d.items):
                if it in col:
                    rows[j, col[it]] = 1.0
                for c in at:
                    if (it, c) in scol:
                        rows[j, scol[(it, c)]] = d.conditions[c] - at[c]
            z_all.append(z)
            x_all.append(cmat @ rows)
            s_all.append(cmat @ d.cov @ cmat.T)
            h_all.append(0.5 * cmat @ cmat.T)
        n_obs = sum(len(z) for z in z_all)
        if p == 0:
            raise SeasonError("nothing to compare: only the reference is on the days selected")
        by_size: dict[int, list[int]] = {}
        for i, z in enumerate(z_all):
            by_size.setdefault(len(z), []).append(i)
        groups = [
            (
                np.stack([z_all[i] for i in idx]),
                np.stack([x_all[i] for i in idx]),
                np.stack([s_all[i] for i in idx]),
                h_all[idx[0]],
            )
            for idx in by_size.values()
        ]
        scale = float(np.sqrt(np.median([np.median(np.diag(s)) for s in s_all])))
        spread = float(np.std(np.concatenate(z_all))) if n_obs > 1 else scale
        return cls(groups, n_obs, p, scale, spread)

    def fit(self, tau2: float) -> tuple[float, np.ndarray, np.ndarray, float]:
        """−2·REML log-likelihood, β̂, (XᵀV⁻¹X)⁻¹, Σ rᵀV⁻¹r at τ²."""
        p = self.p
        a = np.zeros((p, p))
        b = np.zeros(p)
        logdet = 0.0
        ws = []
        for z, x, s, h in self.groups:
            v = s + tau2 * h[None, :, :]
            w = np.linalg.inv(v)
            logdet += float(np.sum(np.linalg.slogdet(v)[1]))
            wx = w @ x  # (n, m, p)
            a += np.einsum("nmp,nmq->pq", x, wx)
            b += np.einsum("nmp,nm->p", wx, z)
            ws.append(w)
        try:
            a_inv = np.linalg.inv(a)
        except np.linalg.LinAlgError:
            return math.inf, np.zeros(p), np.full((p, p), math.nan), math.inf
        beta = a_inv @ b
        rss = 0.0
        for (z, x, _s, _h), w in zip(self.groups, ws, strict=True):
            r = z - x @ beta
            rss += float(np.einsum("nm,nmk,nk->", r, w, r))
        sign, logdet_a = np.linalg.slogdet(a)
        crit = logdet + float(logdet_a) + rss if sign > 0 else math.inf
        return crit, beta, a_inv, rss


@dataclass(frozen=True)
class _Estimate:
    """The model across days at its REML τ: effects, their Knapp–Hartung covariance."""

    tau: float
    q: float  # Cochran's generalised Q at τ = 0
    dof: int
    beta: np.ndarray
    cov: np.ndarray
    sd: np.ndarray
    nu: float  # the t distribution's degrees of freedom
    qt: float  # its 95 % quantile (a two-sided 90 % interval)


def _estimate(stacks: _Stacks) -> _Estimate:
    """τ by REML (bounded search), then the effects and their scaled covariance."""
    from scipy.optimize import minimize_scalar
    from scipy.special import stdtrit

    dof = stacks.n_obs - stacks.p
    crit0, _beta0, _a_inv0, q = stacks.fit(0.0)
    if not math.isfinite(crit0):
        raise SeasonError(
            "the days cannot separate the items' effects from their slopes at the conditions "
            "asked for: fewer --at conditions, or more days"
        )
    scale = stacks.scale
    hi = max(10.0 * stacks.spread, 10.0 * scale, 1e-12)
    tau = 0.0
    if dof > 0:
        opt = minimize_scalar(lambda t: stacks.fit(t * t)[0], bounds=(0.0, hi), method="bounded",
                              options={"xatol": 1e-4 * scale + 1e-15})  # fmt: skip
        if opt.fun < crit0:
            tau = float(opt.x)
    _crit, beta, a_inv, rss = stacks.fit(tau * tau)
    nu = float(max(dof, 1))
    qt = float(stdtrit(nu, 0.95))
    if dof > 0:  # Knapp–Hartung: the variance scaled by the weighted residuals at τ̂
        a_inv = a_inv * (rss / dof)
    sd = np.sqrt(np.maximum(np.diag(a_inv), 0.0))
    return _Estimate(tau, q, dof, beta, a_inv, sd, nu, qt)


def compare_season(
    days: Sequence[DayEffects],
    reference: str | None = None,
    at: Mapping[str, float] | None = None,
    *,
    p_best_draws: int = _P_BEST_DRAWS,
) -> SeasonResult:
    """The items' effects against ``reference`` across ``days``, at the conditions ``at``;
    P(best) from ``p_best_draws`` draws of the effects (0: not computed)."""
    from scipy.special import chdtrc

    at = dict(at or {})
    days = [d for d in days if len(d.items) >= 2]
    if not days:
        raise SeasonError("no day with two items or more to compare")
    listed_days, listed_descents = len(days), sum(sum(d.descents) for d in days)
    net = _network(days, reference)
    days = _with_conditions(net.days, at, net.warnings)
    tested: dict[str, dict[str, tuple[float, float]]] = {it: {} for it in net.linked}
    for c in at:
        for it in net.linked:
            vals = [d.conditions[c] for d in days if it in d.items]
            if vals:
                tested[it][c] = (min(vals), max(vals))
    others, slope_of = _slopes(days, net, tested, at)
    col = {it: k for k, it in enumerate(others)}
    scol = {key: len(others) + k for k, key in enumerate(slope_of)}
    est = _estimate(_Stacks.of(days, col, scol, at))
    out = _items(net, est, tested, col, scol, at)
    _rank(out, days, net, est, col, at, p_best_draws)
    return SeasonResult(
        reference=net.reference,
        at=at,
        items=out,
        tau=est.tau,
        q=est.q,
        dof=est.dof,
        q_p=float(chdtrc(est.dof, est.q)) if est.dof > 0 else None,
        days=len(days),
        descents=sum(sum(d.descents) for d in days),
        warnings=net.warnings,
        listed_days=listed_days,
        listed_descents=listed_descents,
    )


def _items(
    net: _Network,
    est: _Estimate,
    tested: dict[str, dict[str, tuple[float, float]]],
    col: dict[str, int],
    scol: dict[tuple[str, str], int],
    at: Mapping[str, float],
) -> list[SeasonItem]:
    """Every item's effect against the reference with its interval, P(faster) and slopes."""
    from scipy.special import stdtr

    beta, sd, nu, qt = est.beta, est.sd, est.nu, est.qt
    out: list[SeasonItem] = []
    for it in net.all_items:
        base = SeasonItem(it, None, None, None, None, None, net.count_days[it],
                          net.count_desc[it], tested.get(it, {}))  # fmt: skip
        if it == net.reference:
            base.delta_mu, base.ci90, base.stderr = 0.0, (0.0, 0.0), 0.0
            base.note = "reference"
        elif it in col:
            j = col[it]
            e, s = float(beta[j]), float(sd[j])
            base.delta_mu, base.ci90, base.stderr = e, (e - qt * s, e + qt * s), s
            base.p_faster = float(stdtr(nu, -e / s)) if s > 0 else float(e < 0)
            for c in at:
                if (it, c) in scol:
                    k = scol[(it, c)]
                    sl, ss = float(beta[k]), float(sd[k])
                    base.slopes[c] = (sl, (sl - qt * ss, sl + qt * ss))
        else:
            base.note = "not connected to the reference" if it in net.apart else "no day selected"
        out.append(base)
    return out


def _near(item: SeasonItem, days: list[DayEffects], at: Mapping[str, float]) -> bool:
    """Whether the item was tested near every condition of ``at`` (within a tenth of the
    season's range of it, at least :data:`NEAR_MIN`)."""
    for c in at:
        if c not in item.tested:
            return False
        season = [d.conditions[c] for d in days]
        margin = max(NEAR_FRACTION * (max(season) - min(season)), NEAR_MIN)
        lo, hi_ = item.tested[c]
        if not lo - margin <= at[c] <= hi_ + margin:
            return False
    return True


def _rank(
    out: list[SeasonItem],
    days: list[DayEffects],
    net: _Network,
    est: _Estimate,
    col: dict[str, int],
    at: Mapping[str, float],
    p_best_draws: int,
) -> None:
    """P(best) of the items tested near the conditions asked for; the others are named in a
    warning and not ranked there."""
    reference, conds = net.reference, list(at)
    ranked = [x for x in out if x.delta_mu is not None and _near(x, days, at)]
    for x in out:
        if x.delta_mu is not None and not _near(x, days, at) and conds:
            if x.item != reference:
                x.note = "not tested near " + ", ".join(f"{c}={at[c]:g}" for c in conds)
            lo_hi = "; ".join(f"{c} {a:g} to {b:g}" for c, (a, b) in x.tested.items())
            net.warnings.append(
                f"{x.item} was not tested near {', '.join(f'{c}={at[c]:g}' for c in conds)} "
                f"(its days: {lo_hi or 'none'}): not ranked there"
            )
    if len(ranked) >= 2 and p_best_draws > 0:
        idx = [col[x.item] for x in ranked if x.item != reference]
        mean = np.array([est.beta[j] for j in idx])
        cov = est.cov[np.ix_(idx, idx)]
        rng = np.random.default_rng(0)
        zs = rng.multivariate_normal(np.zeros(len(idx)), cov, size=p_best_draws, method="eigh")
        w = np.sqrt(rng.chisquare(est.nu, size=p_best_draws) / est.nu)
        draws = mean[None, :] + zs / w[:, None]
        has_ref = any(x.item == reference for x in ranked)
        if has_ref:
            draws = np.hstack([np.zeros((p_best_draws, 1)), draws])
        best = np.argmin(draws, axis=1)
        names = ([reference] if has_ref else []) + [x.item for x in ranked if x.item != reference]
        for n, name in enumerate(names):
            next(x for x in out if x.item == name).p_best = float(np.mean(best == n))
    elif len(ranked) == 1:
        ranked[0].p_best = 1.0
