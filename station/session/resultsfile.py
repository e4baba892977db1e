"""The one owner of a session's results CSV (``results.csv``) and of its state
(``results.state.json``, :mod:`station.session.resultsstate`): every write of either goes
through :class:`ResultsFile`: the recording's (a new descent appended, anything else the file
in full), a replay's with its state (``annotate``, ``import``), the state a clean recording
leaves, an annotation's rows changed in place, and the exports to another file.

The bytes are the same whichever way a CSV is written: those of
:func:`station.session.results.results_lines` for the day's rows, written atomically
(:func:`station.files.replaced`).
"""

from __future__ import annotations

import array
import contextlib
import hashlib
import json
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import IO, TYPE_CHECKING, Any

from station.errors import InputError
from station.files import read_bytes, write_atomic
from station.session import folder as sessions
from station.session import results
from station.session.codeversion import code_version
from station.session.config import StationConfig
from station.session.marks import Marks
from station.session.records import (
    METADATA_FIELDS,
    Annotation,
    InvalidMark,
    MetadataAnnotation,
    ResultRow,
    ResultStatus,
    ValidMark,
    csv_record,
)
from station.session.results import COLUMNS, MAX_RESULTS, RowWriter, cell_value, parse_row
from station.session.resultsstate import (
    DESCENTS,
    FIT_KEYS,
    STATE,
    Current,
    Fitted,
    ResultsState,
    raw_stamp,
    refit,
    runs_of,
    setup_files,
)

if TYPE_CHECKING:
    from station.session.analysis import DescentResult

_META_COLUMNS = tuple(f for f in METADATA_FIELDS if f.column)
_STATUS = COLUMNS.index("status")
_INVALID = COLUMNS.index("invalid_reason")
#: the setup files and the raw log's stamp of a state, when known (an edit in place keeps
#: those its check read)
Known = tuple[dict[str, str], dict[str, Any]]


