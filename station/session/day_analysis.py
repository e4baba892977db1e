"""A test day's analysis: the one typed result every view of a recorded day renders (the day
report, ``station compare``), made by :meth:`RecordedSession.analysis
<station.session.recorded_session.RecordedSession.analysis>`."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from station.session.analysis import DescentResult
from station.session.comparison import DayComparison
from station.session.records import LineCounts, Metadata
from station.survey.track import Track


@dataclass(frozen=True)
class DayAnalysis:
    """Every descent's fit, the comparison of the items with the decision on each pair, and
    what they were computed from."""

    session: str  # the session folder, as it was named
    track: Track
    results: tuple[DescentResult, ...]  # as a replay gives them, annotations applied
    comparison: DayComparison
    #: the results CSV's header: station version, config and survey with their digests
    header: Mapping[str, str]
    line_counts: LineCounts  # what the timer sent and what became of it
    base_metadata: Metadata  # the day's metadata before any descent's own
    started: str  # local date and time the recording began
    annotations: int  # annotations entered
    config_text: str  # the session's config.yaml
    warnings: tuple[str, ...]  # the track's
