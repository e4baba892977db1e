"""What the day report is drawn from: the replayed day's descents as the report's own records,
its track, its comparison and where it came from."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from station.model.estimate import MISSING, Estimate

if TYPE_CHECKING:
    from station.model.compare_types import JointResult
    from station.session.comparison import DayComparison


@dataclass(frozen=True)
class DescentView:
    """What the report shows of one descent. The report reads descents only through these
    records, made in one place (:func:`descent_views`) from the replayed day, so a change in
    how the session code keeps its results touches one function here."""

    number: int
    start_time: str  # ISO 8601, as in the results CSV
    start_hours: float  # the timer's time of day at the start, hours (unwrapped)
    item: str
    status: str  # the fit's status, or the descent's when it was not fitted
    descent_status: str  # complete, incomplete, aborted
    invalid_reason: str
    notes: str
    flags: str
    photocells_used: int
    mu: Estimate
    cda: Estimate
    v0: Estimate
    residuals_ms: dict[str, float]  # photocell -> computed − measured, ms
    rms_ms: float | None
    speed_x: np.ndarray | None = None
    speed_v: np.ndarray | None = None

    @property
    def fitted(self) -> bool:
        return bool(self.residuals_ms)

    @property
    def good(self) -> bool:
        """Valid and fitted ok: drawn in its item's colour."""
        return self.status == "ok" and not self.invalid_reason


@dataclass
class DayData:
    """What the report is drawn from: the day's descents and track, its comparison, and where
    it came from."""

    session: str
    track: Any  # station.survey.track.Track
    descents: list[DescentView]
    header: dict[str, str] = field(default_factory=dict)  # what the results were computed from
    summary: str = ""  # what the timer sent
    config_metadata: dict[str, Any] = field(default_factory=dict)
    #: the day's comparison with its decisions (None: not computed)
    day_comparison: DayComparison | None = None
    config_text: str = ""
    recorded: str = ""  # local date and time the recording began
    annotations: int = 0
    warnings: list[str] = field(default_factory=list)

    @property
    def comparison(self) -> JointResult | None:
        return None if self.day_comparison is None else self.day_comparison.result

    @property
    def comparison_error(self) -> str | None:
        return None if self.day_comparison is None else self.day_comparison.error or None

    @property
    def compared(self) -> list[Any]:
        """The descents (DescentData) that entered the joint fit (none without one)."""
        dc = self.day_comparison
        return [] if dc is None or dc.result is None else dc.compared


def descent_views(results: Sequence[Any]) -> list[DescentView]:
    """The report's records of a replayed day's results
    (:class:`station.session.analysis.DescentResult`: descent times, fit, typed row, speed)."""
    from station.model.compare import item_of

    out = []
    for r in results:
        d, f, row = r.descent, r.fit, r.row
        out.append(
            DescentView(
                number=row.descent,
                start_time=str(row.start_time),
                start_hours=d.start_us / 3.6e9,  # a descent whose times were all cleared has none
                item=item_of(row),
                status=str(row.status),
                descent_status=str(row.descent_status),
                invalid_reason=row.invalid_reason or "",
                notes=row.notes,
                flags="; ".join(row.flags),
                photocells_used=row.photocells_used,
                mu=f.mu if f else MISSING,
                cda=f.cda if f else MISSING,
                v0=f.v0 if f else MISSING,
                residuals_ms={k: v * 1000 for k, v in f.residuals_s.items()} if f else {},
                rms_ms=row.rms_residual_ms,
                speed_x=r.speed_x,
                speed_v=r.speed_v,
            )
        )
    return out
