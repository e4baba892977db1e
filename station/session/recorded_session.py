"""A recorded session as one object: open a session folder, replay it, its descents and fits
with the annotations applied, annotate it, compare its items, and say what it was computed
from.

``station annotate``, ``export``, ``sessions``, ``compare``, ``report`` and the UI's replay of a
session all go through :class:`RecordedSession`, so each of them replays the same way, reads
the same results CSV and keeps it current by the same rules (the recorder's lock honoured).
Before, each command built its own replay from the command line's arguments and the day's
comparison was glued together three times.

No I/O happens when the object is made but the check that the folder is a session; the
replay is run once, when a result is first asked for, and kept. An annotation that changes no
fit changes the rows it concerns without a replay, when the results CSV is the one a replay
wrote (:mod:`station.session.resultsfile`).
"""

from __future__ import annotations

import datetime as dt
import hashlib
import json
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import IO, TYPE_CHECKING, Any

from station import __version__
from station.errors import InputError
from station.files import (
    MAX_OBSERVATIONS,
    MAX_RAWLOG,
    check_output,
    check_regular,
    open_regular,
)
from station.session import folder as sessions
from station.session import resultsstate
from station.session.config import StationConfig
from station.session.listing import SessionStatus, SessionSummary, minute_of
from station.session.marks import Marks
from station.session.records import Annotation, LineCounts, Metadata
from station.session.results import read_results
from station.session.resultsfile import ResultsFile

# the replay, the fits and the comparison load numpy and scipy (a second): imported where
# they are used, so ``station annotate`` that needs no fit, and ``station sessions``, do not
if TYPE_CHECKING:
    from station.session.acquisition import Acquisition
    from station.session.analysis import DescentResult
    from station.session.comparison import DayComparison
    from station.session.day_analysis import DayAnalysis
    from station.session.fitstore import FitStore
    from station.session.listener import Listener
    from station.survey.track import Track

_BLOCK = 1 << 20


@dataclass(frozen=True)
class Provenance:
    """What a session's results were computed from, to tell two copies or two versions of a
    day apart: the raw log, the config and the survey by their SHA-256 (hex, in full), the
    station version that computes them now, and the host times of the first and last
    records of the raw log (seconds since the epoch; None when it has none)."""

    raw_sha256: str
    config_sha256: str
    survey_sha256: str
    station_version: str
    first_host_time: float | None
    last_host_time: float | None


@dataclass(frozen=True)
class SessionRow:
    """One descent of a session as its results CSV says, with the annotations entered since
    the CSV was written applied to its ski, wax and invalid mark (without refitting)."""

    descent: int
    descent_status: str
    status: str
    ski: str
    wax: str
    invalid_reason: str
    start_time: str = ""  # ISO 8601 local, as the CSV has it (an import's day is its descents')


def sha256_of(path: str, max_bytes: int, what: str) -> str:
    """The SHA-256 of a regular file of at most ``max_bytes``, read in blocks."""
    digest = hashlib.sha256()
    with open_regular(path, max_bytes, what) as fh:
        read = 0
        while block := fh.read(_BLOCK):
            read += len(block)
            if read > max_bytes:
                raise InputError(f"{what} grew past its limit while it was read", path=path)
            digest.update(block)
    return digest.hexdigest()


