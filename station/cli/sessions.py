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
from typing import Any

from station.cli.common import EXIT_BAD_INPUT, _print_json
from station.errors import InputError


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
    from station.session.recorded import RecordedSession, SessionSummary

    found: list[SessionSummary] = []
    for path in find_sessions(args.folder):
        try:
            found.append(RecordedSession(path).summary())
        except InputError as exc:
            found.append(SessionSummary.broken(path, str(exc)))
        except OSError as exc:  # a file that went away or cannot be read meanwhile
            found.append(SessionSummary.broken(path, f"{exc.filename or path}: "
                                                     f"{exc.strerror or exc}"))  # fmt: skip
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
