"""The session's raw log: every chunk of bytes, with a host timestamp, written before parsing.

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
- **Every record is checked where it is read** (:func:`read_rawlog`): a record that is not a
  JSON object with a finite time, a latin-1 ``rx`` or a text event, or that is nested too deep
  or too long, is passed over with a warning naming its line, as a torn last record is.
  Reading is one pass, linear in the file's size.
"""

from __future__ import annotations

import contextlib
import errno
import json
import math
import os
import re
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from itertools import compress, repeat
from typing import BinaryIO, NamedTuple

from station.errors import InputError
from station.files import MAX_RAWLOG, MiB, open_regular

FSYNC_INTERVAL_S = 1.0
#: what a writer holds in memory while the disk is full: hours of a timer's output (a busy
#: day's raw log is a few MB), far below what would hurt the laptop
MAX_HELD = 64 * MiB
#: the longest record a reader accepts: a 64 MB memory import written as one chunk, every
#: byte escaped (``\u00XX``, 6 characters); a record longer is passed over unread
MAX_RECORD = 6 * 64 * MiB + 4096
#: nesting of a record's ``detail`` (the session header is one level)
MAX_DEPTH = 8
#: the latest host time a record may carry (year 2286): ``datetime.fromtimestamp`` takes it
MAX_T = 1e10
#: bad records named one by one in the warnings; the rest are counted in one more line
MAX_NAMED = 10


class Chunk(NamedTuple):
    """Bytes as they arrived, or a connection event (``data`` empty, ``event`` set). A
    NamedTuple, not a frozen dataclass: a replay of a session makes one per record, and a
    frozen dataclass's ``__init__`` cost a fifth of reading the record."""

    t: float
    data: bytes = b""
    event: str = ""
    detail: str = ""


def _size(n: int) -> str:
    return f"{n / MiB:.1f} MB" if n >= MiB else f"{n} bytes"


def _why(exc: OSError) -> str:
    if exc.errno == errno.ENOSPC:
        return "the disk is full"
    return exc.strerror or str(exc)


def _is_record(text: bytes) -> bool:
    try:
        return _check(json.loads(text)) is None
    except (ValueError, RecursionError):
        return False


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
        if _is_record(tail):
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


def _depth(value: object, limit: int) -> bool:
    """``value`` nests at most ``limit`` levels."""
    if isinstance(value, dict):
        return limit > 0 and all(_depth(v, limit - 1) for v in value.values())
    if isinstance(value, list):
        return limit > 0 and all(_depth(v, limit - 1) for v in value)
    return True


def _check(rec: object) -> str | None:
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
    if not _depth(detail, MAX_DEPTH):
        return f"field detail is nested deeper than {MAX_DEPTH} levels"
    return None


_decode = json.JSONDecoder().decode  # a str in: json.loads would sniff the bytes' encoding

#: the common record exactly as :class:`RawLogWriter` writes it: a host time in plain decimal
#: (below 1e10, so within ``MAX_T``), then bytes that are printable ASCII or one of the
#: escapes ``\r`` ``\n`` ``\t``. Such a line is a valid record by construction (what
#: :func:`_check` asks of one), so it is read without the JSON decoder and the check; any
#: other line, valid or not, goes the general way.
_COMMON = re.compile(
    rb'\{"t":((?:0|[1-9][0-9]{0,9})(?:\.[0-9]{1,20})?),"rx":"((?:[ !#-\[\]-~]|\\[rnt])*)"\}\n'
).fullmatch
#: its most common case: one line of printable ASCII and its CR (ALGE, Microgate)
_ONE_LINE = re.compile(
    rb'\{"t":((?:0|[1-9][0-9]{0,9})(?:\.[0-9]{1,20})?),"rx":"([ !#-\[\]-~]*)\\r"\}\n'
).fullmatch
_new_chunk = tuple.__new__


def _unescape(rx: bytes) -> bytes:
    """The bytes of a common record's ``rx`` (JSON escapes of CR, LF and TAB only)."""
    if b"\\" not in rx:
        return rx
    return rx.replace(b"\\r", b"\r").replace(b"\\n", b"\n").replace(b"\\t", b"\t")


