"""Memory import (issue 11): the timer still holds every impulse when the laptop was off or the
cable out. A plain capture or a memory download (ALGE ``RSM`` print-out, TAG ``#DL``: ``DS`` …
``AN`` … ``DE``) becomes a new session, or is merged into an existing one.

- **new session**: the file's bytes are the session's raw log, as if received; results follow.
- **merge** (``into``): impulses the session already has (same channel, same time of day) are
  not doubled; the missing ones are appended to the raw log as one chunk after an ``import``
  event, so that a replay of the session reproduces the merged results; the session's
  results are rewritten.
- either way the file's own bytes are kept in ``SESSION/imports/`` (never overwritten).
- a session whose raw log ends torn (a full disk, a power cut: exactly when a memory import is
  needed) is repaired before anything is appended: the torn bytes go to ``raw.jsonl.torn-N``
  (:func:`station.session.rawlog.repair_tail`), the import's report says so, and the impulses
  the torn record held are taken from the download like any other missing one.

Impulses appended by a merge form descents of their own, but one that continues a descent the
live recording has the first crossings of (the cable came out during it) joins that descent:
the processor replays them after the ``import`` event as from the timer's memory
(:attr:`station.timing.assembly.DescentAssembler.from_memory`); and a descent of the download
that ends short takes the live impulses the recording rejected as without a start, when they
continue it plausibly (the cable came back in during it). The raw log is never rewritten:
a replay joins them again.
"""

from __future__ import annotations

import datetime as dt
import os
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

from station.errors import InputError
from station.files import read_bytes
from station.session import folder as sessions
from station.session.config import StationConfig
from station.session.rawlog import RawLogWriter, read_rawlog
from station.timing.assembly import is_joined
from station.timing.framing import LineFramer
from station.timing.impulses import DAY_US, MEMORY_REPEAT, Edit, Impulse
from station.timing.wireformats import make_parser

if TYPE_CHECKING:
    from station.session.processor import Processor

IMPORTS = "imports"
MAX_IMPORT_BYTES = 64 * 1024 * 1024
LINE_END = {"alge": b"\r", "tag": b"\r\n", "microgate": b"\r"}


@dataclass(frozen=True)
class ImportReport:
    session: str
    impulses_in_file: int
    already_there: int
    added: int
    kept_as: str
    dated: dt.date | None = None  # the test day the new session's impulses were dated by
    #: the session's raw log ended torn (a full disk, a power cut): what was done about it
    repaired: str | None = None


def joined_by_last_import(processor: Processor) -> set[int]:
    """The descents the session's last import joined to the recording, by number: those with
    a crossing kept from its lines (after its ``import`` event) and a ``joined`` flag. A
    descent an earlier import joined says so too, but this one did not touch it: ``station
    import`` listed every joined descent of the session as if this import had joined it."""
    since = processor.import_after_line
    if since is None:
        return set()
    touched = {e.descent for e in processor.events if e.kept and e.line > since}
    return {d.number for d in processor.assembler.finished if d.number in touched and is_joined(d)}


def read_import(path: str) -> bytes:
    """The file's bytes; a folder, special file, unreadable or huge file is one clear line."""
    return read_bytes(path, MAX_IMPORT_BYTES, "capture or memory download")


def _is_impulse(p) -> bool:
    """An impulse line, or an ALGE line repeated from the timer's memory (flag ``m``)."""
    return isinstance(p, Impulse) or (isinstance(p, Edit) and p.kind == MEMORY_REPEAT)


def _identity(p: object) -> tuple[str, ...] | None:
    """What makes a line the same line in the session and in the file: an impulse's channel and
    time of day; an edit's kind, channel and time (a clear or an inserted time the operator
    made at the timer belongs to the day as much as the impulses do). None: neither."""
    if _is_impulse(p):
        assert isinstance(p, (Impulse, Edit))
        return ("impulse", p.channel, str(p.tod_us % DAY_US))
    if isinstance(p, Edit):
        return ("edit", p.kind, p.channel, str(p.tod_us % DAY_US))
    return None


