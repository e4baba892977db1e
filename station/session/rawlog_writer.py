"""The session's raw log, written: every chunk of bytes, with a host timestamp, before parsing.

One JSON object per line, appended and flushed per chunk, fsync'd by a timer within a second:

    {"t": 1763800867.123456, "rx": "?0001 C1  09:06:42.7183 00\\r"}
    {"t": 1763800900.5, "event": "disconnected", "detail": "[Errno 5] Input/output error"}

``rx`` is the bytes decoded as latin-1, which maps each byte to one character, so the bytes
come back exactly (``rx.encode("latin-1")``) while the file stays readable and greppable.

What the station guarantees about this file, whatever happens to the disk or the process:

- **A full disk costs nothing the timer sent while space returns**: a record that cannot be
  written is held in memory (at most ``MAX_HELD`` bytes, said in one line naming the file),
  written again within half a second of space returning (by the fsync timer, also when the
  timer is silent), in order. A writer never raises for a failed write or fsync: the reader
  thread, the port and the processor go on.
- **The station never leaves a torn record**: a record half written when the disk filled is
  completed once space returns; one still held at :meth:`RawLogWriter.close` is cut off
  (``ftruncate``: needs no space), so the file ends on a whole record, and the loss is said.
- **A torn log is repaired, never built upon**: a writer opening a log whose last record is
  torn (killed mid-write, power cut) first moves the torn bytes to a side file
  ``raw.jsonl.torn-N`` and cuts them off, or ends a whole last record that lacks only its line
  end; :attr:`RawLogWriter.repair` says which.

Reading it is :mod:`station.session.rawlog`'s job.
"""

from __future__ import annotations

import contextlib
import json
import os
import threading
import time
from collections import deque
from collections.abc import Callable

from station.errors import InputError
from station.files import MiB
from station.session.rawlog_record import is_record
from station.session.rawlog_record import size as _size
from station.session.rawlog_record import why as _why

FSYNC_INTERVAL_S = 1.0
#: what a writer holds in memory while the disk is full: hours of a timer's output (a busy
#: day's raw log is a few MB), far below what would hurt the laptop
MAX_HELD = 64 * MiB


