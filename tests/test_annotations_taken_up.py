"""A recording takes up what ``station annotate`` appends to its session meanwhile: applied in
the order of the annotations file, as the replay applies them, so the live results CSV is the
one a replay writes; and the last of them even while the recording ends."""

from __future__ import annotations

import datetime as dt
import threading
import time

import numpy as np

from station.session import folder as session_folder
from station.session.folder import RecordingStatus, recording_state
from tests.timing_helpers import ALGE_CHANNELS, write_config

T0 = dt.datetime(2026, 2, 2, 10, 0).timestamp()


def _open(tmp_path, threaded: bool):
    from station.session.acquisition import Acquisition
    from station.session.config import load_config

    cfg = load_config(str(write_config(tmp_path, "/dev/ttyUSB0")))
    session = tmp_path / "session"
    return Acquisition.open(cfg, session_dir=str(session), threaded=threaded), session


def _feed_descents(acq, n: int, mu: float = 0.009) -> None:
    """``n`` descents of the model's own times, as the timer's ALGE lines."""
    from station.model.physics import Conditions, Params, StraightRun
    from station.session.rawlog import Chunk
    from station.timing.wireformats import format_alge

    track = acq.track
    run = StraightRun(track.profile, np.array([pc.x for pc in track.photocells]))
    times = run.solve(Params(0.22, mu, 3.0), Conditions(88.0, 1.079), sensitivities=False).t
    bib = 0
    for k in range(n):
        t0 = T0 + 300.0 * k
        start = dt.datetime.fromtimestamp(t0)
        tod0 = (start.hour * 3600 + start.minute * 60 + start.second) * 10**6
        for ch, t in zip(ALGE_CHANNELS, times, strict=True):
            bib += 1
            line = format_alge(ch, tod0 + int(round(t * 1e6)), bib)
            acq.receive(Chunk(t0 + float(t) + 0.01, (line + "\r").encode("ascii")))


def _rows(session):
    from station.session.results import read_results

    path = session / "results.csv"
    rows = read_results(str(path)) if path.exists() else []
    return [{k: "" if v is None else v for k, v in r.items()} for r in rows]


def _replayed_csv(session, tmp_path, run_station) -> bytes:
    out = tmp_path / "replay.csv"
    r = run_station("replay", session, "--csv", out)
    assert r.returncode == 0, r.stderr
    return out.read_bytes()


def test_an_annotate_meanwhile_reaches_the_live_csv_as_a_replay_has_it(tmp_path, run_station):
    from station.session.records import ValidMark

    acq, session = _open(tmp_path, threaded=True)
    try:
        _feed_descents(acq, 2)
        deadline = time.monotonic() + 60
        while len(_rows(session)) < 2:
            assert time.monotonic() < deadline, "the descents were not fitted"
            time.sleep(0.05)
        r = run_station("annotate", session, "--descents", "2", "--invalid", "fell at PC4")
        assert r.returncode == 0 and "takes them up" in r.stderr, r.stderr
        r = run_station("annotate", session, "--descents", "1", "--ski", "pair 9")
        assert r.returncode == 0, r.stderr
        deadline = time.monotonic() + 20
        while [(x["ski"], x["invalid_reason"]) for x in _rows(session)] != [
            ("pair 9", ""), ("", "fell at PC4")
        ]:  # fmt: skip
            assert time.monotonic() < deadline, _rows(session)
            time.sleep(0.05)
        # the recorder's own annotations go on in the file's order with the others'
        acq.annotate(ValidMark(2))
    finally:
        acq.close()
    assert [x["invalid_reason"] for x in _rows(session)] == ["", ""]
    assert (
        _replayed_csv(session, tmp_path, run_station)
        == (session / session_folder.RESULTS).read_bytes()
    )


def test_the_file_order_decides_between_an_own_and_another_annotation(tmp_path, run_station):
    """Another process marks descent 1 invalid, then the recorder's engineer marks it valid:
    valid, as the replay of the file has it (applied the other way round, it stayed invalid)."""
    from station.session.records import InvalidMark, ValidMark

    acq, session = _open(tmp_path, threaded=False)
    try:
        _feed_descents(acq, 1)
        with session_folder.annotations_locked(str(session)):
            session_folder.append_annotation(str(session), InvalidMark(1, "elsewhere", T0))
        acq.annotate(ValidMark(1, T0 + 1))
        assert acq.results()[0].row.invalid_reason == ""
    finally:
        acq.close()
    assert _rows(session)[0]["invalid_reason"] == ""
    assert (
        _replayed_csv(session, tmp_path, run_station)
        == (session / session_folder.RESULTS).read_bytes()
    )


def test_an_annotate_while_the_recording_ends_is_taken_up_or_finds_it_ended(tmp_path, run_station):
    """The recorder takes up the last records and lets its lock go inside the annotations
    file's lock: an annotate waiting there meanwhile finds it ended and rewrites the CSV."""
    from station.session.records import InvalidMark

    acq, session = _open(tmp_path, threaded=False)
    _feed_descents(acq, 1)
    closer = threading.Thread(target=acq.close)
    with session_folder.annotations_locked(str(session)):  # an annotate in the middle of its append
        closer.start()
        time.sleep(0.3)
        assert closer.is_alive()  # the close waits for it
        session_folder.append_annotation(str(session), InvalidMark(1, "last word", T0))
        assert recording_state(str(session)) is RecordingStatus.NOW
    closer.join(timeout=30)
    assert not closer.is_alive()
    assert recording_state(str(session)) is RecordingStatus.ENDED
    assert _rows(session)[0]["invalid_reason"] == "last word"
    assert (
        _replayed_csv(session, tmp_path, run_station)
        == (session / session_folder.RESULTS).read_bytes()
    )