class _Records:
    """The careful reading of a raw log's records, one line at a time: what both readers do
    with a line that is not the common record (:func:`read_rawlog` with every line). Counts the
    lines (for the warnings) and the bytes (the log may grow while it is read)."""

    def __init__(self, path: str, fh: BinaryIO, warnings: list[str] | None) -> None:
        self.path = path
        self.fh = fh
        self.warnings = warnings
        self.bad = 0  # bad records passed over
        self.i = 0  # the line number of the latest line
        self.total = 0  # bytes read

    def readline(self) -> bytes:
        """The next line from the file (at most ``MAX_RECORD`` + 1 bytes), b"" at its end."""
        try:
            return self.fh.readline(MAX_RECORD + 1)
        except OSError as exc:
            raise InputError(f"cannot read raw log: {_why(exc)}", path=self.path) from None

    def passed_over(self, i: int, why: str) -> None:
        self.bad += 1
        if self.warnings is not None and self.bad <= MAX_NAMED:
            self.warnings.append(f"{self.path}:{i}: {why}; passed over")

    def record(self, raw: bytes) -> Chunk | None:
        """The chunk of the line ``raw`` (one from :meth:`readline`, or a whole line read
        otherwise, or the unended last), or None when it is blank or passed over."""
        self.i += 1
        i = self.i
        self.total += len(raw)
        if self.total > MAX_RAWLOG:  # grew while read
            raise InputError(f"is larger than {_size(MAX_RAWLOG)}, the limit for a raw log",
                             path=self.path)  # fmt: skip
        common = _ONE_LINE(raw)  # a whole line: never one cut at the limit
        if common is not None:
            return _new_chunk(Chunk, (float(common[1]), common[2] + b"\r", "", ""))
        common = _COMMON(raw)
        if common is not None:
            return _new_chunk(Chunk, (float(common[1]), _unescape(common[2]), "", ""))
        if len(raw) > MAX_RECORD and not raw.endswith(b"\n"):
            while raw and not raw.endswith(b"\n"):  # the rest of the line, unread
                raw = self.fh.readline(MiB)
                self.total += len(raw)
            self.passed_over(i, f"record longer than {_size(MAX_RECORD)}, not a raw-log record")
            return None
        whole = raw.endswith(b"\n")
        # ASCII by construction: a damaged byte becomes U+FFFD, which no field takes
        text = raw.decode("ascii", "replace")
        if not text or text.isspace():
            return None
        why: str | None
        try:
            rec = _decode(text)
            why = _check(rec)
        except RecursionError:
            why = "nested too deep"
        except ValueError:
            why = "not JSON"
        if why is not None:
            if whole:
                self.passed_over(i, f"not a raw-log record ({why})")
            elif self.warnings is not None:
                self.warnings.append(
                    f"{self.path}:{i}: torn last record passed over (killed mid-write?)"
                )
            return None
        if "rx" in rec:
            return Chunk(float(rec["t"]), rec["rx"].encode("latin-1"))
        detail = rec.get("detail", "")
        return Chunk(
            float(rec["t"]),
            b"",
            rec["event"],
            json.dumps(detail) if isinstance(detail, dict) else detail,
        )

    def close(self) -> None:
        if self.warnings is not None and self.bad > MAX_NAMED:
            self.warnings.append(
                f"{self.path}: {self.bad - MAX_NAMED} more bad record(s) passed over"
            )


def read_rawlog(path: str, warnings: list[str] | None = None) -> Iterator[Chunk]:
    """The chunks of a raw log in order, read in one pass. A torn last line (killed
    mid-write) and a bad record anywhere (not JSON, a field of the wrong type, a time that is
    not finite, nested too deep, longer than ``MAX_RECORD``) are passed over, each with a
    warning naming its line (the first ``MAX_NAMED``; the rest counted in one more)."""
    fh = open_regular(path, MAX_RAWLOG, "raw log")
    with fh:
        records = _Records(path, fh, warnings)
        readline, record = records.readline, records.record
        while raw := readline():
            chunk = record(raw)
            if chunk is not None:
                yield chunk
    records.close()


class Lines(NamedTuple):
    """A run of common records (:func:`read_rawlog_bulk`): reads of printable ASCII, none
    empty, each ending in a CR or not, with no other CR (a live recording's every read of an
    ALGE or Microgate timer: a whole line, or part of one as the port gave it). A replay takes
    the lines (or the run's bytes) and the host times of the reads that ended them, with no
    object a record; :meth:`chunks` gives the records as the careful reader does."""

    #: each record's host time
    t: list[float]
    #: each record's text: without its CR when ``ends`` is None (every record is one line and
    #: its CR: its line), else as written in the log (a CR as the two characters ``\r``)
    rx: list[str]
    #: None: every record ends in a CR; else the host time of each that does, in order
    ends: list[float] | None
    #: the run's bytes (latin-1), CRs as CRs, when ``ends`` is not None
    text: str

    def chunks(self) -> list[Chunk]:
        """The run as the careful reader gives it, a chunk a record."""
        if self.ends is None:
            return [Chunk(t, (rx + "\r").encode("ascii"))
                    for t, rx in zip(self.t, self.rx, strict=True)]  # fmt: skip
        return [Chunk(t, rx.replace("\\r", "\r").encode("ascii"))
                for t, rx in zip(self.t, self.rx, strict=True)]  # fmt: skip


