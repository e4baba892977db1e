"""``station sessions`` and ``annotate`` against a real recorder: ``station record`` on the
simulated timer's pty, in a process of its own, ended by SIGTERM (its clean end) or SIGKILL."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time

import pytest

from station.session import folder as session_folder
from tests.conftest import station_cmd
from tests.timing_helpers import start_sim, write_config

#: a timer that stays silent: the first start in ten minutes, the port held open
SILENT = ["--descents", "1", "--first-after", "600", "--hold", "600"]


def _status(run_station, session) -> str:
    r = run_station("sessions", session, "--json")
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)[0]["status"]


def _recording(tmp_path, sim_args=SILENT):
    """A recorder on a simulated timer (silent by default), once its session and results CSV
    exist."""
    sim, port, _ = start_sim(tmp_path, *sim_args)
    cfg = write_config(tmp_path, port)
    session = tmp_path / "session"
    rec = subprocess.Popen(
        [*station_cmd(), "record", "--config", str(cfg), "--session-dir", str(session)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 60
    while not (
        (session / session_folder.RAW).exists() and (session / session_folder.RESULTS).exists()
    ):
        assert rec.poll() is None, rec.stderr.read()
        assert time.monotonic() < deadline, "the recorder did not start"
        time.sleep(0.1)
    return sim, rec, session


def _stop(*procs: subprocess.Popen) -> None:
    for p in procs:
        if p.poll() is None:
            p.kill()
        p.wait(timeout=10)


@pytest.mark.slow  # a recorder on a simulated timer's pty
def test_recording_while_the_recorder_runs_and_finished_at_once_after_sigterm(
    tmp_path, run_station
):
    sim, rec, session = _recording(tmp_path)
    try:
        assert _status(run_station, session) == "recording"
        old = time.time() - 3600  # the timer silent for an hour: still recording
        os.utime(session / session_folder.RAW, (old, old))
        assert _status(run_station, session) == "recording"
        # annotate: saved, and the recorder's results.csv left to it
        before = (session / session_folder.RESULTS).read_bytes()
        r = run_station("annotate", session, "--from", "1", "--ski", "pair 7")
        assert r.returncode == 0, r.stderr
        assert "being recorded now" in r.stderr and len(r.stderr.strip().splitlines()) == 1
        assert "takes them up" in r.stderr
        assert (session / session_folder.RESULTS).read_bytes() == before
        rec.send_signal(signal.SIGTERM)
        assert rec.wait(timeout=30) == 0, rec.stderr.read()
        os.utime(
            session / session_folder.RAW
        )  # written a moment ago: the raw log's age would mislead
        assert _status(run_station, session) == "finished"
        assert not (session / session_folder.LOCK).exists()
        # now annotate rewrites the CSV, as export writes it
        r = run_station("annotate", session, "--from", "1", "--wax", "blue")
        assert r.returncode == 0 and "rewritten" in r.stderr, r.stderr
        out = tmp_path / "export.csv"
        assert run_station("export", session, "--csv", out).returncode == 0
        assert out.read_bytes() == (session / session_folder.RESULTS).read_bytes()
    finally:
        _stop(rec, sim)


@pytest.mark.slow  # a recorder on a simulated timer's pty
def test_a_killed_recorder_leaves_no_session_recording(tmp_path, run_station):
    sim, rec, session = _recording(tmp_path)
    try:
        assert _status(run_station, session) == "recording"
        os.kill(rec.pid, signal.SIGKILL)
        rec.wait(timeout=10)
        assert _status(run_station, session) == "interrupted"  # at once: the OS dropped the lock
        # the file left behind breaks neither replay nor export, and annotate may rewrite
        out = tmp_path / "export.csv"
        r = run_station("export", session, "--csv", out)
        assert r.returncode == 0, r.stderr
        r = run_station("annotate", session, "--from", "1", "--ski", "pair 7")
        assert r.returncode == 0 and "rewritten" in r.stderr, r.stderr
        assert _status(run_station, session) == "interrupted"
    finally:
        _stop(rec, sim)


@pytest.mark.slow  # a recorder on a simulated timer's pty
def test_the_recorder_takes_up_an_annotate_and_its_csv_is_the_replays(tmp_path, run_station):
    from tests.test_annotations_taken_up import _rows

    one = ["--speed", "10", "--first-after", "2", "--hold", "600", "--descents", "1", "--seed", "5"]
    sim, rec, session = _recording(tmp_path, one)
    try:
        deadline = time.monotonic() + 60
        while len(_rows(session)) < 1:
            assert rec.poll() is None and time.monotonic() < deadline, rec.stderr.read()
            time.sleep(0.1)
        r = run_station("annotate", session, "--descents", "1", "--invalid", "fell", "--wax", "X")
        assert r.returncode == 0 and "takes them up" in r.stderr, r.stderr
        deadline = time.monotonic() + 20
        while (_rows(session)[0]["invalid_reason"], _rows(session)[0]["wax"]) != ("fell", "X"):
            assert time.monotonic() < deadline, _rows(session)
            time.sleep(0.1)
        rec.send_signal(signal.SIGTERM)
        assert rec.wait(timeout=30) == 0, rec.stderr.read()
        out = tmp_path / "export.csv"
        assert run_station("export", session, "--csv", out).returncode == 0
        assert out.read_bytes() == (session / session_folder.RESULTS).read_bytes()
    finally:
        _stop(rec, sim)
