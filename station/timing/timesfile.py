"""Photocell times of one descent from a CSV file: columns ``photocell`` and ``time``.

``time`` is seconds on any clock (``12.3456``) or a time of day (``10:41:07.2345``, as a timer
prints it); a time of day that goes backwards by more than twelve hours has passed midnight.
Rows may come in any order; they are put in the survey's order down the run and must then
increase. Every problem is reported with the file, the line and the column.

Files as spreadsheets save them are read: a decimal comma is a decimal mark (``10:41:07,2345``,
``12,345``); a header with semicolons means semicolon-separated (as a European Excel or
LibreOffice saves "CSV"), with tabs tab-separated. In a comma-separated file an unquoted decimal
comma splits the time in two fields (``PC1,10:41:07,2345``); when the row has exactly one field
more than the header and the time has no decimal point, the two are joined again, otherwise
the row is refused: a time is never silently cut to whole seconds.
"""

from __future__ import annotations

import csv
import io
import re
from dataclasses import dataclass

from station.errors import InputError
from station.files import MAX_TIMES, read_text
from station.numbers import parse_number

DAY_S = 86400.0
#: a time in seconds beyond this is not a timer's (1e10 s is 300 years)
MAX_SECONDS = 1e10
#: one descent is over in minutes; times spread over more than this are not one descent
MAX_SPAN_S = 3600.0
_CLOCK_FIELD = re.compile(r"[0-9]{1,2}")


@dataclass(frozen=True)
class DescentTimes:
    """Crossing times of one descent, in the order of the photocells down the run."""

    photocells: list[str]
    times: list[float]
    lines: list[int]


def _q(text: str) -> str:
    return repr(text if len(text) <= 40 else text[:37] + "...")


def parse_time(text: str) -> tuple[float, bool]:
    """Seconds from ``ss.ffff`` or ``[h]h:mm:ss.ffff`` / ``mm:ss.ffff`` (decimal point or comma);
    and whether it was a time of day. Raises ValueError with a plain reason."""
    text = text.strip()
    if not text:
        raise ValueError("empty time")
    shown = _q(text)
    if ":" in text:
        parts = text.split(":")
        bad = ValueError(f"{shown} is not hh:mm:ss.ffff")
        if len(parts) not in (2, 3) or not all(_CLOCK_FIELD.fullmatch(p) for p in parts[:-1]):
            raise bad
        try:
            sec = parse_number(parts[-1])
        except ValueError:
            raise bad from None
        nums = [float(p) for p in parts[:-1]] + [sec]
        if len(nums) == 2:
            nums.insert(0, 0.0)
        h, m, s = nums
        if not (0 <= h < 24 and 0 <= m < 60 and 0 <= s < 60):
            raise ValueError(f"{shown} is not a valid time of day")
        return h * 3600.0 + m * 60.0 + s, True
    try:
        value = parse_number(text)
    except ValueError:
        raise ValueError(f"{shown} is not a number of seconds or hh:mm:ss.ffff") from None
    if abs(value) > MAX_SECONDS:
        raise ValueError(f"{shown} s is not a time a timer gives")
    return value, False


def _delimiter(header_line: str) -> str:
    if ";" in header_line:
        return ";"
    if "\t" in header_line:
        return "\t"
    return ","


def _rows(text: str, path: str) -> list[tuple[int, list[str]]]:
    """(line, fields) of every row that is not blank or a ``#`` comment."""
    first = next(
        (ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")), ""
    )
    reader = csv.reader(io.StringIO(text, newline=""), delimiter=_delimiter(first))
    out = []
    try:
        for row in reader:
            if row and any(c.strip() for c in row) and not row[0].lstrip().startswith("#"):
                out.append((reader.line_num, row))
    except csv.Error as exc:
        raise InputError(f"not a CSV file: {exc}", path=path, line=reader.line_num) from None
    return out


def _fields(row: list[str], header: list[str], it: int, path: str, line: int) -> list[str]:
    """The row with as many fields as the header: trailing empty fields (a spreadsheet's
    ``;;``) dropped, a time split at its decimal comma joined again."""
    row = list(row)
    while len(row) > len(header) and not row[-1].strip():
        row.pop()
    if (
        len(row) == len(header) + 1
        and it + 1 < len(row)
        and row[it + 1].strip().isdigit()
        and row[it + 1].strip().isascii()
        and "." not in row[it]
        and row[it].strip()[-1:].isdigit()
    ):
        row[it : it + 2] = [row[it] + "," + row[it + 1]]
    if len(row) != len(header):
        raise InputError(
            f"expected {len(header)} columns, found {len(row)} (a decimal comma in a "
            "comma-separated file? quote the time or separate with ;)"
            if len(row) > len(header)
            else f"expected {len(header)} columns, found {len(row)}",
            path=path,
            line=line,
        )
    return row


def read_times(path: str, photocell_order: list[str]) -> DescentTimes:
    """Read a descent's times and check them against the survey's photocells."""
    text = read_text(path, MAX_TIMES, "times file")
    numbered = _rows(text, path)
    if not numbered:
        raise InputError("empty times file; expected columns photocell,time", path=path)
    header_line, header = numbered[0]
    cols = [c.strip().lower() for c in header]
    for need in ("photocell", "time"):
        if need not in cols:
            raise InputError(
                f"missing column {need!r} (header is {','.join(header)[:60]!r})",
                path=path,
                line=header_line,
                field="header",
            )
    ipc, it = cols.index("photocell"), cols.index("time")
    order = {pid: k for k, pid in enumerate(photocell_order)}
    entries: list[tuple[int, str, float, bool, int]] = []
    seen: dict[str, int] = {}
    for line, raw in numbered[1:]:
        row = _fields(raw, header, it, path, line)
        pid = row[ipc].strip()
        if pid not in order:
            known = ", ".join(photocell_order)
            raise InputError(
                f"unknown photocell {pid[:40]!r} (the survey has {known})",
                path=path,
                line=line,
                field="photocell",
            )
        if pid in seen:
            raise InputError(
                f"photocell {pid[:40]} appears twice (first on line {seen[pid]})",
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
    return _in_order(entries, path)


def _in_order(entries: list[tuple[int, str, float, bool, int]], path: str) -> DescentTimes:
    """The times in the survey's order of the photocells, midnight unwrapped, checked to
    increase within one descent's span. ``entries``: (order, photocell, time, time of day,
    line) as read."""
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
    if times[-1] - times[0] > MAX_SPAN_S:
        raise InputError(
            f"the times span {times[-1] - times[0]:.0f} s; one descent is over in minutes",
            path=path,
            line=entries[-1][4],
            field="time",
        )
    return DescentTimes(
        photocells=[e[1] for e in entries],
        times=times,
        lines=[e[4] for e in entries],
    )
