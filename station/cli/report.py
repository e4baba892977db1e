"""``station report SESSION --out DIR``: the day report, one self-contained HTML page with
pictures (station/report/day_report.py), for the people who were not at the run."""

from __future__ import annotations

import argparse
import os
import sys
from typing import Any

from station.cli.common import _positive, open_output, output_dir, unique_prefix
from station.errors import InputError


def cmd_report(args: argparse.Namespace) -> int:
    from station.cli.recording import _replay_run
    from station.cli.sessions import recording_started
    from station.model.compare import CompareError, collect, joint_fit
    from station.report.day_report import DayData, build_day_report, descent_views
    from station.session import store as sessions

    if not sessions.is_session(args.session):
        raise InputError("not a session directory (no raw.jsonl)", path=args.session)
    out = output_dir(args.out, "--out")  # checked (and made) before the day is replayed
    name = os.path.basename(os.path.normpath(os.path.abspath(args.session))) or "session"
    path = os.path.join(out, f"{name}.html")
    ns = argparse.Namespace(source=args.session, config=None, fast=True, date=None)
    acq = _replay_run(ns, quiet=True)  # the session as a replay gives it, annotations included
    results = acq.results()
    base = acq.day.base_metadata()
    day = DayData(
        session=args.session,
        track=acq.track,
        descents=descent_views(results),
        header=sessions.results_header(acq.config, acq.track.name),
        summary=acq.summary(),
        config_metadata={k: getattr(base, k, None) for k in ("skier", "ski", "wax", "notes")},
        recorded=recording_started(args.session),
        annotations=len(sessions.read_annotations(args.session)),
    )
    with open(os.path.join(args.session, sessions.CONFIG), encoding="utf-8") as fh:
        day.config_text = fh.read()
    day.warnings = list(acq.track.warnings)
    data, excluded, windy = collect(results, args.wind_limit)
    reference = args.reference
    if reference is not None:
        reference = unique_prefix(reference, sorted({d.item for d in data}), "item", "--reference")
    try:
        res = joint_fit(
            acq.track,
            data,
            drift=args.drift,
            reference=reference,
            excluded=excluded,
            wind_flagged=windy,
            wind_limit_ms=args.wind_limit,
        )
    except CompareError as exc:
        day.comparison_error = str(exc)
    else:
        day.comparison, day.compared = res, data
    page = build_day_report(day)
    with open_output(path, "--out") as fh:
        fh.write(page)
    print(path)
    print(f"{len(results)} descents; open it in a browser", file=sys.stderr)
    return 0


def add_parsers(sub: Any) -> None:
    p = sub.add_parser("report", help="the day report: one HTML page with pictures")
    p.add_argument("session", metavar="SESSION", help="session folder")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="folder for SESSION_NAME.html (made if missing)")  # fmt: skip
    p.add_argument("--reference", metavar="ITEM",
                   help="compare every item with this one (its beginning is enough)")  # fmt: skip
    p.add_argument("--drift", choices=["auto", "on", "off"], default="auto",
                   help="fit a linear drift of μ per hour (auto: when an item recurs)")  # fmt: skip
    p.add_argument("--wind-limit", type=_positive, default=1.0, metavar="MS",
                   help="flag descents with more along-track wind (m/s)")  # fmt: skip
    p.set_defaults(func=cmd_report)
