"""A recording that ends cleanly leaves the results state a replay would write (issue 19), so
the first ``station annotate`` after ``station record`` changes rows in place instead of
replaying the day; a recording whose results CSV could not be written leaves none, and the
annotate replays as before. Real parts: ``station record`` against the simulated timer on a
pty, its session annotated by :class:`RecordedSession` and compared with a replay of the
session from scratch."""

from __future__ import annotations

import shutil
import subprocess
import threading
import time
from pathlib import Path

import pytest

from station.session import folder as session_folder
from station.session.acquisition import Acquisition
from station.session.listener import QuietListener
from station.session.recorded_session import RecordedSession
from station.session.records import (
    Annotation,
    FitModel,
    InvalidMark,
    Metadata,
    MetadataAnnotation,
    ModelChange,
)
from station.session.replay import replay_chunks
from station.session.resultsstate import DESCENTS, STATE
from tests.conftest import station_cmd
from tests.session_helpers import make_session
from tests.test_annotate_in_place import csv_of, from_scratch
from tests.timing_helpers import record_with_sim, start_sim, write_config

SIM = ["--speed", "10", "--first-after", "2", "--hold", "1", "--seed", "7"]


def source_day(tmp_path: Path) -> Path:
    (tmp_path / "src").mkdir()
    return make_session(tmp_path / "src", order="ABBAAB", annotate=False)


def record_chunks(source: Path, session: Path, during=None) -> Acquisition:
    """The recorder's own loop (threads, fit worker, results CSV, raw log) fed the chunks of
    a recorded day as its serial reader would feed them; ``during(acq)`` after the third
    descent's chunks. Quick: no timer in real time (the pty tests below have one)."""
    cfg = session_folder.load_session_config(str(source))
    acq = Acquisition.open(cfg, QuietListener(), session_dir=str(session))
    try:
        for chunk in replay_chunks(str(source), None, threading.Event(), []):
            if chunk.event != "session":
                acq.receive(chunk)
            if during is not None and acq.finished_descents == 3:
                during(acq)
                during = None
    finally:
        acq.close()
    return acq


def test_a_recording_leaves_the_state_a_replay_writes(tmp_path, replays):
    source = source_day(tmp_path)
    session = tmp_path / "rec"
    acq = record_chunks(source, session)
    assert acq.not_as_replayed is None
    assert (session / STATE).exists() and csv_of(session) == from_scratch(session)
    RecordedSession(str(session)).annotate(
        [InvalidMark(2, "fell", 2.0), ModelChange(4, FitModel.VELOCITY, 2.0)]
    )
    assert replays == []
    assert csv_of(session) == from_scratch(session)


def fitted_again_after_later_ones(*annotations: Annotation):
    """``during`` for :func:`record_chunks`: once descents 2 and 3 are fitted (with the survey
    covariance of the first), the annotations, which fit descent 1 again."""

    def during(acq: Acquisition) -> None:
        end = time.monotonic() + 60
        while len(acq.results()) < 3:
            assert time.monotonic() < end
            time.sleep(0.01)
        for a in annotations:
            acq.annotate(a)

    return during


AFTER_LATER_ONES = {
    "a model change": [ModelChange(1, FitModel.VELOCITY)],
    "a mass for the descent": [
        MetadataAnnotation(Metadata(mass_kg=70.0), descents=(1,), t=2.0),
    ],
    "a mass, air and a model": [
        MetadataAnnotation(Metadata(mass_kg=95.0, pressure_hpa=840.0), descents=(1, 2), t=2.0),
        ModelChange(1, FitModel.VELOCITY),
    ],
}


@pytest.mark.parametrize("kind", list(AFTER_LATER_ONES))
def test_a_descent_fitted_again_during_the_recording_gives_what_a_replay_gives(
    tmp_path, replays, kind
):
    """Descent 1 fitted again after later descents took the survey's covariance: the survey
    covariance is computed at a point no annotation moves (the reference fit of the first
    descent on the photocells, :class:`station.session.analysis.Analyser`), so the live CSV is
    the replay's byte for byte, the recorder leaves its state, and the next annotate, of the
    descent that handed the covariance on, runs in place (it used to differ from the replay
    in the 6th digit, and the recorder left no state)."""
    source = source_day(tmp_path)
    session = tmp_path / "rec"
    acq = record_chunks(source, session, fitted_again_after_later_ones(*AFTER_LATER_ONES[kind]))
    assert csv_of(session) == from_scratch(session)
    assert acq.not_as_replayed is None
    assert (session / STATE).exists() and (session / DESCENTS).exists()
    RecordedSession(str(session)).annotate(
        [InvalidMark(2, "fell", 3.0), ModelChange(1, FitModel.CONSTANT, 3.0)]
    )
    assert replays == []
    assert csv_of(session) == from_scratch(session)


