"""The session's raw log: every chunk of bytes, with a host timestamp, written before parsing.

One JSON object per line, appended and flushed per chunk, fsync'd by a timer within a second:

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
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass

from station.errors import InputError
from station.files import MAX_RAWLOG, read_bytes

FSYNC_INTERVAL_S = 1.0


@dataclass(frozen=True)
class Chunk:
    """Bytes as they arrived, or a connection event (``data`` empty, ``event`` set)."""

    t: float
    data: bytes = b""
    event: str = ""
    detail: str = ""


class RawLogWriter:
    """Append-only writer; every call is flushed to the OS before it returns, and a timer thread
    fsyncs what was written within ``FSYNC_INTERVAL_S``.

    The sync is on a timer, not on the next write: a timer that sends one line and then falls
    silent for ten minutes must not leave that line in the page cache all that time (a power
    cut at the trackside would lose it). The writing thread never waits for the disk. An fsync
    that fails (disk gone) is raised by the next write or by :meth:`close`."""

    def __init__(
        self, path: str, header: dict | None = None, fsync_interval_s: float = FSYNC_INTERVAL_S
    ) -> None:
        self.path = path
        new = not os.path.exists(path) or os.path.getsize(path) == 0
        try:
            self._fh = open(path, "a", encoding="ascii", newline="\n")  # noqa: SIM115
        except OSError as exc:
            raise InputError(
                f"cannot write the raw log: {exc.strerror or exc}", path=path
            ) from None
        self._lock = threading.Lock()
        self._dirty = False
        self._closed = threading.Event()
        self._sync_error: OSError | None = None
        self.interval_s = fsync_interval_s
        self._syncer = threading.Thread(target=self._sync_loop, name="rawlog-fsync", daemon=True)
        self._syncer.start()
        if new and header is not None:
            self._write({"t": time.time(), "event": "session", "detail": header})

    def _sync_loop(self) -> None:
        # half the interval: a record written just after a check is on disk within the interval
        while not self._closed.wait(self.interval_s / 2):
            with self._lock:
                if self._dirty and not self._fh.closed:
                    try:
                        os.fsync(self._fh.fileno())
                        self._dirty = False
                    except OSError as exc:
                        self._sync_error = exc

    def _write(self, record: dict) -> None:
        text = json.dumps(record, ensure_ascii=True, separators=(",", ":")) + "\n"
        with self._lock:
            if self._sync_error is not None:
                exc, self._sync_error = self._sync_error, None
                raise exc
            self._fh.write(text)
            self._fh.flush()
            self._dirty = True

    def write(self, t: float, data: bytes) -> None:
        self._write({"t": t, "rx": data.decode("latin-1")})

    def event(self, t: float, event: str, detail: str = "") -> None:
        self._write({"t": t, "event": event, "detail": detail})

    def sync(self) -> None:
        with self._lock:
            self._fh.flush()
            os.fsync(self._fh.fileno())
            self._dirty = False

    def close(self) -> None:
        self._closed.set()
        if self._syncer.is_alive() and self._syncer is not threading.current_thread():
            self._syncer.join()
        if not self._fh.closed:
            try:
                self.sync()
            finally:
                self._fh.close()


def read_rawlog(path: str, warnings: list[str] | None = None) -> Iterator[Chunk]:
    """The chunks of a raw log in order. A torn last line (killed mid-write) is passed over
    with a warning; a bad line anywhere else is an error naming it."""
    # ASCII by construction; a damaged byte makes its line "not a raw-log record", named
    lines = read_bytes(path, MAX_RAWLOG, "raw log").decode("ascii", "replace").split("\n")
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
