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
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import IO, Any

from station.session import store as sessions
from station.session.analysis import DescentResult, FitCache
from station.session.comparing import Comparer
from station.session.comparison import DayComparison
from station.session.config import SerialConfig, StationConfig
from station.session.day import Day, Effect
from station.session.fitstore import FitStore
from station.session.rawlog import Chunk, RawLogWriter
from station.session.records import (
    Annotation,
    DescentStatus,
    DescentTimes,
    LineCounts,
    Metadata,
    MetadataAnnotation,
    ModelChange,
    Progress,
    ResultRow,
)
from station.session.replay import replay_chunks, source_date
from station.session.resultsfile import ResultsFile
from station.session.resultsstate import Fitted, fitted_of
from station.survey.load import load_survey
from station.survey.track import Track, build_track
from station.timing.assembly import ImpulseEvent, TimedDescent


class Listener:
    """What an acquisition tells the outside world. Called from the reader and the fit worker
    threads, always with immutable records; the defaults do nothing, but for warnings, which
    go to stderr: a failure is never passed over in silence."""

    #: wants every impulse and the open descent's progress (the UI); a headless run does not
    live_view = False

    def connection(self, state: str, detail: str) -> None:
        """The timer connected, disconnected, cannot be opened; a replay started; an error."""

    def impulses(self, events: tuple[ImpulseEvent, ...], counts: LineCounts) -> None:
        """Impulses parsed from the latest chunk, with what became of each."""

    def progress(self, progress: Progress) -> None:
        """The open descent, and the number and metadata the next one will get."""

    def result(self, result: DescentResult) -> None:
        """A descent was fitted, fitted again, or marked."""

    def comparison(self, day: DayComparison) -> None:
        """The day's comparison of items, recomputed (while shown, and when the source
        ended)."""

    def warning(self, text: str) -> None:
        """Something failed and the acquisition went on."""
        print(f"warning: {text}", file=sys.stderr, flush=True)

    def ended(self, counts: LineCounts, results: tuple[DescentResult, ...]) -> None:
        """A replay reached its end and every descent is fitted: the lines read and the
        descents as the results show them (the summary is the listener's to word)."""


class QuietListener(Listener):
    """Says nothing, warnings neither: a replay whose caller reports only its results (export,
    annotate, compare, report), where a line per descent or a repeated site warning would
    bury the one answer asked for."""

    def warning(self, text: str) -> None:
        pass


@dataclass(frozen=True)
class _Fit:
    descent: DescentTimes


@dataclass(frozen=True)
class _Annotate:
    annotation: Annotation
    #: already applied to the day (a session's annotations are, in the order of its file):
    #: the job only fits again and shows what it concerns
    applied: bool = False


@dataclass(frozen=True)
class _End:
    """The source ended: tell the listener once every descent before it is fitted."""


@dataclass(frozen=True)
class _WriteResults:
    """Write the session's results CSV (the empty one at the start: on the worker, so the
    reader opens the port without waiting for the CSV writer to load)."""


_STOP = object()

#: how often an idle fit worker looks for annotations another process (``station annotate``)
#: appended to the session being recorded
ANNOTATIONS_POLL_S = 0.5
#: how long the recorder waits for another writer of the annotations file (it appends one
#: record) before it appends its own without the lock
ANNOTATIONS_WAIT_S = 2.0
#: how long the end of ``station record`` waits to print the whole day's decisions
FINAL_COMPARISON_S = 30.0
_Job = _Fit | _Annotate | _End | _WriteResults


