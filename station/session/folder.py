"""A session directory: everything a test day needs to be replayed later.

    SESSION/
      raw.jsonl        every byte from the timer, with host timestamps (station.session.rawlog)
      config.yaml      the station config as it was, verbatim
      <survey files>   the survey YAML and its observation file, at the same relative paths
      results.csv      one row per descent, rewritten after each descent
      annotations.jsonl  what the engineer entered: metadata, invalid marks, refits
      fits.jsonl       every descent's fit, keyed by what it depends on (a cache:
                       station.session.fitstore), so a replay fits only what changed
      results.state.json  what results.csv was computed from and where its rows are, so
      results.descents.json  an annotate changes the rows it concerns without a replay
                       (station.session.resultsstate), and refits only the descents it
                       concerns (their crossing times, in the order they were fitted)
      recording.lock   there while the session is recorded (:class:`RecordingLock`)

Replaying a session (``station replay SESSION``) runs its own snapshot through the same
processor and reproduces ``results.csv`` byte for byte.

A session never overwrites files: it is made in a new or empty folder only, and its snapshot
files are created exclusively. A folder that cannot be written (read-only, a file, a full disk)
is one line before recording starts; a results CSV that cannot be rewritten during recording is
a line on the terminal (:func:`save_results`), never the end of the recording: the raw log is
the day, the CSV can be exported from it later.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import enum
import errno
import hashlib
import json
import os
import re
import socket
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from types import ModuleType

from station.errors import InputError
from station.files import MAX_OBSERVATIONS, MAX_YAML, read_bytes, read_text
from station.session.config import StationConfig, load_config
from station.session.records import Annotation, annotation_from_json, annotation_to_json
from station.yamlfile import load_yaml

#: flock, where the system has it (not on Windows: whether a session is recorded is then
#: "cannot tell", and the annotations file is written without a lock)
fcntl: ModuleType | None
try:
    import fcntl as _fcntl

    fcntl = _fcntl
except ImportError:
    fcntl = None

#: an annotations file is the engineer's typing: kilobytes
MAX_ANNOTATIONS = 64 * 1024 * 1024

RAW = "raw.jsonl"
CONFIG = "config.yaml"
RESULTS = "results.csv"
ANNOTATIONS = "annotations.jsonl"
LOCK = "recording.lock"
FITS = "fits.jsonl"
#: what results.csv was computed from (station.session.resultsstate)
RESULTS_STATE = "results.state.json"
#: the descents' crossing times as the results CSV's replay fitted them (the same module)
RESULTS_DESCENTS = "results.descents.json"
#: files made from the others (a replay makes them again): not part of what a session is
DERIVED = (RESULTS, LOCK, FITS, RESULTS_STATE, RESULTS_DESCENTS)


def is_session(path: str) -> bool:
    return os.path.isdir(path) and os.path.exists(os.path.join(path, RAW))


def default_dir(base: str = "sessions") -> str:
    return os.path.join(base, dt.datetime.now().strftime("%Y-%m-%d_%H%M%S"))


def _inside(rel: str) -> bool:
    return not os.path.isabs(rel) and not os.path.normpath(rel).startswith("..")


def _copy(src: str, dst: str, what: str) -> None:
    """Copy a regular file of bounded size into the session, never over an existing file."""
    data = read_bytes(src, MAX_OBSERVATIONS, what)
    os.makedirs(os.path.dirname(dst), exist_ok=True)
    with open(dst, "xb") as fh:
        fh.write(data)


def snapshot(cfg: StationConfig, session: str) -> None:
    """Copy the config and the survey (with its observation file) into the session."""
    cfg_dir = os.path.dirname(os.path.abspath(cfg.path))
    text = cfg.text
    rel = os.path.relpath(cfg.survey_path, cfg_dir)
    if not _inside(rel):
        rel = os.path.join("survey", os.path.basename(cfg.survey_path))
        text = re.sub(r"(?m)^survey:.*$", f"survey: {rel}", text)
    survey_dst = os.path.join(session, rel)
    _copy(cfg.survey_path, survey_dst, "survey file")
    data = load_yaml(cfg.survey_path)
    obs = data.get("observations") if isinstance(data, dict) else None
    if isinstance(obs, str):
        src = os.path.join(os.path.dirname(cfg.survey_path), obs)
        if os.path.exists(src):
            if _inside(obs):
                _copy(src, os.path.join(os.path.dirname(survey_dst), obs), "observation file")
            else:
                dst = os.path.join(os.path.dirname(survey_dst), os.path.basename(obs))
                _copy(src, dst, "observation file")
                stext = read_text(survey_dst, MAX_YAML, "survey file")
                stext = re.sub(
                    r"(?m)^observations:.*$", f"observations: {os.path.basename(obs)}", stext
                )
                with open(survey_dst, "w", encoding="utf-8") as fh:
                    fh.write(stext)
    with open(os.path.join(session, CONFIG), "x", encoding="utf-8") as fh:
        fh.write(text)


def create(cfg: StationConfig, session: str) -> str:
    """Make the session folder and its snapshot; refuse a folder that holds anything (another
    session's files are never overwritten) and say in one line why a folder cannot be made."""
    check_new(session)
    made = not os.path.exists(session)
    try:
        os.makedirs(session, exist_ok=True)
        snapshot(cfg, session)
    except OSError as exc:
        if made:
            _remove_partial(session)
        raise InputError(
            f"cannot write the session folder: {exc.strerror or exc}; choose another --session-dir",
            path=session,
        ) from None
    return session


def check_new(session: str) -> None:
    """Refuse, in one line, a folder a new session cannot be made in (a session there, a
    file, a folder that holds anything): what :func:`create` checks, for the commands that
    must say it before the terminal UI starts (``live``, ``demo``)."""
    if os.path.exists(os.path.join(session, RAW)):
        raise InputError(
            "a session is already recorded there; choose a new --session-dir", path=session
        )
    if os.path.lexists(session) and not os.path.isdir(session):
        raise InputError("is a file, not a folder; choose a new --session-dir", path=session)
    if os.path.isdir(session) and os.listdir(session):
        raise InputError(
            "the folder is not empty and a session never overwrites files; "
            "choose a new --session-dir",
            path=session,
        )


def _remove_partial(session: str) -> None:
    """Remove what :func:`create` made before it failed (only its own new folder)."""
    for root, dirs, files in os.walk(session, topdown=False):
        for name in files:
            with contextlib.suppress(OSError):
                os.unlink(os.path.join(root, name))
        for name in dirs:
            with contextlib.suppress(OSError):
                os.rmdir(os.path.join(root, name))
    with contextlib.suppress(OSError):
        os.rmdir(session)


def save_results(path: str, write: Callable[[str], None]) -> str | None:
    """Rewrite the results CSV with ``write(path)``. A failure (disk full, folder gone,
    permissions, or a bug in the writer) is returned as one line for the terminal instead of
    raised: the caller keeps recording the raw log, from which ``station export`` writes the
    CSV later."""
    try:
        write(path)
    except OSError as exc:
        why = exc.strerror or str(exc)
    except Exception as exc:  # noqa: BLE001 - the recording goes on whatever the CSV does
        why = f"{type(exc).__name__}: {exc}"
    else:
        return None
    return (
        f"cannot write {path}: {why}; the raw log keeps recording "
        "(station export writes the CSV from it later)"
    )


def load_session_config(session: str) -> StationConfig:
    path = os.path.join(session, CONFIG)
    if not os.path.exists(path):
        raise InputError("session has no config.yaml; give --config", path=session)
    return load_config(path)


def _digest(path: str) -> str:
    return hashlib.sha256(read_bytes(path, MAX_OBSERVATIONS)).hexdigest()[:12]


def results_header(cfg: StationConfig, survey_name: str) -> dict[str, str]:
    """What the results were computed from, the same live and in replay."""
    # the config's air data, then the density it gives (a given density is not said twice)
    air = "".join(f"{k} {v:g} | " for k, v in cfg.air.given())
    return {
        "survey": f"{survey_name} ({os.path.basename(cfg.survey_path)} | "
        f"sha256 {_digest(cfg.survey_path)})",
        "config": f"{os.path.basename(cfg.path)} (sha256 {_digest(cfg.path)})",
        "protocol": cfg.serial.protocol,
        "skier": f"mass {cfg.mass_kg:g} kg",
        "air": f"{air}density {cfg.air_density:.4f} kg/m3",
        "fit": f"model {cfg.model} | 90 % intervals linearised (Wald) | Student t",
    }


def append_annotation(session: str, annotation: Annotation) -> str:
    """Append one annotation (flushed and fsync'd: it is the engineer's word); returns the
    line written (without its line end), by which its writer knows it when it reads it back."""
    path = os.path.join(session, ANNOTATIONS)
    record = annotation_to_json(annotation)
    line = json.dumps(record, ensure_ascii=False, sort_keys=True)
    try:
        with open(path, "a", encoding="utf-8") as fh:
            fh.write(line + "\n")
            fh.flush()
            os.fsync(fh.fileno())
    except OSError as exc:
        raise InputError(f"cannot write the annotation: {exc.strerror or exc}", path=path) from None
    return line


def read_annotations(session: str) -> list[Annotation]:
    """The session's annotations in order; a torn last line is passed over, a kind this
    version does not know too; a bad record is one error naming file, line and field."""
    path = os.path.join(session, ANNOTATIONS)
    if not os.path.exists(path):
        return []
    out = []
    lines = read_text(path, MAX_ANNOTATIONS, "annotations file").splitlines()
    for i, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        try:
            rec = json.loads(line)
        except (ValueError, RecursionError):  # nested 100 000 deep is not a record either
            if i == len(lines):
                break
            raise InputError("not an annotation record", path=path, line=i) from None
        if not isinstance(rec, dict):
            continue
        try:
            annotation = annotation_from_json(rec)
        except InputError as exc:
            raise InputError(exc.message, path=path, line=i, field=exc.field) from None
        if annotation is not None:
            out.append(annotation)
    return out


@dataclass(frozen=True)
class AppendedRecord:
    """One whole line of the annotations file read back: the annotation, or why not."""

    line: str
    annotation: Annotation | None  # None: blank, a kind this version does not know, or bad
    problem: str = ""


def read_annotations_after(session: str, offset: int) -> tuple[list[AppendedRecord], int]:
    """The whole records appended at or after byte ``offset`` of the annotations file, and the
    offset after the last of them: a record still being written (no line end yet) is left
    for the next read. For the recorder, which takes up what ``station annotate`` appends."""
    path = os.path.join(session, ANNOTATIONS)
    try:
        with open(path, "rb") as fh:
            fh.seek(offset)
            data = fh.read(MAX_ANNOTATIONS)
    except FileNotFoundError:
        return [], offset
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", path=path) from None
    end = data.rfind(b"\n") + 1
    out = []
    for raw in data[:end].split(b"\n")[:-1]:
        line = raw.decode("utf-8", "replace")
        if not line.strip():
            out.append(AppendedRecord(line, None))
            continue
        try:
            rec = json.loads(line)
            annotation = annotation_from_json(rec) if isinstance(rec, dict) else None
        except (ValueError, InputError, RecursionError) as exc:
            out.append(AppendedRecord(line, None, f"not an annotation record ({exc})"))
            continue
        out.append(AppendedRecord(line, annotation))
    return out, offset + end


# ----------------------------------------------------------------------------- being recorded


class RecordingStatus(enum.Enum):
    """Whether a session is being recorded now, as its lock file says (:class:`RecordingLock`)."""

    NOW = "recording"  # a live process holds the lock
    ENDED = "ended"  # no lock file: the recorder ended it (or a session older than the lock)
    INTERRUPTED = "interrupted"  # a lock file nobody holds: the recorder was killed or crashed
    UNKNOWN = "unknown"  # the lock cannot be read or tried (permissions, a file system without)


_BUSY = (errno.EWOULDBLOCK, errno.EAGAIN)


class RecordingLock:
    """The fact that a session is being recorded: the recording process holds an exclusive
    ``flock`` on ``SESSION/recording.lock`` from the creation of the session to
    :meth:`Acquisition.close <station.session.acquisition.Acquisition.close>`.

    Why a lock and not the raw log's age: a timer can be silent for minutes in a recording that
    goes on, and a recording that ended a second ago is finished. The OS drops a flock when its
    process ends however it ends (SIGKILL, a crash, a power cut), so a dead recorder never
    leaves a session "recording". A clean end removes the file *before* it lets the lock go; a
    file that is there and free was therefore left by a recorder that died: the session was
    interrupted (its results CSV may lack the last descent; a replay has it).

    The file holds the recorder's pid, host and start time as text, for a person who wonders."""

    def __init__(self, path: str, fd: int | None, problem: str = "") -> None:
        self.path = path
        self._fd = fd
        #: why the lock could not be taken ("" when held); the recording goes on without it
        self.problem = problem

    @classmethod
    def take(cls, session: str) -> RecordingLock:
        """Create the lock file and lock it. A file system without flock (some network or
        FUSE mounts) must not cost the test day: the recording goes on and ``problem`` says
        that ``station sessions`` cannot tell whether it is being recorded."""
        path = os.path.join(session, LOCK)
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        except OSError as exc:
            raise InputError(
                f"cannot make the recording lock: {exc.strerror or exc}; choose another "
                "--session-dir",
                path=path,
            ) from None
        problem = ""
        try:
            if fcntl is None:
                raise OSError(0, "this system has no flock")
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            why = exc.strerror or str(exc)
            problem = (f"cannot lock {path} ({why}): station sessions cannot tell whether this "
                       "session is being recorded")  # fmt: skip
        info = {"pid": os.getpid(), "host": socket.gethostname(), "t": time.time()}
        with contextlib.suppress(OSError):  # for a person; the lock is the fact
            os.write(fd, (json.dumps(info) + "\n").encode("ascii"))
        return cls(path, fd, problem)

    def release(self) -> None:
        """The recording ended: remove the file, then let the lock go (in this order, so that a
        free lock on a file still there means a recorder that died). Idempotent."""
        if self._fd is None:
            return
        with contextlib.suppress(OSError):
            os.unlink(self.path)
        fd, self._fd = self._fd, None
        os.close(fd)


def recording_state(session: str) -> RecordingStatus:
    """Is ``session`` being recorded now? A non-blocking try of its lock, released at once.

    Opened read-only, so a read-only folder or medium (a session copied to a stick) is read as
    well; a session from before the lock file has none and reads as ended."""
    path = os.path.join(session, LOCK)
    try:  # without waiting: a FIFO put there must not hang a listing
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except FileNotFoundError:
        return RecordingStatus.ENDED
    except OSError:
        return RecordingStatus.UNKNOWN
    try:
        if fcntl is None:
            return RecordingStatus.UNKNOWN
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except OSError as exc:
            return RecordingStatus.NOW if exc.errno in _BUSY else RecordingStatus.UNKNOWN
        # got it: was the file removed (the recorder ended) between our open and our lock?
        try:
            same = os.path.samestat(os.stat(path), os.fstat(fd))
        except FileNotFoundError:
            same = False
        return RecordingStatus.INTERRUPTED if same else RecordingStatus.ENDED
    finally:
        os.close(fd)


@contextlib.contextmanager
def annotations_locked(session: str, timeout_s: float | None = None) -> Iterator[bool | None]:
    """Hold an exclusive flock on the annotations file. Every writer of it appends only while
    holding it (``station annotate``, the recorder), so whoever holds it sees whole records and
    no one appends meanwhile:

    - two ``station annotate`` at once cannot leave a CSV without the other's annotation (the
      one that renamed its CSV last would win);
    - the recorder reads what others appended in the order of the file, and at its end takes
      up the last of them and lets its recording lock go *inside* this lock, so an annotate
      either finds the session recorded (and the recorder takes its record up) or ended (and
      rewrites the CSV itself), never in between.

    Yields True when held; False when ``timeout_s`` (None: wait as long as it takes) passed
    first; None on a file system without flock (the caller goes on as before the lock)."""
    path = os.path.join(session, ANNOTATIONS)
    try:
        # O_NONBLOCK: a FIFO there is an error at once (no reader), not a hang
        fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NONBLOCK, 0o644)
    except OSError as exc:
        raise InputError(f"cannot write the annotation: {exc.strerror or exc}", path=path) from None
    try:
        yield _flock_within(fd, timeout_s)
    finally:
        os.close(fd)  # lets the lock go


def _flock_within(fd: int, timeout_s: float | None) -> bool | None:
    if fcntl is None:
        return None
    deadline = None if timeout_s is None else time.monotonic() + timeout_s
    while True:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | (0 if deadline is None else fcntl.LOCK_NB))
            return True
        except OSError as exc:
            if exc.errno not in _BUSY:
                return None
        if deadline is None or time.monotonic() >= deadline:
            return False
        time.sleep(0.01)
