"""``station record``, ``replay`` and ``export``: a test day recorded from the timer, replayed
from its raw log or a plain capture, and its results written.

The session modules are imported inside each command, not at the top: they load numpy and
scipy (1.2 s on the 2-core test machine), and ``station --help`` or a mistyped command imports
every command module to build its parser (station/cli/main.py).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from station.cli.common import _date, _positive, _warn, open_output, output_path, whole_number
from station.errors import InputError

if TYPE_CHECKING:
    from station.session.analysis import DescentResult


def cmd_record(args: argparse.Namespace) -> int:
    from station.cli.console import PrintListener, day_summary
    from station.session import folder as sessions
    from station.session.configcheck import checked_config
    from station.session.ports import check_port
    from station.session.runs import record

    cfg = checked_config(args.config)  # config, survey and photocells, as station check does
    check_port(cfg.serial.port, args.config)  # then a wrong port: say so and list them
    folder = args.session_dir or sessions.default_dir()

    def started() -> None:  # said once the folder is accepted, not before a refusal
        print(f"recording to {folder} from {cfg.serial.port} ({cfg.serial.protocol}); "
              "Ctrl-C ends", file=sys.stderr)  # fmt: skip

    acq = record(cfg, folder, PrintListener(port=cfg.serial.port),
                 max_descents=args.max_descents, duration_s=args.duration,
                 started=started)  # fmt: skip
    print(day_summary(acq), file=sys.stderr)
    results = os.path.join(folder, sessions.RESULTS)
    if acq.csv_problem is not None:  # the last line names no file that is not there
        print(f"results: not written (said above); station export {folder} --csv {results} "
              "writes them from the raw log", file=sys.stderr)  # fmt: skip
    else:
        print(f"results: {results}", file=sys.stderr)
    from station.cli.console import add_after

    add_after(folder, cfg.store)  # when a season store is configured
    log = acq.rawlog
    if log is not None and log.lost_records:  # the disk stayed full to the end
        raise InputError(
            f"{log.lost_records} record(s) ({log.lost_bytes} bytes) the timer sent could not "
            "be written: the disk was full; import the timer's memory to fill the gap: "
            f"station import DOWNLOAD --into {folder}",
            path=log.path,
        )
    return 0


def cmd_replay(args: argparse.Namespace) -> int:
    from station.cli.console import PrintListener, day_summary, replay_config
    from station.cli.tui import replay_ui
    from station.session.runs import replay

    output_path(args.csv, "--csv")
    output_path(args.events, "--events")
    output_path(args.times, "--times")
    cfg = replay_config(args.source, args.config)  # a wrong source or config is said first
    if args.no_fit:
        return _replay_no_fit(args, cfg)
    speed = None if args.fast else args.speed
    if args.ui:
        return replay_ui(cfg, args.source, speed, _date(args.date))
    warnings: list[str] = []
    acq = replay(args.source, cfg, PrintListener(), speed=speed, date=_date(args.date),
                 warnings=warnings)  # fmt: skip
    for w in warnings:
        _warn(w)
    print(day_summary(acq), file=sys.stderr)
    if args.csv:
        with open_output(args.csv, "--csv") as fh:
            acq.write_csv_to(fh)
    if args.events:
        with open_output(args.events, "--events") as fh:
            acq.write_events_to(fh)
    _write_times(acq.results(), args.times)
    return 0


def _replay_no_fit(args: argparse.Namespace, cfg: Any) -> int:
    """``replay --no-fit``: framing, parsing and the descents, nothing fitted. A quick check of
    a capture (a line per descent: its photocells and times, its status and flags), its
    crossing times for another tool (``--times``), its impulses' fates (``--events``); and the
    measure of the replay's own throughput (benchmarks/replay_speed.py)."""
    from station.report.text import count, impulses_text
    from station.session.replay import replay_unfitted
    from station.timing.impulses import format_tod

    if args.csv or args.ui:
        option = "--csv" if args.csv else "--ui"
        raise InputError(f"{option} shows fits: leave out --no-fit", path=args.source)
    warnings: list[str] = []
    replayed = replay_unfitted(args.source, cfg, warnings)
    ended = replayed.descents
    for w in warnings:
        _warn(w)
    lines = []
    for n in sorted(ended):  # one f-string a descent: a long capture has thousands
        d = ended[n]
        times, pcs = d.times_us, d.photocells
        if times:
            what = (f"{count(len(pcs), 'photocell')}, {pcs[0]} {format_tod(times[0], 4)}, "
                    f"{pcs[-1]} +{(times[-1] - times[0]) / 1e6:.4f} s")  # fmt: skip
        else:
            what = "no time left"
        if d.flags:
            lines.append(f"descent {n} · {d.status} · {what} · {'; '.join(d.flags)}")
        else:
            lines.append(f"descent {n} · {d.status} · {what}")
    if lines and "-" not in (args.times, args.events):  # standard output is a CSV's
        print("\n".join(lines))
    by_status: dict[str, int] = {}
    for d in ended.values():
        by_status[d.status] = by_status.get(d.status, 0) + 1
    c = replayed.line_counts()
    parts = ", ".join(f"{v} {k}" for k, v in sorted(by_status.items()))
    print(
        f"{count(c.lines, 'line')}: {impulses_text(c)}, {count(c.edits, 'edit')}, "
        f"{count(c.skipped, 'other timer line')}, {c.unparsed} unparsed; "
        f"{count(len(ended), 'descent')}" + (f" ({parts})" if parts else "") + "; not fitted",
        file=sys.stderr,
    )
    if args.events:
        with open_output(args.events, "--events") as fh:
            replayed.write_events_to(fh)
    if args.times:
        from station.session.crossings import write_descent_times
        from station.session.records import DescentTimes

        with open_output(args.times, "--times") as fh:
            n_rows = write_descent_times([DescentTimes.of(d) for d in ended.values()], fh)
        where = "standard output" if args.times == "-" else args.times
        print(f"{n_rows} crossing times -> {where}", file=sys.stderr)
    return 0


