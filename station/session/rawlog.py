"""The session's raw log: every chunk of bytes, with a host timestamp, written before parsing.

One JSON object per line, appended and flushed per chunk, fsync'd at least once a second:

    {"t": 1763800867.123456, "rx": "?0001 C1  09:06:42.7183 00\\r"}
    {"t": 1763800900.5, "event": "disconnected", "detail": "[Errno 5] Input/output error"}

``rx`` is the bytes decoded as latin-1, which maps each byte to one character, so the bytes
come back exactly (``rx.encode("latin-1")``) while the file stays readable and greppable.
A process killed mid-write leaves at most one torn last line; the reader passes over it and
says so, and everything before it replays.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Iterator
from dataclasses import dataclass

from station.errors import InputError

FSYNC_INTERVAL_S = 1.0


@dataclass(frozen=True)
class Chunk:
    """Bytes as they arrived, or a connection event (``data`` empty, ``event`` set)."""

    t: float
    data: bytes = b""
    event: str = ""
    detail: str = ""


class RawLogWriter:
    """Append-only writer; every call is on disk (flushed) before it returns."""

    def __init__(self, path: str, header: dict | None = None) -> None:
        self.path = path
        new = not os.path.exists(path) or os.path.getsize(path) == 0
        self._fh = open(path, "a", encoding="ascii", newline="\n")  # noqa: SIM115
        self._last_sync = 0.0
        if new and header is not None:
            self._write({"t": time.time(), "event": "session", "detail": header})

    def _write(self, record: dict) -> None:
        self._fh.write(json.dumps(record, ensure_ascii=True, separators=(",", ":")) + "\n")
        self._fh.flush()
        now = time.monotonic()
        if now - self._last_sync >= FSYNC_INTERVAL_S:
            os.fsync(self._fh.fileno())
            self._last_sync = now

    def write(self, t: float, data: bytes) -> None:
        self._write({"t": t, "rx": data.decode("latin-1")})

    def event(self, t: float, event: str, detail: str = "") -> None:
        self._write({"t": t, "event": event, "detail": detail})

    def sync(self) -> None:
        self._fh.flush()
        os.fsync(self._fh.fileno())
        self._last_sync = time.monotonic()

    def close(self) -> None:
        if not self._fh.closed:
            self.sync()
            self._fh.close()


def read_rawlog(path: str, warnings: list[str] | None = None) -> Iterator[Chunk]:
    """The chunks of a raw log in order. A torn last line (killed mid-write) is passed over
    with a warning; a bad line anywhere else is an error naming it."""
    try:
        fh = open(path, encoding="ascii", newline="\n")  # noqa: SIM115
    except OSError as exc:
        raise InputError(f"cannot read raw log: {exc.strerror}", path=path) from None
    with fh:
        lines = fh.read().split("\n")
    last = len(lines)
    while last and not lines[last - 1]:
        last -= 1
    for i, text in enumerate(lines[:last], start=1):
        try:
            rec = json.loads(text)
            t = float(rec["t"])
        except (ValueError, KeyError, TypeError):
            if i == last:
                if warnings is not None:
                    warnings.append(f"{path}:{i}: torn last record passed over (killed mid-write?)")
                return
            raise InputError("not a raw-log record", path=path, line=i) from None
        if "rx" in rec:
            yield Chunk(t, rec["rx"].encode("latin-1"))
        else:
            detail = rec.get("detail", "")
            yield Chunk(
                t,
                b"",
                str(rec.get("event", "")),
                json.dumps(detail) if isinstance(detail, dict) else str(detail),
            )
