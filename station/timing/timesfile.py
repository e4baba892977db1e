"""Photocell times of one descent from a CSV file: columns ``photocell`` and ``time``.

``time`` is seconds on any clock (``12.3456``) or a time of day (``10:41:07.2345``, as a timer
prints it); a time of day that goes backwards by more than twelve hours has passed midnight.
Rows may come in any order; they are put in the survey's order down the run and must then
increase. Every problem is reported with the file, the line and the column.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass

from station.errors import InputError

DAY_S = 86400.0


@dataclass(frozen=True)
class DescentTimes:
    """Crossing times of one descent, in the order of the photocells down the run."""

    photocells: list[str]
    times: list[float]
    lines: list[int]


def parse_time(text: str) -> tuple[float, bool]:
    """Seconds from ``ss.ffff`` or ``[h]h:mm:ss.ffff`` / ``mm:ss.ffff``; and whether it was a
    time of day. Raises ValueError with a plain reason."""
    text = text.strip()
    if not text:
        raise ValueError("empty time")
    if ":" in text:
        parts = text.split(":")
        if len(parts) not in (2, 3):
            raise ValueError(f"{text!r} is not hh:mm:ss.ffff")
        try:
            nums = [float(p) for p in parts]
        except ValueError:
            raise ValueError(f"{text!r} is not hh:mm:ss.ffff") from None
        if len(nums) == 2:
            nums.insert(0, 0.0)
        h, m, s = nums
        if not (0 <= h < 24 and 0 <= m < 60 and 0 <= s < 60) or h != int(h) or m != int(m):
            raise ValueError(f"{text!r} is not a valid time of day")
        return h * 3600.0 + m * 60.0 + s, True
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{text!r} is not a number of seconds or hh:mm:ss.ffff") from None
    if not math.isfinite(value):
        raise ValueError(f"{text!r} is not a finite time")
    return value, False


def read_times(path: str, photocell_order: list[str]) -> DescentTimes:
    """Read a descent's times and check them against the survey's photocells."""
    try:
        with open(path, encoding="utf-8-sig", newline="") as fh:
            rows = list(csv.reader(fh))
    except OSError as exc:
        raise InputError(f"cannot read times file: {exc.strerror}", path=path) from None
    except UnicodeDecodeError:
        raise InputError("not a UTF-8 text file", path=path) from None
    numbered = [(i, r) for i, r in enumerate(rows, start=1) if r and any(c.strip() for c in r)]
    numbered = [(i, r) for i, r in numbered if not r[0].lstrip().startswith("#")]
    if not numbered:
        raise InputError("empty times file; expected columns photocell,time", path=path)
    header_line, header = numbered[0]
    cols = [c.strip().lower() for c in header]
    for need in ("photocell", "time"):
        if need not in cols:
            raise InputError(
                f"missing column {need!r} (header is {','.join(header)!r})",
                path=path,
                line=header_line,
                field="header",
            )
    ipc, it = cols.index("photocell"), cols.index("time")
    order = {pid: k for k, pid in enumerate(photocell_order)}
    entries: list[tuple[int, str, float, bool, int]] = []
    seen: dict[str, int] = {}
    for line, row in numbered[1:]:
        if len(row) <= max(ipc, it):
            raise InputError(
                f"expected {len(header)} columns, found {len(row)}",
                path=path,
                line=line,
            )
        pid = row[ipc].strip()
        if pid not in order:
            known = ", ".join(photocell_order)
            raise InputError(
                f"unknown photocell {pid!r} (the survey has {known})",
                path=path,
                line=line,
                field="photocell",
            )
        if pid in seen:
            raise InputError(
                f"photocell {pid} appears twice (first on line {seen[pid]})",
                path=path,
                line=line,
                field="photocell",
            )
        seen[pid] = line
        try:
            value, tod = parse_time(row[it])
        except ValueError as exc:
            raise InputError(str(exc), path=path, line=line, field="time") from None
        entries.append((order[pid], pid, value, tod, line))
    if len(entries) < 2:
        raise InputError(
            f"{len(entries)} time(s); a descent needs at least two photocells",
            path=path,
            line=numbered[-1][0],
        )
    kinds = {e[3] for e in entries}
    if len(kinds) > 1:
        raise InputError(
            "times mix seconds and time of day; use one form",
            path=path,
            line=entries[0][4],
            field="time",
        )
    entries.sort(key=lambda e: e[0])
    times = [e[2] for e in entries]
    if entries[0][3]:  # time of day: unwrap midnight
        for k in range(1, len(times)):
            while times[k] < times[k - 1] - DAY_S / 2:
                times[k] += DAY_S
    for k in range(1, len(times)):
        if times[k] <= times[k - 1]:
            raise InputError(
                f"time at {entries[k][1]} is not later than at {entries[k - 1][1]} "
                f"(line {entries[k - 1][4]}); times must increase down the run",
                path=path,
                line=entries[k][4],
                field="time",
            )
    return DescentTimes(
        photocells=[e[1] for e in entries],
        times=times,
        lines=[e[4] for e in entries],
    )
