"""What a session's results CSV was computed from (``SESSION/results.state.json``), so that
``station annotate`` can bring the CSV up to date without replaying the day when the
annotation is all that changed (:meth:`station.session.resultsfile.ResultsFile.edit`, the one
writer of the CSV and of this state).

A replay of the whole raw log costs about a second at 200 descents and several at 2000, and
most annotations change a column or two of a few rows: an invalid or valid mark the
``status`` and ``invalid_reason`` of one row; ski, wax, notes, skier or the snow temperature
the metadata columns of the descents they are for. Those rows are changed in place and the
file written once. An annotation that changes a fit (a model; a mass, air or wind for listed
descents) fits those descents alone (:func:`refit`), with their crossing times from
``SESSION/results.descents.json`` (the replay's descents in the order it fitted them, and the
survey covariance of each set of photocells, which no annotation moves:
:class:`station.session.analysis.Analyser`); a change from descent N on is replayed (its fits
from the fit store but those changed).

The state says, for one results CSV:

- the SHA-256 of the CSV itself (a CSV damaged, cut or edited by hand is not trusted);
- the raw log's SHA-256, size and modification time (read for its hash again only when the
  size or time changed), the SHA-256 of every other file of the session but the annotations
  and what is made from the others (config, survey, observations), and the code that
  computes results (:func:`station.session.codeversion.code_version`): results of another
  day, setup or station are not taken for this one's;
- the SHA-256 of the annotations file the CSV shows;
- where its rows are (the bytes of its head, then of each row), the descent of each row, the
  status of the fit of each row marked invalid (the CSV says ``invalid`` there), and the
  SHA-256 of the descents file with the timer precision the fits were judged by.

When any of it does not hold, or the state is missing or cannot be read, the day is replayed
and the state written anew with the CSV. The state is written by every replay that writes
the session's CSV (``annotate``, ``import``), and by a recording that ended cleanly when what
it recorded is what a replay gives: then the first annotate after either runs in place.

The rows the fast path writes are those a replay writes, byte for byte: the metadata in force
for a descent is found by the day's own rules (:class:`station.session.marks.Marks`, which
:class:`station.session.day.Day` uses too, without importing the day: that imports the fit,
0.9 s of numpy and scipy), a refit runs the day's own analyser, and the tests compare the
result with a replay's from scratch for every kind of annotation
(tests/test_annotate_in_place.py).
"""

from __future__ import annotations

import array
import base64
import binascii
import functools
import hashlib
import json
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from station.errors import InputError
from station.files import MAX_OBSERVATIONS, MAX_RAWLOG, read_bytes
from station.session import folder as sessions
from station.session.codeversion import code_version
from station.session.config import StationConfig
from station.session.records import (
    csv_record,
)
from station.session.results import (
    MAX_RESULTS,
    RowWriter,
    results_frame,
)

STATE = sessions.RESULTS_STATE
DESCENTS = sessions.RESULTS_DESCENTS
FORMAT = 1
#: the metadata keys a fit depends on (Day.fit_job: mass, the air's density, the wind): an
#: annotation that names one is fitted again, by a replay
FIT_KEYS = frozenset(
    {"mass_kg", "air_temperature_c", "pressure_hpa", "humidity_pct", "wind_ms", "wind_from_deg"}
)
#: a state file is small (a few numbers a descent)
MAX_STATE = 16 * 1024 * 1024


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _setup_names(session: str) -> list[str]:
    """The session's files but the raw log, the annotations and what is made from the others
    (results, fits, lock, this state; temporary files begin with a dot): its config, survey
    and observations, by their paths inside it."""
    skip = {sessions.RAW, sessions.ANNOTATIONS, *sessions.DERIVED}
    out = []
    for root, dirs, files in os.walk(session):
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        for name in files:
            rel = os.path.relpath(os.path.join(root, name), session)
            if rel not in skip and not name.startswith("."):
                out.append(rel)
    return sorted(out)


def setup_files(session: str, names: Sequence[str] | None = None) -> dict[str, str]:
    """The SHA-256 of each of the session's setup files (:func:`_setup_names`)."""
    if names is None:
        names = _setup_names(session)
    return {
        rel: _sha256(read_bytes(os.path.join(session, rel), MAX_OBSERVATIONS, "session file"))
        for rel in names
    }