def _identities(data: bytes, protocol: str) -> list[tuple[str, tuple[str, ...], int | None]]:
    """(line text, identity, device day) of every impulse and edit line in the bytes, in order."""
    framer = LineFramer()
    parser = make_parser(protocol)
    out = []
    for line in framer.feed(data) + framer.flush():
        p = parser.parse(line)
        ident = _identity(p)
        if ident is not None:
            out.append((line, ident, getattr(p, "day", None)))
    return out


def _impulses(found: list[tuple[str, tuple[str, ...], int | None]]) -> int:
    return sum(ident[0] == "impulse" for _line, ident, _day in found)


def _keep_bytes(session: str, src: str, data: bytes) -> str:
    folder = os.path.join(session, IMPORTS)
    os.makedirs(folder, exist_ok=True)
    base = os.path.basename(src) or "import"
    name, n = base, 1
    while os.path.exists(os.path.join(folder, name)):
        n += 1
        name = f"{base}.{n}"
    with open(os.path.join(folder, name), "wb") as fh:
        fh.write(data)
    return os.path.join(IMPORTS, name)


def day_noon(date: dt.date) -> float:
    """The host time the bytes of a download are filed under: noon of the test day, local.
    A descent is dated by the day that puts its start nearest its host time, so every time of
    day of that date stays on it (the import's own time, hours or days later, would date the
    whole test day by the day it was downloaded)."""
    return dt.datetime.combine(date, dt.time(12)).timestamp()


def import_new(
    path: str, config: StationConfig, session: str, date: dt.date | None = None
) -> ImportReport:
    """A new session whose raw log is the file's bytes, dated ``date`` (default: the file's
    modification date, as the replay of a plain capture is)."""
    data = read_import(path)
    day = date or dt.date.fromtimestamp(os.path.getmtime(path))
    sessions.create(config, session)
    kept = _keep_bytes(session, path, data)
    log = RawLogWriter(
        os.path.join(session, sessions.RAW),
        header={"port": f"import {os.path.basename(path)}", "protocol": config.serial.protocol},
    )
    try:
        log.event(day_noon(day), "import", kept)
        log.write(day_noon(day), data)
    finally:
        log.close()
    n = _impulses(_identities(data, config.serial.protocol))
    return ImportReport(session, n, 0, n, kept, day)


def import_into(path: str, session: str) -> ImportReport:
    """Merge a memory download into a session: only impulses it does not have yet."""
    if not sessions.is_session(session):
        raise InputError("not a session directory (no raw.jsonl)", path=session)
    # two writers of one raw log
    if sessions.recording_state(session) is sessions.RecordingStatus.NOW:
        raise InputError(
            "is being recorded now; merge the memory download once the recording has ended",
            path=session,
        )
    config = sessions.load_session_config(session)
    protocol = config.serial.protocol
    data = read_import(path)
    have: set[tuple[str, ...]] = set()
    framer = LineFramer()
    parser = make_parser(protocol)
    last_t: float | None = None  # the session's own last host time: the merged bytes' day
    for chunk in read_rawlog(os.path.join(session, sessions.RAW)):
        if chunk.t == chunk.t:  # not NaN
            last_t = chunk.t
        if chunk.event:
            continue
        for line in framer.feed(chunk.data):
            ident = _identity(parser.parse(line))
            if ident is not None:
                have.add(ident)
    found = _identities(data, protocol)
    new = [(line, ident) for line, ident, _day in found if ident not in have]
    missing = [line for line, _ident in new]  # in the file's order: an impulse, then its clear
    added = sum(ident[0] == "impulse" for _line, ident in new)
    n = _impulses(found)
    kept = _keep_bytes(session, path, data)
    # a torn last record (what a full disk or a power cut leaves) is cut off into a side file
    # first: appending after it would glue the import to half a record, unreadable
    log = RawLogWriter(os.path.join(session, sessions.RAW))
    when = last_t if last_t is not None else time.time()
    try:
        edits = len(missing) - added
        log.event(when, "import", f"{kept}: {added} of {n} impulses added"
                  + (f", and {edits} edit line(s)" if edits else ""))  # fmt: skip
        if missing:
            # a line end first: a live line cut off at the end of the log stays cut off
            end = LINE_END[protocol]
            log.write(when, end + b"".join(s.encode("latin-1") + end for s in missing))
    finally:
        log.close()
    return ImportReport(session, n, n - added, added, kept, repaired=log.repair)