class Acquisition:
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
        self.compare = compare
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
            acq._submit(_WriteResults())
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
        self._submit(_End())

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

    def _after(self, first_event: int, done: list[TimedDescent]) -> list[_Job]:
        """With the lock held: what the chunk did, for the listener; the finished descents."""
        proc = self.day.processor
        cur = proc.assembler.current
        jobs: list[_Job] = []
        if cur is not None and cur.number != self._announced:
            self._announced = cur.number
            jobs += self._descent_started(cur.number)
        if self.listener.live_view:
            new = tuple(proc.events[first_event:])
            if new:
                self._tell(self.listener.impulses, new, proc.line_counts())
            if new or done:
                self._tell(self.listener.progress, self.day.progress())
        if not self.keep_events:
            # a recording hands each impulse's fate to the listener once and keeps none: a
            # replay of the raw log lists them all (--events); 1.5 kB a descent otherwise
            del proc.events[:]
        for d in done:
            times = DescentTimes.of(d)
            d.settle(times)  # the assembler keeps the day's one copy of its times, not two
            if times.status != DescentStatus.ABORTED and self._first_end(times.number):
                self.finished_descents += 1
            jobs.append(_Fit(times))
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

    def _descent_started(self, number: int) -> list[_Job]:
        """The demo's skis: when a descent starts, the next pair is already waiting."""
        if not self.ski_rotation:
            return []
        ski = self.ski_rotation[number % len(self.ski_rotation)]
        return self._add_metadata_locked({"ski": ski}, number + 1)[1]

    # ------------------------------------------------------------------ annotations

    def add_metadata(self, values: Mapping[str, Any], from_descent: int | None = None) -> int:
        """Metadata for the next descent on (or from ``from_descent``), stored and applied at
        once, so the descent it is for sees it; returns the number it applies from."""
        with self.lock:
            start, jobs = self._add_metadata_locked(values, from_descent)
            progress = self.day.progress()
        self._submit_all(jobs)
        if self.listener.live_view:
            self._tell(self.listener.progress, progress)
        return start

    def _add_metadata_locked(
        self, values: Mapping[str, Any], from_descent: int | None
    ) -> tuple[int, list[_Job]]:
        start = from_descent if from_descent is not None else self.day.next_number()
        a = MetadataAnnotation(Metadata.from_values(values), from_descent=start, t=time.time())
        if self.session_dir is None:
            self.day.annotate(a)
            return start, []
        return start, self._record_locked(a)

    def annotate(self, a: Annotation) -> None:
        """An invalid mark, a valid mark or a refit: stored now, fitted again by the fit worker
        after the descents already queued."""
        if self.session_dir is None:
            self._submit(_Annotate(a))  # applied by the worker, in its turn
            return
        with self.lock:
            jobs = self._record_locked(a)
        self._submit_all(jobs)

    # -- annotations another process appends (``station annotate`` while this records)
    #
    # Every writer appends to annotations.jsonl only under its flock
    # (:func:`station.session.store.annotations_locked`). The recorder applies every record,
    # its own and the others', to the day at once and in the order of the file, as a replay
    # applies them; the fits they call for go to the worker, which sees by then every fit
    # already under way. The worker looks for others' records when idle; :meth:`close` takes
    # up the last of them and lets the recording lock go inside the flock, so an annotate
    # finds the session either recorded (its record is taken up here) or ended (it rewrites
    # the results CSV itself).

    def _record_locked(self, own: Annotation) -> list[_Job]:
        """With the lock held: store ``own`` after what others appended before it, and apply
        both in the file's order. A writer holding the file longer than ANNOTATIONS_WAIT_S
        does not stop the day: the record is appended without the file lock then."""
        assert self.session_dir is not None
        with sessions.annotations_locked(self.session_dir, ANNOTATIONS_WAIT_S):
            return self._take_up_locked(own)

    def _take_up_locked(self, own: Annotation | None = None) -> list[_Job]:
        """With the lock and the annotations file held: the records others appended since the
        last look, then ``own``, applied to the day; the jobs that fit again and show them."""
        assert self.session_dir is not None
        records, self._ann_offset = sessions.read_annotations_after(
            self.session_dir, self._ann_offset
        )
        taken: list[Annotation] = []
        for rec in records:
            if rec.line in self._own_lines:  # ours, applied when it was written
                self._own_lines.remove(rec.line)
            elif rec.problem:
                self._not_as_replayed("a record of the annotations file was passed over")
                self._tell(self.listener.warning, f"{sessions.ANNOTATIONS}: {rec.problem}; "
                           "passed over")  # fmt: skip
            elif rec.annotation is not None:
                taken.append(rec.annotation)
        if own is not None:
            self._own_lines.append(sessions.append_annotation(self.session_dir, own))
            taken.append(own)
        jobs: list[_Job] = []
        for a in taken:
            if (
                isinstance(a, MetadataAnnotation)
                and a.descents is None
                and self._fit_from >= (a.from_descent or 0)
            ):
                # a replay applies it to those fitted already (or being fitted); the
                # recording does not
                self._not_as_replayed("metadata from a descent already fitted on")
            self.day.annotate(a)
            if not (isinstance(a, MetadataAnnotation) and a.descents is None):
                jobs.append(_Annotate(a, applied=True))  # a change from N on: nothing to refit
        return jobs

    def _poll_annotations(self) -> None:
        """The worker, idle: take up what another process appended (without waiting for the
        file: a writer holding it is asked again at the next look)."""
        self._last_poll = time.monotonic()
        if self.session_dir is None or self._closing:
            return
        try:
            grown = os.path.getsize(os.path.join(self.session_dir, sessions.ANNOTATIONS))
        except OSError:
            return
        if grown <= self._ann_offset:
            return
        jobs: list[_Job] = []
        with self.lock, sessions.annotations_locked(self.session_dir, 0.0) as held:
            if held is not False:
                jobs = self._take_up_locked()
            progress = self.day.progress()
        for job in jobs:
            self._jobs.put(job)  # this worker runs them next, in order
        if jobs and self.listener.live_view:
            self._tell(self.listener.progress, progress)

    # ------------------------------------------------------------------ consumers

    def _submit(self, job: _Job) -> None:
        if self._worker is None:
            self._run(job)
        else:
            self._jobs.put(job)

    def _submit_all(self, jobs: Iterable[_Job]) -> None:
        for job in jobs:
            self._submit(job)

    def _work(self) -> None:
        while True:
            try:
                job = self._jobs.get(timeout=ANNOTATIONS_POLL_S)
            except queue.Empty:
                self._run_poll()
                continue
            if job is _STOP:
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

    def _run(self, job: _Job) -> None:
        """One job; whatever it raises is reported, never passed to the reader."""
        try:
            self._handle(job)
        except Exception as exc:  # noqa: BLE001 - the day goes on
            self._not_as_replayed(f"a {type(job).__name__.strip('_').lower()} job failed")
            self._tell(self.listener.warning, f"{type(job).__name__.strip('_').lower()} "
                       f"failed: {type(exc).__name__}: {exc}")  # fmt: skip

    def _handle(self, job: _Job) -> None:
        day = self.day
        if isinstance(job, _WriteResults):
            with self.lock:
                current = day.snapshot()
            self._write_session_csv(current)
            return
        if isinstance(job, _End):
            with self.lock:
                counts, snapshot = day.processor.line_counts(), day.snapshot()
            self._tell(self.listener.ended, counts, snapshot)
            if self.comparer is not None:  # the whole day's comparison, once, shown or not
                self.comparer.source_ended()
            return
        with self.lock:
            if isinstance(job, _Fit):
                effect = Effect(refit=(job.descent.number,))
                fit_jobs = [day.fit_job(job.descent)]
                self._fit_from = max(self._fit_from, job.descent.number)
            else:
                a = job.annotation
                effect = _effect_now(day, a) if job.applied else day.annotate(a)
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
                self._jobs.put(_STOP)
                self._worker.join()
            with contextlib.ExitStack() as held:
                jobs: list[_Job] = []
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


