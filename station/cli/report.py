"""``station report SESSION --out DIR``: the day report, one self-contained HTML page with
pictures (station/report/day_report.py), for the people who were not at the run."""

from __future__ import annotations

import argparse
import os
import sys
from typing import Any

from station.cli.common import _positive, open_output, output_dir, reference_item


def cmd_report(args: argparse.Namespace) -> int:
    # here, not at the top: numpy, scipy and matplotlib (see recording.py's note)
    from station.cli.console import day_summary, replayed
    from station.report.day_data import DayData, descent_views
    from station.report.day_report import build_day_report
    from station.report.text import count
    from station.session import store as sessions
    from station.session.recorded import RecordedSession

    session = RecordedSession(args.session, speed_curves=True)  # the report draws them
    out = output_dir(args.out, "--out")  # checked (and made) before the day is replayed
    path = os.path.join(out, f"{session.name}.html")
    results = replayed(session).results()  # as a replay gives them, annotations included
    base = session.base_metadata()
    day = DayData(
        session=args.session,
        track=session.track,
        descents=descent_views(results),
        header=session.results_header(),
        summary=day_summary(session.run()),
        config_metadata={k: getattr(base, k, None) for k in ("skier", "ski", "wax", "notes")},
        recorded=session.started(),
        annotations=len(session.annotations()),
    )
    with open(session.file(sessions.CONFIG), encoding="utf-8") as fh:
        day.config_text = fh.read()
    day.warnings = list(session.track.warnings)
    reference = reference_item(args.reference, results, args.wind_limit)
    day.day_comparison = session.compare(
        wind_limit_ms=args.wind_limit, reference=reference, drift=args.drift
    )
    page = build_day_report(day)
    with open_output(path, "--out") as fh:
        fh.write(page)
    print(path)
    print(f"{count(len(results), 'descent')}; open it in a browser", file=sys.stderr)
    return 0


def add_parsers(sub: Any) -> None:
    p = sub.add_parser("report", help="the day report: one HTML page with pictures")
    p.add_argument("session", metavar="SESSION", help="session folder")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="folder for SESSION_NAME.html (made if missing, in a folder that "
                        "exists)")  # fmt: skip
    p.add_argument("--reference", metavar="ITEM",
                   help="compare every item with this one (its beginning is enough)")  # fmt: skip
    p.add_argument("--drift", choices=["auto", "on", "off"], default="auto",
                   help="fit a linear drift of μ per hour (auto: when an item recurs)")  # fmt: skip
    p.add_argument("--wind-limit", type=_positive, default=1.0, metavar="MS",
                   help="flag descents with more along-track wind (m/s)")  # fmt: skip
    p.set_defaults(func=cmd_report)