@pytest.mark.slow  # a simulated timer on a pty, in real time
def test_record_then_annotate_runs_in_place_and_writes_what_a_replay_writes(tmp_path, replays):
    _, session, _ = record_with_sim(tmp_path, [*SIM, "--descents", "4"], max_descents=4)
    assert (session / STATE).exists() and (session / DESCENTS).exists()
    assert csv_of(session) == from_scratch(session)  # the recording's CSV is a replay's

    # an invalid mark, and a model change of a descent after the one that hands the survey on
    said = RecordedSession(str(session)).annotate(
        [InvalidMark(2, "fell at gate 3", time.time()), ModelChange(3, FitModel.VELOCITY)]
    )
    assert said.endswith(f"{session / session_folder.RESULTS} rewritten")
    assert replays == []  # in place: no replay of the day
    rows = csv_of(session).decode().splitlines()
    assert "fell at gate 3" in rows[-3] and ',"velocity",' in rows[-2]
    assert csv_of(session) == from_scratch(session)

    # the state the annotate left holds too: the next one is in place again
    copy = tmp_path / "copy"
    shutil.copytree(session, copy)
    RecordedSession(str(copy)).annotate([InvalidMark(4, "wind", time.time())])
    assert replays == []
    assert csv_of(copy) == from_scratch(copy)


