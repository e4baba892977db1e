"""Being recorded is a fact (the recorder's flock on ``recording.lock``), not the raw log's age;
``station annotate`` rewrites the results CSV of a session nobody records, as export would.

The lock is tried here from another open file description in the same process, which flock
treats as another holder; tests/test_recording_lock_process.py does it with a real recorder."""

from __future__ import annotations

import json
import os
import time

import pytest

from station.session import folder as session_folder
from station.session.folder import RecordingLock, RecordingStatus, recording_state
from tests.session_helpers import make_session


@pytest.fixture
def session(tmp_path):
    return make_session(tmp_path, order="ABA")


def _rows(session) -> list[dict]:
    """The session's results CSV, an empty cell as "" (as the text reader gave it)."""
    from station.session.results import read_results

    rows = read_results(str(session / session_folder.RESULTS))
    return [{k: "" if v is None else v for k, v in r.items()} for r in rows]


def _one_line(r, *expect: str) -> str:
    assert r.returncode == 2, (r.stdout, r.stderr)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    for e in expect:
        assert e in lines[0], lines[0]
    return lines[0]


def _status(run_station, session) -> str:
    r = run_station("sessions", session, "--json")
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)[0]["status"]


def test_the_lock_says_recording_until_released_and_a_dead_holder_reads_interrupted(tmp_path):
    folder = str(tmp_path)
    # no lock file: a session from before it
    assert recording_state(folder) is RecordingStatus.ENDED
    lock = RecordingLock.take(folder)
    assert lock.problem == ""
    assert recording_state(folder) is RecordingStatus.NOW
    assert recording_state(folder) is RecordingStatus.NOW  # trying it did not take it
    info = json.loads((tmp_path / session_folder.LOCK).read_text())
    assert info["pid"] == os.getpid()
    lock.release()
    assert not (tmp_path / session_folder.LOCK).exists()
    assert recording_state(folder) is RecordingStatus.ENDED
    lock.release()  # idempotent
    # a recorder that died leaves its file, and the OS has dropped its lock
    (tmp_path / session_folder.LOCK).write_text('{"pid": 1}\n')
    assert recording_state(folder) is RecordingStatus.INTERRUPTED


def test_a_second_lock_on_the_same_session_is_refused(tmp_path):
    lock = RecordingLock.take(str(tmp_path))
    try:
        with pytest.raises(session_folder.InputError, match="recording lock"):
            RecordingLock.take(str(tmp_path))
        assert recording_state(str(tmp_path)) is RecordingStatus.NOW
    finally:
        lock.release()


def test_an_acquisition_holds_the_lock_from_creation_to_close(tmp_path):
    from station.session.acquisition import Acquisition
    from station.session.config import load_config
    from tests.timing_helpers import write_config

    cfg = load_config(str(write_config(tmp_path, "/dev/ttyUSB0")))
    session = tmp_path / "s"
    acq = Acquisition.open(cfg, session_dir=str(session), threaded=False)
    try:
        assert recording_state(str(session)) is RecordingStatus.NOW
        assert (session / session_folder.LOCK).exists() and session_folder.is_session(str(session))
    finally:
        acq.close()
    assert recording_state(str(session)) is RecordingStatus.ENDED
    # the finished session holds what it held before there was a lock: no lock file
    assert (
        session_folder.LOCK not in os.listdir(session)
        and (session / session_folder.RESULTS).exists()
    )
    acq.close()  # idempotent, and does not touch a lock it no longer has


def test_sessions_status_is_the_lock_not_the_raw_logs_age(run_station, session):
    raw = session / session_folder.RAW
    os.utime(raw, (time.time(), time.time()))  # written a second ago: it used to say recording
    assert _status(run_station, session) == "finished"
    lock = RecordingLock.take(str(session))
    try:
        old = time.time() - 3600  # a timer silent for an hour
        os.utime(raw, (old, old))
        assert _status(run_station, session) == "recording"
        r = run_station("sessions", session.parent)
        assert r.returncode == 0 and "recording" in r.stdout
    finally:
        lock.release()
    assert _status(run_station, session) == "finished"
    (session / session_folder.LOCK).write_text("")  # left by a killed recorder
    assert _status(run_station, session) == "interrupted"


def test_a_left_lock_file_breaks_nothing_and_a_read_only_session_is_read(run_station, session):
    (session / session_folder.LOCK).write_text('{"pid": 1}\n')  # a recorder killed: its file stays
    out = session.parent / "export.csv"
    r = run_station("export", session, "--csv", out)
    assert r.returncode == 0, r.stderr
    assert out.read_bytes() == (session / session_folder.RESULTS).read_bytes()
    r = run_station("replay", session)
    assert r.returncode == 0, r.stderr
    os.chmod(session / session_folder.LOCK, 0o444)
    os.chmod(session, 0o555)
    try:
        assert _status(run_station, session) == "interrupted"
        r = run_station("export", session, "--csv", out)
        assert r.returncode == 0, r.stderr
    finally:
        os.chmod(session, 0o755)


def test_annotate_rewrites_results_csv_as_export_writes_it(run_station, session, tmp_path):
    before = (session / session_folder.RESULTS).read_bytes()
    r = run_station("annotate", session, "--descents", "2", "--invalid", "fell at PC4")
    assert r.returncode == 0, r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "rewritten" in lines[0] and "results.csv" in lines[0], r.stderr
    after = (session / session_folder.RESULTS).read_bytes()
    assert after != before
    exported = tmp_path / "export.csv"
    assert run_station("export", session, "--csv", exported).returncode == 0
    assert exported.read_bytes() == after
    rows = _rows(session)
    assert [r["invalid_reason"] for r in rows] == ["", "fell at PC4", ""]
    # ski and wax too, and a refit with another model
    r = run_station("annotate", session, "--descents", "1,3", "--ski", "pair C", "--model",
                    "velocity")  # fmt: skip
    assert r.returncode == 0, r.stderr
    rows = _rows(session)
    assert [r["ski"] for r in rows] == ["pair C", "pair B", "pair C"]
    assert [r["model"] for r in rows] == ["velocity", "constant", "velocity"]
    assert run_station("export", session, "--csv", exported).returncode == 0
    assert exported.read_bytes() == (session / session_folder.RESULTS).read_bytes()