class ResultsFile:
    """The results CSV of a session folder (``session``; None: a day with no folder, whose
    CSV is only exported) with the header ``header()`` gives (made once, when first needed:
    it reads the config and survey for their digests; an edit in place keeps the file's)."""

    def __init__(
        self, session: str | None, header: Callable[[], dict[str, str]] | None = None
    ) -> None:
        self.session = session
        self.path = None if session is None else os.path.join(session, sessions.RESULTS)
        self._header_of = header
        self._header: dict[str, str] | None = None
        # what the file holds (rows by descent, its size and inode): a new descent is appended
        # to it; None: unknown (not written yet, or a write failed): rewritten in full (a
        # list: descent n's row at n - 1, None where the file has none; 8 bytes a descent)
        self._rows: list[ResultRow | None] | None = None
        self._size = 0
        self._inode = 0
        #: why the CSV is not written now (said once, not after every descent); None: it is
        self.problem: str | None = None

    def header(self) -> dict[str, str]:
        if self._header is None:
            assert self._header_of is not None, "a results file edited in place has no header"
            self._header = self._header_of()
        return self._header

    # ------------------------------------------------------------------ exports

    def export(self, rows: Sequence[ResultRow], path: str) -> None:
        """The CSV of ``rows`` at ``path`` (export, ``replay --csv``, the UI's ``e``)."""
        results.write_results([csv_record(r) for r in rows], path, self.header())

    def export_to(self, fh: IO[str], rows: Sequence[ResultRow]) -> None:
        """The CSV of ``rows`` into an open text file (``--csv -``: standard output)."""
        results.write_results_to(fh, [csv_record(r) for r in rows], self.header())

    # ------------------------------------------------------------------ a recording's

    def save(
        self, changed: Sequence[DescentResult], snapshot: Callable[[], Sequence[DescentResult]]
    ) -> str | None:
        """Bring the CSV up to date with ``changed`` (the results just fitted or marked; at
        the end, all). A descent after every one the file holds is appended to it, so a
        2000-descent day costs per descent what its first did; an earlier row that changed (an
        annotation, a refit, descents ending out of order) rewrites the file in full, of
        ``snapshot()``. Returns the line to tell (:meth:`write_all`), None: nothing to say."""
        if self.path is None:
            return None
        new = self._new_rows(changed)
        if new is not None:
            if not new:
                return None  # the file holds them already
            if self._append(new):
                return None
        return self.write_all(snapshot())

    def _new_rows(self, changed: Sequence[DescentResult]) -> dict[int, ResultRow] | None:
        """The rows to append (by descent); None: the file is to be written in full."""
        rows = self._rows
        if rows is None:
            return None
        new: dict[int, ResultRow] = {}
        last = len(rows)  # the last descent the file has (the list ends with its row)
        for r in sorted(changed, key=lambda r: r.number):
            n = r.number
            old = rows[n - 1] if n <= last else None
            if old is r.row or old == r.row:
                new.pop(n, None)  # unchanged (a later view may change it again)
            elif old is not None or n < last:
                return None  # an earlier row changed: the file is rewritten
            else:
                new[n] = r.row
        return new

    def _append(self, new: dict[int, ResultRow]) -> bool:
        """Append the rows ``new``; False when it failed (then the file is written in full,
        which says what failed)."""
        rows = self._rows
        assert rows is not None and self.path is not None
        try:
            self._size = results.append_results(
                self.path, [csv_record(r) for r in new.values()], self._size, self._inode
            )
        except Exception:  # noqa: BLE001 - written in full, which says what failed
            self._rows = None
            return False
        for n, row in new.items():
            if n > len(rows):
                rows.extend([None] * (n - len(rows)))
            rows[n - 1] = row
        return True

    def write_all(self, snapshot: Sequence[DescentResult]) -> str | None:
        """The CSV in full. One that cannot be written is said once (the returned line), and
        written again after the next descent (the raw log, written first, is not affected);
        once written again, the line says so. None: nothing to say."""
        if self.path is None:
            return None
        path = self.path
        self._rows = None
        problem = sessions.save_results(path, lambda p: self.export([r.row for r in snapshot], p))
        if problem is None:
            with contextlib.suppress(OSError):  # unknown size: the next write is in full
                st = os.stat(path)
                self._size, self._inode = st.st_size, st.st_ino
                self._rows = _rows_by_number(snapshot)
        said = None
        if problem is not None and problem != self.problem:
            said = problem
        elif problem is None and self.problem is not None:
            said = f"{path} written again: it is complete"
        self.problem = problem
        return said

    def end_recording(
        self, why_not: str | None, day: Callable[[], tuple[Sequence[ResultRow], Fitted]]
    ) -> str | None:
        """At the end of a recording, with the annotations file held: the state a replay
        would write with the CSV, so that the first ``station annotate`` changes rows in place
        instead of replaying the day; only when nothing says the results differ from a
        replay's (``why_not`` None) and the CSV on disk is byte for byte the one a replay
        writes of the rows ``day()`` gives. Otherwise there is none (one left from before
        would not match the CSV) and the annotate replays. Returns why there is none."""
        assert self.session is not None
        session = self.session
        if why_not is None:
            try:
                rows, fitted = day()
                written = self._state_of_recording(rows, _annotations_digest(session), fitted)
            except Exception:  # noqa: BLE001 - no state: the next annotate replays
                written = False
            if not written:
                why_not = "the results state could not be written"
        if why_not is not None:
            for name in (STATE, DESCENTS):
                with contextlib.suppress(OSError):
                    os.unlink(os.path.join(session, name))
        return why_not

    def _state_of_recording(
        self, rows: Sequence[ResultRow], annotations_sha256: str | None, fitted: Fitted
    ) -> bool:
        """The state of the CSV a recording wrote, when it is the one a replay writes of
        ``rows``; returns whether it was written. The CSV is read, never written here."""
        if annotations_sha256 is None:
            return False
        assert self.path is not None and self.session is not None
        try:
            data = read_bytes(self.path, MAX_RESULTS, "results CSV")
            encoded, layout = self._encoded(rows, hashlib.sha256(data).hexdigest())
        except (OSError, InputError, ValueError):
            return False
        if data != b"".join(encoded):
            return False  # a write failed, or was cut short: the CSV is not a replay's
        try:
            fits = _write_descents(self.session, fitted)
        except (OSError, ValueError, TypeError):
            return False
        return self._write_state(layout, annotations_sha256, _statuses(rows), None, fits)

    def _encoded(self, rows: Sequence[ResultRow], sha256: str) -> tuple[list[bytes], _Layout]:
        """The CSV of ``rows`` in pieces (its head, then each row) and where they are (the
        SHA-256 ``sha256`` of the whole); ``ValueError`` for descents out of order."""
        head, lines = results.results_lines([csv_record(r) for r in rows], self.header())
        encoded = [head.encode("utf-8")] + [x.encode("utf-8") for x in lines]
        lengths = array.array("I", [len(row) for row in encoded[1:]])
        runs = runs_of([r.descent for r in rows])
        return encoded, _Layout(sha256, len(encoded[0]), lengths, runs)

    # ------------------------------------------------------------------ a replay's

    def write_replay(
        self, rows: Sequence[ResultRow], annotations_sha256: str | None, fitted: Fitted | None
    ) -> str:
        """The CSV of a replay (``rows`` as its results show them, the invalid marks on them)
        and its state; ``annotations_sha256``: of the annotations file the replay applied,
        taken before it read them; ``fitted``: the replay's descents as it fitted them, for a
        later refit of one. Returns the CSV's path. The CSV is written first: a state that
        cannot be written leaves the old one, which no longer matches the CSV."""
        assert self.path is not None and self.session is not None
        encoded, layout = self._encoded(rows, "")
        fits = None
        if fitted is not None:
            try:
                fits = _write_descents(self.session, fitted)
            except (OSError, ValueError, TypeError):
                fits = None  # refits replay the day
        layout = replace(layout, sha256=write_atomic(self.path, encoded))
        if annotations_sha256 is not None:
            self._write_state(layout, annotations_sha256, _statuses(rows), None, fits)
        return self.path

    # ------------------------------------------------------------------ an annotation's

    def edit(
        self,
        config: StationConfig,
        cur: Current,
        new: Sequence[Annotation],
        annotations_sha256: str | None,
    ) -> str | None:
        """Bring the CSV ``cur`` up to date with the annotations ``new`` appended after those
        it shows, without a replay, when none of them changes a fit of the day but those of
        listed descents (fitted again alone: :func:`resultsstate.refit`); write it and its
        state. Returns the CSV's path, or None when a replay is needed (nothing written)."""
        assert self.path is not None and self.session is not None
        change = _Change.of(cur.state, new)
        if change is None or ((change.metadata or change.refit) and config.items):
            # the bib of a descent names an item (ski, wax …) over what the annotations say:
            # not known here; such a day is replayed
            return None
        edited = _Edit(self.session, config, cur, change).rows()
        if edited is None:
            return None
        changed, statuses = edited
        state = cur.state
        span = state.spans([k for k, _ in changed])
        # the file in pieces: the unchanged stretches as they are, the changed rows new
        whole = memoryview(cur.data)
        pieces: list[bytes | memoryview] = []
        lengths = array.array("I", state.lengths)
        at = 0
        for k, row in changed:
            pieces += [whole[at : span[k][0]], row]
            at = span[k][1]
            lengths[k] = len(row)
        pieces.append(whole[at:])
        # the CSV first: a state that is not written then is the old one, which does not
        # hold for the new CSV (its SHA-256), so the next annotate replays
        digest = write_atomic(self.path, pieces)
        if annotations_sha256 is not None:
            layout = _Layout(digest, state.head, lengths, state.runs)
            self._write_state(
                layout, annotations_sha256, statuses, (cur.files, cur.raw), state.fits
            )
        return self.path

    # ------------------------------------------------------------------ the state

    def _write_state(
        self,
        layout: _Layout,
        annotations_sha256: str,
        statuses: dict[int, str],
        known: Known | None,
        fits: dict[str, Any] | None,
    ) -> bool:
        """The state of the CSV ``layout`` describes; False when it could not be written
        (then the next annotate replays)."""
        assert self.session is not None
        session = self.session
        try:
            files, raw = known if known is not None else (
                setup_files(session), raw_stamp(session)
            )  # fmt: skip
            state = ResultsState(
                code_version(), files, raw, annotations_sha256, layout.sha256, layout.runs,
                layout.head, layout.lengths, statuses, fits,
            )  # fmt: skip
            text = json.dumps(state.to_json(), separators=(",", ":")).encode()
            # written over the old one, not renamed: a state cut short is no JSON, and the
            # old one does not hold for the new CSV; either way the next annotate replays
            flags = os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_NONBLOCK  # a FIFO: no wait
            fd = os.open(os.path.join(session, STATE), flags, 0o666)
            with os.fdopen(fd, "wb") as fh:
                fh.write(text)
        except (OSError, InputError):
            return False  # no state: the next annotate replays
        return True