#: the bulk reader's block: a few thousand records; a line not ended within ``BULK_LONG``
#: is read the careful way, from the file
BULK_BLOCK = 256 * 1024
BULK_LONG = 4 * MiB
#: a block's whole rest is checked again after a line that is not a common record when the
#: block's first check missed at most this many lines (the session's header, an event); each
#: check costs a scan of the block
BULK_RETRIES = 2
#: a block whose first check missed more than one line in ``BULK_DENSE`` is read the careful
#: way, and so are the next 1, 3, 7 … (at most ``BULK_BACKOFF``) unchecked: a log of other
#: records (a TAG timer's CR LF) costs a check no more than a few blocks in a hundred
BULK_DENSE = 8
BULK_BACKOFF = 7
#: a run of common records shorter than this among others is read the careful way (a run
#: costs a few microseconds, a record one)
BULK_SHORT = 8
_LINES = re.compile(rb"[^\n]*\n").findall  # each whole line, its line end kept
_NUM = r"(?:0|[1-9][0-9]{0,9})(?:\.[0-9]{1,20})?"  # as in _ONE_LINE: a plain decimal below 1e10
_TXT = r"[ !#-\[\]-~]*"  # printable ASCII but " and \
#: a common record is ``{"t":NUM,"rx":"TXT"}`` or ``{"t":NUM,"rx":"TXT\r"}`` (not empty) and
#: its line end; after a line end, its head (and the line end before it) ...
_HEAD = re.compile(r'\n\{"t":(' + _NUM + r'),"rx"').findall
#: ... and its tail, which ends the line: ``:"TXT\r"}`` and the line end (the text: the line),
#: or any common record's, ``:"TXT"}`` too (the text as written, its CR escaped)
_TAIL_LINE = re.compile(r':"(' + _TXT + r')\\r"\}\n').findall
_TAIL = re.compile(r':"(' + _TXT + r'(?:\\r)?)"\}\n').findall
_ENDS_CR = '\\r"}\n'  # (only at a line's end)
_EMPTY = ':""}\n'
#: a run of common records from where it is matched on
_RUN = re.compile(r'(?:\{"t":' + _NUM + r',"rx":"(?=[^"])' + _TXT + r'(?:\\r)?"\}\n)+').match


def _tails(text: str, a: int, b: int, n: int) -> tuple[list[str], bool]:
    """The texts of the ``n`` lines ``text[a:b]`` as their tails give them, and whether each
    ends in an escaped CR (then the tails give the lines themselves, without it). Why one
    function: a block checked whole (:func:`_common_run`) and a run found by ``_RUN``
    (:func:`_found_run`) must read their texts alike, and each had these lines."""
    one_line = text.count(_ENDS_CR, a, b) == n
    return (_TAIL_LINE if one_line else _TAIL)(text, a, b), one_line


def _run_of(ts: list[str], rxs: list[str], one_line: bool) -> Lines:
    """The run of the common records of host times ``ts`` (as written) and texts ``rxs``
    (the lines, when ``one_line``; else as written)."""
    t = list(map(float, ts))
    if one_line:
        return Lines(t, rxs, None, "")
    text = "".join(rxs)
    if "\\" in text:  # (only in the escape of a CR)
        text = text.replace("\\r", "\r")
    return Lines(t, rxs, list(compress(t, map(str.endswith, rxs, repeat("\\r")))), text)


def _common_run(text: str, a: int, b: int) -> Lines | int:
    """The lines ``text[a:b]`` (``text[a - 1]`` a line end, ``text[b - 1]`` another) as one
    run when every one is a common record, else about how many are not (at least 1): a few
    scans and sums, no Python a line.

    Why the counts and lengths suffice: a head starts at a line end and holds no other, so
    with ``n`` lines (the ``n`` line ends before them are at ``a - 1`` and the first ``n - 1``
    within; the last cannot start one before ``b``) ``n`` heads are one at each line's
    start. A tail holds one line end, its last: ``n`` tails are one at each line's end. A
    line's tail cannot start before its head ends (it holds a ``"`` only as its second and its
    last but two characters, it starts with a ``:``, and the head ends ``,"rx"``), so the
    heads (10 characters and the time) and tails (5 and the text as written) add up to the
    lines' length only when each line is its head and its tail and nothing between: a common
    record, or an empty one (``:""}``: none is common)."""
    n = text.count("\n", a, b)
    ts = _HEAD(text, a - 1, b)
    if len(ts) != n:
        return max(1, n - len(ts))
    rxs, one_line = _tails(text, a, b, n)
    if len(rxs) != n:
        return max(1, n - len(rxs))
    if (17 if one_line else 15) * n + len("".join(ts)) + len("".join(rxs)) != b - a:
        return 1
    if not one_line and text.find(_EMPTY, a, b) >= 0:
        return 1
    return _run_of(ts, rxs, one_line)