def test_annotate_while_recording_saves_and_leaves_the_csv_to_the_recorder(run_station, session):
    before = (session / session_folder.RESULTS).read_bytes()
    n = len((session / session_folder.ANNOTATIONS).read_text().splitlines())
    lock = RecordingLock.take(str(session))
    try:
        r = run_station("annotate", session, "--descents", "2", "--invalid", "fell")
    finally:
        lock.release()
    assert r.returncode == 0, r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "being recorded now" in lines[0], r.stderr
    assert "the recording takes them up" in lines[0]
    assert (
        session / session_folder.RESULTS
    ).read_bytes() == before  # the recorder's file, untouched
    assert len((session / session_folder.ANNOTATIONS).read_text().splitlines()) == n + 1


def test_a_results_csv_that_cannot_be_written_is_one_line_and_the_annotation_stays(
    run_station, session
):
    (session / session_folder.RESULTS).unlink()
    (session / session_folder.RESULTS).mkdir()  # not writable as a file, even for root
    n = len((session / session_folder.ANNOTATIONS).read_text().splitlines())
    r = run_station("annotate", session, "--descents", "2", "--invalid", "fell")
    line = _one_line(r, "annotations are saved", "results.csv was not rewritten", "is a folder")
    assert str(session / session_folder.RESULTS) in line
    saved = (session / session_folder.ANNOTATIONS).read_text().splitlines()
    assert len(saved) == n + 1 and json.loads(saved[-1])["reason"] == "fell"
    r = run_station("sessions", session)  # a results CSV that is a folder: one line, too
    _one_line(r, "is a folder, not a results CSV")


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes a read-only file")
def test_a_read_only_results_csv_is_one_line_and_the_annotation_stays(run_station, session):
    os.chmod(session / session_folder.RESULTS, 0o444)
    r = run_station("annotate", session, "--from", "2", "--ski", "X")
    _one_line(r, "annotations are saved", "not writable")
    last = json.loads((session / session_folder.ANNOTATIONS).read_text().splitlines()[-1])
    assert last["values"]["ski"] == "X"


def test_two_annotates_at_once_both_reach_the_csv(session):
    """The second waits for the first's lock on the annotations file; its CSV has both."""
    import threading

    from station.session.recorded_session import RecordedSession
    from station.session.records import InvalidMark

    def rewrite_results(path: str) -> None:
        RecordedSession(path).rewrite_results()

    order = []
    with session_folder.annotations_locked(str(session)):
        session_folder.append_annotation(str(session), InvalidMark(1, "first", 0.0))

        def second():
            with session_folder.annotations_locked(str(session)):
                order.append("second")
                session_folder.append_annotation(str(session), InvalidMark(3, "second", 0.0))
                rewrite_results(str(session))

        t = threading.Thread(target=second)
        t.start()
        time.sleep(0.2)
        assert order == []  # waiting
        rewrite_results(str(session))
        order.append("first")
    t.join(timeout=60)
    assert order == ["first", "second"]
    rows = _rows(session)
    assert [r["invalid_reason"] for r in rows] == ["first", "", "second"]


def test_a_memory_download_is_not_merged_into_a_session_being_recorded(run_station, session):
    """Two writers of one raw log (the recorder and the merge) would interleave their records."""
    capture = session.parent / "memory.txt"
    capture.write_bytes(b" 0001 C0  10:00:00.0000 00\r")
    raw = (session / session_folder.RAW).read_bytes()
    lock = RecordingLock.take(str(session))
    try:
        r = run_station("import", capture, "--config", session / "config.yaml", "--into", session)
    finally:
        lock.release()
    _one_line(r, "being recorded now", str(session))
    assert (session / session_folder.RAW).read_bytes() == raw
    r = run_station("import", capture, "--config", session / "config.yaml", "--into", session)
    assert r.returncode == 0, r.stderr


def test_a_file_system_without_flock_costs_a_warning_not_the_recording(
    tmp_path, monkeypatch, run_station
):
    """Some network and FUSE mounts refuse flock (ENOLCK): the day is recorded all the same,
    one warning says why, and ``station sessions`` says it cannot tell."""
    import errno
    import fcntl

    from station.session.acquisition import Acquisition
    from station.session.config import load_config
    from station.session.listener import Listener
    from tests.timing_helpers import write_config

    def no_flock(fd, op):
        raise OSError(errno.ENOLCK, os.strerror(errno.ENOLCK))

    class Heard(Listener):
        def __init__(self):
            self.warnings = []

        def warning(self, text):
            self.warnings.append(text)

    monkeypatch.setattr(fcntl, "flock", no_flock)
    cfg = load_config(str(write_config(tmp_path, "/dev/ttyUSB0")))
    heard = Heard()
    session = tmp_path / "s"
    acq = Acquisition.open(cfg, heard, session_dir=str(session), threaded=False)
    try:
        assert len(heard.warnings) == 1 and "cannot tell whether" in heard.warnings[0]
        assert session_folder.is_session(str(session))
        assert recording_state(str(session)) is RecordingStatus.UNKNOWN
        assert _status(run_station, session).startswith("unknown")
    finally:
        acq.close()
    assert recording_state(str(session)) is RecordingStatus.ENDED
