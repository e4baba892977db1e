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
from dataclasses import dataclass, field
from typing import Any

from station.cli.common import EXIT_BAD_INPUT
from station.errors import InputError


@dataclass
class ConfigCheck:
    """What the checks found: the config and track when they could be read, the problems
    (each one line; any of them stops a recording) and notes (worth reading, not fatal)."""

    path: str
    config: Any = None  # station.session.config.StationConfig
    track: Any = None  # station.survey.track.Track
    problems: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def check_config(path: str) -> ConfigCheck:
    """Every check that needs no timer: the config's keys and values, the survey read and the
    track fitted to it, every channel's photocell in the survey, the day's set-up (protocol,
    pairing, site). Stops at the first stage that fails (a config that cannot be read has no
    survey to check), but lists every problem of the stage that does."""
    from station.session.config import load_config
    from station.session.day import Day
    from station.survey.load import load_survey
    from station.survey.track import build_track

    out = ConfigCheck(path)
    try:
        out.config = cfg = load_config(path)
        track = build_track(load_survey(cfg.survey_path))
    except InputError as exc:
        out.problems.append(str(exc))
        return out
    out.track = track
    known = set(track.photocell_ids)
    for ch, pc in cfg.channels.items():
        if pc not in known:
            out.problems.append(str(InputError(
                f"photocell {pc!r} is not in the survey ({', '.join(track.photocell_ids)})",
                path=path, field=f"photocells.{ch}",
            )))  # fmt: skip
    if out.problems:
        return out
    mapped = set(cfg.channels.values())
    unmapped = [p for p in track.photocell_ids if p not in mapped]
    if unmapped:
        out.notes.append(
            f"{path}: field photocells: no channel for {', '.join(unmapped)} of the survey: "
            "descents will be timed without them"
        )
    try:
        day = Day.start(cfg, track)
    except InputError as exc:
        out.problems.append(str(exc))
        return out
    if day.analyser.site_warning:
        out.notes.append(day.analyser.site_warning)
    out.notes.extend(track.warnings)
    return out


def checked_config(path: str) -> Any:
    """The config of ``record`` and ``live``, after the same checks as ``station check`` (the
    first problem raised, as every bad input is); the port is theirs to check next."""
    result = check_config(path)
    if result.problems:
        more = len(result.problems) - 1
        first = result.problems[0]
        raise InputError(first + (f" (and {more} more: station check {path})" if more else ""))
    return result.config


def cmd_check(args: argparse.Namespace) -> int:
    from station.report.text import count

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