@dataclass(frozen=True)
class _Layout:
    """Where the rows of a CSV are: its SHA-256, ``head`` bytes, then rows of ``lengths``,
    one for each descent of ``runs``."""

    sha256: str
    head: int
    lengths: array.array[int]
    runs: list[tuple[int, int]]


def _statuses(rows: Sequence[ResultRow]) -> dict[int, str]:
    """The fit's status of each row marked invalid (the CSV says ``invalid`` there)."""
    return {r.descent: r.status.value for r in rows if r.invalid_reason}


def _annotations_digest(session: str) -> str | None:
    from station.session.resultsstate import annotations_digest

    return annotations_digest(session)


def _rows_by_number(snapshot: Sequence[DescentResult]) -> list[ResultRow | None]:
    """The rows of ``snapshot``, descent n's at n - 1 (None for a number without one)."""
    rows: list[ResultRow | None] = [None] * max((r.number for r in snapshot), default=0)
    for r in snapshot:
        rows[r.number - 1] = r.row
    return rows


def _write_descents(session: str, fitted: Fitted) -> dict[str, Any]:
    """The replay's descents as it fitted them (``results.descents.json``), for a refit of
    one; returns what the state says of it."""
    from station.session.fitstore import to_json

    rec = {
        "order": [to_json(d) for d in fitted.order],
        "sources": [[list(ids), n, to_json(cov)] for ids, n, cov in fitted.sources],
        "own": fitted.own,
    }
    data = json.dumps(rec, separators=(",", ":")).encode()
    digest = write_atomic(os.path.join(session, DESCENTS), [data])
    return {"sha256": digest, "timer_precision_s": fitted.timer_precision_s}


