"""A full disk costs nothing the timer sent (issue 18): the raw log holds what it cannot write,
says so naming the file, writes it once space returns, and never ends torn.

The in-process tests fail ``os.write`` on the raw log's descriptor (ENOSPC, also after a
partial write, as a filling disk does); the last test records from the simulated timer onto a
real tmpfs that is filled and emptied during the recording."""

from __future__ import annotations

import errno
import os
import shutil
import subprocess
import time

import pandas as pd
import pytest

from station.session.rawlog import RawLogWriter, read_rawlog


class Disk:
    """``os.write`` on one descriptor fails while ``full``; ``room`` bytes may go first."""

    def __init__(self, monkeypatch) -> None:
        self.fd = -1
        self.full = False
        self.room = 0
        real = os.write

        def write(fd, data):
            if fd == self.fd and self.full:
                if self.room > 0:
                    n = min(self.room, len(data))
                    self.room -= n
                    return real(fd, bytes(data[:n]))
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            return real(fd, data)

        monkeypatch.setattr(os, "write", write)


def _writer(tmp_path, monkeypatch, **kw):
    disk = Disk(monkeypatch)
    said: list[str] = []
    w = RawLogWriter(str(tmp_path / "raw.jsonl"), header={"port": "x"}, on_problem=said.append,
                     **kw)  # fmt: skip
    disk.fd = w._fd
    return w, disk, said


def test_what_cannot_be_written_is_held_and_written_once_space_returns(tmp_path, monkeypatch):
    w, disk, said = _writer(tmp_path, monkeypatch, fsync_interval_s=60)
    path = tmp_path / "raw.jsonl"
    try:
        w.write(1.0, b"A\r")
        disk.full, disk.room = True, 7  # B is cut after 7 bytes: the file ends torn meanwhile
        w.write(2.0, b"B\r")
        w.write(3.0, b"C\r")
        assert w.held_bytes > 0 and len(said) == 1
        assert said[0].startswith(f"{path}: cannot write the raw log (the disk is full)")
        assert "held in memory (up to 64.0 MB)" in said[0]
        disk.full = False
        w.write(4.0, b"D\r")
        assert w.held_bytes == 0
        assert said[1] == f"{path}: written again: 2 record(s) (at most 42 bytes held in " \
            "memory) are on disk"  # fmt: skip
    finally:
        w.close()
    warnings: list[str] = []
    chunks = list(read_rawlog(str(path), warnings))
    assert [c.data for c in chunks if c.data] == [b"A\r", b"B\r", b"C\r", b"D\r"]
    assert warnings == [] and w.lost_records == 0


def test_a_silent_timer_s_last_line_is_written_when_space_returns(tmp_path, monkeypatch):
    w, disk, said = _writer(tmp_path, monkeypatch, fsync_interval_s=0.2)
    try:
        disk.full = True
        w.write(1.0, b"last\r")  # then the timer falls silent
        assert w.held_bytes > 0
        disk.full = False
        deadline = time.monotonic() + 5
        while w.held_bytes and time.monotonic() < deadline:
            time.sleep(0.05)
        assert w.held_bytes == 0  # the fsync timer wrote it, no further write needed
    finally:
        w.close()
    assert [c.data for c in read_rawlog(str(tmp_path / "raw.jsonl")) if c.data] == [b"last\r"]


def test_closed_on_a_full_disk_the_log_ends_on_a_whole_record_and_the_loss_is_said(
    tmp_path, monkeypatch
):
    w, disk, said = _writer(tmp_path, monkeypatch, fsync_interval_s=60)
    w.write(1.0, b"A\r")
    disk.full, disk.room = True, 5
    w.write(2.0, b"B\r")
    w.write(3.0, b"C\r")
    w.close()  # never raises
    path = tmp_path / "raw.jsonl"
    assert path.read_bytes().endswith(b"\n")
    warnings: list[str] = []
    assert [c.data for c in read_rawlog(str(path), warnings) if c.data] == [b"A\r"]
    assert warnings == [] and w.lost_records == 2
    assert said[-1].startswith(f"{path}: 2 record(s)") and "station import" in said[-1]


