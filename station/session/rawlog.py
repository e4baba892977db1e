"""The session's raw log, read: its records in order, each checked where it is read.

A record that is not a JSON object with a finite time, a latin-1 ``rx`` or a text event, or
that is nested too deep or too long, is passed over with a warning naming its line, as a torn
last record is (:mod:`station.session.rawlog_record` says what a record is; the writer, with
its guarantees, is :mod:`station.session.rawlog_writer`). Reading is one pass, linear in the
file's size.

The log is read a block of whole lines at a time and decoded by msgspec into typed records
in one call: a replay's hundreds of thousands of records without Python a record. A block
the decoder does not take as it is (a damaged or torn record, a blank line, a byte beyond
ASCII, a value out of range) is halved until the lines at fault are read one at a time by
the standard library's decoder and :func:`~station.session.rawlog_record.check`, which name
what is wrong with each.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Iterator
from itertools import compress, repeat
from operator import attrgetter
from typing import NamedTuple

import msgspec

from station.errors import InputError
from station.files import MAX_RAWLOG, MiB, open_regular
from station.session.rawlog_record import MAX_T, Chunk, check
from station.session.rawlog_record import size as _size
from station.session.rawlog_record import why as _why
from station.session.rawlog_writer import FSYNC_INTERVAL_S, MAX_HELD, RawLogWriter, repair_tail

__all__ = [
    "FSYNC_INTERVAL_S",
    "MAX_HELD",
    "MAX_NAMED",
    "MAX_RECORD",
    "Chunk",
    "Lines",
    "RawLogWriter",
    "read_rawlog",
    "read_rawlog_bulk",
    "repair_tail",
]

#: the longest record a reader accepts: a 64 MB memory import written as one chunk, every
#: byte escaped (``\u00XX``, 6 characters); a record longer is passed over unread
MAX_RECORD = 6 * 64 * MiB + 4096
#: bad records named one by one in the warnings; the rest are counted in one more line
MAX_NAMED = 10
#: the bytes read at a time: a few thousand records
BLOCK = 256 * 1024
#: a block the typed decoding does not take is halved down to this many lines, then read a
#: line at a time
CAREFUL_LINES = 16


class _Record(msgspec.Struct, gc=False):
    """A record as the writer writes it: its host time, and its bytes or an event."""

    t: float
    rx: str | msgspec.UnsetType = msgspec.UNSET
    event: str | msgspec.UnsetType = msgspec.UNSET
    detail: str | dict = ""


_decode_block = msgspec.json.Decoder(_Record).decode_lines
_decode = json.JSONDecoder().decode  # a str in: json.loads would sniff the bytes' encoding
_t, _rx = attrgetter("t"), attrgetter("rx")
_new_chunk = tuple.__new__
_LINES = re.compile(rb"[^\n]*\n").findall  # each whole line, its line end kept
#: a character a run's reads may not hold (printable ASCII and the CR only)
_NOT_PRINTABLE = re.compile(r"[^ -~\r]").search


class Lines(NamedTuple):
    """A run of records (:func:`read_rawlog_bulk`) whose reads are printable ASCII, none empty,
    each ending in a CR or not, with no other CR (a live recording's every read of an ALGE or
    Microgate timer: a whole line, or part of one as the port gave it). A replay takes the
    lines (or the run's bytes) and the host times of the reads that ended them, with no object
    a record; :meth:`chunks` gives the records one by one."""

    #: each record's host time
    t: list[float]
    #: each record's text: without its CR when ``ends`` is None (every record is one line and
    #: its CR: its line), else as read
    rx: list[str]
    #: None: every record ends in a CR; else the host time of each that does, in order
    ends: list[float] | None
    #: the run's bytes (latin-1), CRs as CRs, when ``ends`` is not None
    text: str

    def chunks(self) -> list[Chunk]:
        """The run a chunk a record."""
        if self.ends is None:
            return [_new_chunk(Chunk, (t, (rx + "\r").encode("ascii"), "", ""))
                    for t, rx in zip(self.t, self.rx, strict=True)]  # fmt: skip
        return [_new_chunk(Chunk, (t, rx.encode("ascii"), "", ""))
                for t, rx in zip(self.t, self.rx, strict=True)]  # fmt: skip


class _Careful(Exception):
    """A block holds a line the typed decoding does not take as it is."""


def _fits(rx: str) -> bool:
    """A read :class:`Lines` takes: printable ASCII, not empty, a CR only at its end."""
    return bool(rx) and _NOT_PRINTABLE(rx) is None and rx.count("\r") == rx.endswith("\r")


def _lines_of(ts: list[float], rxs: list[str]) -> Lines:
    """The run of reads that fit :class:`Lines` (their host times and texts)."""
    ended = list(map(str.endswith, rxs, repeat("\r")))
    if all(ended):
        return Lines(ts, "".join(rxs)[:-1].split("\r"), None, "")
    return Lines(ts, rxs, list(compress(ts, ended)), "".join(rxs))


def _run(ts: list[float], rxs: list[str]) -> list[Chunk | Lines]:
    """Records of bytes (their host times and texts, each checked but for latin-1) as runs
    of :class:`Lines` and, between them, a chunk a record that does not fit one."""
    text = "".join(rxs)
    if (
        text.isascii()
        and all(rxs)
        and _NOT_PRINTABLE(text) is None
        and text.count("\r") == sum(map(str.endswith, rxs, repeat("\r")))
    ):
        return [_lines_of(ts, rxs)]
    out: list[Chunk | Lines] = []
    a = 0
    for k in [k for k, fits in enumerate(map(_fits, rxs)) if not fits]:
        rx = rxs[k]
        if not rx.isascii() and check({"t": 0, "rx": rx}) is not None:
            raise _Careful  # (beyond latin-1: named at its line)
        if k > a:
            out.append(_lines_of(ts[a:k], rxs[a:k]))
        out.append(_new_chunk(Chunk, (ts[k], rx.encode("latin-1"), "", "")))
        a = k + 1
    if a < len(rxs):
        out.append(_lines_of(ts[a:], rxs[a:]))
    return out


def _event(rec: _Record) -> Chunk:
    """The chunk of an event record, checked."""
    if rec.event is msgspec.UNSET or check({"t": rec.t, "event": rec.event, "detail": rec.detail}):
        raise _Careful
    detail = rec.detail
    return Chunk(rec.t, b"", rec.event, json.dumps(detail) if isinstance(detail, dict) else detail)


def _typed(block: bytes) -> list[Chunk | Lines]:
    """The records of ``block`` (whole lines), decoded at once, or :class:`_Careful`. Each
    line must be one record: a line end is never within a valid JSON value between a ``}``
    and a ``{``, so with every line end between them the lines hold one record each when
    there are as many records as lines."""
    n = block.count(b"\n")
    if not (block.isascii() and block[:1] == b"{" and block.count(b"}\n") == n
            and block.count(b"\n{") == n - 1):  # fmt: skip
        raise _Careful
    try:
        recs = _decode_block(block)
    except msgspec.MsgspecError:
        raise _Careful from None
    ts = list(map(_t, recs))
    if len(recs) != n or not (min(ts) >= 0 and max(ts) <= MAX_T):
        raise _Careful
    rxs = list(map(_rx, recs))
    if msgspec.UNSET not in rxs:
        return _run(ts, rxs)
    out: list[Chunk | Lines] = []
    a = 0
    for k in [k for k, rx in enumerate(rxs) if rx is msgspec.UNSET]:
        if k > a:
            out += _run(ts[a:k], rxs[a:k])
        out.append(_event(recs[k]))
        a = k + 1
    if a < n:
        out += _run(ts[a:], rxs[a:])
    return out


class _Reader:
    """One pass over an open raw log: the blocks decoded at once, the lines at fault one at a
    time. Counts the lines (for the warnings) and the bytes (the log may grow while read)."""

    def __init__(self, path: str, fd: int, warnings: list[str] | None) -> None:
        self.path = path
        self.fd = fd
        self.warnings = warnings
        self.bad = 0  # bad records passed over
        self.i = 0  # the line number of the latest line
        self.total = 0  # bytes read

    def read(self) -> bytes:
        try:
            return os.read(self.fd, BLOCK)
        except OSError as exc:
            raise InputError(f"cannot read raw log: {_why(exc)}", path=self.path) from None

    def items(self) -> Iterator[Chunk | Lines]:
        """The records in order, runs of reads as :class:`Lines`."""
        rest = b""  # the unended line at the end of what was read
        while block := self.read():
            data = rest + block if rest else block
            cut = data.rfind(b"\n") + 1
            if not cut and len(data) > MAX_RECORD:
                data = self._overlong(data)
                cut = data.rfind(b"\n") + 1
            if not cut:
                rest = data
                continue
            rest = data[cut:]
            yield from self._lines(data[:cut] if rest else data)
        if rest:  # the unended last line
            chunk = self.record(rest)
            if chunk is not None:
                yield chunk

    def _lines(self, block: bytes) -> Iterator[Chunk | Lines]:
        """The records of whole lines: at once, or halved, or a line at a time."""
        try:
            if self.total + len(block) > MAX_RAWLOG or len(block) > MAX_RECORD + 1:
                raise _Careful  # (said at its line; a line may be too long)
            items = _typed(block)
        except _Careful:
            n = block.count(b"\n")
            if n > CAREFUL_LINES:
                half = block.index(b"\n", len(block) // 2) + 1
                if half == len(block):
                    half = block.index(b"\n") + 1
                yield from self._lines(block[:half])
                yield from self._lines(block[half:])
                return
            yield from filter(None, map(self.record, _LINES(block)))
            return
        self.i += block.count(b"\n")
        self.total += len(block)
        yield from items

    def _overlong(self, start: bytes) -> bytes:
        """Pass over a line longer than ``MAX_RECORD`` (``start``: what was read of it),
        reading on to its end: the bytes after it."""
        self.i += 1
        i = self.i
        self._count(len(start))
        after = b""
        while block := self.read():
            k = block.find(b"\n")
            if k >= 0:
                self.total += k + 1
                after = block[k + 1 :]
                break
            self.total += len(block)
        self.passed_over(i, f"record longer than {_size(MAX_RECORD)}, not a raw-log record")
        return after

    def _count(self, n: int) -> None:
        self.total += n
        if self.total > MAX_RAWLOG:  # grew while read
            raise InputError(f"is larger than {_size(MAX_RAWLOG)}, the limit for a raw log",
                             path=self.path)  # fmt: skip

    def passed_over(self, i: int, why: str) -> None:
        self.bad += 1
        if self.warnings is not None and self.bad <= MAX_NAMED:
            self.warnings.append(f"{self.path}:{i}: {why}; passed over")

    def record(self, raw: bytes) -> Chunk | None:
        """The chunk of one line (the unended last too), or None when it is blank or passed
        over; what is wrong with it said."""
        self.i += 1
        i = self.i
        self._count(len(raw))
        whole = raw.endswith(b"\n")
        if len(raw) - whole > MAX_RECORD:
            self.passed_over(i, f"record longer than {_size(MAX_RECORD)}, not a raw-log record")
            return None
        # ASCII by construction: a damaged byte becomes U+FFFD, which no field takes
        text = raw.decode("ascii", "replace")
        if not text or text.isspace():
            return None
        why: str | None
        try:
            rec = _decode(text)
            why = check(rec)
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


def _items(path: str, warnings: list[str] | None) -> Iterator[Chunk | Lines]:
    fh = open_regular(path, MAX_RAWLOG, "raw log")
    with fh:
        reader = _Reader(path, fh.fileno(), warnings)
        yield from reader.items()
    reader.close()


def read_rawlog(path: str, warnings: list[str] | None = None) -> Iterator[Chunk]:
    """The chunks of a raw log in order, read in one pass. A torn last line (killed
    mid-write) and a bad record anywhere (not JSON, a field of the wrong type, a time that is
    not finite, nested too deep, longer than ``MAX_RECORD``) are passed over, each with a
    warning naming its line (the first ``MAX_NAMED``; the rest counted in one more)."""
    for item in _items(path, warnings):
        if isinstance(item, Lines):
            yield from item.chunks()
        else:
            yield item


def read_rawlog_bulk(path: str, warnings: list[str] | None = None) -> Iterator[Chunk | Lines]:
    """What :func:`read_rawlog` reads, the same records and warnings, with runs of reads of
    printable ASCII as :class:`Lines`: for a bulk replay (``replay SESSION --no-fit``)."""
    return _items(path, warnings)