def _effect_now(day: Day, a: Annotation) -> Effect:
    """What an annotation the day already has calls for, now: the descents it concerns that
    are fitted by now (one fitted meanwhile was fitted before it, or with it: fitted again)."""
    if isinstance(a, MetadataAnnotation):
        numbers = sorted(a.descents or ())
        return Effect(refit=tuple(n for n in numbers if n in day.results))
    if a.descent not in day.results:
        return Effect()
    if isinstance(a, ModelChange):
        return Effect(refit=(a.descent,))
    return Effect(changed=(a.descent,))


# ----------------------------------------------------------------------------- commands


def record(
    config: StationConfig,
    session_dir: str,
    listener: Listener,
    max_descents: int | None = None,
    duration_s: float | None = None,
    started: Callable[[], None] | None = None,
) -> Acquisition:
    """Record headless until SIGINT/SIGTERM, ``max_descents`` or ``duration_s``; any of them
    ends the open descent the same way (:meth:`Acquisition.close`). ``started`` is called once
    the session folder is made and the raw log open (not for a folder refused)."""
    from station.session.serialport import ensure_port_free

    ensure_port_free(config.serial)  # a second recorder on the port: one line, no session made
    # compare, shown all along: the console says after every descent whether the day is
    # decided
    acq = Acquisition.open(config, listener, session_dir=session_dir, compare=True)
    acq.show_comparison(True)
    if started is not None:
        started()
    stop = threading.Event()
    previous = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        previous[sig] = signal.signal(sig, lambda *_: stop.set())
    t_end = None if duration_s is None else time.monotonic() + duration_s
    try:
        acq.start_serial()
        while not stop.is_set() and acq.reading:
            if t_end is not None and time.monotonic() >= t_end:
                break
            if max_descents is not None and acq.finished_descents >= max_descents:
                break
            stop.wait(0.1)
    finally:
        acq.close(comparison_wait_s=FINAL_COMPARISON_S)
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if acq.source_error is not None:
        raise acq.source_error
    return acq


def replay(
    source: str,
    config: StationConfig,
    listener: Listener | None = None,
    speed: float | None = None,
    date: dt.date | None = None,
    warnings: list[str] | None = None,
    fits: FitCache | None = None,
    speed_curves: bool = True,
) -> Acquisition:
    """Feed a session (with its annotations) or a plain capture through the loop, in line.
    Without a listener the replay says nothing as it goes: the caller reports its results
    (and ``warnings`` collects what the raw log's reader passed over). ``fits``: the fits
    stored with the session, used where they fit and added to; ``speed_curves``: the fitted
    speed along the run of each descent (for the views that draw it)."""
    import gc

    acq = Acquisition.open(
        config, listener or QuietListener(), date=source_date(source, date), threaded=False
    )
    acq.day.analyser.fits = fits
    acq.day.analyser.speed_curves = speed_curves
    # a replay makes objects by the hundred thousand and keeps most: the garbage collector
    # need not scan the set-up's (modules, the track, the grids) at every full collection
    gc.freeze()
    try:
        acq.replay(source, speed, warnings)
        acq.close()
    finally:
        gc.unfreeze()
    return acq