@pytest.mark.slow  # a simulated timer on a pty, in real time
def test_a_recording_whose_results_csv_was_not_written_leaves_no_state(tmp_path, replays):
    sim, port, _ = start_sim(tmp_path, *SIM, "--descents", "2")
    cfg = write_config(tmp_path, port)
    session = tmp_path / "session"
    rec = subprocess.Popen(
        [*station_cmd(), "record", "--config", str(cfg), "--session-dir", str(session),
         "--max-descents", "2"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        # the empty CSV of the start, then a folder in its place: every write after it fails
        end = time.monotonic() + 60
        while not (session / session_folder.RESULTS).exists():
            assert time.monotonic() < end and rec.poll() is None, rec.stderr.read()
            time.sleep(0.01)
        (session / session_folder.RESULTS).unlink()
        (session / session_folder.RESULTS).mkdir()
        out, err = rec.communicate(timeout=120)
    finally:
        sim.wait(timeout=30)
    assert rec.returncode == 0, err
    assert f"cannot write {session / session_folder.RESULTS}" in out + err
    assert "results: not written" in err
    assert not (session / STATE).exists() and not (session / DESCENTS).exists()

    # the annotate replays the day, and writes the CSV (and its state) a replay writes
    (session / session_folder.RESULTS).rmdir()
    said = RecordedSession(str(session)).annotate([InvalidMark(1, "gate", time.time())])
    assert said.endswith("rewritten")
    assert replays == [str(session)]
    assert csv_of(session) == from_scratch(session)
    assert (session / STATE).exists()


def test_a_descent_joined_by_a_download_on_the_line_is_vouched_for_as_a_replay_gives_it(
    tmp_path, demo_track, replays
):
    """TAG, the recorder's own loop: descent 1 whole; descent 2 cut short by the cable (it is
    fitted short, and its four photocells get their survey covariance from it); the timer's
    memory sent on the line (``DS`` … ``DE``) ends it again whole; descent 3 whole. The
    recording leaves a state; annotates of descent 2 and of descent 1 then run in place and
    write what a replay from scratch writes."""
    from station.session.config import load_config
    from station.session.rawlog import Chunk, RawLogWriter
    from tests.test_memory_import import TAG_CHANNELS, _descent_lines, _frame

    cfg_path = write_config(tmp_path, "/dev/null", "tag", TAG_CHANNELS)
    source = tmp_path / "src"
    session_folder.create(load_config(str(cfg_path)), str(source))
    host = 1_767_520_800.0
    days = [_descent_lines(demo_track, 36_000 + s, k + 1, "TN", 9 * k + 1)
            for k, s in enumerate((0, 120, 400))]  # fmt: skip
    chunks = [Chunk(host + 0.01 * i, x.encode()) for i, x in enumerate(days[0])]
    chunks += [Chunk(host + 120 + 0.01 * i, x.encode()) for i, x in enumerate(days[1][:4])]
    chunks += [
        Chunk(host + 121.0, b"", "disconnected", "unplugged"),
        Chunk(host + 300.0, b"", "timeout"),
        Chunk(host + 310.0, b"", "connected"),
    ]
    memory = [_frame("DS 01  00 START - FINISH     ")]
    memory += [_frame(s.split("\t")[0].replace("TN", "AN", 1)) for s in days[1]]
    memory.append(_frame("DE 01"))
    chunks += [Chunk(host + 320.0 + 0.01 * i, x.encode()) for i, x in enumerate(memory)]
    chunks += [Chunk(host + 400 + 0.01 * i, x.encode()) for i, x in enumerate(days[2])]
    log = RawLogWriter(str(source / session_folder.RAW), header={"port": "/dev/null"})
    for c in chunks:
        if c.event:
            log.event(c.t, c.event, c.detail)
        else:
            log.write(c.t, c.data)
    log.close()

    session = tmp_path / "rec"
    acq = record_chunks(source, session)
    assert acq.not_as_replayed is None
    rows = csv_of(session).decode().splitlines()
    assert "joined: PC4 recorded live" in rows[-2]
    assert (session / STATE).exists() and csv_of(session) == from_scratch(session)
    RecordedSession(str(session)).annotate(
        [MetadataAnnotation(Metadata(mass_kg=70.0), descents=(2,), t=2.0)]
    )
    RecordedSession(str(session)).annotate([ModelChange(1, FitModel.VELOCITY, 3.0)])
    assert replays == []
    assert csv_of(session) == from_scratch(session)


def test_an_edit_that_changes_descent_1s_photocells_after_later_ones_is_as_replayed(
    tmp_path, demo_track, replays
):
    """TAG, the recorder's own loop: descents 1-3 whole; then PC5 of descent 1 cancelled at
    the timer (``TC``): descent 1 ends again on eight photocells, the first on them, and its
    reference fit gives them their survey covariance; descent 4 missed PC5 and takes it. The
    recording leaves a state; annotates of descents 1 and 4 run in place and write what a
    replay from scratch writes."""
    from station.session.config import load_config
    from station.session.rawlog import Chunk, RawLogWriter
    from station.timing.wireformats import format_tag
    from tests.test_memory_import import DAY, TAG_CHANNELS, _descent_lines

    cfg_path = write_config(tmp_path, "/dev/null", "tag", TAG_CHANNELS)
    source = tmp_path / "src"
    session_folder.create(load_config(str(cfg_path)), str(source))
    host = 1_767_520_800.0
    days = [_descent_lines(demo_track, 36_000 + 120 * k, k + 1, "TN", 9 * k + 1) for k in range(4)]
    del days[3][4]  # descent 4 missed PC5
    chunks = []
    for k in range(3):
        chunks += [Chunk(host + 120 * k + 0.01 * i, x.encode()) for i, x in enumerate(days[k])]
    pc5 = days[0][4].split()
    tod = pc5[4].split(":")
    tod_us = round((int(tod[0]) * 3600 + int(tod[1]) * 60 + float(tod[2])) * 1e6)
    cancel = format_tag("5", tod_us, 5, 1, DAY, "TC") + "\r\n"
    chunks.append(Chunk(host + 300.0, cancel.encode()))
    chunks += [Chunk(host + 360 + 0.01 * i, x.encode()) for i, x in enumerate(days[3])]
    log = RawLogWriter(str(source / session_folder.RAW), header={"port": "/dev/null"})
    for c in chunks:
        log.write(c.t, c.data)
    log.close()

    session = tmp_path / "rec"
    acq = record_chunks(source, session)
    assert acq.not_as_replayed is None
    an = acq.day.analyser
    eight = ("PC1", "PC2", "PC3", "PC4", "PC6", "PC7", "PC8", "PC9")
    assert acq.day.results[1].descent.photocells == eight
    assert an.survey_source[eight] == 1 and acq.day.results[4].descent.photocells == eight
    assert (session / STATE).exists() and csv_of(session) == from_scratch(session)
    RecordedSession(str(session)).annotate([ModelChange(1, FitModel.VELOCITY, 2.0)])
    RecordedSession(str(session)).annotate(
        [MetadataAnnotation(Metadata(mass_kg=70.0), descents=(1, 4), t=3.0)]
    )
    assert replays == []
    assert csv_of(session) == from_scratch(session)
