"""The one acquisition loop: what ``station record``, the UI's ``live`` and ``demo``, and every
replay (CLI and UI) run.

    source ──chunk──▶ raw log ──▶ processor ──finished descent──▶ queue ──▶ fit worker
    (serial reader                (lines, impulses,                         fit, results CSV,
     or replay)                    descents)                                listener

- **Raw log first**: every chunk is on disk before the processor sees it; whatever happens
  after, the day replays.
- **Fitting and the results CSV are consumers**, isolated from the reader: a finished descent
  goes on a queue; a fit worker fits it and rewrites the CSV. A fit that raises gives that
  descent ``status: error`` with the reason (:mod:`station.session.analysis`); a CSV that cannot
  be written is reported and tried again after the next descent; any other exception in a
  consumer is reported and the worker goes on. Nothing a consumer does reaches the reader.
- **One way to end**: :meth:`Acquisition.close` stops the source, ends the open descent as the
  end of a capture does (the processor's ``finish``), waits for the fits and writes the CSV.
  Quitting the UI, Ctrl-C or SIGTERM in ``record``, and the end of a replay all go through it,
  so a session replays to the same CSV however it was ended.
- **Annotations from elsewhere**: what ``station annotate`` appends to the session being
  recorded is taken up by the fit worker (when idle, and by :meth:`Acquisition.close`), applied
  with the recorder's own in the order of the annotations file, as a replay applies them.
- **Snapshots only**: the outside world hears of the day through a :class:`Listener`, called
  with immutable records (:mod:`station.session.records`), never with the day itself.

Replays run the same loop without threads (``threaded=False``): the fits run in line, in order.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import os
import queue
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import replace
from typing import IO, Any

from station.session import folder as sessions
from station.session.analysis import DescentResult
from station.session.comparing import Comparer
from station.session.config import SerialConfig, StationConfig
from station.session.day import Day, Effect
from station.session.fitstore import FitStore
from station.session.intake import AnnotationIntake, effect_now
from station.session.jobs import STOP, End, Fit, Job, WriteResults
from station.session.listener import Listener
from station.session.rawlog import Chunk, RawLogWriter
from station.session.records import (
    DescentStatus,
    DescentTimes,
    LineCounts,
    ResultRow,
)
from station.session.replay import replay_chunks, write_events
from station.session.resultsfile import ResultsFile
from station.session.resultsstate import Fitted, fitted_of
from station.session.watch import ConfigWatch
from station.survey.load import load_survey
from station.survey.track import Track, build_track
from station.timing.assembly import TimedDescent

#: how often an idle fit worker looks for annotations another process (``station annotate``)
#: appended to the session being recorded
ANNOTATIONS_POLL_S = 0.5
#: how long the end of ``station record`` waits to print the whole day's decisions
FINAL_COMPARISON_S = 30.0


class Acquisition(AnnotationIntake):
    """One test day being acquired from a source (serial port or replay)."""

    def __init__(
        self,
        day: Day,
        listener: Listener | None = None,
        *,
        session_dir: str | None = None,
        rawlog: RawLogWriter | None = None,
        threaded: bool = True,
        compare: bool = False,
        ski_rotation: Sequence[str] = (),
    ) -> None:
        self.day = day
        self.listener = listener or Listener()
        self.session_dir = session_dir
        self.rawlog = rawlog
        #: a replay in line keeps every descent's speed curve and fit (the report draws them
        #: all); a recording or the UI keeps the curve only in what it hands to the listener
        #: (12 kB a descent, half a 2000-descent day's memory: the UI asks again for the one it
        #: shows), and the fit only in the session's fit store where it has one (4 kB a
        #: descent: :attr:`DescentResult.fit` reads it back)
        self.keep_curves = not threaded
        #: likewise every impulse's fate (``replay --events`` lists them; the UI is told each)
        self.keep_events = not threaded
        self.ski_rotation = tuple(ski_rotation)
        self.lock = threading.Lock()  # guards the day: processor, results, annotations
        self.finished_descents = 0  # descents the processor ended, aborted ones not counted
        self._counted = bytearray()  # 1 at n - 1: descent n counted in finished_descents
        self.source_error: BaseException | None = None
        self._stop = threading.Event()
        self._source: threading.Thread | None = None
        self._reader: Any = None
        self._announced: int | None = None
        self._closed = False
        #: the results CSV (its header: the session's config and survey do not change during
        #: the day, so their digests are read once)
        self.results_file = ResultsFile(
            session_dir, lambda: sessions.results_header(self.config, self.track.name)
        )
        #: why the day's results may not be what a replay of its raw log gives (a chunk or a
        #: job that failed, an annotation that changed descents fitted before it): then the
        #: recording leaves no results state and the first annotate replays; None: they are
        self.not_as_replayed: str | None = None
        self._fit_from = -1  # the highest descent whose fit has begun (under the lock)
        self._closing = False
        self._jobs: queue.Queue[object] = queue.Queue()
        #: held while the session is recorded (``station sessions``, ``annotate`` try it)
        self.recording_lock: sessions.RecordingLock | None = None
        self._ann_offset = 0  # bytes of annotations.jsonl taken up (own and others' records)
        self._own_lines: list[str] = []  # own records appended, not yet read back
        self._last_poll = 0.0
        self._worker: threading.Thread | None = None
        # the day's comparison, in a process of its own (never the fit worker's: at 2000
        # descents a joint fit takes seconds, and the next descent's fit would wait for it)
        self.comparer: Comparer | None = None
        #: what the timer sends against what the config expects (a live source only)
        self._watch: ConfigWatch | None = None
        if threaded:
            self._worker = threading.Thread(target=self._work, name="fit-worker", daemon=True)
            self._worker.start()
            if compare:
                self.comparer = Comparer(
                    day.track,
                    post=lambda cmp: self._tell(self.listener.comparison, cmp),
                    warn=lambda text: self._tell(self.listener.warning, text),
                )

    @classmethod
    def open(
        cls,
        config: StationConfig,
        listener: Listener | None = None,
        *,
        session_dir: str | None = None,
        date: dt.date | None = None,
        threaded: bool = True,
        compare: bool = False,
        ski_rotation: Sequence[str] = (),
    ) -> Acquisition:
        """A new day. With ``session_dir`` the session folder is created (config and survey
        copied into it), the day runs from that copy as its replay will, and the raw log and
        the results CSV are written there."""
        rawlog = None
        lock = None
        listener = listener or Listener()
        if session_dir is not None:
            # the user's own config and survey first: a photocell the survey lacks is said
            # naming their files, before a folder is made that the next try would find not
            # empty (the day itself then runs from the session's copy, as its replay will)
            Day.start(config, build_track(load_survey(config.survey_path)), date)
            sessions.create(config, session_dir)
            lock = sessions.RecordingLock.take(session_dir)  # held until close(): "recording"
        try:
            if session_dir is not None:
                config = sessions.load_session_config(session_dir)
            day = Day.start(config, build_track(load_survey(config.survey_path)), date)
            if session_dir is not None:
                rawlog = RawLogWriter(
                    os.path.join(session_dir, sessions.RAW),
                    header={"port": config.serial.port, "protocol": config.serial.protocol},
                    on_problem=listener.warning,  # a full disk: one line, red in the UI
                )
        except BaseException:
            if lock is not None:
                lock.release()
            raise
        acq = cls(
            day,
            listener,
            session_dir=session_dir,
            rawlog=rawlog,
            threaded=threaded,
            compare=compare,
            ski_rotation=ski_rotation,
        )
        acq.recording_lock = lock
        if session_dir is not None:  # stored as they are made: the day's replays reuse them
            day.analyser.fits = FitStore.for_session(session_dir, config)
        for problem in (lock.problem if lock is not None else "", day.analyser.site_warning):
            if problem:
                acq._tell(acq.listener.warning, problem)
        if session_dir is not None:
            acq._submit(WriteResults())
        if ski_rotation:
            acq.add_metadata({"ski": ski_rotation[0]}, from_descent=1)
        return acq

    @property
    def config(self) -> StationConfig:
        return self.day.config

    @property
    def track(self) -> Track:
        return self.day.track

    # ------------------------------------------------------------------ sources

    def start_serial(self, serial: SerialConfig | None = None) -> None:
        """Read the timer in a thread of its own until :meth:`stop` or :meth:`close`."""
        from station.session.serialport import SerialReader

        cfg = serial or self.config.serial
        self._watch = ConfigWatch(cfg.protocol, self.config.channels)

        def on_chunk(t: float, data: bytes) -> None:
            self.receive(Chunk(t, data))

        def on_event(t: float, event: str, detail: str) -> None:
            self.receive(Chunk(t, b"", event, detail))
            self._tell(self.listener.connection, event, detail)

        self._reader = SerialReader(cfg, on_chunk, on_event, self.idle)

        def read() -> None:
            self._reader.run()  # in this thread: the reader ends when stopped
            if self._reader.error is not None:
                self.source_error = self._reader.error
                self._tell(self.listener.connection, "error", str(self._reader.error))

        self._start_source(read, "serial-reader")

    def start_replay(
        self, source: str, speed: float | None = None, warnings: list[str] | None = None
    ) -> None:
        """Replay a session or a capture in a thread, paced at ``speed`` (the UI)."""
        self._start_source(lambda: self.replay(source, speed, warnings), "replay")

    def replay(
        self, source: str, speed: float | None = None, warnings: list[str] | None = None
    ) -> None:
        """Feed a session (its annotations first) or a plain capture through the loop, in
        this thread; at its end, end the open descent and tell the listener when all is fitted."""
        try:
            if sessions.is_session(source):
                for a in sessions.read_annotations(source):
                    with self.lock:
                        self.day.apply(a)
            name = os.path.basename(os.path.normpath(source))
            self._tell(self.listener.connection, "replay", name)
            for chunk in replay_chunks(source, speed, self._stop, warnings):
                self.receive(chunk)
        except BaseException as exc:
            if self._worker is None:
                raise  # a replay on the command line: its InputError is the command's
            self.source_error = exc
            self._tell(self.listener.connection, "error", str(exc))
            return
        if self._stop.is_set():
            return
        self.end_of_input()
        self._submit(End())

    def _start_source(self, target: Callable[[], None], name: str) -> None:
        if self._closed:  # quit before the source was ready (the demo's simulator starting)
            return
        self._source = threading.Thread(target=target, name=name, daemon=True)
        self._source.start()

    @property
    def reading(self) -> bool:
        """The source is still running."""
        return self._source is not None and self._source.is_alive()

    # ------------------------------------------------------------------ the loop

    def receive(self, chunk: Chunk) -> None:
        """A chunk from the source: raw log first, then the processor."""
        if self.rawlog is not None:
            if chunk.event:
                self.rawlog.event(chunk.t, chunk.event, chunk.detail)
            else:
                self.rawlog.write(chunk.t, chunk.data)  # on disk before anything parses it
        with self.lock:
            n = len(self.day.processor.events)
            try:
                done = self.day.processor.feed(chunk)
            except Exception as exc:  # noqa: BLE001 - the bytes are logged; go on reading
                done = []
                self._not_as_replayed("a chunk could not be processed")
                self._tell(self.listener.warning, f"a chunk could not be processed: {exc!r}")
            jobs = self._after(n, done)
        self._submit_all(jobs)

    def idle(self, t: float) -> None:
        """After every read: end a descent whose time-out passed (logged, so replay ends it too)."""
        with self.lock:
            done = self.day.processor.tick(t)
            if done and self.rawlog is not None:
                self.rawlog.event(t, "timeout")
            jobs = self._after(len(self.day.processor.events), done) if done else []
        self._submit_all(jobs)

    def end_of_input(self) -> None:
        """The source ended: its unfinished last line, then the open descent."""
        with self.lock:
            n = len(self.day.processor.events)
            jobs = self._after(n, self.day.processor.finish())
        self._submit_all(jobs)

    def _after(self, first_event: int, done: list[TimedDescent]) -> list[Job]:
        """With the lock held: what the chunk did, for the listener; the finished descents."""
        proc = self.day.processor
        cur = proc.assembler.current
        jobs: list[Job] = []
        if cur is not None and cur.number != self._announced:
            self._announced = cur.number
            jobs += self._descent_started(cur.number)
        if self.listener.live_view:
            new = tuple(proc.events[first_event:])
            if new:
                self._tell(self.listener.impulses, new, proc.line_counts())
            if new or done:
                self._tell(self.listener.progress, self.day.progress())
        if self._watch is not None:  # what the timer sent, against what the config expects
            for text in self._watch.look(proc, first_event, time.monotonic()):
                self._tell(self.listener.warning, text)
        if not self.keep_events:
            # a recording hands each impulse's fate to the listener once and keeps none: a
            # replay of the raw log lists them all (--events); 1.5 kB a descent otherwise
            del proc.events[:]
        for d in done:
            times = DescentTimes.of(d)
            d.settle(times)  # the assembler keeps the day's one copy of its times, not two
            if times.status != DescentStatus.ABORTED and self._first_end(times.number):
                self.finished_descents += 1
            jobs.append(Fit(times))
        return jobs

    def _first_end(self, number: int) -> bool:
        """With the lock held: descent ``number`` ends (not aborted) for the first time. An
        edit at the timer or the timer's memory ends a descent again (refitted): counted
        twice, ``--max-descents`` stopped the recording a descent early, and that one was
        lost (one byte a descent)."""
        counted = self._counted
        if number > len(counted):
            counted.extend(bytes(number - len(counted)))
        if counted[number - 1]:
            return False
        counted[number - 1] = 1
        return True

    def _descent_started(self, number: int) -> list[Job]:
        """The demo's skis: when a descent starts, the next pair is already waiting."""
        if not self.ski_rotation:
            return []
        ski = self.ski_rotation[number % len(self.ski_rotation)]
        return self._add_metadata_locked({"ski": ski}, number + 1)[1]

    # ------------------------------------------------------------------ consumers

    def _submit(self, job: Job) -> None:
        if self._worker is None:
            self._run(job)
        else:
            self._jobs.put(job)

    def _submit_all(self, jobs: Iterable[Job]) -> None:
        for job in jobs:
            self._submit(job)

    def _work(self) -> None:
        while True:
            try:
                job = self._jobs.get(timeout=ANNOTATIONS_POLL_S)
            except queue.Empty:
                self._run_poll()
                continue
            if job is STOP:
                return
            self._run(job)  # type: ignore[arg-type]
            if time.monotonic() - self._last_poll > 2 * ANNOTATIONS_POLL_S:
                self._run_poll()  # a busy worker looks too

    def _run_poll(self) -> None:
        try:
            self._poll_annotations()
        except Exception as exc:  # noqa: BLE001 - the day goes on
            self._tell(self.listener.warning, f"reading {sessions.ANNOTATIONS} failed: "
                       f"{type(exc).__name__}: {exc}")  # fmt: skip

    def _run(self, job: Job) -> None:
        """One job; whatever it raises is reported, never passed to the reader."""
        try:
            self._handle(job)
        except Exception as exc:  # noqa: BLE001 - the day goes on
            self._not_as_replayed(f"a {type(job).__name__.strip('_').lower()} job failed")
            self._tell(self.listener.warning, f"{type(job).__name__.strip('_').lower()} "
                       f"failed: {type(exc).__name__}: {exc}")  # fmt: skip

    def _handle(self, job: Job) -> None:
        day = self.day
        if isinstance(job, WriteResults):
            with self.lock:
                current = day.snapshot()
            self._write_session_csv(current)
            return
        if isinstance(job, End):
            with self.lock:
                counts, snapshot = day.processor.line_counts(), day.snapshot()
            self._tell(self.listener.ended, counts, snapshot)
            if self.comparer is not None:  # the whole day's comparison, once, shown or not
                self.comparer.source_ended()
            return
        with self.lock:
            if isinstance(job, Fit):
                effect = Effect(refit=(job.descent.number,))
                fit_jobs = [day.fit_job(job.descent)]
                self._fit_from = max(self._fit_from, job.descent.number)
            else:
                a = job.annotation
                effect = effect_now(day, a) if job.applied else day.annotate(a)
                # a refit after later descents gives the replay's fit: the survey covariance
                # each descent takes does not hang on the order of the fits (Analyser)
                fit_jobs = [day.fit_job(day.results[n].descent) for n in effect.refit]
        fitted = [day.analyser.run(j) for j in fit_jobs]  # outside the lock: the reader goes on
        kept = fitted if self.keep_curves else [r.lean() for r in fitted]
        with self.lock:
            views = [day.store(r) for r in kept] + [day.view(n) for n in effect.changed]
        if views:
            self._save_csv(views)
        for i, v in enumerate(views):
            if i < len(fitted) and v is not fitted[i]:  # the listener shows the new fit whole
                f = fitted[i]
                v = replace(v, kept_fit=f.kept_fit, speed_x=f.speed_x, speed_v=f.speed_v)
            self._tell(self.listener.result, v)
        if self.comparer is not None:
            for v in views:
                self.comparer.update(v)

    def show_comparison(self, shown: bool) -> None:
        """A view opened (True) or closed (False) the comparison: computed only while shown."""
        if self.comparer is not None:
            self.comparer.show(shown)

    def _save_csv(self, results: Sequence[DescentResult]) -> None:
        """The session's results CSV up to date with ``results`` (:meth:`ResultsFile.save`)."""
        self._say(self.results_file.save(results, self.results))

    def _write_session_csv(self, snapshot: Sequence[DescentResult]) -> None:
        """The session's results CSV in full (:meth:`ResultsFile.write_all`)."""
        self._say(self.results_file.write_all(snapshot))

    def _say(self, line: str | None) -> None:
        if line is not None:
            self._tell(self.listener.warning, line)

    def _not_as_replayed(self, why: str) -> None:
        if self.not_as_replayed is None:
            self.not_as_replayed = why

    def _write_results_state(self) -> None:
        """At the end of a recording, with the annotations file held: the results state a
        replay would write with the CSV (:meth:`ResultsFile.end_recording`), when nothing
        says the results differ from a replay's."""
        why = self.not_as_replayed
        if why is None:
            if self.results_file.problem is not None:
                why = "the results CSV was not written"
            elif self.rawlog is None or self.rawlog.lost_records:
                why = "records of the raw log were lost"
            elif self.source_error is not None:
                why = "the timer could not be read"
        self.not_as_replayed = self.results_file.end_recording(why, self._as_fitted)

    def _as_fitted(self) -> tuple[list[ResultRow], Fitted]:
        with self.lock:
            return [r.row for r in self.day.snapshot()], fitted_of(self.day)

    def _tell(self, fn: Callable[..., None], *args: Any) -> None:
        """Call the listener; what it raises stays with it."""
        with contextlib.suppress(Exception):  # a listener must never stop the loop
            fn(*args)

    # ------------------------------------------------------------------ ending

    def stop(self) -> None:
        """Stop reading (from any thread); the day is not ended yet: see :meth:`close`."""
        self._stop.set()
        if self._reader is not None:
            self._reader.stop()
        src = self._source
        if src is not None and src is not threading.current_thread():
            src.join(timeout=10)

    def close(self, comparison_wait_s: float = 0.0) -> None:
        """End the day as the end of a capture would: stop the source, end the open descent,
        fit what is left, write the results CSV, close the raw log. Idempotent. Then the
        comparison ends, after ``comparison_wait_s`` at most for the whole day's."""
        if self._closed:
            return
        self._closed = True
        try:
            self._end_day()
        finally:
            if self.comparer is not None:
                self.comparer.close(comparison_wait_s)

    def _end_day(self) -> None:
        try:
            self.stop()
            self.end_of_input()
            self._closing = True
            if self._worker is not None:
                self._jobs.put(STOP)
                self._worker.join()
            with contextlib.ExitStack() as held:
                jobs: list[Job] = []
                if self.session_dir is not None:  # the last records others appended
                    try:
                        with self.lock:
                            locked = sessions.annotations_locked(self.session_dir)
                            if held.enter_context(locked) is not True:
                                self._not_as_replayed("the annotations file could not be held")
                            jobs = self._take_up_locked()
                    except Exception as exc:  # noqa: BLE001 - the CSV and the raw log first
                        self._not_as_replayed("annotations could not be taken up at the end")
                        self._tell(self.listener.warning, f"annotations entered elsewhere may "
                                   f"be missing from the results CSV: {exc}")  # fmt: skip
                for job in jobs:
                    self._run(job)
                with self.lock:
                    snapshot = self.day.snapshot()
                self._save_csv(snapshot)  # written already, unless a write failed
                if self.rawlog is not None:
                    self.rawlog.close()
                if self.session_dir is not None:  # the raw log as it stays, the CSV final
                    self._write_results_state()
                if self.recording_lock is not None:  # inside the annotations lock: see above
                    self.recording_lock.release()
        finally:
            if self.recording_lock is not None:
                self.recording_lock.release()  # the results CSV is final: no longer recording

    # ------------------------------------------------------------------ views

    @property
    def csv_problem(self) -> str | None:
        """Why the session's results CSV is not written now (None: it is)."""
        return self.results_file.problem

    def speed_curve(self, res: DescentResult) -> tuple[Any, Any] | None:
        """The fitted speed along the run of a result kept without it (one model solve, no
        fit; the UI's plot of the descent it shows)."""
        return self.day.analyser.speed_curve(res)

    def results(self) -> tuple[DescentResult, ...]:
        """Every descent as the results show it."""
        with self.lock:
            return self.day.snapshot()

    def line_counts(self) -> LineCounts:
        """The lines read so far and what became of them (for the summary a command prints)."""
        with self.lock:
            return self.day.processor.line_counts()

    def write_csv(self, path: str) -> int:
        """The results CSV at ``path`` (export, ``replay --csv``, the UI's ``e``); returns the
        number of descents written."""
        results = self.results()
        self.results_file.export([r.row for r in results], path)
        return len(results)

    def write_events_to(self, fh: IO[str]) -> None:
        """Every parsed impulse and its fate (``replay --events``: a replay keeps them)."""
        write_events(self.day.processor, fh)

    def write_csv_to(self, fh: IO[str]) -> None:
        """The results CSV into an open text file: ``--csv -`` writes to standard output."""
        self.results_file.export_to(fh, [r.row for r in self.results()])

    def write_session_results(self, session: str, annotations_sha256: str | None) -> str:
        """The results CSV of this replay into the session folder ``session``, with the state
        that lets the next annotate change rows in place (``annotations_sha256``: of the
        annotations file the replay applied, taken before it read them); returns its path."""
        rows, fitted = self._as_fitted()
        out = ResultsFile(session, self.results_file.header)
        return out.write_replay(rows, annotations_sha256, fitted)
