"""Every descent the assembler starts is dated by the host time of the line that started it,
by whatever path it started (issue 18's spirit: a start time without a date hides where the
descent belongs). A session's replay has no date of its own: it dates each start by the host
time the live recording kept with its bytes, so a descent without one came out with a time of
day only, and a timer reset behind such a start went unflagged.

The paths: a start impulse; a start far from the timer's clock, held until the next impulse
confirms it (then two starts come in one call of the assembler, and the held one may finish
in it); a start recovered after a damaged line; a start typed in at the timer (``i``) or
repeated from its memory (``m``); a held start taken as it is at the end of the input."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import pytest

from station.session.analysis import start_time
from station.session.config import load_config
from station.session.processor import Processor
from station.session.rawlog import Chunk
from station.survey.load import load_survey
from station.survey.track import build_track
from station.timing.assembly import TimedDescent
from station.timing.wireformats import format_alge
from tests.timing_helpers import write_config

CAPTURE = "ALGETdC8001-202002020841.dump"
DAY = dt.datetime(2026, 3, 1)  # the test day of the synthetic lines, local
THREE = {"C0": "PC1", "C1": "PC5", "C2": "PC9"}  # 174 m and 170 m apart


def _processor(tmp: Path, channels: dict[str, str], pairing: str = "bib") -> Processor:
    cfg = load_config(str(write_config(tmp, "/dev/null", channels=channels,
                                       extra=f"descent: {{pairing: {pairing}}}\n")))  # fmt: skip
    return Processor(cfg, build_track(load_survey(str(cfg.survey_path))))


def _tod(s: str) -> int:
    h, m, sec = s.split(":")
    return round((int(h) * 3600 + int(m) * 60 + float(sec)) * 1e6)


def _host(hms: str) -> float:
    """The host clock at ``hms`` of the test day."""
    return DAY.timestamp() + _tod(hms) / 1e6


def _run(proc: Processor, lines: list[tuple[float, str]], last_end: bool = True):
    """Each (host time, line) as one chunk of a raw log; the finished descents, by number
    (the last version of each)."""
    done: list[TimedDescent] = []
    for i, (t, line) in enumerate(lines):
        end = "\r" if last_end or i < len(lines) - 1 else ""
        done += proc.feed(Chunk(t, (line + end).encode("latin-1")))
    done += proc.finish()
    return {d.number: d for d in done}


def _dated(proc: Processor, d: TimedDescent) -> str:
    """The start time a session's replay gives (no date of its own: the host times')."""
    return start_time(d, proc.start_host.get(d.number), None)


def _imp(ch: str, hms: str, bib: int, flag: str = " ") -> str:
    return format_alge(ch, _tod(hms), bib, flag)


def _descent(ch_times: list[tuple[str, str]], bib: int, host_lag_s: float = 0.0):
    """Lines of one descent, each arriving at its own time on the host clock (+ lag)."""
    return [(_host(hms) + host_lag_s, _imp(ch, hms, bib)) for ch, hms in ch_times]


def test_the_real_capture_recorded_dates_every_descent(tmp_path, real):
    """The real ALGE day (several bibs on the course at once, paired by bib) as a recording
    whose host clock is not the timer's: bib 45's start at 11:08:48.8376, seven minutes after
    the timer's last impulse and not confirmed by the host clock, is held until the next
    start confirms it; the two starts come in one call, and descent 108 had no host time (its
    start time read 11:08:48.837600, no date)."""
    proc = _processor(tmp_path, {"C0": "PC1", "C1": "PC9"})
    data = (real / "alge" / CAPTURE).read_bytes().split(b"\n")
    t0 = dt.datetime(2020, 2, 2, 8, 0).timestamp()
    lines = [(t0 + i, s.decode("latin-1")) for i, s in enumerate(data)]
    done = _run(proc, lines)
    assert len(done) > 100 and set(done) == set(range(1, proc.assembler.count + 1))
    undated = [n for n, d in done.items() if not _dated(proc, d).startswith("2020-02-02T")]
    assert undated == []
    d108 = done[108]
    assert d108.bib == "45" and d108.first_line == 545
    assert proc.start_host.get(108) == t0 + 544  # its own line's host time, not the next one's
    assert _dated(proc, d108).startswith("2020-02-02T11:08:48.837600")


def test_a_session_replay_of_the_real_capture_dates_every_start(tmp_path, real, run_station):
    """The same through the command a user runs: `station replay SESSION --csv`."""
    import pandas as pd

    from station.session import folder as session_folder
    from station.session.rawlog import RawLogWriter

    cfg = write_config(tmp_path, "/dev/null", channels={"C0": "PC1", "C1": "PC9"},
                       extra="descent: {pairing: bib}\n")  # fmt: skip
    session = tmp_path / "s"
    session_folder.create(load_config(str(cfg)), str(session))
    t0 = dt.datetime(2020, 2, 2, 8, 0).timestamp()
    log = RawLogWriter(str(session / "raw.jsonl"), header={"port": "/dev/ttyUSB0"})
    for i, line in enumerate((real / "alge" / CAPTURE).read_bytes().split(b"\n")):
        log.write(t0 + i, line + b"\r")
    log.close()
    out = tmp_path / "r.csv"
    r = run_station("replay", session, "--csv", out)
    assert r.returncode == 0, r.stderr
    df = pd.read_csv(out, comment="#")
    assert len(df) > 100
    assert df["start_time"].str.startswith("2020-02-02T").all(), df[
        ~df["start_time"].str.startswith("2020-02-02T")
    ][["descent", "start_time"]]


def test_a_held_start_confirmed_by_the_next_start_gets_its_own_host_time(tmp_path):
    """The timer's clock jumps 20 min ahead of the host's estimate (a break; the host clock
    disagrees): bib 2's start is held; bib 3's start confirms it; both start in one call."""
    proc = _processor(tmp_path, THREE)
    lines = _descent([("C0", "10:00:00"), ("C1", "10:00:15"), ("C2", "10:00:27")], 1)
    lines += [(_host("10:01:00"), _imp("C0", "10:20:00", 2)),
              (_host("10:01:30"), _imp("C0", "10:20:30", 3))]  # fmt: skip
    lines += [(_host("10:01:45"), _imp("C1", "10:20:15", 2)),
              (_host("10:01:57"), _imp("C2", "10:20:27", 2)),
              (_host("10:02:15"), _imp("C1", "10:20:45", 3)),
              (_host("10:02:27"), _imp("C2", "10:20:57", 3))]  # fmt: skip
    done = _run(proc, lines)
    assert [(n, d.bib, d.status) for n, d in done.items()] == [
        (1, "1", "complete"), (2, "2", "complete"), (3, "3", "complete")]  # fmt: skip
    assert proc.start_host.get(2) == _host("10:01:00")
    assert proc.start_host.get(3) == _host("10:01:30")
    assert [_dated(proc, d)[:19] for d in done.values()] == [
        "2026-03-01T10:00:00", "2026-03-01T10:20:00", "2026-03-01T10:20:30"]  # fmt: skip


def test_a_start_typed_in_or_repeated_from_memory_is_dated(tmp_path):
    """A start the operator typed in at the timer (``i``: no descent of its bib yet) and one
    the timer sent again from its memory (``m``: not had live) each start a descent."""
    proc = _processor(tmp_path, THREE)
    lines = _descent([("C0", "10:00:00"), ("C1", "10:00:15"), ("C2", "10:00:27")], 1)
    lines += [(_host("10:05:40"), _imp("C0", "10:05:00", 5, "i"))]
    lines += _descent([("C1", "10:05:15"), ("C2", "10:05:27")], 5, host_lag_s=40)
    lines += [(_host("10:06:01"), _imp("C0", "10:06:00", 6, "m"))]
    lines += _descent([("C1", "10:06:15"), ("C2", "10:06:27")], 6)
    done = _run(proc, lines)
    assert [(n, d.bib, d.status) for n, d in done.items()] == [
        (1, "1", "complete"), (2, "5", "complete"), (3, "6", "complete")]  # fmt: skip
    assert any("edited at the timer" in f for f in done[2].flags)
    assert proc.start_host.get(2) == _host("10:05:40")
    assert proc.start_host.get(3) == _host("10:06:01")
    assert [_dated(proc, d)[:19] for d in done.values()] == [
        "2026-03-01T10:00:00", "2026-03-01T10:05:00", "2026-03-01T10:06:00"]  # fmt: skip
    # a typed-in or downloaded time is not the timer's clock now: not taken for a reset
    assert not any("backwards" in f for d in done.values() for f in d.flags)


def test_a_start_recovered_after_a_damaged_line_is_dated(tmp_path):
    proc = _processor(tmp_path, THREE)
    lines = _descent([("C0", "10:00:00"), ("C1", "10:00:15"), ("C2", "10:00:27")], 1)
    lines += [(_host("10:03:00"), "\x07#%garbled 0C0 10:0")]  # bib 2's start, damaged
    lines += _descent([("C1", "10:03:15"), ("C2", "10:03:27")], 2)
    done = _run(proc, lines)
    assert done[2].bib == "2" and done[2].photocells == ["PC5", "PC9"]
    assert "start line damaged" in done[2].flags[0]
    assert proc.start_host.get(2) == _host("10:03:15")
    assert _dated(proc, done[2])[:19] == "2026-03-01T10:03:15"


def test_a_start_held_at_the_end_and_a_last_line_without_its_end_are_dated(tmp_path):
    """A start still held for confirmation when the recording ends is taken as it is; a start
    on the last line, its line end never sent, is read at the end: both with the host time
    their bytes came with."""
    proc = _processor(tmp_path, THREE)
    lines = _descent([("C0", "10:00:00"), ("C1", "10:00:15"), ("C2", "10:00:27")], 1)
    lines += [(_host("10:01:00"), _imp("C0", "10:30:00", 2))]  # held: nothing confirms it
    done = _run(proc, lines)
    assert done[2].status == "aborted"
    assert proc.start_host.get(2) == _host("10:01:00")
    assert _dated(proc, done[2])[:19] == "2026-03-01T10:30:00"

    proc = _processor(tmp_path, THREE)
    lines = _descent([("C0", "10:00:00"), ("C1", "10:00:15"), ("C2", "10:00:27")], 1)
    lines += [(_host("10:02:00"), _imp("C0", "10:02:00", 2))]
    done = _run(proc, lines, last_end=False)
    assert done[2].status == "aborted"
    assert proc.start_host.get(2) == _host("10:02:00")
    assert _dated(proc, done[2])[:19] == "2026-03-01T10:02:00"


@pytest.mark.parametrize("confirmed_by", ["its finish", "the next start"])
def test_a_timer_reset_is_flagged_on_a_start_held_and_confirmed_in_one_call(tmp_path, confirmed_by):
    """At 10:10 the timer is reset to 00:00: the first start after it is 10 h behind the
    clock and the host's now, so it is held; the next impulse confirms it. With two
    photocells that is its own finish (the descent starts and ends in one call), else the next
    skier's start (two starts in one call). Either way the descent is flagged (it was not when
    it had finished before the processor looked, or was not the latest started)."""
    proc = _processor(tmp_path, {"C0": "PC1", "C1": "PC9"})
    lines = _descent([("C0", "10:00:00"), ("C1", "10:00:27")], 1)
    lines += _descent([("C0", "10:05:00"), ("C1", "10:05:27")], 2)
    if confirmed_by == "its finish":
        lines += [(_host("10:10:00"), _imp("C0", "00:00:05", 3)),
                  (_host("10:10:27"), _imp("C1", "00:00:32", 3))]  # fmt: skip
    else:
        lines += [(_host("10:10:00"), _imp("C0", "00:00:05", 3)),
                  (_host("10:10:10"), _imp("C0", "00:00:15", 4)),
                  (_host("10:10:27"), _imp("C1", "00:00:32", 3)),
                  (_host("10:10:37"), _imp("C1", "00:00:42", 4))]  # fmt: skip
    done = _run(proc, lines)
    assert done[3].status == "complete"
    assert done[3].flags and done[3].flags[0].startswith(
        "starts 10.08 h before descent 2 by the timer's clock"
    ), done[3].flags
    assert proc.start_host.get(3) == _host("10:10:00")
    if confirmed_by == "the next start":
        assert done[4].status == "complete" and not done[4].flags  # after 3: not backwards
        assert proc.start_host.get(4) == _host("10:10:10")


def test_a_host_time_that_is_nan_dates_by_the_day_given():
    """A host time of NaN (no host clock to go by) is no host time: the day's date, not an
    exception that would end the day's fits."""
    d = TimedDescent(1, ["PC1"], [_tod("10:00:00")])
    assert start_time(d, float("nan"), DAY.date())[:19] == "2026-03-01T10:00:00"
    assert start_time(d, float("nan"), None) == "10:00:00"


