"""Framing and the raw log: no byte lost, a torn last record survived."""

from __future__ import annotations

import json

import pytest

from station.errors import InputError
from station.session.rawlog import RawLogWriter, read_rawlog
from station.timing.framing import MAX_LINE, LineFramer


def test_lines_split_across_reads_and_every_line_end():
    f = LineFramer()
    assert f.feed(b" 0042 C0 12:00") == []
    assert f.feed(b":00.1234 00\r") == [" 0042 C0 12:00:00.1234 00"]
    assert f.feed(b"a\r\nb\nc\r") == ["a", "b", "c"]
    assert f.feed(b"d\r") == ["d"]
    assert f.feed(b"\ne\r\n") == ["e"]  # the LF of a CR LF split across reads is no empty line
    assert f.feed(b"tail") == [] and f.flush() == ["tail"]


def test_a_runaway_line_is_cut_not_kept_forever():
    f = LineFramer()
    out = f.feed(b"x" * (3 * MAX_LINE + 5))
    assert [len(x) for x in out] == [MAX_LINE] * 3 and f.flush() == ["x" * 5]


def test_every_byte_value_comes_back_exactly(tmp_path):
    path = tmp_path / "raw.jsonl"
    payloads = [bytes(range(256)), b"\r\n\x00\xff", b" 0001 C0  10:00:00.0000 00\r"]
    w = RawLogWriter(str(path), header={"port": "loop://"})
    for i, p in enumerate(payloads):
        w.write(1000.0 + i, p)
    w.event(1010.0, "disconnected", "EIO")
    w.close()
    chunks = list(read_rawlog(str(path)))
    assert [c.data for c in chunks if c.data] == payloads
    assert [c.event for c in chunks if c.event] == ["session", "disconnected"]
    assert all(json.loads(line) for line in path.read_text().splitlines())


def test_a_torn_last_record_is_passed_over_with_a_warning(tmp_path):
    path = tmp_path / "raw.jsonl"
    w = RawLogWriter(str(path))
    w.write(1.0, b"first\r")
    w.write(2.0, b"second\r")
    w.close()
    with open(path, "a") as fh:
        fh.write('{"t": 3.0, "rx": "thi')  # killed mid-write
    warnings: list[str] = []
    chunks = list(read_rawlog(str(path), warnings))
    assert [c.data for c in chunks] == [b"first\r", b"second\r"]
    assert "torn last record" in warnings[0]


def test_a_bad_record_inside_the_log_is_an_error(tmp_path):
    path = tmp_path / "raw.jsonl"
    path.write_text('{"t": 1, "rx": "a"}\nnonsense\n{"t": 2, "rx": "b"}\n')
    with pytest.raises(InputError, match=r"raw.jsonl:2: not a raw-log record"):
        list(read_rawlog(str(path)))


def test_a_lone_chunk_is_fsynced_within_a_second_without_a_further_write(tmp_path, monkeypatch):
    import os
    import time

    import station.session.rawlog as rawlog

    synced: list[float] = []
    real_fsync = os.fsync

    def spy(fd):
        synced.append(time.monotonic())
        real_fsync(fd)

    monkeypatch.setattr(rawlog.os, "fsync", spy)
    w = RawLogWriter(str(tmp_path / "raw.jsonl"))
    try:
        w.write(1.0, b" 0001 C0  10:00:00.0000 00\r")
        time.sleep(0.2)
        w.write(1.2, b" 0002 C1  10:00:00.2000 00\r")
        written = time.monotonic()
        time.sleep(1.3)  # the timer falls silent: no further write
        after = [t for t in synced if t >= written]
        assert after and after[0] - written <= 1.0
        n = len(synced)
        time.sleep(0.6)
        assert len(synced) == n  # nothing new written: no needless fsync
    finally:
        w.close()