def _write_times(results: Sequence[DescentResult], out: str | None) -> None:
    """``--times OUT``: one row per impulse kept in a descent (station.session.crossings)."""
    if out:
        from station.session.crossings import write_times

        with open_output(out, "--times") as fh:
            n = write_times(results, fh)
        where = "standard output" if out == "-" else out
        print(f"{n} crossing times -> {where}", file=sys.stderr)


def cmd_export(args: argparse.Namespace) -> int:
    from station.cli.console import replayed
    from station.session.recorded_session import RecordedSession

    session = RecordedSession(args.source)
    if not args.csv and not args.times:
        raise InputError("give --csv OUT and/or --times OUT", path=args.source)
    output_path(args.csv, "--csv")
    output_path(args.times, "--times")
    results = replayed(session).results()
    if args.csv:
        with open_output(args.csv, "--csv") as fh:
            session.write_results_to(fh)
        where = "standard output" if args.csv == "-" else args.csv
        print(f"{len(results)} descents -> {where}", file=sys.stderr)
    _write_times(results, args.times)
    return 0


def _descent_count(text: str) -> int:
    """``--max-descents``: a whole number of descents, at least one."""
    return whole_number(text, "a whole number", 1, "at least 1 descent")


def add_parsers(sub: Any) -> None:
    p = sub.add_parser("record", help="record a timer headless: raw log, descents, fits, CSV")
    p.add_argument("--config", required=True, help="station config YAML")
    p.add_argument("--session-dir", metavar="DIR", help="default: sessions/DATE_TIME")
    p.add_argument(
        "--max-descents",
        type=_descent_count,
        metavar="N",
        help="stop after N descents (aborted ones not counted)",
    )
    p.add_argument("--duration", type=_positive, metavar="S", help="stop after S seconds")
    p.set_defaults(func=cmd_record)

    p = sub.add_parser("replay", help="replay a session or a plain capture of a timer's output")
    p.add_argument("source", metavar="CAPTURE_OR_SESSION",
                   help="a session folder, or a file of the timer's output")  # fmt: skip
    p.add_argument("--config", help="station config (default: the session's own)")
    p.add_argument("--csv", metavar="OUT", help="write the results CSV; - = stdout")
    p.add_argument(
        "--events", metavar="OUT", help="write every parsed impulse and its fate (CSV); - = stdout"
    )
    p.add_argument("--times", metavar="OUT", help="write the crossing times of every descent (CSV)")
    p.add_argument("--date", help="date of a plain capture, YYYY-MM-DD (default: file date)")
    pace = p.add_mutually_exclusive_group()
    pace.add_argument("--speed", type=_positive, metavar="X", help="replay at X times real time")
    pace.add_argument("--fast", action="store_true", help="as fast as possible (the default)")
    p.add_argument("--ui", action="store_true", help="show the replay in the terminal UI")
    p.add_argument(
        "--no-fit",
        action="store_true",
        help="descents, times and events only, nothing fitted (a quick check of a capture)",
    )
    p.set_defaults(func=cmd_replay)

    p = sub.add_parser("export", help="write a session's results CSV")
    p.add_argument("source", metavar="SESSION", help="session folder")
    p.add_argument("--csv", metavar="OUT", help="results CSV to write; - = stdout")
    p.add_argument("--times", metavar="OUT", help="the crossing times of every descent (CSV)")
    p.set_defaults(func=cmd_export)