def test_beyond_the_memory_bound_records_are_counted_and_the_gap_is_logged(tmp_path, monkeypatch):
    size = len(RawLogWriter._encode({"t": 0.0, "rx": "0123456789\r"}))
    w, disk, said = _writer(tmp_path, monkeypatch, fsync_interval_s=60, max_held=2 * size + 1)
    try:
        disk.full = True
        for i in range(6):
            w.write(float(i), b"0123456789\r")  # two are held, four lost
        assert w.lost_records == 4 and any("the bound" in s for s in said)
        disk.full = False
        w.write(9.0, b"after\r")
    finally:
        w.close()
    chunks = list(read_rawlog(str(tmp_path / "raw.jsonl")))
    assert [c.data for c in chunks if c.data] == [b"0123456789\r"] * 2 + [b"after\r"]
    lost = [c for c in chunks if c.event == "lost"]
    assert len(lost) == 1 and lost[0].detail.startswith("4 record(s)")


def test_a_failing_fsync_is_said_and_retried_not_raised(tmp_path, monkeypatch):
    said: list[str] = []
    w = RawLogWriter(str(tmp_path / "raw.jsonl"), fsync_interval_s=0.1, on_problem=said.append)
    real = os.fsync
    failing = [True]

    def fsync(fd):
        if failing[0]:
            raise OSError(errno.EIO, os.strerror(errno.EIO))
        real(fd)

    monkeypatch.setattr(os, "fsync", fsync)
    w.write(1.0, b"A\r")
    time.sleep(0.4)
    w.write(2.0, b"B\r")  # does not raise
    failing[0] = False
    time.sleep(0.4)
    w.close()
    assert said[0].endswith("cannot sync the raw log to disk (Input/output error); retrying")
    assert said[-1].endswith("synced to disk again")


def test_the_acquisition_tells_its_listener_and_fits_on_while_the_disk_is_full(
    tmp_path, demo_track, monkeypatch
):
    """The recorder's warning is the listener's (a line in record, red in the UI), and the
    descents the timer sends meanwhile are fitted and then on disk."""
    from station.session.acquisition import Acquisition
    from station.session.config import load_config
    from tests.test_acquisition import Recorder, descent_lines, feed_like_a_reader
    from tests.timing_helpers import write_config

    disk = Disk(monkeypatch)
    seen = Recorder()
    session = tmp_path / "session"
    acq = Acquisition.open(load_config(str(write_config(tmp_path, "loop://"))), seen,
                           session_dir=str(session))  # fmt: skip
    assert acq.rawlog is not None
    disk.fd, disk.full = acq.rawlog._fd, True
    descents = descent_lines(demo_track, [36000, 36060])
    feed_like_a_reader(acq, descents[:1])
    disk.full = False
    feed_like_a_reader(acq, descents[1:])
    acq.close()
    raw = session / "raw.jsonl"
    assert seen.warnings[0].startswith(f"{raw}: cannot write the raw log (the disk is full)")
    assert any(w.startswith(f"{raw}: written again") for w in seen.warnings)
    assert [r.row.status for r in acq.results()] == ["ok", "ok"]
    lines = b"".join(c.data for c in read_rawlog(str(raw)))
    assert lines == "".join(line for d in descents for line in d).encode()


# ---------------------------------------------------------------- a real full disk


@pytest.fixture
def small_disk(tmp_path):
    """A 3 MB tmpfs (root only: skipped where mounting is not permitted)."""
    mnt = tmp_path / "disk"
    mnt.mkdir()
    if not shutil.which("mount"):
        pytest.skip("no mount command")
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=3m", "tmpfs", str(mnt)],
                       capture_output=True, text=True)  # fmt: skip
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {r.stderr.strip()}")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], check=False)


