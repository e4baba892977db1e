"""A session as ``station sessions`` lists it: its status and its summary line, read from its
files without replaying it (:meth:`RecordedSession.summary
<station.session.recorded_session.RecordedSession.summary>`)."""

from __future__ import annotations

import datetime as dt
from dataclasses import asdict, dataclass
from enum import StrEnum
from typing import Any


class SessionStatus(StrEnum):
    """What ``station sessions`` says of a session as a whole (its ``status`` column)."""

    RECORDING = "recording"  # a process holds its recording lock
    FINISHED = "finished"
    INTERRUPTED = "interrupted"  # its recorder died: the results CSV may lack the last descent
    NO_RESULTS = "no results (station export SESSION --csv …)"
    UNKNOWN = "unknown (its recording.lock cannot be tried)"
    BROKEN = "broken"  # it cannot be read (the reason is in ``problem``)


@dataclass(frozen=True)
class SessionSummary:
    """One line of ``station sessions`` (:meth:`RecordedSession.summary`)."""

    path: str
    started: str  # local date and time of the first raw-log record, "" when unknown
    descents: int
    fitted: int  # descents with status ok
    invalid: int  # marked invalid by the engineer
    items: tuple[str, ...]
    status: SessionStatus
    problem: str = ""  # why a broken session cannot be read; "" for the others
    #: when ``station import`` made it (its raw log's first record), "" for a recorded one:
    #: ``started`` is then its first descent's start, the test day, not the day of the import
    imported: str = ""

    @classmethod
    def broken(cls, path: str, why: str) -> SessionSummary:
        """The line of a session that cannot be read, saying why."""
        return cls(path, "", 0, 0, 0, (), SessionStatus.BROKEN, why)

    def to_json(self) -> dict[str, Any]:
        out = asdict(self) | {"items": list(self.items)}
        if not self.problem:
            del out["problem"]  # the listing of a readable session is as it was
        if not self.imported:
            del out["imported"]
        return out


def minute_of(iso: str) -> str:
    """'2026-01-12 10:00' of a results CSV's start time (ISO 8601 local), "" if it is none."""
    try:
        return dt.datetime.fromisoformat(iso).strftime("%Y-%m-%d %H:%M")
    except (TypeError, ValueError):
        return ""