def repair_tail(path: str) -> str | None:
    """Make the log at ``path`` end on a whole record before anything is appended to it.

    A last line without its line end is either a whole record that lacks only the ``\\n``
    (it is ended) or a torn one: its bytes go to a side file ``PATH.torn-N`` (fsync'd first),
    then are cut off the log. Returns what was done, in one line naming the files, or None
    when the log was whole. Reads only the torn tail (from the last line end on)."""
    try:
        fd = os.open(path, os.O_RDWR | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        return None
    try:
        size = os.fstat(fd).st_size
        if size == 0 or os.pread(fd, 1, size - 1) == b"\n":
            return None
        end = size  # find the last line end, block by block from the end
        start = 0
        while end > 0:
            begin = max(0, end - 65536)
            block = os.pread(fd, end - begin, begin)
            k = block.rfind(b"\n")
            if k >= 0:
                start = begin + k + 1
                break
            end = begin
        tail = os.pread(fd, size - start, start)
        if is_record(tail):
            os.lseek(fd, 0, os.SEEK_END)
            os.write(fd, b"\n")
            os.fsync(fd)
            return f"{path}: its last record lacked its line end; ended before appending"
        n = 1
        while os.path.exists(f"{path}.torn-{n}"):
            n += 1
        side = f"{path}.torn-{n}"
        with open(side, "xb") as fh:
            fh.write(tail)
            fh.flush()
            os.fsync(fh.fileno())
        os.ftruncate(fd, start)
        os.fsync(fd)
        return (
            f"{path}: torn last record ({_size(len(tail))}, killed mid-write?) cut off before "
            f"appending; its bytes are kept in {side}"
        )
    finally:
        os.close(fd)


class RawLogWriter:
    """Append-only writer; every call is written to the OS before it returns, and a timer
    thread fsyncs what was written within ``FSYNC_INTERVAL_S``.

    The sync is on a timer, not on the next write: a timer that sends one line and then falls
    silent for ten minutes must not leave that line in the page cache all that time (a power
    cut at the trackside would lose it). The writing thread never waits for the disk.

    A write or fsync that fails (a full disk) never raises: the record is held in memory (up to
    ``max_held`` bytes; beyond, records are counted as lost and a ``lost`` event says so in the
    log once space returns), ``on_problem`` hears of it in one line naming the file, and the
    timer thread tries again every half interval. An existing log with a torn tail is repaired
    first (:func:`repair_tail`; :attr:`repair` says what was done)."""

    def __init__(
        self,
        path: str,
        header: dict | None = None,
        fsync_interval_s: float = FSYNC_INTERVAL_S,
        on_problem: Callable[[str], None] | None = None,
        max_held: int = MAX_HELD,
    ) -> None:
        self.path = path
        self.on_problem = on_problem
        self.max_held = max_held
        try:
            self.repair = repair_tail(path)
            self._fd = os.open(
                path,
                os.O_WRONLY | os.O_APPEND | os.O_CREAT | getattr(os, "O_CLOEXEC", 0),
                0o666,
            )
        except OSError as exc:
            raise InputError(f"cannot write the raw log: {_why(exc)}", path=path) from None
        self._lock = threading.Lock()
        self._dirty = False
        self._closed = threading.Event()
        self._held: deque[bytes] = deque()  # records not (wholly) written yet, in order
        self._held_bytes = 0
        self._head_written = 0  # bytes of the first held record already in the file
        self._failing: str | None = None  # the reason writes fail now; said once
        self._sync_failing: str | None = None
        self._dropped = 0  # records beyond max_held, not kept
        self._dropped_bytes = 0
        self._held_max = 0  # the most held at once during the current failure
        self._held_records = 0  # records that went through memory during it
        #: records the timer sent that are not in the file (dropped, or held at close)
        self.lost_records = 0
        self.lost_bytes = 0
        self.interval_s = fsync_interval_s
        self._syncer = threading.Thread(target=self._sync_loop, name="rawlog-fsync", daemon=True)
        self._syncer.start()
        if header is not None and os.fstat(self._fd).st_size == 0:
            self._write({"t": time.time(), "event": "session", "detail": header})

    @property
    def held_bytes(self) -> int:
        """Bytes held in memory, not yet in the file (a full disk)."""
        return self._held_bytes

    def _tell(self, said: list[str]) -> None:
        """Outside the lock: a listener may take its time."""
        if self.on_problem is not None:
            for text in said:
                with contextlib.suppress(Exception):  # a listener never stops the writer
                    self.on_problem(text)

    def _sync_loop(self) -> None:
        # half the interval: a record written just after a check is on disk within the interval
        while not self._closed.wait(self.interval_s / 2):
            said: list[str] = []
            with self._lock:
                if self._fd < 0:
                    return
                if self._held:
                    self._flush_locked(said)
                if self._dirty:
                    self._sync_locked(said)
            self._tell(said)

    def _sync_locked(self, said: list[str]) -> None:
        try:
            os.fsync(self._fd)
        except OSError as exc:
            why = _why(exc)
            if self._sync_failing != why:
                said.append(f"{self.path}: cannot sync the raw log to disk ({why}); retrying")
            self._sync_failing = why
            return
        self._dirty = False
        if self._sync_failing is not None:
            said.append(f"{self.path}: synced to disk again")
            self._sync_failing = None

    def _flush_locked(self, said: list[str]) -> bool:
        """Write what is held, in order; True once nothing is held."""
        while self._held:
            rec = self._held[0]
            try:
                n = os.write(self._fd, rec[self._head_written :])
            except OSError as exc:
                why = _why(exc)
                if self._failing is None:
                    said.append(
                        f"{self.path}: cannot write the raw log ({why}); what the timer sends "
                        f"is held in memory (up to {_size(self.max_held)}) and written when "
                        "space returns"
                    )
                self._failing = why
                return False
            self._dirty = True
            self._head_written += n
            if self._head_written == len(rec):
                self._held.popleft()
                self._held_bytes -= len(rec)
                self._head_written = 0
        if self._failing is not None:
            said.append(
                f"{self.path}: written again: {self._held_records} record(s) "
                f"(at most {_size(self._held_max)} held in memory) are on disk"
                + (f"; {self._dropped} record(s) beyond that were lost" if self._dropped else "")
            )
            self._failing = None
            self._held_max = self._held_records = 0
        if self._dropped:  # in the log where the gap is, once it can be written
            lost = {
                "t": time.time(),
                "event": "lost",
                "detail": f"{self._dropped} record(s), {self._dropped_bytes} bytes, not "
                "written: the disk was full and the memory bound reached",
            }
            self._dropped = self._dropped_bytes = 0
            self._held.append(self._encode(lost))
            self._held_bytes += len(self._held[-1])
            return self._flush_locked(said)
        return True

    @staticmethod
    def _encode(record: dict) -> bytes:
        return (json.dumps(record, ensure_ascii=True, separators=(",", ":")) + "\n").encode("ascii")

    def _write(self, record: dict) -> None:
        text = self._encode(record)
        said: list[str] = []
        with self._lock:
            if self._fd < 0:
                raise ValueError(f"{self.path}: the raw log is closed")
            if self._held:
                self._flush_locked(said)
            if self._held and self._held_bytes + len(text) > self.max_held:
                if not self._dropped:
                    said.append(
                        f"{self.path}: {_size(self._held_bytes)} held in memory, the bound; "
                        "what the timer sends now is lost until space returns (import the "
                        "timer's memory afterwards: station import … --into the session)"
                    )
                self._dropped += 1
                self._dropped_bytes += len(text)
                self.lost_records += 1
                self.lost_bytes += len(text)
            else:
                self._held.append(text)
                self._held_bytes += len(text)
                self._flush_locked(said)
                if self._held:  # this record is held (records leave from the front)
                    self._held_records += 1
                    self._held_max = max(self._held_max, self._held_bytes)
        self._tell(said)

    def write(self, t: float, data: bytes) -> None:
        self._write({"t": t, "rx": data.decode("latin-1")})

    def event(self, t: float, event: str, detail: str = "") -> None:
        self._write({"t": t, "event": event, "detail": detail})

    def sync(self) -> None:
        """Write what is held and fsync now (a failure is said, not raised)."""
        said: list[str] = []
        with self._lock:
            if self._fd >= 0:
                self._flush_locked(said)
                self._sync_locked(said)
        self._tell(said)

    def close(self) -> None:
        """Write what is held, fsync, close. What still cannot be written is cut off at the
        last whole record (the file never ends torn) and counted in :attr:`lost_records`;
        never raises."""
        self._closed.set()
        if self._syncer.is_alive() and self._syncer is not threading.current_thread():
            self._syncer.join()
        said: list[str] = []
        with self._lock:
            if self._fd < 0:
                return
            if not self._flush_locked(said):
                held = len(self._held)
                size = 0
                try:
                    size = os.fstat(self._fd).st_size
                    if self._head_written:
                        os.ftruncate(self._fd, size - self._head_written)
                except OSError as exc:
                    said.append(f"{self.path}: cannot cut off a torn record: {_why(exc)}")
                self.lost_records += held
                self.lost_bytes += self._held_bytes
                said.append(
                    f"{self.path}: {held} record(s) ({_size(self._held_bytes)}) the timer sent "
                    f"could not be written: {self._failing}; import the timer's memory "
                    "(station import … --into the session) to fill the gap"
                )
                self._held.clear()
                self._held_bytes = self._head_written = 0
            if self._dirty:
                self._sync_locked(said)
            os.close(self._fd)
            self._fd = -1
        self._tell(said)