class RecordedSession:
    """A session folder (see :mod:`station.session.folder` for what it holds)."""

    def __init__(
        self, path: str, config: StationConfig | None = None, *, speed_curves: bool = False
    ) -> None:
        if not os.path.lexists(path):
            raise InputError("no such session folder", path=path)
        if not sessions.is_session(path):
            raise InputError("not a session directory (no raw.jsonl)", path=path)
        self.path = path
        self._config = config
        #: the quiet replay (:meth:`run`) draws each descent's fitted speed along the run
        #: (the report does; a listing, the results CSV and the comparison need none)
        self.speed_curves = speed_curves
        self._run: Acquisition | None = None
        #: what the raw log's reader passed over in the replay (a torn last record)
        self.warnings: list[str] = []

    # ------------------------------------------------------------------ what it is

    @property
    def name(self) -> str:
        return os.path.basename(os.path.normpath(os.path.abspath(self.path))) or "session"

    @property
    def config(self) -> StationConfig:
        """The session's own config snapshot (or the one it was opened with)."""
        if self._config is None:
            self._config = sessions.load_session_config(self.path)
        return self._config

    def file(self, name: str) -> str:
        return os.path.join(self.path, name)

    def recording_state(self) -> sessions.RecordingStatus:
        return sessions.recording_state(self.path)

    def first_record(self) -> Any:
        """The raw log's first record as JSON gives it (the session header), None when it
        cannot be read: a bounded read of a regular file (a FIFO or a link to a device is
        None)."""
        try:
            with open_regular(self.file(sessions.RAW), MAX_RAWLOG, "raw log") as fh:
                return json.loads(fh.readline(64 * 1024))
        except (InputError, OSError, ValueError):
            return None

    def started(self, first: Any = None) -> str:
        """Local date and time of the first raw-log record (``first``, if read already), ""
        when it cannot be read."""
        if first is None:
            first = self.first_record()
        try:
            t = float(first["t"])
            return dt.datetime.fromtimestamp(t).strftime("%Y-%m-%d %H:%M")
        except (ValueError, KeyError, TypeError, OverflowError):
            return ""

    def made_by_import(self, first: Any = None) -> bool:
        """Whether the raw log's header says ``station import`` wrote it (port "import
        FILE"): its records' host times are the import's, not the test day's."""
        if first is None:
            first = self.first_record()
        try:
            port = first["detail"]["port"] if first.get("event") == "session" else ""
        except (KeyError, TypeError, AttributeError):
            return False
        return isinstance(port, str) and port.startswith("import ")

    def provenance(self) -> Provenance:
        """What the results are computed from (reads the raw log, config and survey)."""
        from station.session.rawlog import read_rawlog

        raw = self.file(sessions.RAW)
        times = [c.t for c in read_rawlog(raw)]
        return Provenance(
            raw_sha256=sha256_of(raw, MAX_RAWLOG, "raw log"),
            config_sha256=sha256_of(self.config.path, MAX_OBSERVATIONS, "config"),
            survey_sha256=sha256_of(self.config.survey_path, MAX_OBSERVATIONS, "survey file"),
            station_version=__version__,
            first_host_time=times[0] if times else None,
            last_host_time=times[-1] if times else None,
        )

    # ------------------------------------------------------------------ replaying it

    def replay(
        self,
        listener: Listener | None = None,
        *,
        speed: float | None = None,
        warnings: list[str] | None = None,
    ) -> Acquisition:
        """Replay the session (its annotations applied) through the acquisition loop, in
        line; a new replay each call, told to ``listener`` as it goes. The fits stored with
        the session are used where their key matches, and the new ones stored."""
        from station.session.runs import replay

        fits = self.fits()
        acq = replay(
            self.path, self.config, listener, speed=speed, warnings=warnings, fits=fits,
            speed_curves=self.speed_curves,
        )  # fmt: skip
        if fits is not None:
            fits.compact()
        return acq

    def fits(self) -> FitStore | None:
        """The session's stored fits (``fits.jsonl``, :mod:`station.session.fitstore`)."""
        from station.session.fitstore import FitStore

        return FitStore.for_session(self.path, self.config)

    def start_replay(
        self, listener: Listener, *, speed: float | None = None, compare: bool = False
    ) -> Acquisition:
        """The replay in threads of its own, paced at ``speed`` (the UI): the acquisition
        is returned at once; ``listener`` hears the day as it goes."""
        from station.session.acquisition import Acquisition

        acq = Acquisition.open(self.config, listener, compare=compare)
        acq.day.analyser.fits = self.fits()
        acq.start_replay(self.path, speed)
        return acq

    def run(self) -> Acquisition:
        """The quiet replay of the session, run once and kept."""
        if self._run is None:
            self._run = self.replay(warnings=self.warnings)
        return self._run

    @property
    def track(self) -> Track:
        return self.run().track

    def results(self) -> tuple[DescentResult, ...]:
        """Every descent, fitted, with the annotations applied, as a replay gives them."""
        return self.run().results()

    def write_results_to(self, fh: IO[str]) -> None:
        """The results CSV into an open text file (as ``station export`` writes it)."""
        self.run().write_csv_to(fh)

    # ------------------------------------------------------------------ its results CSV

    def results_rows(self) -> list[dict[str, Any]] | None:
        """The rows of the session's own results CSV (:func:`read_results`), None when it
        has none yet."""
        path = self.file(sessions.RESULTS)
        if not os.path.lexists(path):
            return None
        return read_results(path)

    def rows(self) -> list[SessionRow]:
        """The descents of the results CSV with the annotations entered since it was written
        (``station annotate`` appends to annotations.jsonl and leaves the CSV as recorded
        while a recorder owns it): ski, wax and invalid marks as a replay would give them,
        by the same :class:`Day` rules, without replaying or refitting anything."""
        rows = self.results_rows() or []
        records = self.annotations()
        day = None
        if records:
            try:
                day = Marks.of(self.config, records)
            except InputError:
                day = None
        out = []
        for r in rows:
            n = r.get("descent")
            n = n if isinstance(n, int) else 0
            ski, wax, invalid = r.get("ski"), r.get("wax"), r.get("invalid_reason")
            if day is not None:
                meta = day.metadata_for(n)
                ski, wax, invalid = meta.ski, meta.wax, day.invalid.get(n, "")
            out.append(SessionRow(n, _text(r.get("descent_status")), _text(r.get("status")),
                                  _text(ski), _text(wax), _text(invalid),
                                  _text(r.get("start_time"))))  # fmt: skip
        return out

    def descent_numbers(self) -> list[int]:
        """The descent numbers the session has: from its results CSV, else (none, or one
        that cannot be read) by replaying it: the raw log knows them."""
        numbers = resultsstate.descent_numbers(self.path)
        if numbers is not None:  # the state lists them: 2000 rows are not read for this
            return numbers
        try:
            rows = self.results_rows()
        except InputError:
            rows = None
        if rows is not None:
            return [r["descent"] for r in rows if isinstance(r.get("descent"), int)]
        return [r.number for r in self.results()]

    # ------------------------------------------------------------------ annotating it

    def annotations(self) -> list[Annotation]:
        return sessions.read_annotations(self.path)

    def check_descents(self, numbers: Sequence[int], field: str = "--descents") -> None:
        """Refuse descents the session does not have: an annotation for descent 99 of an
        8-descent day would be stored, replayed and do nothing, while the engineer believes it
        took effect."""
        if not numbers:
            return
        have = set(self.descent_numbers())
        missing = sorted(set(numbers) - have)
        if missing:
            span = f"descents {min(have)}–{max(have)}" if have else "no descents yet"
            raise InputError(
                f"no descent {', '.join(map(str, missing))} in this session (it has {span})",
                path=self.path,
                field=field,
            )

    def annotate(self, records: Sequence[Annotation]) -> str:
        """Append annotations and bring the results CSV up to date: rewritten here, or taken
        up by the recorder when one is recording the session (``station annotate``, and what
        was entered in a replay of the session). Returns the line that says what happened."""
        with sessions.annotations_locked(self.path):  # another annotate waits: one CSV each
            before = resultsstate.annotations_digest(self.path)
            for rec in records:
                sessions.append_annotation(self.path, rec)
            n = len(records)
            said = f"{n} annotation{'' if n == 1 else 's'} added to {self.path}"
            state = self.recording_state()
            if state is sessions.RecordingStatus.NOW:  # the recorder takes them up (Acquisition)
                return (f"{said}; it is being recorded now: the recording takes them up and "
                        "its results.csv shows them in a moment")  # fmt: skip
            if state is sessions.RecordingStatus.UNKNOWN:
                return (f"{said}; whether it is being recorded cannot be told (recording.lock), "
                        "so results.csv was left alone: station export "
                        f"{self.path} --csv {self.file(sessions.RESULTS)} "
                        "writes it with them")  # fmt: skip
            self._run = None  # the annotations changed: replay again
            path = self._rewrite_rows(before, records) or self.rewrite_results()
        return f"{said}; {path} rewritten"

    def _rewrite_rows(self, before: str | None, records: Sequence[Annotation]) -> str | None:
        """The results CSV brought up to date with ``records`` without a replay, where none of
        them changes a fit and the CSV is the one a replay wrote with the annotations before
        them (``before``: the annotations file's SHA-256 then); None: a replay is needed."""
        cur = resultsstate.current(self.path, before)
        if cur is None:
            return None
        try:
            config = self.config
        except InputError:
            return None  # the replay says why
        after = resultsstate.annotations_digest(self.path)
        try:
            edit = ResultsFile(self.path).edit
            return self._saved(lambda: edit(config, cur, records, after))
        except InputError:
            raise  # the CSV cannot be written: a replay would not write it either
        except Exception as exc:  # noqa: BLE001 - a bug here must not lose the annotation
            self.warnings.append(f"results.csv not changed in place ({type(exc).__name__}: "
                                 f"{exc}); the day is replayed")  # fmt: skip
            return None

    def rewrite_results(self) -> str:
        """Rewrite the results CSV from the raw log and the annotations, as ``station export``
        writes it (the same replay, the same writer), once the recorder no longer owns it,
        with the state that lets the next annotate change rows in place. A CSV that cannot be
        written is one line that says the annotations are saved."""
        digest = resultsstate.annotations_digest(self.path)  # before the replay reads them
        self._run = None

        def write() -> str:
            return self.run().write_session_results(self.path, digest)

        path = self._saved(write)
        assert path is not None
        return path

    def _saved(self, write: Callable[[], str | None]) -> str | None:
        """``write()`` of the results CSV; what stops it is one line that says the
        annotations are saved."""
        path = self.file(sessions.RESULTS)
        try:
            check_output(path, sessions.RESULTS)
            return write()
        except OSError as exc:
            why = exc.strerror or str(exc)
        except InputError as exc:
            why = exc.message if exc.path == path else str(exc)
        raise InputError(
            f"the annotations are saved, but results.csv was not rewritten: {why}; "
            f"station export {self.path} --csv FILE writes the results elsewhere",
            path=path,
        ) from None

    # ------------------------------------------------------------------ comparing its items

    def compare(
        self,
        *,
        wind_limit_ms: float | None = None,
        reference: str | None = None,
        **options: Any,
    ) -> DayComparison:
        """The joint fit of the day's valid descents (:func:`compare_results`; the wind limit
        its default)."""
        from station.session.comparison import WIND_LIMIT_MS, compare_results

        if wind_limit_ms is None:
            wind_limit_ms = WIND_LIMIT_MS
        return compare_results(
            self.track, self.results(), wind_limit_ms=wind_limit_ms, reference=reference,
            **options,
        )  # fmt: skip

    def analysis(
        self,
        *,
        upto: int | None = None,
        wind_limit_ms: float | None = None,
        reference: str | None = None,
        **options: Any,
    ) -> DayAnalysis:
        """The day's analysis (:class:`DayAnalysis`) as it stood after descent ``upto`` (every
        descent: None), its comparison made with ``options`` (:func:`compare_results`)."""
        from station.session.comparison import WIND_LIMIT_MS, compare_results
        from station.session.day_analysis import DayAnalysis

        results = self.results_upto(upto)
        comparison = compare_results(
            self.track, results, reference=reference,
            wind_limit_ms=WIND_LIMIT_MS if wind_limit_ms is None else wind_limit_ms, **options,
        )  # fmt: skip
        with open(self.file(sessions.CONFIG), encoding="utf-8") as fh:
            config_text = fh.read()
        return DayAnalysis(
            session=self.path, track=self.track, results=results, comparison=comparison,
            header=self.results_header(), line_counts=self.line_counts(),
            base_metadata=self.base_metadata(), started=self.started(),
            annotations=len(self.annotations()), config_text=config_text,
            warnings=tuple(self.track.warnings),
        )  # fmt: skip

    # ------------------------------------------------------------------ what the commands show

    def results_upto(self, upto: int | None) -> tuple[DescentResult, ...]:
        """The descents as the day stood after descent ``upto`` (``compare --upto``; every
        descent: None)."""
        results = self.results()
        if upto is None:
            return results
        return tuple(r for r in results if r.row.descent <= upto)

    def line_counts(self) -> LineCounts:
        """The lines the replay read and what became of them (a command's summary line)."""
        return self.run().line_counts()

    def base_metadata(self) -> Metadata:
        """The day's metadata before any descent's own: the config's, with the annotations."""
        return self.run().day.base_metadata()

    def results_header(self) -> dict[str, str]:
        """The header lines of the results CSV a replay writes (station, config, track)."""
        acq = self.run()
        return sessions.results_header(acq.config, acq.track.name)

    def write_results_csv(self) -> str:
        """The results CSV of the replay into the session, with the state a recording leaves
        (``station import``), so the next annotate changes rows in place; returns its path."""
        digest = resultsstate.annotations_digest(self.path)  # before the replay reads them
        return self.run().write_session_results(self.path, digest)

    def joined_by_last_import(self) -> set[int]:
        """The descents the session's last ``station import`` joined to the recording
        (:func:`station.session.memory_import.joined_by_last_import`)."""
        from station.session.memory_import import joined_by_last_import

        return joined_by_last_import(self.run().day.processor)

    def summary(self) -> SessionSummary:
        """The session as ``station sessions`` lists it, from its results CSV and annotations
        without replaying or fitting anything; one that cannot be read is an
        :class:`InputError` (or the :class:`OSError` of a file that went meanwhile)."""
        from station.model.compare import item_name  # here: numpy (see the note above)

        check_regular(self.file(sessions.RAW), MAX_RAWLOG, "raw log")
        rows = self.rows()
        items: list[str] = []
        for r in rows:
            it = item_name(r.ski, r.wax)
            if r.descent_status != "aborted" and it not in items:
                items.append(it)
        has_results = os.path.lexists(self.file(sessions.RESULTS))
        head = self.first_record()
        started, imported = self.started(head), ""
        if self.made_by_import(head):
            first = next((m for m in map(minute_of, (r.start_time for r in rows)) if m), "")
            if first:
                started, imported = first, started
        return SessionSummary(
            path=self.path,
            started=started,
            imported=imported,
            descents=sum(r.descent_status != "aborted" for r in rows),
            fitted=sum(r.status == "ok" and not r.invalid_reason for r in rows),
            invalid=sum(bool(r.invalid_reason) for r in rows),
            items=tuple(items),
            status=self.status(has_results),
        )

    def status(self, has_results: bool) -> SessionStatus:
        """``recording`` while a process holds the session's lock, whatever the timer does;
        ``interrupted`` when its recorder died (killed, crashed) without ending it, so its
        results CSV may lack the last descent; ``finished`` when it was ended (or is older
        than the lock)."""
        state = self.recording_state()
        if state is sessions.RecordingStatus.NOW:
            return SessionStatus.RECORDING
        if not has_results:
            return SessionStatus.NO_RESULTS
        if state is sessions.RecordingStatus.INTERRUPTED:
            return SessionStatus.INTERRUPTED
        if state is sessions.RecordingStatus.UNKNOWN:
            return SessionStatus.UNKNOWN
        return SessionStatus.FINISHED


def _text(value: Any) -> str:
    return "" if value is None else str(value)
