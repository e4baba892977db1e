"""Framing and the raw log: no byte lost, a torn last record survived."""

from __future__ import annotations

import json

import pytest

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


def test_a_bad_record_inside_the_log_is_passed_over_naming_its_line(tmp_path):
    path = tmp_path / "raw.jsonl"
    path.write_text('{"t": 1, "rx": "a"}\nnonsense\n{"t": 2, "rx": "b"}\n')
    warnings: list[str] = []
    assert [c.data for c in read_rawlog(str(path), warnings)] == [b"a", b"b"]
    assert warnings == [f"{path}:2: not a raw-log record (not JSON); passed over"]


HOSTILE = {
    "rx beyond latin-1": '{"t": 1, "rx": "\\u20ac"}',
    "rx a number": '{"t": 1, "rx": 42}',
    "t NaN": '{"t": NaN, "rx": "a"}',
    "t 1e400": '{"t": 1e400, "rx": "a"}',
    "t text": '{"t": "1", "rx": "a"}',
    "t true": '{"t": true, "rx": "a"}',
    "t negative": '{"t": -5, "rx": "a"}',
    "not an object": "[1, 2]",
    "event a number": '{"t": 1, "event": 3}',
    "detail a list": '{"t": 1, "event": "x", "detail": [1]}',
    "neither": '{"t": 1}',
    "deep detail": '{"t": 1, "event": "x", "detail": ' + '{"a": ' * 20 + "1" + "}" * 21,
    "200 000 deep": "[" * 200_000 + "]" * 200_000,
}


@pytest.mark.parametrize("name", sorted(HOSTILE))
def test_every_hostile_record_is_passed_over_with_its_line(tmp_path, name):
    path = tmp_path / "raw.jsonl"
    good = '{"t": 1, "rx": "a"}\n'
    path.write_text(good + HOSTILE[name] + "\n" + good)
    warnings: list[str] = []
    chunks = list(read_rawlog(str(path), warnings))
    assert [c.data for c in chunks] == [b"a", b"a"]
    assert len(warnings) == 1 and warnings[0].startswith(f"{path}:2: not a raw-log record (")


def test_many_bad_records_name_ten_and_count_the_rest(tmp_path):
    path = tmp_path / "raw.jsonl"
    path.write_text("x\n" * 25 + '{"t": 1, "rx": "a"}\n')
    warnings: list[str] = []
    assert [c.data for c in read_rawlog(str(path), warnings)] == [b"a"]
    assert len(warnings) == 11 and warnings[-1] == f"{path}: 15 more bad record(s) passed over"


def test_a_record_over_the_limit_is_passed_over_unread(tmp_path, monkeypatch):
    import station.session.rawlog as rawlog

    monkeypatch.setattr(rawlog, "MAX_RECORD", 100)
    path = tmp_path / "raw.jsonl"
    path.write_text('{"t": 1, "rx": "' + "x" * 500 + '"}\n{"t": 2, "rx": "b"}\n')
    warnings: list[str] = []
    assert [c.data for c in read_rawlog(str(path), warnings)] == [b"b"]
    assert warnings[0].startswith(f"{path}:1: record longer than 100 bytes")


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


def test_a_writer_never_appends_to_a_torn_tail(tmp_path):
    path = tmp_path / "raw.jsonl"
    path.write_text('{"t": 1, "rx": "a"}\n{"t": 2, "rx": "b')  # killed mid-write
    w = RawLogWriter(str(path))
    w.write(3.0, b"c")
    w.close()
    side = tmp_path / "raw.jsonl.torn-1"
    assert side.read_text() == '{"t": 2, "rx": "b'
    assert w.repair == (f"{path}: torn last record (17 bytes, killed mid-write?) cut off before "
                        f"appending; its bytes are kept in {side}")  # fmt: skip
    warnings: list[str] = []
    assert [c.data for c in read_rawlog(str(path), warnings)] == [b"a", b"c"]
    assert warnings == []
    # a second torn tail goes to a second side file; a whole record lacking only its line
    # end is ended, not cut
    with open(path, "a") as fh:
        fh.write('{"t": 4, "rx": "d')
    RawLogWriter(str(path)).close()
    assert (tmp_path / "raw.jsonl.torn-2").read_text() == '{"t": 4, "rx": "d'
    with open(path, "a") as fh:
        fh.write('{"t": 5, "rx": "e"}')
    w = RawLogWriter(str(path))
    w.write(6.0, b"f")
    w.close()
    assert "ended before appending" in (w.repair or "")
    assert [c.data for c in read_rawlog(str(path))] == [b"a", b"c", b"e", b"f"]
