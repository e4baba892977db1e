"""The session's results CSV during a recording: each descent's row appended (the day's rows
are not rewritten after every descent), the file rewritten in full only when an earlier row
changes (an annotation, a refit), the same bytes as a replay's CSV either way, and a write that
fails (disk full) reported and made good by the next one."""

from __future__ import annotations

import os

import pandas as pd

import station.session.results as results
from station.session import folder as sessions
from station.session.acquisition import Acquisition
from station.session.config import load_config
from station.session.listener import Listener
from station.session.rawlog import Chunk
from station.session.records import FitModel, InvalidMark, ModelChange, csv_record
from station.session.runs import replay
from tests.test_acquisition import T0, descent_lines
from tests.timing_helpers import write_config


class Warnings(Listener):
    def __init__(self) -> None:
        self.warnings: list[str] = []

    def warning(self, text: str) -> None:
        self.warnings.append(text)


def count_full_writes(monkeypatch) -> list[int]:
    """How many times the results CSV is written in full (the list's length)."""
    real = results.write_results
    calls: list[int] = []

    def write(rows, path, header):
        calls.append(len(rows))
        real(rows, path, header)

    monkeypatch.setattr(results, "write_results", write)
    return calls


def feed(acq: Acquisition, descents: list[list[str]], t0: float = T0) -> None:
    for i, line in enumerate(line for d in descents for line in d):
        acq.receive(Chunk(t0 + i, line.encode()))


def replayed(session) -> bytes:
    out = session.parent / "replayed.csv"
    acq = replay(str(session), sessions.load_session_config(str(session)))
    acq.write_csv(str(out))
    return out.read_bytes()


def test_each_descent_is_appended_and_an_annotation_rewrites_the_file(
    tmp_path, demo_track, monkeypatch
):
    full = count_full_writes(monkeypatch)
    cfg = load_config(str(write_config(tmp_path, "loop://")))
    session = tmp_path / "session"
    csv = session / sessions.RESULTS
    acq = Acquisition.open(cfg, Warnings(), session_dir=str(session), threaded=False)
    assert full == [0]  # the header, at the start
    inode = os.stat(csv).st_ino
    starts = [36000 + 60 * k for k in range(6)]
    lines = descent_lines(demo_track, starts)
    feed(acq, lines[:3])
    # three descents, three rows: appended to the same file, not written again in full
    assert full == [0] and os.stat(csv).st_ino == inode
    assert list(pd.read_csv(csv, comment="#")["descent"]) == [1, 2, 3]
    assert csv.read_bytes() == _as_written(acq)

    acq.annotate(InvalidMark(2, "fell at PC4"))  # an earlier row changed: the file in full
    assert full == [0, 3]
    assert list(pd.read_csv(csv, comment="#")["invalid_reason"].fillna("")) == [
        "", "fell at PC4", ""
    ]  # fmt: skip
    # a refit of an earlier descent: in full (not descent 1, whose first fit gave the survey's
    # covariance of the crossing times that later fits reuse: a replay fits it with the
    # velocity model first)
    acq.annotate(ModelChange(3, FitModel.VELOCITY))
    assert full == [0, 3, 3]
    inode = os.stat(csv).st_ino
    feed(acq, lines[3:], T0 + 1000)
    assert full == [0, 3, 3] and os.stat(csv).st_ino == inode  # appended again
    acq.close()
    assert full == [0, 3, 3]  # the end has nothing left to write
    assert list(pd.read_csv(csv, comment="#")["descent"]) == [1, 2, 3, 4, 5, 6]
    assert csv.read_bytes() == replayed(session)  # a replay gives the same bytes


def _as_written(acq: Acquisition) -> bytes:
    """The results CSV as one full write of the day's rows gives it."""
    import io

    buf = io.StringIO(newline="")
    acq.write_csv_to(buf)
    return buf.getvalue().encode("utf-8")


def test_a_full_disk_while_appending_is_reported_and_the_next_descent_writes_it_all(
    tmp_path, demo_track, monkeypatch
):
    disk_full = {"on": False}
    real_append, real_write = results.append_results, results.write_results

    def append(path, rows, size, inode=None):
        if disk_full["on"]:
            with open(path, "a") as fh:  # half a row reached the disk before it filled
                fh.write('4,"2026-')
            raise OSError(28, "No space left on device")
        return real_append(path, rows, size, inode)

    def write(rows, path, header):
        if disk_full["on"]:
            raise OSError(28, "No space left on device")
        real_write(rows, path, header)

    monkeypatch.setattr(results, "append_results", append)
    monkeypatch.setattr(results, "write_results", write)
    cfg = load_config(str(write_config(tmp_path, "loop://")))
    session = tmp_path / "session"
    csv = session / sessions.RESULTS
    seen = Warnings()
    acq = Acquisition.open(cfg, seen, session_dir=str(session), threaded=False)
    lines = descent_lines(demo_track, [36000 + 60 * k for k in range(6)])
    feed(acq, lines[:2])
    disk_full["on"] = True
    feed(acq, lines[2:4], T0 + 500)
    problems = [w for w in seen.warnings if "No space left on device" in w]
    assert len(problems) == 1  # said once, not after every descent
    assert str(csv) in problems[0] and "raw log keeps recording" in problems[0]
    disk_full["on"] = False
    feed(acq, lines[4:5], T0 + 1000)  # space again: this descent's write has everything
    assert "written again: it is complete" in seen.warnings[-1]
    assert list(pd.read_csv(csv, comment="#")["descent"]) == [1, 2, 3, 4, 5]
    feed(acq, lines[5:], T0 + 1500)
    acq.close()
    assert csv.read_bytes() == replayed(session)


def test_appending_rows_gives_the_bytes_of_writing_them_all(tmp_path, demo_track):
    cfg = load_config(str(write_config(tmp_path, "loop://")))
    acq = Acquisition.open(cfg, Warnings(), threaded=False)
    feed(acq, descent_lines(demo_track, [36000, 36060, 36120]))
    acq.close()
    rows = [csv_record(r.row) for r in acq.results()]
    header = {"survey": "x, y; z", "config": "c"}
    whole, parts = tmp_path / "whole.csv", tmp_path / "parts.csv"
    results.write_results(rows, str(whole), header)
    results.write_results(rows[:1], str(parts), header)
    size = os.path.getsize(parts)
    size = results.append_results(str(parts), rows[1:], size)
    assert parts.read_bytes() == whole.read_bytes() and size == os.path.getsize(whole)
    # a file that changed since (another writer) is not appended to: the caller rewrites it
    with open(parts, "a") as fh:
        fh.write("\n")
    try:
        results.append_results(str(parts), rows[1:], size)
    except ValueError:
        pass
    else:
        raise AssertionError("appended to a file that changed")
