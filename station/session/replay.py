"""Replay sources: a session's raw log or a plain capture of a timer's output, as chunks paced
at a chosen speed; and the list of every parsed impulse with its fate.

The acquisition loop (:mod:`station.session.acquisition`) feeds these chunks through the same
processor as a live recording, so a replay reproduces the live results.
"""

from __future__ import annotations

import datetime as dt
import os
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import IO

from station import csvfiles
from station.files import MAX_CAPTURE, open_regular
from station.session import folder as sessions
from station.session.config import StationConfig
from station.session.processor import Processor
from station.session.rawlog import Chunk, Lines, read_rawlog, read_rawlog_bulk
from station.session.records import LineCounts
from station.timing.assembly import TimedDescent
from station.timing.impulses import format_tod

CAPTURE_CHUNK = 4096


def capture_chunks(path: str) -> Iterator[Chunk]:
    """A plain capture of a timer's output: bytes without host times."""
    with open_regular(path, MAX_CAPTURE, "capture") as fh:
        while data := fh.read(CAPTURE_CHUNK):
            yield Chunk(float("nan"), data)


def source_date(source: str, date: dt.date | None) -> dt.date | None:
    """The date of a replay: given, else a plain capture's file date (a session's raw log has
    host times of its own)."""
    if date is None and not sessions.is_session(source):
        return dt.date.fromtimestamp(os.path.getmtime(source))
    return date


def replay_chunks(
    source: str,
    speed: float | None = None,
    stop: threading.Event | None = None,
    warnings: list[str] | None = None,
) -> Iterator[Chunk]:
    """The chunks of a session's raw log or of a plain capture, paced at ``speed`` times the
    recorded host time (as fast as possible without), until ``stop`` is set. A plain capture
    has no host times: its chunks come with ``t = None``."""
    if sessions.is_session(source):
        chunks: Iterator[Chunk] = read_rawlog(os.path.join(source, sessions.RAW), warnings)
        if not speed and stop is None:  # a raw log's records all have host times
            yield from chunks
            return
    else:
        chunks = capture_chunks(source)
    first_t = None
    m0 = time.monotonic()
    for chunk in chunks:
        if stop is not None and stop.is_set():
            return
        has_time = chunk.t == chunk.t  # not NaN
        if speed and has_time:
            first_t = chunk.t if first_t is None else first_t
            delay = (chunk.t - first_t) / speed - (time.monotonic() - m0)
            if delay > 0:
                if stop is None:
                    time.sleep(delay)
                elif stop.wait(delay):
                    return
        yield chunk if has_time else Chunk(None, chunk.data)  # type: ignore[arg-type]


def bulk_chunks(source: str, warnings: list[str] | None = None) -> Iterator[Chunk | Lines]:
    """The chunks of ``source`` as fast as they come, for :meth:`Processor.feed_chunks`
    (``replay --no-fit``): a session's raw log read in bulk (runs of its common records as
    :class:`Lines`: :func:`read_rawlog_bulk`), a plain capture as :func:`replay_chunks`
    gives it."""
    if sessions.is_session(source):
        return read_rawlog_bulk(os.path.join(source, sessions.RAW), warnings)
    return replay_chunks(source, None, None, warnings)


def write_events(processor: Processor, fh: IO[str]) -> None:
    """The parsed impulses into an open text file (``newline=""``): line, channel, photocell,
    time, flag, kept or why not."""
    w = csvfiles.writer(fh, lineterminator="\r\n")  # a reason quotes the timer's line
    w.writerow(["line", "channel", "photocell", "time", "flag", "kept", "reason", "descent"])
    for e in processor.events:
        w.writerow(
            [e.line, e.channel, e.photocell or "", format_tod(e.tod_us, 4), e.flag,
             "yes" if e.kept else "no", e.reason, e.descent or ""]
        )  # fmt: skip
    for line, reason, text in processor.unparsed:
        w.writerow([line, "", "", "", "", "no", f"unparsed: {reason}: {text!r}", ""])


@dataclass(frozen=True)
class Unfitted:
    """``replay --no-fit`` of a session folder or a plain capture: its descents as they ended
    (one an edit changed, as it ended last), by number, nothing fitted, and the processor that
    made them (its line counts, every impulse's fate)."""

    descents: dict[int, TimedDescent]
    processor: Processor

    def line_counts(self) -> LineCounts:
        return self.processor.line_counts()

    def write_events_to(self, fh: IO[str]) -> None:
        """Every parsed impulse and its fate (:func:`write_events`)."""
        write_events(self.processor, fh)


def replay_unfitted(source: str, config: StationConfig, warnings: list[str]) -> Unfitted:
    """Framing, parsing and the descents of ``source``, nothing fitted: a quick check of a
    capture, its crossing times for another tool, and the measure of the replay's own
    throughput (benchmarks/replay_speed.py). ``warnings`` collects what the reader passed
    over."""
    from station import runtime
    from station.session.processor import Processor
    from station.survey.load import load_survey
    from station.survey.track import build_track

    proc = Processor(config, build_track(load_survey(config.survey_path)))
    ended: dict[int, TimedDescent] = {}  # a descent an edit changed ends again: the latest kept
    with runtime.bulk_without_collector():  # a bulk replay makes no garbage cycles
        for d in proc.feed_chunks(bulk_chunks(source, warnings)):
            ended[d.number] = d
        for d in proc.finish():
            ended[d.number] = d
    return Unfitted(ended, proc)