@dataclass
class _Change:
    """What annotations appended after those a CSV shows change: the rows they touch, the
    invalid marks they leave (a row's earlier reason is in its cell), whether metadata
    changed, and the descents whose fit changes (fitted again)."""

    touched: set[int]
    reasons: dict[int, str]
    metadata: bool
    refit: set[int]

    @classmethod
    def of(cls, state: ResultsState, new: Sequence[Annotation]) -> _Change | None:
        """None: one of them changes the fits of most of the day (a replay)."""
        out = cls(set(), {}, False, set())
        for a in new:
            if isinstance(a, InvalidMark | ValidMark):
                out.touched.add(a.descent)
                out.reasons[a.descent] = (a.reason or "marked invalid") \
                    if isinstance(a, InvalidMark) else ""  # fmt: skip
            elif isinstance(a, MetadataAnnotation):
                out.metadata = True
                keys = a.values.values().keys()
                if FIT_KEYS & keys:
                    if a.descents is None:
                        return None  # from N on: most of the day fitted again, by a replay
                    out.refit.update(a.descents)
                elif not any(f.column for f in METADATA_FIELDS if f.key in keys):
                    continue  # a key results.csv has no column for (grind, snow type …)
                elif a.descents is not None:
                    out.touched.update(a.descents)
                else:
                    start = a.from_descent or 0
                    out.touched.update(n for n in state.descents if n >= start)
            else:  # a model change
                out.refit.add(a.descent)
        return out