def test_a_memory_download_merged_into_a_session_is_dated_and_not_taken_for_a_reset(tmp_path, real):
    """The real day recorded live with the cable out for 100 lines, then the timer's memory
    merged in (`station import`): the merged descents come after the live ones in the raw log
    but start earlier. Every descent is dated (3 were not: two held starts confirmed by
    another start, one at the end), and the first merged start is not taken for a reset of
    the timer's clock (it was, as going 56 min backwards)."""
    from station.session import folder as session_folder
    from station.session.memory_import import import_into
    from station.session.rawlog import RawLogWriter
    from station.session.runs import replay

    cap = real / "alge" / CAPTURE
    cfg = write_config(tmp_path, "/dev/null", channels={"C0": "PC1", "C1": "PC9"})
    session = tmp_path / "s"
    session_folder.create(load_config(str(cfg)), str(session))
    t0 = dt.datetime(2020, 2, 2, 9, 47).timestamp()
    log = RawLogWriter(str(session / "raw.jsonl"), header={"port": "/dev/ttyUSB0"})
    for i, line in enumerate(cap.read_bytes().split(b"\n")):
        if not 200 <= i < 300:  # the cable was out
            log.write(t0 + i * 10, line + b"\r")
    log.close()
    assert import_into(str(cap), str(session)).added > 20
    res = replay(str(session), session_folder.load_session_config(str(session))).results()
    assert len(res) > 100
    assert [r.number for r in res if not r.row.start_time.startswith("2020-02-02T")] == []
    assert [r.number for r in res if any("backwards" in f for f in r.row.flags)] == []


def test_a_reset_within_a_memory_download_is_still_flagged(tmp_path):
    proc = _processor(tmp_path, {"C0": "PC1", "C1": "PC9"})
    lines = _descent([("C0", "10:00:00"), ("C1", "10:00:27")], 1)
    for t, line in lines:
        proc.feed(Chunk(t, (line + "\r").encode()))
    proc.feed(Chunk(_host("10:01:00"), event="import", detail="imports/memory.txt"))
    lines = _descent([("C0", "09:00:00"), ("C1", "09:00:27")], 2)  # before 1: not a reset
    lines += _descent([("C0", "00:00:05"), ("C1", "00:00:32")], 3)  # reset after 2
    done = _run(proc, lines)
    assert not done[2].flags
    assert done[3].flags[0].startswith("starts 9.00 h before descent 2"), done[3].flags