def annotations_digest(session: str) -> str | None:
    """The SHA-256 of the annotations file as it is (of no bytes when there is none); None
    when it cannot be read (then no state is written or trusted)."""
    path = os.path.join(session, sessions.ANNOTATIONS)
    if not os.path.lexists(path):
        return _sha256(b"")
    try:
        return _sha256(read_bytes(path, sessions.MAX_ANNOTATIONS, "annotations file"))
    except (InputError, OSError):
        return None


def raw_stamp(session: str, known: dict[str, Any] | None = None) -> dict[str, Any]:
    """The raw log's size, modification time and SHA-256. A raw log of the size and time
    ``known`` gives is taken to have its SHA-256 too, as make and git judge a file by its
    size and time: a recorder never writes to a session again once it ended, and reading a
    2000-descent day's log for its hash (1 MB) was a third of an annotate's time."""
    path = os.path.join(session, sessions.RAW)
    st = os.stat(path)
    stamp: dict[str, Any] = {"size": st.st_size, "mtime_ns": st.st_mtime_ns}
    if known is not None and all(known.get(k) == v for k, v in stamp.items()):
        return {**stamp, "sha256": known.get("sha256")}
    return {**stamp, "sha256": _sha256(read_bytes(path, MAX_RAWLOG, "raw log"))}


@dataclass
class ResultsState:
    """What one results CSV was computed from, and where its rows are: after ``head`` bytes,
    rows of ``lengths`` bytes, one for each descent of ``runs`` (first, last). Kept compact, so
    that reading and writing it costs a 2000-descent day little more than a 200-descent one:
    the lengths as an array of 32-bit numbers (base64), the descents as runs (1–2000)."""

    code: str
    files: dict[str, str]
    raw: dict[str, Any]
    annotations_sha256: str
    results_sha256: str
    runs: list[tuple[int, int]]
    head: int
    lengths: array.array[int]
    statuses: dict[int, str] = field(default_factory=dict)  # the fit's, of rows marked invalid
    #: what a refit of one descent needs: the SHA-256 of the descents file (DESCENTS) and the
    #: timer's precision the day's fits were judged by; None: refits replay the day
    fits: dict[str, Any] | None = None

    @property
    def descents(self) -> list[int]:
        return [n for first, last in self.runs for n in range(first, last + 1)]

    @property
    def size(self) -> int:
        """The size of the CSV."""
        return self.head + sum(self.lengths)

    def row_of(self, number: int) -> int:
        """The row of a descent (from 0), -1 when the CSV has none."""
        k = 0
        for first, last in self.runs:
            if first <= number <= last:
                return k + number - first
            k += last - first + 1
        return -1

    def spans(self, rows: Sequence[int]) -> dict[int, tuple[int, int]]:
        """Where the rows ``rows`` (numbers from 0) begin and end in the CSV."""
        out: dict[int, tuple[int, int]] = {}
        pos, at = self.head, 0
        for k in sorted(set(rows)):
            pos += sum(self.lengths[at:k])
            at = k
            out[k] = (pos, pos + self.lengths[k])
        return out

    def to_json(self) -> dict[str, Any]:
        return {
            "format": FORMAT, "code": self.code, "files": self.files, "raw": self.raw,
            "annotations_sha256": self.annotations_sha256,
            "results_sha256": self.results_sha256, "runs": self.runs, "head": self.head,
            "lengths": _packed(self.lengths),
            "statuses": {str(k): v for k, v in self.statuses.items()},
            "fits": self.fits,
        }  # fmt: skip

    @classmethod
    def from_json(cls, rec: Any) -> ResultsState:
        """The state from its JSON form; anything else is ``ValueError`` (not trusted)."""
        if not isinstance(rec, dict) or rec.get("format") != FORMAT:
            raise ValueError("not a results state of this version")
        try:
            state = cls(
                code=_typed(rec["code"], str), files=_typed(rec["files"], dict),
                raw=_typed(rec["raw"], dict),
                annotations_sha256=_typed(rec["annotations_sha256"], str),
                results_sha256=_typed(rec["results_sha256"], str),
                runs=_runs(rec["runs"]),
                head=_typed(rec["head"], int),
                lengths=_unpacked(_typed(rec["lengths"], str)),
                statuses={int(k): _typed(v, str) for k, v in _typed(rec["statuses"], dict).items()},
                fits=None if rec.get("fits") is None else _typed(rec["fits"], dict),
            )  # fmt: skip
        except KeyError as exc:
            raise ValueError(f"no {exc}") from None
        if sum(last - first + 1 for first, last in state.runs) != len(state.lengths):
            raise ValueError("rows and descents disagree")
        return state


