"""``station import``: a timer's memory (plain capture or memory download) into a new session,
or merged into an existing one without doubling impulses (station.session.memory_import)."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from station.cli.common import _date
from station.errors import InputError


def cmd_import(args: argparse.Namespace) -> int:
    from station.cli.console import day_summary  # here: numpy, see recording.py's note
    from station.session import memory_import
    from station.session import store as sessions
    from station.session.config import load_config
    from station.session.recorded import RecordedSession
    from station.timing.assembly import JOINED

    if args.into and args.date:
        raise InputError("--date is for a new session; --into keeps the session's own dates",
                         field="--date")  # fmt: skip
    if args.into:
        report = memory_import.import_into(args.file, args.into)
        config = sessions.load_session_config(args.into)
        if config.serial.protocol != load_config(args.config).serial.protocol:
            print("station: warning: --config names another protocol than the session's; "
                  "the session's config was used", file=sys.stderr)  # fmt: skip
    else:
        config = load_config(args.config)
        report = memory_import.import_new(args.file, config, args.session_dir, _date(args.date))
        config = sessions.load_session_config(args.session_dir)
    if report.repaired:
        print(f"station: warning: {report.repaired}", file=sys.stderr)
    # with the state a recording leaves: the next annotate changes rows in place
    session = RecordedSession(report.session, config)
    session.write_results_csv()
    print(
        f"{report.impulses_in_file} impulses in {args.file}: {report.already_there} already in "
        f"the session, {report.added} added; the file is kept as {report.kept_as}",
        file=sys.stderr,
    )
    # the descents this download completed: said, not only flagged (not those an earlier
    # import joined: they are flagged still)
    mine = session.joined_by_last_import()
    results = session.results()
    for res in results:
        if res.number not in mine:
            continue
        joined = next((f for f in res.row.flags if f.startswith(JOINED)), None)
        if joined is not None:
            print(f"descent {res.number}: {joined}", file=sys.stderr)
    if not args.into and results and all(r.descent.day is not None for r in results):
        # a timer that dates its impulses (TAG's day counter) is believed over --date and the
        # file's date: say which date the descents got, not the one that was not used
        days = sorted({r.row.start_time[:10] for r in results if r.row.start_time})
        unused = (
            f"--date {args.date}"
            if args.date
            else f"the file's date {report.dated.isoformat()}"
            if report.dated
            else ""
        )
        print(f"dated {', '.join(days)} by the timer's own day counter"
              + (f" ({unused} not used)" if unused else ""), file=sys.stderr)  # fmt: skip
    elif report.dated is not None and not args.date:
        print(f"dated {report.dated.isoformat()} by the file's date; give --date YYYY-MM-DD when "
              "the test day was another", file=sys.stderr)  # fmt: skip
    print(day_summary(session.run()), file=sys.stderr)
    return 0


def add_parsers(sub: Any) -> None:
    p = sub.add_parser(
        "import", help="a timer's memory download or a capture into a new or existing session"
    )
    p.add_argument("file", metavar="FILE", help="plain capture or memory download")
    p.add_argument("--config", required=True, help="station config YAML")
    where = p.add_mutually_exclusive_group(required=True)
    where.add_argument("--session-dir", metavar="NEW", help="make a new session there")
    where.add_argument("--into", metavar="SESSION", help="merge into this session")
    p.add_argument("--date", metavar="YYYY-MM-DD",
                   help="the test day of a new session (default: the file's date)")  # fmt: skip
    p.set_defaults(func=cmd_import)