def _fill(mnt) -> None:
    with open(mnt / "filler", "wb") as fh:
        try:
            while True:
                fh.write(b"\0" * 65536)
                fh.flush()
        except OSError as exc:
            assert exc.errno == errno.ENOSPC


def _until(rec, out: list[str], pred) -> None:
    """Read the recorder's stdout into ``out`` until a line satisfies ``pred``."""
    while not any(pred(line) for line in out):
        line = rec.stdout.readline()
        assert line, "".join(out) + rec.stderr.read()
        out.append(line)


def _descent(n: int):
    return lambda line: line.split()[:2] == ["descent", str(n)]


def _recording(tmp_path, session, descents: int, seed: int):
    from tests.conftest import station_cmd
    from tests.timing_helpers import start_sim, write_config

    # a descent every 2 s: a tmpfs page (4 kB) the raw log has begun takes ~9 descents to fill
    sim, port, _ = start_sim(
        tmp_path, "--speed", "20", "--interval", "40", "--first-after", "2", "--hold", "1",
        "--descents", str(descents), "--seed", str(seed),
    )  # fmt: skip
    cfg = write_config(tmp_path, port)
    rec = subprocess.Popen(
        [*station_cmd(), "record", "--config", str(cfg), "--session-dir", str(session),
         "--max-descents", str(descents)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    return sim, rec


@pytest.mark.slow  # a simulated timer on a pty, in real time
def test_a_disk_filled_during_a_recording_loses_no_descent(tmp_path, small_disk, run_station):
    session = small_disk / "session"
    raw = session / "raw.jsonl"
    full = f"warning: {raw}: cannot write the raw log (the disk is full)"
    sim, rec = _recording(tmp_path, session, 16, 5)
    out: list[str] = []
    try:
        _until(rec, out, _descent(1))
        _fill(small_disk)
        _until(rec, out, lambda line: line.startswith(full))
        n = sum(line.startswith("descent") for line in out)
        _until(rec, out, _descent(n + 2))  # two more descents held in memory only
        os.remove(small_disk / "filler")
        rest, err = rec.communicate(timeout=120)
        out.append(rest)
    finally:
        if rec.poll() is None:
            rec.kill()
        sim.wait(timeout=30)
    text = "".join(out)
    assert rec.returncode == 0, err
    assert f"warning: {raw}: written again" in text
    assert "results: " in err and "Traceback" not in err
    warnings: list[str] = []
    list(read_rawlog(str(raw), warnings))
    assert warnings == []
    replayed = tmp_path / "replay.csv"
    r = run_station("replay", session, "--csv", replayed)
    assert r.returncode == 0, r.stderr
    df = pd.read_csv(replayed, comment="#")
    assert list(df["status"]) == ["ok"] * 16


@pytest.mark.slow  # a simulated timer on a pty, in real time
def test_a_disk_that_stays_full_ends_with_one_line_and_a_whole_log(tmp_path, small_disk):
    session = small_disk / "session"
    raw = session / "raw.jsonl"
    sim, rec = _recording(tmp_path, session, 12, 6)
    out: list[str] = []
    try:
        _until(rec, out, lambda line: "timer connected" in line)
        _fill(small_disk)
        rest, err = rec.communicate(timeout=120)
        out.append(rest)
    finally:
        if rec.poll() is None:
            rec.kill()
        sim.wait(timeout=30)
    text = "".join(out)
    assert rec.returncode == 2, err
    assert f"warning: {raw}: cannot write the raw log (the disk is full)" in text
    last = err.strip().splitlines()
    assert last[-2].startswith("results: not written")  # no claim of a file not there
    assert last[-1].startswith(f"station: error: {raw}: ") and "could not be written" in last[-1]
    assert "station import" in last[-1] and "Traceback" not in err
    assert raw.read_bytes().endswith(b"\n")
    warnings: list[str] = []
    list(read_rawlog(str(raw), warnings))
    assert warnings == []