class _Edit:
    """The rows of a CSV an annotation changes, made anew as a replay makes them."""

    def __init__(self, session: str, config: StationConfig, cur: Current, change: _Change):
        self.session, self.config, self.cur, self.change = session, config, cur, change
        state = cur.state
        #: the row (from 0) of each descent concerned that the CSV has (one it has none for
        #: is still to come: nothing to show)
        self.where = {n: k for n in change.touched | change.refit if (k := state.row_of(n)) >= 0}
        self.span = state.spans(list(self.where.values()))
        self.writer = RowWriter()

    def _text(self, k: int) -> str:
        a, b = self.span[k]
        return self.cur.data[a:b].decode("utf-8")

    def _refitted(self) -> dict[int, tuple[bytes, str]] | None:
        """The new rows (and fit statuses) of the descents fitted again; None: a replay."""
        numbers = self.change.refit & self.where.keys()
        if not numbers:
            return {}
        starts: dict[int, str] = {}
        for n in numbers:
            try:
                starts[n] = parse_row(self._text(self.where[n]))[1]
            except ValueError:
                return None
        return refit(self.session, self.config, self.cur.state, starts)

    def rows(self) -> tuple[list[tuple[int, bytes]], dict[int, str]] | None:
        """The changed rows (row, its new bytes) in the file's order and the statuses of the
        rows marked invalid; None: a replay is needed."""
        refitted = self._refitted()
        if refitted is None:
            return None
        marks = None
        if self.change.metadata:  # what is in force follows from every annotation of the day
            try:
                marks = Marks.of(self.config, sessions.read_annotations(self.session))
            except Exception:  # noqa: BLE001 - the replay says what is wrong
                return None
        statuses = dict(self.cur.state.statuses)
        changed: list[tuple[int, bytes]] = []
        for n in sorted(self.where):
            k = self.where[n]
            statuses.pop(n, None)
            if n in refitted:
                row, status = refitted[n]
                if parse_row(row.decode("utf-8"))[_INVALID]:
                    statuses[n] = status
                changed.append((k, row))
                continue
            marked = self._marked(n, k, marks, self.cur.state.statuses.get(n))
            if marked is None:
                return None
            cells, status = marked
            if cells[_INVALID]:
                statuses[n] = status
            changed.append((k, self.writer.text(cells).encode("utf-8")))
        return changed, statuses

    def _marked(
        self, n: int, k: int, marks: Marks | None, held: str | None
    ) -> tuple[list[Any], str] | None:
        """The cells of descent ``n``'s row ``k`` with the metadata and invalid mark now in
        force, and its fit's status (``held``: the state's, for a row marked invalid); None: a
        replay."""
        try:
            text = self._text(k)
            cells = parse_row(text)
            if self.writer.text(cells) != text or cells[0] != n:
                return None  # not written by this writer: replayed
        except ValueError:
            return None
        if marks is not None:
            meta = marks.metadata_for(n)
            for f in _META_COLUMNS:
                v = getattr(meta, f.key)
                cells[COLUMNS.index(f.key)] = cell_value(f.key, ("" if v is None else v)
                                                        if f.kind is str else v)  # fmt: skip
        status = held or cells[_STATUS]
        if status == ResultStatus.INVALID.value:
            return None  # the fit's status is not known: replayed
        if marks is not None:
            cells[_INVALID] = cell_value("invalid_reason", marks.invalid.get(n, ""))
        elif n in self.change.reasons:
            cells[_INVALID] = cell_value("invalid_reason", self.change.reasons[n])
        cells[_STATUS] = ResultStatus.INVALID.value if cells[_INVALID] else status
        return cells, status
