"""Recording and replaying: the edge between the serial port or files and the processor.

``record`` logs every chunk to the raw log *before* the processor sees it, fits each finished
descent, prints one line per descent and rewrites the session's results CSV. ``replay`` feeds a
session's raw log, or a plain capture of a timer's output, through the same processor.
"""

from __future__ import annotations

import csv
import datetime as dt
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from station.errors import InputError
from station.session import store as sessions
from station.session.analysis import DescentResult
from station.session.config import StationConfig
from station.session.day import Day
from station.session.processor import Processor
from station.session.rawlog import Chunk, RawLogWriter, read_rawlog
from station.session.results import write_results
from station.survey.load import load_survey
from station.survey.track import build_track
from station.timing.assembly import TimedDescent
from station.timing.impulses import format_tod

CAPTURE_CHUNK = 4096


def describe(res: DescentResult) -> str:
    """One line per descent, for the terminal."""
    d, f = res.descent, res.fit
    when = res.start_time.replace("T", " ")[:22]
    used = f"{len(d.photocells)}/{len(d.photocells) + len(d.missing)}"
    head = f"descent {d.number:>3}  {when}  {used} photocells"
    if f is None:
        return f"{head}  {d.status}: {'; '.join(d.flags)}"
    e, ci = f.estimates, f.ci90

    def part(name: str, key: str, spec: str) -> str:
        if e.get(key) is None:
            return f"{name} —"
        c = ci.get(key)
        rng = f" [{format(c[0], spec)}, {format(c[1], spec)}]" if c else ""
        return f"{name} {format(e[key], spec)}{rng}"

    rms = res.row.get("rms_residual_ms")
    text = (
        f"{head}  {part('μ', 'mu', '.5f')}  {part('CdA', 'cda', '.4f')}  "
        f"v0 {_num(e.get('v0'), '.2f')}  rms {_num(rms, '.2f')} ms  {f.status}"
    )
    if d.flags:
        text += f"  ({'; '.join(d.flags)})"
    return text


def _num(v: float | None, spec: str) -> str:
    return "—" if v is None else format(v, spec)


@dataclass
class Run:
    """A test day being recorded or replayed: its :class:`Day` and where it came from."""

    day: Day

    @classmethod
    def start(cls, config: StationConfig, date: dt.date | None = None) -> Run:
        track = build_track(load_survey(config.survey_path))
        return cls(Day.start(config, track, date))

    @property
    def config(self) -> StationConfig:
        return self.day.config

    @property
    def processor(self) -> Processor:
        return self.day.processor

    @property
    def results(self) -> list[DescentResult]:
        return [self.day.results[k] for k in sorted(self.day.results)]

    def finish_descents(self, done: list[TimedDescent]) -> list[DescentResult]:
        return self.day.finish(done)

    def header(self) -> dict[str, str]:
        return sessions.results_header(self.config, self.day.track.name)

    def write_csv(self, path: str) -> None:
        write_results(self.day.rows(), path, self.header())

    def summary(self) -> str:
        c = self.processor.counts
        st: dict[str, int] = {}
        for r in self.results:
            st[r.row["status"]] = st.get(r.row["status"], 0) + 1
        parts = ", ".join(f"{v} {k}" for k, v in sorted(st.items()))
        return (
            f"{self.processor.lines} lines: {c['impulse']} impulses, {c['edit']} edits, "
            f"{c['skipped']} other timer lines, {c['unparsed']} unparsed; "
            f"{len(self.results)} descents" + (f" ({parts})" if parts else "")
        )


# ----------------------------------------------------------------------------- record


def record(
    config: StationConfig,
    session_dir: str,
    out: Callable[[str], None] = print,
    max_descents: int | None = None,
    duration_s: float | None = None,
) -> Run:
    """Record until SIGINT/SIGTERM, ``max_descents`` or ``duration_s``."""
    from station.session.serialport import SerialReader

    sessions.create(config, session_dir)
    config = sessions.load_session_config(session_dir)  # run from the snapshot, as replay will
    run = Run.start(config)
    results_path = os.path.join(session_dir, sessions.RESULTS)
    run.write_csv(results_path)
    log = RawLogWriter(
        os.path.join(session_dir, sessions.RAW),
        header={"port": config.serial.port, "protocol": config.serial.protocol},
    )
    lock = threading.Lock()
    stop = threading.Event()

    def finished(done: list[TimedDescent]) -> None:
        for res in run.finish_descents(done):
            out(describe(res))
        if done:
            run.write_csv(results_path)
            real = sum(r.descent.status != "aborted" for r in run.results)
            if max_descents is not None and real >= max_descents:
                stop.set()

    def on_chunk(t: float, data: bytes) -> None:
        log.write(t, data)  # first: on disk before anything parses it
        with lock:
            finished(run.processor.feed(Chunk(t, data)))

    def on_event(t: float, event: str, detail: str) -> None:
        log.event(t, event, detail)
        with lock:
            run.processor.feed(Chunk(t, b"", event, detail))
        if event == "disconnected":
            out(f"timer disconnected ({detail}); reconnecting")
        elif event == "connected":
            out(f"timer connected on {detail}")
        elif event == "open-failed":
            out(f"cannot open {config.serial.port} ({detail}); retrying")

    def on_idle(t: float) -> None:
        with lock:
            done = run.processor.tick(t)
            if done:
                log.event(t, "timeout")
                finished(done)

    reader = SerialReader(config.serial, on_chunk, on_event, on_idle)
    previous = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        previous[sig] = signal.signal(sig, lambda *_: stop.set())
    reader.start()
    t_end = None if duration_s is None else time.monotonic() + duration_s
    try:
        while not stop.is_set() and reader.is_alive():
            if t_end is not None and time.monotonic() >= t_end:
                break
            stop.wait(0.1)
    finally:
        reader.stop()
        reader.join(timeout=5)
        with lock:
            finished(run.processor.finish())
            run.write_csv(results_path)
        log.close()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if reader.error is not None:
        raise reader.error
    return run


# ----------------------------------------------------------------------------- replay


def capture_chunks(path: str) -> Iterator[Chunk]:
    """A plain capture of a timer's output: bytes without host times."""
    try:
        fh = open(path, "rb")  # noqa: SIM115
    except OSError as exc:
        raise InputError(f"cannot read capture: {exc.strerror}", path=path) from None
    with fh:
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


def replay(
    source: str,
    config: StationConfig,
    out: Callable[[str], None] = print,
    speed: float | None = None,
    date: dt.date | None = None,
    warnings: list[str] | None = None,
) -> Run:
    """Feed a session (with its annotations) or a plain capture through the processor."""
    run = Run.start(config, source_date(source, date))
    if sessions.is_session(source):
        for record in sessions.read_annotations(source):
            run.day.annotate(record)
    for chunk in replay_chunks(source, speed, warnings=warnings):
        for res in run.finish_descents(run.processor.feed(chunk)):
            out(describe(res))
    for res in run.finish_descents(run.processor.finish()):
        out(describe(res))
    return run


def write_events(run: Run, path: str) -> None:
    """The parsed impulses: line, channel, photocell, time, flag, kept or why not."""
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(["line", "channel", "photocell", "time", "flag", "kept", "reason", "descent"])
        for e in run.processor.events:
            w.writerow(
                [e.line, e.channel, e.photocell or "", format_tod(e.tod_us, 4), e.flag,
                 "yes" if e.kept else "no", e.reason, e.descent or ""]
            )  # fmt: skip
        for line, reason, text in run.processor.unparsed:
            w.writerow([line, "", "", "", "", "no", f"unparsed: {reason}: {text!r}", ""])
