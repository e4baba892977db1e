"""What the commands that record or replay print on the terminal: a line per descent and per
connection change as it happens, and the day's summary at the end.

The acquisition loop (:mod:`station.session.acquisition`) tells its listener immutable records;
wording them for a person is this module's job, so the session layer needs no text of the
report layer. Not a command module: ``record``, ``replay``, ``import`` and the UI commands
share it, as they share :mod:`station.cli.common`.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from station.cli.common import _warn
from station.errors import InputError
from station.report.text import describe, summary
from station.session import store as sessions
from station.session.acquisition import Acquisition, Listener
from station.session.analysis import DescentResult
from station.session.config import StationConfig, load_config
from station.session.recorded import RecordedSession
from station.session.records import Annotation

if TYPE_CHECKING:  # the comparison's modules load numpy and scipy: when one comes
    from station.session.comparison import DayComparison


def _print(text: str) -> None:
    print(text, flush=True)  # a line per descent as it happens, also through a pipe (tee)


class PrintListener(Listener):
    """``station record`` and ``replay``: one line per descent and per connection change."""

    def __init__(self, out: Callable[[str], None] = _print, port: str = "") -> None:
        self.out = out
        self.port = port
        self._told: set[int] = set()  # descents already printed: a second line is an update
        self._decisions: tuple[str, ...] = ()  # the decisions last printed

    def connection(self, state: str, detail: str) -> None:
        if state == "disconnected":
            self.out(f"timer disconnected ({detail}); reconnecting")
        elif state == "connected":
            self.out(f"timer connected on {detail}")
        elif state == "open-failed":
            self.out(f"cannot open {self.port} ({detail}); retrying")
        elif state == "error":
            self.out(f"error: {detail}")

    def result(self, result: DescentResult) -> None:
        n = result.descent.number
        again = "  (updated: an annotation or a refit)" if n in self._told else ""
        self._told.add(n)
        self.out(describe(result) + again)

    def warning(self, text: str) -> None:
        self.out(f"warning: {text}")

    def comparison(self, day: DayComparison) -> None:
        """The decision on each pair of items ("decided: …" or "not yet: …") when it changed;
        the rest of the comparison is for the UI and ``station compare``."""
        from station.report.comparison_text import decision_block

        block = decision_block(day)
        if block and tuple(block[1:]) != self._decisions:
            self._decisions = tuple(block[1:])
            self.out("\n".join(block))


def day_summary(acq: Acquisition) -> str:
    """The summary line of a recorded or replayed day: lines read, descents, fits."""
    return summary(acq.line_counts(), acq.results())


def replay_config(source: str, config: str | None) -> StationConfig:
    """The config of a replay: ``--config``, else a session's own snapshot; a plain capture
    has none of its own."""
    if not os.path.exists(source):
        raise InputError("no such session or capture", path=source)
    if os.path.isdir(source) and not sessions.is_session(source):
        raise InputError(f"is a folder without {sessions.RAW}: not a session, and a capture is "
                         "a file", path=source)  # fmt: skip
    if config:
        return load_config(config)
    if sessions.is_session(source):
        return sessions.load_session_config(source)
    raise InputError("a plain capture needs --config (protocol, channels, survey)", path=source)


def replayed(session: RecordedSession) -> RecordedSession:
    """The session with its quiet replay run (:meth:`RecordedSession.run`); what the raw
    log's reader passed over (a torn last record) is said once, as a warning."""
    session.run()
    _say_warnings(session)
    return session


def annotate_session(session: RecordedSession, records: Sequence[Annotation]) -> str:
    """:meth:`RecordedSession.annotate`, saying what its replay passed over; returns its line."""
    try:
        return session.annotate(records)
    finally:
        _say_warnings(session)


def _say_warnings(session: RecordedSession) -> None:
    while session.warnings:
        _warn(session.warnings.pop(0))


def add_after(session: str, config_store: str | None) -> None:
    """``record``, ``live`` and ``annotate``: add or update the session in the season store
    when one is configured ($STATION_STORE, else the config's ``store:``). It never fails the
    command that called it (the day is recorded, the annotation saved): one line either way."""
    import sqlalchemy as sa

    from station.store.db import database_error, open_store, safe_url
    from station.store.writer import add_session

    target = os.environ.get("STATION_STORE") or config_store
    if not target:
        return
    if sessions.recording_state(session) is sessions.Recording.NOW:
        return  # the recorder adds it when the recording ends
    where = safe_url(target)
    try:
        store = open_store(target, create=True, say=lambda m: print(m, file=sys.stderr))
        try:
            verdict = add_session(store, session)
        finally:
            store.close()
    except (InputError, sa.exc.SQLAlchemyError) as exc:
        why = database_error(exc, where).message if isinstance(exc, sa.exc.SQLAlchemyError) \
            else str(exc)  # fmt: skip
        _warn(f"{session} not added to the season store {where}: {why}; "
              f"station season add {session} --store {where} adds it later")  # fmt: skip
        return
    print(f"season store {where}: {session} {verdict}", file=sys.stderr)
