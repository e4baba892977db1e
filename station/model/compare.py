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
linearly in the number of descents; BLAS threads are capped at one (threadpoolctl) since the
dense parts are tiny and a pool of threads on a shared 2-core machine costs far more than it
saves (50 descents took 3.7 s instead of 0.19 s with the default pool).

Uncertainty. Given the scatter γ, the global parameters are Student t around their
estimate with the scale σ̂²·S⁻¹ (S the Schur complement: the fixed-effect block of the
mixed-model equations' inverse). The scatter is itself estimated, and on small days poorly (2
descents an item: at 0 on one day in ten at 0.5 % scatter), so every interval, P(a faster),
P(best) and the items' covariance come from that t integrated over γ's posterior (its REML
likelihood, a prior flat in the scatter), each scale with Kenward-Roger's correction for the
scatter being estimated (:mod:`station.model.compare_inference`). Where the day pins the scatter
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

The parts, one job each: the inputs and the result (:mod:`station.model.compare_types`), the
day's parameters and forward model (:mod:`station.model.compare_layout`), the solver
(:mod:`station.model.compare_reml`), the uncertainty (:mod:`station.model.compare_inference`),
the result assembled from them (:mod:`station.model.compare_result`) and the drift's
straightness (:mod:`station.model.compare_drift`). The result in words for people is
:mod:`station.report.comparison_text`.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import replace
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits  # type: ignore[import-untyped]

from station.model.compare_drift import (
    BEND_P,
    bend_unseen,
    bend_warning,
    drift_bend,
    unseen_bend_warning,
)
from station.model.compare_result import fit_day
from station.model.compare_types import (
    CompareError,
    DayInputs,
    DescentData,
    JointResult,
)
from station.model.physics import G_STANDARD
from station.model.timer import TIMER_PRECISION_S
from station.survey.track import Track

US_PER_HOUR = 3.6e9


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
    with threadpool_limits(limits=1, user_api="blas"):
        try:
            res = fit_day(track, data, cda_fixed, model, drift, reference, timer_sd_s, follow)
        except CompareError:  # too few times for the quadratic: the straight drift, warned
            if not follow:
                raise
            res = fit_day(track, data, cda_fixed, model, drift, reference, timer_sd_s)
    if bent is not None and bent.p < BEND_P:
        res = replace(res, warnings=(*res.warnings, bend_warning(bent, res)))
    elif bent is None and res.drift_per_hour is not None and bend_unseen(data):
        res = replace(res, warnings=(*res.warnings, unseen_bend_warning(data)))
    flagged = tuple(wind_flagged)
    warnings = res.warnings
    if flagged and wind_limit_ms is not None:
        warnings += (
            f"descents {', '.join(map(str, flagged))} had more than {wind_limit_ms:g} m/s of "
            "along-track wind: check them, or mark them invalid",
        )
    return replace(res, excluded=tuple(excluded), wind_flagged=flagged, warnings=warnings)


def day_timer_sd(data: Iterable[DescentData]) -> float:
    """The timer's precision of a day: the coarsest its descents' single fits were judged
    against (they share one timer, so all are the same unless a config changed)."""
    return max((d.timer_sd_s for d in data), default=TIMER_PRECISION_S)


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
