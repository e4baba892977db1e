"""The day's comparison of its items (skis, waxes): the one glue between a day's results and the
joint fit of :mod:`station.model.compare`, for ``station compare``, ``station report`` and the
UI's comparison view.

It was written three times (the compare command, the report, the acquisition loop), each
choosing the descents, fitting them and noting the ones left out and those with wind its own
way; one function keeps the three answers the same.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

from station.model.compare import (
    CompareError,
    DescentData,
    JointResult,
    collect,
    joint_fit,
)
from station.session.analysis import DescentResult
from station.survey.track import Track

#: along-track wind (m/s) above which a compared descent is flagged
WIND_LIMIT_MS = 1.0


@dataclass(frozen=True)
class DayComparison:
    """A day's comparison: the descents compared, and the joint fit or why there is none."""

    compared: list[DescentData] = field(default_factory=list)
    result: JointResult | None = None
    #: why there is no result (the joint fit's own words); "" when there is one
    error: str = ""


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
) -> DayComparison:
    """The joint fit of the valid descents among ``results`` (marked invalid, failed fits and
    descents with fewer than three photocells are left out and listed in the result), with a
    warning naming the descents that had more along-track wind than ``wind_limit_ms``."""
    data, excluded, windy = collect(results, wind_limit_ms)
    try:
        res = joint_fit(
            track, data, cda_fixed=cda_fixed, model=model, drift=drift,
            reference=reference, timer_sd_s=timer_sd_s, excluded=excluded,
            wind_flagged=windy, wind_limit_ms=wind_limit_ms,
        )  # fmt: skip
    except CompareError as exc:
        return DayComparison(data, None, str(exc))
    return DayComparison(data, res)
