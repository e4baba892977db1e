"""The day's comparison of its items (skis, waxes): the one producer of what ``station
compare``, ``station report``, ``station record``'s console and the UI's comparison show.

It chooses the descents, fits them jointly, notes the ones left out and those with wind, and
decides each pair (:mod:`station.model.sequential`); every view renders the typed
:class:`DayComparison` it returns (:mod:`station.report.comparison_text`), none computes its own.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field, replace

from station.model.compare import collect, joint_fit
from station.model.compare_types import CompareError, Comparison, DescentData, JointResult
from station.model.sequential import DEFAULT_HORIZON, Decision, day_decisions
from station.session.analysis import DescentResult
from station.survey.track import Track

#: along-track wind (m/s) above which a compared descent is flagged
WIND_LIMIT_MS = 1.0
_WORDS = {2: "two", 3: "three"}


@dataclass(frozen=True)
class DayComparison:
    """A day's comparison: the descents compared, the joint fit or why there is none, and the
    decision on each of its pairs after the latest descent."""

    compared: list[DescentData] = field(default_factory=list)
    result: JointResult | None = None
    #: why there is no result (the joint fit's own words); "" when there is one
    error: str = ""
    #: one per comparison of ``result``, in its order (none without a result)
    decisions: tuple[Decision, ...] = ()
    #: descents per item over which the decisions spend their error rate
    horizon: int = DEFAULT_HORIZON
    margin: float | None = None
    #: the number of each compared descent, in run order (kept when ``compared`` is not:
    #: :meth:`summary`)
    numbers: tuple[int, ...] = ()

    @property
    def last_descent(self) -> int:
        """The number of the latest compared descent (0: none)."""
        return self.numbers[-1] if self.numbers else 0

    def summary(self) -> DayComparison:
        """The comparison without the descents' data, as the live views need it (at 2000
        descents their times were 0.5 MB to send and 21 ms to read back, the interpreter's
        lock held against the next descent's fit)."""
        return replace(self, compared=[])

    def decision(self, comparison: Comparison) -> Decision | None:
        """The decision on one of the result's comparisons (None: not one of them)."""
        if self.result is None:
            return None
        for c, d in zip(self.result.comparisons, self.decisions, strict=True):
            if c is comparison:
                return d
        return None


def compared_items(
    results: Iterable[DescentResult], wind_limit_ms: float = WIND_LIMIT_MS
) -> list[str]:
    """The names of the items a comparison of these results would compare, sorted (for
    matching a reference given by its beginning)."""
    data, _excluded, _windy = collect(results, wind_limit_ms)
    return sorted({d.item for d in data})


def compare_results(
    track: Track,
    results: Iterable[DescentResult],
    *,
    wind_limit_ms: float = WIND_LIMIT_MS,
    reference: str | None = None,
    cda_fixed: float | None = None,
    model: str = "constant",
    drift: str = "auto",
    timer_sd_s: float | None = None,
    horizon: int = DEFAULT_HORIZON,
    margin: float | None = None,
    at_least: int = 0,
) -> DayComparison:
    """The joint fit of the valid descents among ``results`` (marked invalid, failed fits and
    descents with fewer than three photocells are left out and listed in the result), with a
    warning naming the descents that had more along-track wind than ``wind_limit_ms``, and
    the decision on every pair after the latest of them. With fewer than ``at_least``
    descents to compare there is no joint fit (the live views wait for two)."""
    data, excluded, windy = collect(results, wind_limit_ms)
    numbers = tuple(d.number for d in data)
    if len(data) < at_least:
        return DayComparison(data, None, f"it needs at least {_WORDS.get(at_least, at_least)} "
                             "fitted descents",
                             horizon=horizon, margin=margin, numbers=numbers)  # fmt: skip
    try:
        res = joint_fit(
            track, data, cda_fixed=cda_fixed, model=model, drift=drift,
            reference=reference, timer_sd_s=timer_sd_s, excluded=excluded,
            wind_flagged=windy, wind_limit_ms=wind_limit_ms,
        )  # fmt: skip
    except CompareError as exc:
        return DayComparison(data, None, str(exc), horizon=horizon, margin=margin,
                             numbers=numbers)  # fmt: skip
    run_items = [d.item for d in data]
    decisions = day_decisions(res.comparisons, run_items, horizon=horizon, margin=margin)
    return DayComparison(data, res, "", tuple(decisions), horizon, margin, numbers)
