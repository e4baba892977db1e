"""What a raw-log record is: the rule the reader checks every record by, and the writer's
repair of a torn tail judges the tail by.

A record is a JSON object with a finite host time ``t`` and either ``rx`` (the bytes as
latin-1 text) or an ``event`` (text) with a ``detail`` (text or an object nested at most
``MAX_DEPTH`` levels).
"""

from __future__ import annotations

import errno
import json
import math
from typing import NamedTuple

from station.files import MiB

#: nesting of a record's ``detail`` (the session header is one level)
MAX_DEPTH = 8
#: the latest host time a record may carry (year 2286): ``datetime.fromtimestamp`` takes it
MAX_T = 1e10


class Chunk(NamedTuple):
    """Bytes as they arrived, or a connection event (``data`` empty, ``event`` set). A
    NamedTuple, not a frozen dataclass: a replay of a session makes one per record, and a
    frozen dataclass's ``__init__`` cost a fifth of reading the record."""

    t: float
    data: bytes = b""
    event: str = ""
    detail: str = ""


def size(n: int) -> str:
    return f"{n / MiB:.1f} MB" if n >= MiB else f"{n} bytes"


def why(exc: OSError) -> str:
    if exc.errno == errno.ENOSPC:
        return "the disk is full"
    return exc.strerror or str(exc)


def is_record(text: bytes) -> bool:
    """``text`` (one line) is a whole raw-log record."""
    try:
        return check(json.loads(text)) is None
    except (ValueError, RecursionError):
        return False


def depth_within(value: object, limit: int) -> bool:
    """``value`` nests at most ``limit`` levels."""
    if isinstance(value, dict):
        return limit > 0 and all(depth_within(v, limit - 1) for v in value.values())
    if isinstance(value, list):
        return limit > 0 and all(depth_within(v, limit - 1) for v in value)
    return True


def check(rec: object) -> str | None:
    """Why ``rec`` is not a raw-log record, or None."""
    if type(rec) is not dict:
        return "not a JSON object"
    t = rec.get("t")
    if type(t) is not float and type(t) is not int:  # not a bool, not text
        return "field t is not a number"
    if not math.isfinite(t) or not 0 <= t <= MAX_T:
        return f"field t is {t!r}, not a host time"
    rx = rec.get("rx")
    if rx is not None or "rx" in rec:
        if type(rx) is not str:
            return "field rx is not text"
        if not rx.isascii():
            try:
                rx.encode("latin-1")
            except UnicodeEncodeError:
                return "field rx holds a character beyond latin-1 (not a byte)"
        return None
    if "event" not in rec:
        return "neither rx nor event"
    if not isinstance(rec["event"], str):
        return "field event is not text"
    detail = rec.get("detail", "")
    if not isinstance(detail, (str, dict)):
        return "field detail is neither text nor an object"
    if not depth_within(detail, MAX_DEPTH):
        return f"field detail is nested deeper than {MAX_DEPTH} levels"
    return None
