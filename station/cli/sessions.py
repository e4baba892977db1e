"""``station sessions [DIR]``: the recorded test days in a folder, with their date, descents,
test items and status, read from each session's results CSV and annotations without
replaying or fitting anything (the csv module, not pandas).

Whether a session is being recorded is a fact, not a guess from the raw log's age: the
recorder holds a lock on ``recording.lock`` in the session (:class:`station.session.store.
RecordingLock`), which this command tries without waiting."""

from __future__ import annotations

import argparse
import csv
import datetime as dt
import json
import os
from dataclasses import asdict, dataclass
from typing import Any

from station.cli.common import _print_json
from station.errors import InputError


@dataclass(frozen=True)
class SessionSummary:
    """One line of ``station sessions``."""

    path: str
    started: str  # local date and time of the first raw-log record, "" when unknown
    descents: int
    fitted: int  # descents with status ok
    invalid: int  # marked invalid by the engineer
    items: tuple[str, ...]
    status: str  # recording | finished | interrupted | no results … | unknown


def read_results_rows(session: str) -> list[dict[str, str]] | None:
    """The rows of a session's results CSV as text, or None when it has none yet.

    The ``#`` header lines are skipped only at the top, so a quoted note that spans lines and
    begins one with ``#`` stays part of its row."""
    from station.files import MAX_OBSERVATIONS, check_regular
    from station.session import store as sessions

    path = os.path.join(session, sessions.RESULTS)
    if not os.path.lexists(path):
        return None
    check_regular(path, MAX_OBSERVATIONS, "results CSV")  # a FIFO would block the open
    try:
        fh = open(path, encoding="utf-8", newline="")  # noqa: SIM115
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", path=path) from None
    with fh:
        pos = fh.tell()
        line = fh.readline()
        while line.startswith("#"):
            pos = fh.tell()
            line = fh.readline()
        fh.seek(pos)
        try:
            return list(csv.DictReader(fh))
        except (csv.Error, UnicodeDecodeError) as exc:
            raise InputError(f"not a results CSV: {exc}", path=path) from None


def session_descents(session: str) -> list[int]:
    """The descent numbers a session has: from its results CSV, else (none, or one that
    cannot be read) by replaying it: the raw log knows them."""
    try:
        rows = read_results_rows(session)
    except InputError:
        rows = None
    if rows is not None:
        return [int(r["descent"]) for r in rows if (r.get("descent") or "").isdigit()]
    from station.cli.recording import _replay_run

    ns = argparse.Namespace(source=session, config=None, fast=True, date=None)
    return [r.number for r in _replay_run(ns, quiet=True).results()]


def recording_started(session: str) -> str:
    """Local date and time of the first raw-log record ("" when unreadable)."""
    from station.session import store as sessions

    try:
        with open(os.path.join(session, sessions.RAW), encoding="ascii", errors="replace") as fh:
            first = json.loads(fh.readline())
        t = float(first["t"])
    except (OSError, ValueError, KeyError, TypeError):
        return ""
    return dt.datetime.fromtimestamp(t).strftime("%Y-%m-%d %H:%M")


def _annotated(session: str, rows: list[dict[str, str]]) -> list[dict[str, Any]]:
    """The rows with the annotations entered since the CSV was written (``station annotate``
    appends to annotations.jsonl and leaves results.csv as recorded): ski, wax and invalid
    marks as a replay would give them, by the same :class:`Day` rules, without refitting."""
    from station.session import store as sessions
    from station.session.day import Day

    records = sessions.read_annotations(session)
    if not records:
        return list(rows)
    try:
        cfg = sessions.load_session_config(session)
    except InputError:
        return list(rows)
    day = Day(cfg, None, None, None)  # type: ignore[arg-type]  # metadata rules only
    for rec in records:
        day.annotate(rec)
    out: list[dict[str, Any]] = []
    for r in rows:
        n = int(r["descent"]) if (r.get("descent") or "").isdigit() else 0
        meta = day.metadata_for(n)
        row: dict[str, Any] = {**r, "ski": meta.ski or "", "wax": meta.wax or ""}
        row["invalid_reason"] = day.invalid.get(n, "")
        out.append(row)
    return out


def session_status(session: str, has_results: bool) -> str:
    """``recording`` while a process holds the session's lock, whatever the timer does;
    ``interrupted`` when its recorder died (killed, crashed) without ending it, so its
    results CSV may lack the last descent; ``finished`` when it was ended (or is older than
    the lock)."""
    from station.session import store as sessions

    state = sessions.recording_state(session)
    if state is sessions.Recording.NOW:
        return "recording"
    if not has_results:
        return "no results (station export SESSION --csv …)"
    if state is sessions.Recording.INTERRUPTED:
        return "interrupted"
    if state is sessions.Recording.UNKNOWN:
        return "unknown (its recording.lock cannot be tried)"
    return "finished"


def summarise(session: str) -> SessionSummary:
    from station.model.compare import item_name
    from station.session import store as sessions

    rows = _annotated(session, read_results_rows(session) or [])
    items: list[str] = []
    for r in rows:
        it = item_name(r.get("ski"), r.get("wax"))
        if r.get("descent_status") != "aborted" and it not in items:
            items.append(it)
    status = session_status(session, os.path.exists(os.path.join(session, sessions.RESULTS)))
    return SessionSummary(
        path=session,
        started=recording_started(session),
        descents=sum(r.get("descent_status") != "aborted" for r in rows),
        fitted=sum(r.get("status") == "ok" and not r.get("invalid_reason") for r in rows),
        invalid=sum(bool(r.get("invalid_reason")) for r in rows),
        items=tuple(items),
        status=status,
    )


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
    found = [summarise(s) for s in find_sessions(args.folder)]
    found.sort(key=lambda s: (s.started, s.path))
    if args.json:
        _print_json([asdict(s) | {"items": list(s.items)} for s in found])
        return 0
    if not found:
        print(f"no sessions in {args.folder}")
        return 0
    width = max(len("session"), *(len(s.path) for s in found))
    print(f"{'session':<{width}}  {'started':<16}  {'descents':>8}  {'ok':>3}  {'inval':>5}  "
          "status       items")  # fmt: skip
    for s in found:
        items = "; ".join(s.items) or "—"
        print(f"{s.path:<{width}}  {s.started or '—':<16}  {s.descents:>8}  {s.fitted:>3}  "
              f"{s.invalid:>5}  {s.status:<11}  {items}")  # fmt: skip
    return 0


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
