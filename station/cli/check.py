"""``station check CONFIG``: the station config, its survey and the photocell mapping checked
the evening before, without a timer attached; ``record`` and ``live`` run the same checks
before they look at the serial port.

A config that names a photocell the survey lacks, or a survey the track cannot be fitted to,
used to be found only at the trackside, after the timer was plugged in (``record`` checked the
port first). Here every problem is one line naming file, line and field, exit status 2; a
config that is fine gets one ``ok`` line saying what it will record.
"""

from __future__ import annotations

import argparse
import os
import sys
from typing import Any

from station.cli.common import EXIT_BAD_INPUT


def cmd_check(args: argparse.Namespace) -> int:
    # here, not at the top: the survey, numpy and scipy (``station --help`` imports this module)
    from station.report.text import count
    from station.session.configcheck import check_config

    result = check_config(args.config)
    for note in result.notes:
        print(f"note: {note}", file=sys.stderr)
    for problem in result.problems:
        print(problem)
    if result.problems:
        print(f"station check: {count(len(result.problems), 'problem')} in {args.config}",
              file=sys.stderr)  # fmt: skip
        return EXIT_BAD_INPUT
    cfg, track = result.config, result.track
    assert cfg is not None and track is not None  # no problems: both were read
    port = cfg.serial.port
    attached = "://" in port or os.path.exists(port)
    print(
        f"ok: {args.config}: {cfg.serial.protocol} timer on {port}"
        f"{'' if attached else ' (not attached now)'}, {count(len(cfg.channels), 'channel')} "
        f"to {len(set(cfg.channels.values()))} of the {count(len(track.photocells), 'photocell')}"
        f" of {track.name} "
        f"({track.length_m:.1f} m, {track.drop_m:.1f} m drop), skier {cfg.mass_kg:g} kg"
    )
    return 0


def add_parsers(sub: Any) -> None:
    p = sub.add_parser(
        "check", help="check a station config, its survey and photocells (no timer needed)"
    )
    p.add_argument("config", metavar="CONFIG", help="station config YAML")
    p.set_defaults(func=cmd_check)
