"""The checks of a station config that need no timer: its keys and values, its survey read and
the track fitted to it, every channel's photocell in the survey, the day's set-up.

``station check CONFIG`` prints them; ``record`` and ``live`` run them before they look at the
serial port, so a config that names a photocell the survey lacks is found the evening before,
not at the trackside after the timer was plugged in.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from station.errors import InputError
from station.session.config import StationConfig, load_config
from station.session.day import Day
from station.survey.load import load_survey
from station.survey.track import Track, build_track


@dataclass
class ConfigCheck:
    """What the checks found: the config and track when they could be read, the problems
    (each one line; any of them stops a recording) and notes (worth reading, not fatal)."""

    path: str
    config: StationConfig | None = None
    track: Track | None = None
    problems: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def check_config(path: str) -> ConfigCheck:
    """Every check that needs no timer: the config's keys and values, the survey read and the
    track fitted to it, every channel's photocell in the survey, the day's set-up (protocol,
    pairing, site). Stops at the first stage that fails (a config that cannot be read has no
    survey to check), but lists every problem of the stage that does."""
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


def checked_config(path: str) -> StationConfig:
    """The config of ``record`` and ``live``, after the same checks as ``station check`` (the
    first problem raised, as every bad input is); the port is theirs to check next."""
    result = check_config(path)
    if result.problems:
        more = len(result.problems) - 1
        first = result.problems[0]
        raise InputError(first + (f" (and {more} more: station check {path})" if more else ""))
    assert result.config is not None  # no problems: it was read
    return result.config