def _runs(value: Any) -> list[tuple[int, int]]:
    """Runs of descents, in order, each after the one before."""
    out: list[tuple[int, int]] = []
    for run in _typed(value, list):
        first, last = _typed(run, list)
        if _typed(first, int) > _typed(last, int) or (out and first <= out[-1][1]):
            raise ValueError("descents out of order")
        out.append((first, last))
    return out


def runs_of(descents: Sequence[int]) -> list[tuple[int, int]]:
    """Descents in order as runs of consecutive numbers."""
    out: list[list[int]] = []
    for n in descents:
        if out and n == out[-1][1] + 1:
            out[-1][1] = n
        elif out and n <= out[-1][1]:
            raise ValueError("descents out of order")
        else:
            out.append([n, n])
    return [(a, b) for a, b in out]


def _packed(lengths: array.array[int]) -> str:
    a = array.array("I", lengths)
    if sys.byteorder == "big":
        a.byteswap()  # little-endian in the file
    return base64.b64encode(a.tobytes()).decode("ascii")


def _unpacked(text: str) -> array.array[int]:
    try:
        data = base64.b64decode(text, validate=True)
    except binascii.Error:
        raise ValueError("lengths are not base64") from None
    if len(data) % 4:
        raise ValueError("lengths of the wrong size")
    a = array.array("I")
    a.frombytes(data)
    if sys.byteorder == "big":
        a.byteswap()
    return a


def _typed(value: Any, kind: type) -> Any:
    if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
        raise ValueError(f"expected {kind.__name__}")
    return value


# ------------------------------------------------------------------------ the replay's descents


def fitted_of(day: Any) -> Fitted:
    """A day's descents (:class:`station.session.day.Day`) in the order they were fitted, and
    the descent on each set of photocells whose reference fit gave the survey's covariance the
    later ones take (the analyser's rule: :class:`station.session.analysis.Analyser`)."""
    order = [day.results[n].descent for n in day.results]  # fitted once each, in this order
    an = day.analyser
    own = [d.number for d in order if an.computes_own(d.number, d.photocells)]
    return Fitted(order, an.survey_sources(), day.timer_precision_s(), own)


@dataclass
class Fitted:
    """A replay's descents as it fitted them: in the order it fitted them (the crossing times,
    :class:`DescentTimes`), the survey covariance of each set of photocells and the descent
    whose reference fit gave it (the later ones take it; those before it computed their
    own), the descents whose fit computed its own, and the timer's precision. Any descent can
    then be fitted again alone and gets the fit the replay would give it."""

    order: list[Any]  # DescentTimes
    sources: list[tuple[tuple[str, ...], int, Any]]  # photocells, descent, covariance
    timer_precision_s: float
    own: list[int] = field(default_factory=list)  # descents whose fit computed its own


# ----------------------------------------------------------------------------- reading


@dataclass
class Current:
    """A results CSV its state says is current: its bytes and its state."""

    data: bytes
    state: ResultsState
    files: dict[str, str]
    raw: dict[str, Any]


@functools.lru_cache(maxsize=1)
def _parsed(text: bytes) -> ResultsState:
    return ResultsState.from_json(json.loads(text))


def read_state(session: str) -> ResultsState | None:
    """The state as its file says (None: none, or not one of this version); parsed once a
    process for the same bytes (``annotate`` looks at it for the descents, then to annotate)."""
    try:
        return _parsed(read_bytes(os.path.join(session, STATE), MAX_STATE, "results state"))
    except (OSError, ValueError, RecursionError, InputError):  # not trusted: replayed
        return None