def _found_run(text: str, a: int, b: int) -> Lines:
    """The run of common records ``text[a:b]`` found by ``_RUN``: their heads and tails, one
    of each a line."""
    rxs, one_line = _tails(text, a, b, text.count("\n", a, b))
    return _run_of(_HEAD(text, a - 1, b), rxs, one_line)


def read_rawlog_bulk(path: str, warnings: list[str] | None = None) -> Iterator[Chunk | Lines]:
    """What :func:`read_rawlog` reads, the same chunks and warnings, with runs of the common
    record (a read of printable ASCII, ending in a CR or not) as :class:`Lines`: for a bulk
    replay (``replay SESSION --no-fit``), where reading a record at a time was the most of it.

    The log is read in blocks of ``BULK_BLOCK``; the whole records of a block are checked to
    be common records all at once (:func:`_common_run`), and are one run then. Otherwise the
    runs among them are found by one match each, and every other line (an event, a read of
    several lines, of a CR LF or of nothing, a damaged or torn record, a byte beyond ASCII)
    is read the careful way (:class:`_Records`, as :func:`read_rawlog` reads it). A record cut by a
    block's end waits for the next block; one not ended within ``BULK_LONG``, and every
    line once the log has grown past its limit while read, is read from the file as
    :func:`read_rawlog` reads it."""
    fh = open_regular(path, MAX_RAWLOG, "raw log")
    with fh:
        records = _Records(path, fh, warnings)
        record = records.record
        rest = b""  # the unended line at the end of what was read
        offset = 0  # the file's offset of ``rest``
        backoff = skip = 0  # blocks read the careful way unchecked: after many other records
        while True:
            try:
                # no line longer than a careful read of one (it would cut it at the limit)
                block = fh.read(min(BULK_BLOCK, MAX_RECORD + 1 - len(rest)))
            except OSError as exc:
                raise InputError(f"cannot read raw log: {_why(exc)}", path=path) from None
            if not block:
                if rest:  # the unended last line
                    chunk = record(rest)
                    if chunk is not None:
                        yield chunk
                break
            data = rest + block
            cut = data.rfind(b"\n") + 1  # the whole lines: data[:cut]
            if not cut:  # no line ended yet
                rest = data
                if len(rest) > min(BULK_LONG, MAX_RECORD):  # from the file, as read_rawlog does
                    fh.seek(offset)
                    raw = records.readline()
                    chunk = record(raw) if raw else None
                    if chunk is not None:
                        yield chunk
                    offset = fh.tell()
                    rest = b""
                continue
            rest = data[cut:]
            offset += cut
            # every line the careful way: the log grew past its limit while read (said at its
            # line), or the blocks before held many other records (a TAG timer's CR LF)
            careful = records.total + cut > MAX_RAWLOG or skip > 0
            if not careful:
                # text[k + 1] is data[k]: a line end before the first line
                text = "\n" + data[:cut].decode("latin-1")
                end = cut + 1
                run = _common_run(text, 1, end)
                if isinstance(run, Lines):
                    records.i += len(run.t)
                    records.total += cut
                    backoff = 0
                    yield run
                    continue
                misses = run
                if misses * BULK_DENSE > text.count("\n", 1, end):  # many other records: this
                    careful = True  # block and the next 1, 3, 7 … careful, unchecked
                    skip = backoff = min(2 * backoff + 1, BULK_BACKOFF)
                else:
                    backoff = 0
            else:
                skip = max(0, skip - 1)
            if careful:
                for raw in _LINES(data, 0, cut):
                    chunk = record(raw)
                    if chunk is not None:
                        yield chunk
                continue
            pos = 1
            retries = 0 if misses > BULK_RETRIES else BULK_RETRIES
            while pos < end:
                if retries and pos > 1:  # the rest of the block all common, after a line?
                    retries -= 1
                    run = _common_run(text, pos, end)
                    if isinstance(run, Lines):
                        records.i += len(run.t)
                        records.total += end - pos
                        yield run
                        break
                m = _RUN(text, pos, end)
                if m is not None:  # common records: a run of them, unless a few
                    b = m.end()
                    if text.count("\n", pos, b) >= BULK_SHORT:
                        run = _found_run(text, pos, b)
                        records.i += len(run.t)
                        records.total += b - pos
                        yield run
                        pos = b
                        if pos == end:
                            break
                nl = text.index("\n", pos) + 1
                chunk = record(data[pos - 1 : nl - 1])
                if chunk is not None:
                    yield chunk
                pos = nl
    records.close()
