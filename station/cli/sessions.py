"""``station sessions [DIR]``: the recorded test days in a folder (default ``./sessions``), with
their date, descents, test items and status, read from each session's results CSV and
annotations without replaying or fitting anything (the csv module, not pandas).

Whether a session is being recorded is a fact, not a guess from the raw log's age: the
recorder holds a lock on ``recording.lock`` in the session (:class:`station.session.store.
RecordingLock`), which this command tries without waiting.

A listing survives its worst member: every file is opened only if it is a regular file, and
read within a bound (a FIFO or a link to ``/dev/zero`` as ``raw.jsonl`` does not hang it), and a
session that cannot be read (a binary ``results.csv``, a folder where a file should be) is
listed as ``broken`` with the reason, also on stderr, while the others are listed as usual. The
exit status is 0 when at least one session was read (or the folder holds none), 2 when every
session found is broken.
"""

from __future__ import annotations

import argparse
import os
import sys
from dataclasses import asdict, dataclass
from enum import StrEnum
from typing import Any

from station.cli.common import EXIT_BAD_INPUT, _print_json
from station.errors import InputError
from station.files import MAX_RAWLOG, check_regular


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
    """One line of ``station sessions``."""

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

    def to_json(self) -> dict[str, Any]:
        out = asdict(self) | {"items": list(self.items)}
        if not self.problem:
            del out["problem"]  # the listing of a readable session is as it was
        if not self.imported:
            del out["imported"]
        return out


def _minute(iso: str) -> str:
    """'2026-01-12 10:00' of a results CSV's start time (ISO 8601 local), "" if it is none."""
    import datetime as dt

    try:
        return dt.datetime.fromisoformat(iso).strftime("%Y-%m-%d %H:%M")
    except (TypeError, ValueError):
        return ""


def session_status(session: Any, has_results: bool) -> SessionStatus:
    """``recording`` while a process holds the session's lock, whatever the timer does;
    ``interrupted`` when its recorder died (killed, crashed) without ending it, so its
    results CSV may lack the last descent; ``finished`` when it was ended (or is older than
    the lock)."""
    from station.session import store as sessions  # here: yaml (``station --help``)

    state = session.recording_state()
    if state is sessions.RecordingStatus.NOW:
        return SessionStatus.RECORDING
    if not has_results:
        return SessionStatus.NO_RESULTS
    if state is sessions.RecordingStatus.INTERRUPTED:
        return SessionStatus.INTERRUPTED
    if state is sessions.RecordingStatus.UNKNOWN:
        return SessionStatus.UNKNOWN
    return SessionStatus.FINISHED


def summarise(path: str) -> SessionSummary:
    """One session's line; a session that cannot be read raises :class:`InputError`."""
    from station.model.compare import item_name  # here: numpy, see recording.py's note
    from station.session import store as sessions
    from station.session.recorded import RecordedSession

    check_regular(os.path.join(path, sessions.RAW), MAX_RAWLOG, "raw log")
    session = RecordedSession(path)
    rows = session.rows()
    items: list[str] = []
    for r in rows:
        it = item_name(r.ski, r.wax)
        if r.descent_status != "aborted" and it not in items:
            items.append(it)
    has_results = os.path.lexists(session.file(sessions.RESULTS))
    head = session.first_record()
    started, imported = session.started(head), ""
    if session.made_by_import(head):
        first = next((m for m in map(_minute, (r.start_time for r in rows)) if m), "")
        if first:
            started, imported = first, started
    return SessionSummary(
        path=path,
        started=started,
        imported=imported,
        descents=sum(r.descent_status != "aborted" for r in rows),
        fitted=sum(r.status == "ok" and not r.invalid_reason for r in rows),
        invalid=sum(bool(r.invalid_reason) for r in rows),
        items=tuple(items),
        status=session_status(session, has_results),
    )


def broken(path: str, why: str) -> SessionSummary:
    return SessionSummary(path, "", 0, 0, 0, (), SessionStatus.BROKEN, why)


def find_sessions(folder: str) -> list[str]:
    """Sessions in ``folder`` (or ``folder`` itself when it is one), oldest first."""
    from station.session import store as sessions

    if not os.path.exists(folder):
        raise InputError("no such folder", path=folder)
    if not os.path.isdir(folder):
        raise InputError("not a folder", path=folder)
    if sessions.is_session(folder):
        return [folder]
    try:
        names = sorted(os.listdir(folder))
    except OSError as exc:
        raise InputError(f"cannot list: {exc.strerror}", path=folder) from None
    return [os.path.join(folder, n) for n in names if sessions.is_session(os.path.join(folder, n))]


def cmd_sessions(args: argparse.Namespace) -> int:
    found: list[SessionSummary] = []
    for path in find_sessions(args.folder):
        try:
            found.append(summarise(path))
        except InputError as exc:
            found.append(broken(path, str(exc)))
        except OSError as exc:  # a file that went away or cannot be read meanwhile
            found.append(broken(path, f"{exc.filename or path}: {exc.strerror or exc}"))
    found.sort(key=lambda s: (s.started, s.path))
    readable = [s for s in found if not s.problem]
    word = "error" if found and not readable else "warning"
    for s in found:
        if s.problem:
            print(f"station: {word}: {s.problem}; listed as broken", file=sys.stderr)
    status = EXIT_BAD_INPUT if found and not readable else 0
    if args.json:
        _print_json([s.to_json() for s in found])
        return status
    if not found:
        print(f"no sessions in {args.folder}")
        return status
    width = max(len("session"), *(len(s.path) for s in found))
    print(f"{'session':<{width}}  {'started':<16}  {'descents':>8}  {'ok':>3}  {'inval':>5}  "
          "status       items")  # fmt: skip
    for s in found:
        items = "; ".join(s.items) or "—"
        if s.problem:
            items = s.problem
        if s.imported:
            items += f"  (imported {s.imported})"
        print(f"{s.path:<{width}}  {s.started or '—':<16}  {s.descents:>8}  {s.fitted:>3}  "
              f"{s.invalid:>5}  {s.status:<11}  {items}")  # fmt: skip
    return status


def add_parsers(sub: Any) -> None:
    p = sub.add_parser("sessions", help="list the recorded sessions: date, descents, items, status")
    p.add_argument(
        "folder",
        metavar="DIR",
        nargs="?",
        default="sessions",
        help="folder holding the sessions (default: ./sessions), or one session",
    )
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=cmd_sessions)