def current(session: str, annotations_sha256: str | None) -> Current | None:
    """The results CSV and its state when the state holds for the session as it is, with the
    annotations file whose SHA-256 is ``annotations_sha256``; None otherwise (replay)."""
    state = read_state(session)
    if state is None:
        return None
    if annotations_sha256 is None or state.annotations_sha256 != annotations_sha256:
        return None
    if state.code != code_version():
        return None
    try:
        names = _setup_names(session)
        if names != sorted(state.files):
            return None
        data = read_bytes(os.path.join(session, sessions.RESULTS), MAX_RESULTS, "results CSV")
        if len(data) != state.size or _sha256(data) != state.results_sha256:
            return None
        files = setup_files(session, names)
        if files != state.files:
            return None
        raw = raw_stamp(session, state.raw)
        if raw["sha256"] != state.raw.get("sha256") or raw["size"] != state.raw.get("size"):
            return None
    except (OSError, InputError):
        return None
    return Current(data, state, files, raw)


def descent_numbers(session: str) -> list[int] | None:
    """The descents of the results CSV as its state lists them, when the state is of this CSV
    (by its size: a check of what the engineer typed, not of the results); None otherwise."""
    state = read_state(session)
    try:
        size = os.path.getsize(os.path.join(session, sessions.RESULTS))
    except OSError:
        return None
    return state.descents if state is not None and size == state.size else None


# ----------------------------------------------------------------------- a refit of one descent


def refit(
    session: str, config: StationConfig, state: ResultsState, start_times: dict[int, str]
) -> dict[int, tuple[bytes, str]] | None:
    """The rows of the descents ``start_times`` names (with their start times as the CSV has
    them) fitted again as a replay would fit them now, with the session's annotations: each
    one's new row and its fit's status; None when one of them cannot be fitted alone (not in
    the descents file, or a file of another version: a replay then). The survey covariance
    each takes is the one the replay's fit took (the descents file's: no annotation moves
    it). Loads the fit (numpy, scipy): only here."""
    from dataclasses import replace

    import numpy as np

    from station.session.analysis import Analyser
    from station.session.day import Day
    from station.session.fitstore import from_json
    from station.session.records import DescentStatus, DescentTimes
    from station.survey.load import load_survey
    from station.survey.track import build_track

    info = state.fits
    if info is None:
        return None
    try:
        data = read_bytes(os.path.join(session, DESCENTS), MAX_STATE * 8, "descents file")
        if _sha256(data) != info.get("sha256"):
            return None
        rec = json.loads(data)
        precision = _typed(info.get("timer_precision_s"), float)
        order = rec["order"]
        where = {d["number"]: i for i, d in enumerate(order)}
        sources = {tuple(ids): (n, cov) for ids, n, cov in rec["sources"]}
        own = set(rec["own"])
        track = build_track(load_survey(config.survey_path))
        analyser = Analyser(config, track)
        analyser.speed_curves = False
        # no fit store: opening it reads every stored fit's key (0.9 s of a 1.5 s refit at
        # 2000 descents), and the few fits made here cost the next replay milliseconds
        analyser.fits = None
        day = Day(config, track, None, analyser)  # type: ignore[arg-type]  # fits, no impulses
        for a in sessions.read_annotations(session):
            day.annotate(a)
    except Exception:  # noqa: BLE001 - anything amiss: the replay says what is wrong
        return None
    out: dict[int, tuple[bytes, str]] = {}
    writer = RowWriter()
    for n, started in start_times.items():
        i = where.get(n)
        if i is None:
            return None
        try:
            d = from_json(DescentTimes, order[i])
        except Exception:  # noqa: BLE001 - not this version's: replayed
            return None
        # the survey covariance the replay's fit of it took: its own (it was first fitted
        # before its photocells had one), else that of its photocells
        source = sources.get(d.photocells)
        if n in own:
            analyser.own_survey(n, d.photocells)
        elif source is None:
            if d.status != DescentStatus.ABORTED:  # (an aborted one is not fitted)
                return None  # a descents file that does not say: replayed
        else:
            try:
                cov = from_json(np.ndarray, source[1])
            except Exception:  # noqa: BLE001 - not this version's: replayed
                return None
            analyser.hand_on(d.photocells, source[0], cov)
        # the day's own job, with the start time of the CSV and the day's timer precision
        # (the replay's processor knows both; here there is none; no items: see ResultsFile.edit)
        job = day.job(d, started, precision)
        res = analyser.run(job)
        row = replace(res.row, invalid_reason=day.invalid.get(n, ""))
        text = writer.text(results_frame([csv_record(row)])[0])
        out[n] = (text.encode("utf-8"), res.row.status.value)
    return out
