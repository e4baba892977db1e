"""The day's result from the solved day model: the items' μ, the comparisons of every pair,
the drift, P(best) and the verdict, assembled into one :class:`JointResult` (:func:`fit_day`)."""

from __future__ import annotations

import math
from dataclasses import replace
from itertools import combinations

import numpy as np
from scipy.special import chdtrc  # χ² survival (no scipy.stats)

from station.model.compare_inference import Inference
from station.model.compare_layout import DayModel, Layout
from station.model.compare_reml import Solution, solve
from station.model.compare_types import (
    Comparison,
    ComparisonStatus,
    DescentEffect,
    ItemResult,
    JointResult,
)
from station.model.estimate import Estimate
from station.model.physics import Conditions, Params, StraightRun
from station.model.timer import POOR_FIT_P
from station.survey.track import Track


def fit_day(
    track, data, cda_fixed, model, drift, reference, timer_sd_s, bend: bool = False
) -> JointResult:
    lay = Layout.of(data, cda_fixed, model, drift, reference, bend)
    day = DayModel(track, data, lay, cda_fixed)
    sol = solve(day)
    inf = Inference(sol, lay.dof)
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
    centre = inf.centre  # μ, μ1, drift and Δμ: the centres of their own intervals (Inference)
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


def _item_cov(lay: Layout, inf: Inference) -> tuple[tuple[float, ...], ...]:
    cols = [lay.mu_index(it) for it in lay.items]
    sub = inf.cov[np.ix_(cols, cols)]
    return tuple(tuple(float(x) for x in row) for row in sub)


def _drift(data, lay: Layout, inf: Inference):
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


def _run_time(track: Track, day: DayModel, data, cda_out: dict[str, Estimate], v0: float):
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


def _comparisons(lay: Layout, inf: Inference, mus: dict[str, float], run_times):
    """Every pair of items, the reference first: Δμ with its interval, P(a faster) and Δt
    over the run (and the degrees of freedom of the Student t that interval is equivalent to,
    :meth:`Inference.equivalent_dof`)."""
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


def _p_best(lay: Layout, inf: Inference) -> dict[str, float]:
    """P(this item has the lowest μ) of the items skied at least twice, by simulation from the
    day's distribution of their μ (:class:`Inference`: the scatter's uncertainty in it, as in
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


def _status(data, sol: Solution, inf: Inference, timer_sd_s: float):
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
