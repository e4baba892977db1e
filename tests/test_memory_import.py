"""``station import``: a timer's memory into a new session, or merged into one (issue 11)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from station.model.physics import Conditions, Params, StraightRun
from station.timing.wireformats import format_tag, tag_cs16
from tests.timing_helpers import write_config

TAG_CHANNELS = {str(i + 1): f"PC{i + 1}" for i in range(9)}
DAY = 9500  # 2026-01-04


def _frame(data: str) -> str:
    return f"{data}\t{tag_cs16(data)}\r\n"


def _descent_lines(demo_track, start_s: float, bib: int, kind: str, seq0: int) -> list[str]:
    xs = np.array([pc.x for pc in demo_track.photocells])
    run = StraightRun(demo_track.profile, xs)
    t = run.solve(Params(0.22, 0.0085, 3.4), Conditions(88, 1.079)).t
    return [
        format_tag(str(i + 1), int((start_s + ti) * 1e6), seq0 + i, bib, DAY, kind) + "\r\n"
        for i, ti in enumerate(t)
    ]


def _download(demo_track, n: int) -> str:
    lines = [_frame("DS 01  00 START - FINISH     ")]
    for k in range(n):
        body = _descent_lines(demo_track, 36_000 + 120 * k, k + 1, "AN", 9 * k + 1)
        lines += [_frame(s.split("\t")[0]) for s in body]
    return "".join(lines) + _frame("DE 01")


def test_a_download_becomes_a_session_and_merges_without_doubling(
    tmp_path, demo_track, run_station
):
    cfg = write_config(tmp_path, "/dev/null", "tag", TAG_CHANNELS)
    live = tmp_path / "live.txt"  # what the station got before the cable came out
    live.write_text("".join(_descent_lines(demo_track, 36_000, 1, "TN", 1)), newline="")
    session = tmp_path / "s"
    r = run_station("import", live, "--config", cfg, "--session-dir", session)
    assert r.returncode == 0, r.stderr
    assert "9 impulses" in r.stderr and "9 added" in r.stderr
    df = pd.read_csv(session / "results.csv", comment="#")
    assert list(df["status"]) == ["ok"]
    assert df.loc[0, "start_time"].startswith("2026-01-04T10:00:00")  # the TAG day counter

    memory = tmp_path / "download.txt"
    memory.write_text(_download(demo_track, 3), newline="")
    r = run_station("import", memory, "--config", cfg, "--into", session)
    assert r.returncode == 0, r.stderr
    assert "27 impulses" in r.stderr and "9 already in the session, 18 added" in r.stderr
    df = pd.read_csv(session / "results.csv", comment="#")
    assert list(df["status"]) == ["ok", "ok", "ok"] and list(df["photocells_used"]) == [9] * 3
    # the raw bytes of both imports are kept; a second merge adds nothing
    kept = sorted(p.name for p in (session / "imports").iterdir())
    assert kept == ["download.txt", "live.txt"]
    assert (session / "imports" / "download.txt").read_bytes() == memory.read_bytes()
    r = run_station("import", memory, "--config", cfg, "--into", session)
    assert "27 already in the session, 0 added" in r.stderr
    assert len(pd.read_csv(session / "results.csv", comment="#")) == 3
    # the session replays to the same results
    out = tmp_path / "replay.csv"
    assert run_station("replay", session, "--csv", out).returncode == 0
    assert out.read_bytes() == (session / "results.csv").read_bytes()


def test_an_imported_session_is_annotated_in_place_as_after_a_recording(
    tmp_path, demo_track, run_station, replays
):
    """``station import`` leaves the results state a recording leaves, so the next annotate
    changes rows in place (no replay of the day) and writes what a replay writes."""
    from station.session.recorded import RecordedSession
    from station.session.records import FitModel, InvalidMark, ModelChange
    from tests.test_annotate_in_place import csv_of, from_scratch

    cfg = write_config(tmp_path, "/dev/null", "tag", TAG_CHANNELS)
    memory = tmp_path / "download.txt"
    memory.write_text(_download(demo_track, 4), newline="")
    session = tmp_path / "s"
    r = run_station("import", memory, "--config", cfg, "--session-dir", session)
    assert r.returncode == 0, r.stderr
    assert csv_of(session) == from_scratch(session)
    replays.clear()  # the import's own and from_scratch's: the annotate's are what counts
    RecordedSession(str(session)).annotate(
        [InvalidMark(2, "fell", 2.0), ModelChange(3, FitModel.VELOCITY, 2.0)]
    )
    assert replays == []
    assert csv_of(session) == from_scratch(session)


def test_import_bad_paths_are_one_line(tmp_path, run_station):
    cfg = write_config(tmp_path, "/dev/null", "tag", TAG_CHANNELS)
    r = run_station("import", tmp_path, "--config", cfg, "--session-dir", tmp_path / "n")
    assert r.returncode == 2 and "folder" in r.stderr and "Traceback" not in r.stderr
    r = run_station("import", tmp_path / "nope", "--config", cfg, "--session-dir", tmp_path / "n")
    assert r.returncode == 2 and "Traceback" not in r.stderr
    r = run_station("import", cfg, "--config", cfg, "--into", tmp_path / "nosession")
    assert r.returncode == 2 and "not a session" in r.stderr


def test_a_merged_download_brings_the_operators_clears_with_it(tmp_path, run_station):
    """A finish the operator cleared at the timer must not come back with the download: the
    clear line is merged too, in its place after the impulse it cancels."""
    cfg = write_config(tmp_path, "/dev/null", "alge", {"C0": "PC1", "C1": "PC9"})
    live = tmp_path / "live.txt"
    live.write_text(" 0001 C0  09:00:00.0000 00\r 0001 C1  09:00:30.0000 00\r", newline="")
    session = tmp_path / "s"
    assert run_station("import", live, "--config", cfg, "--session-dir", session).returncode == 0
    memory = tmp_path / "memory.txt"
    memory.write_text(
        " 0001 C0  09:00:00.0000 00\r 0001 C1  09:00:30.0000 00\r"
        " 0003 C0  10:01:00.0000 00\r 0003 C1  10:01:10.0000 00\rc0003 C1  10:01:10.0000 00\r",
        newline="",
    )
    r = run_station("import", memory, "--config", cfg, "--into", session)
    assert r.returncode == 0, r.stderr
    assert "2 already in the session, 2 added" in r.stderr
    raw = (session / "raw.jsonl").read_text()
    assert "c0003 C1  10:01:10.0000" in raw  # the clear is in the session's raw log
    r = run_station("export", session, "--times", "-")
    assert r.returncode == 0, r.stderr
    assert "10:01:10" not in r.stdout  # the cleared finish is not a crossing time
    assert "10:01:00" in r.stdout and "09:00:30" in r.stdout


def test_a_torn_session_is_repaired_and_a_merge_replays_every_descent_of_both(
    tmp_path, real, run_station
):
    """Issue 18: the live recording of a real ALGE day ends in a torn record (the disk filled,
    the power went); the timer's memory merged into it gives every descent of the day."""
    import datetime as dt
    import json

    from station.session import store
    from station.session.config import load_config
    from station.session.rawlog import RawLogWriter

    cap = real / "alge" / "ALGETdC8001-202002020841.dump"
    cfg = write_config(tmp_path, "/dev/null", channels={"C0": "PC1", "C1": "PC9"})
    session = tmp_path / "s"
    store.create(load_config(str(cfg)), str(session))
    lines = cap.read_bytes().split(b"\n")
    cut = len(lines) * 2 // 5
    t0 = dt.datetime(2020, 2, 2, 8, 0).timestamp()
    log = RawLogWriter(str(session / "raw.jsonl"), header={"port": "/dev/ttyUSB0"})
    for i, line in enumerate(lines[:cut]):
        log.write(t0 + i, line + b"\r")
    log.close()
    torn = json.dumps({"t": t0 + cut, "rx": lines[cut].decode() + "\r"})[:17]
    with open(session / "raw.jsonl", "a") as fh:
        fh.write(torn)  # the last record half written
    r = run_station("import", cap, "--config", cfg, "--into", session)
    assert r.returncode == 0, r.stderr
    side = session / "raw.jsonl.torn-1"
    assert f"{session / 'raw.jsonl'}: torn last record (17 bytes" in r.stderr
    assert str(side) in r.stderr and side.read_text() == torn

    merged, whole = tmp_path / "merged.csv", tmp_path / "whole.csv"
    r = run_station("replay", session, "--csv", merged)
    assert r.returncode == 0, r.stderr
    assert "passed over" not in r.stderr
    r = run_station("replay", cap, "--config", cfg, "--csv", whole, "--date", "2020-02-02")
    assert r.returncode == 0, r.stderr
    cols = ["start_time", "status", "photocells_used"]
    got = pd.read_csv(merged, comment="#")[cols]
    want = pd.read_csv(whole, comment="#")[cols]
    assert len(want) > 100
    # the merged lines are dated by the session's day, not the day of the import
    assert (got["start_time"].str[:10] != dt.date.today().isoformat()).all()
    for df in (got, want):  # times of day: one descent of bib pairs is undated in a session
        df["start_time"] = df["start_time"].str.extract(r"(\d\d:\d\d:\d\d\.\d+)")[0]
    pd.testing.assert_frame_equal(got, want)


def _alge_capture(path, demo_track, start_s: float, bib0: int = 1):
    from station.timing.wireformats import format_alge
    from tests.timing_helpers import ALGE_CHANNELS

    xs = np.array([pc.x for pc in demo_track.photocells])
    t = (
        StraightRun(demo_track.profile, xs)
        .solve(Params(0.22, 0.0085, 3.4), Conditions(88, 1.079))
        .t
    )
    lines = [format_alge(ch, int((start_s + ti) * 1e6), bib0 + k)
             for k, (ch, ti) in enumerate(zip(ALGE_CHANNELS, t, strict=True))]  # fmt: skip
    path.write_text("".join(x + "\r" for x in lines), newline="")
    return path


def test_an_import_is_dated_by_the_test_day_not_by_today(tmp_path, demo_track, run_station):
    """A download imported days later was dated by the day of the import; now by the file's
    date (said on stderr), by --date, and a merge by the session's own day."""
    import datetime as dt
    import os

    cfg = write_config(tmp_path, "/dev/null")
    cap = _alge_capture(tmp_path / "day.txt", demo_track, 36_000)
    t_file = dt.datetime(2026, 1, 14, 18, 30).timestamp()
    os.utime(cap, (t_file, t_file))
    r = run_station("import", cap, "--config", cfg, "--session-dir", tmp_path / "a")
    assert r.returncode == 0, r.stderr
    assert "dated 2026-01-14 by the file's date; give --date YYYY-MM-DD" in r.stderr
    df = pd.read_csv(tmp_path / "a" / "results.csv", comment="#")
    assert df.loc[0, "start_time"].startswith("2026-01-14T10:00:00")
    r = run_station("import", cap, "--config", cfg, "--session-dir", tmp_path / "b",
                    "--date", "2026-01-12")  # fmt: skip
    assert r.returncode == 0 and "by the file's date" not in r.stderr, r.stderr
    df = pd.read_csv(tmp_path / "b" / "results.csv", comment="#")
    assert df.loc[0, "start_time"].startswith("2026-01-12T10:00:00")
    # a download merged later: its descents on the session's day
    later = _alge_capture(tmp_path / "later.txt", demo_track, 36_600, bib0=100)
    r = run_station("import", later, "--config", cfg, "--into", tmp_path / "b")
    assert r.returncode == 0, r.stderr
    df = pd.read_csv(tmp_path / "b" / "results.csv", comment="#")
    assert [s[:19] for s in df["start_time"]] == ["2026-01-12T10:00:00", "2026-01-12T10:10:00"]
    r = run_station(
        "import", later, "--config", cfg, "--into", tmp_path / "b", "--date", "2026-01-12"
    )
    assert r.returncode == 2 and "--date is for a new session" in r.stderr


def test_a_tag_download_says_it_is_dated_by_the_timer_not_by_the_file(
    tmp_path, demo_track, run_station
):
    """TAG dates its impulses (day counter): the descents get the timer's day whatever the
    file's date or --date, and the message says so; it said "dated <file's date> by the
    file's date; give --date …", a date the descents did not get and an option that does
    nothing for them."""
    import datetime as dt
    import os

    cfg = write_config(tmp_path, "/dev/null", "tag", TAG_CHANNELS)
    memory = tmp_path / "download.txt"
    memory.write_text(_download(demo_track, 2), newline="")
    t_file = dt.datetime(2026, 3, 9, 18, 30).timestamp()
    os.utime(memory, (t_file, t_file))
    r = run_station("import", memory, "--config", cfg, "--session-dir", tmp_path / "a")
    assert r.returncode == 0, r.stderr
    assert "by the file's date" not in r.stderr, r.stderr
    assert "dated 2026-01-04 by the timer's own day counter" in r.stderr, r.stderr
    assert "2026-03-09" in r.stderr  # the date not used is named
    df = pd.read_csv(tmp_path / "a" / "results.csv", comment="#")
    assert all(s.startswith("2026-01-04T") for s in df["start_time"])
    r = run_station("import", memory, "--config", cfg, "--session-dir", tmp_path / "b",
                    "--date", "2026-01-12")  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "dated 2026-01-04 by the timer's own day counter (--date 2026-01-12 not used)" in (
        r.stderr
    )


# -- a descent split between the live log and the timer's memory (the cable came out during it)


def _tag_line(data: str) -> str:
    return f"{data}\t{tag_cs16(data)}\r\n"


def test_the_cp540s_download_joins_the_descent_whose_start_was_recorded_live(
    tmp_path, real, run_station
):
    """The real CP540 download (SOURCES.md: bib 1 M1 20:37:44.136, M4 20:37:46.613): the
    station recorded bib 1's start, then the cable came out; merged, the download's M4 is
    that descent's finish, by the timer's own clock, and the row says it was joined (it was a
    lone start, and the finish a descent of its own that went nowhere)."""
    import datetime as dt

    from station.session import store
    from station.session.acquisition import replay
    from station.session.config import load_config
    from station.session.rawlog import RawLogWriter
    from station.timing.impulses import DAY_US

    cfg = write_config(tmp_path, "/dev/ttyUSB0", "tag", {"M1": "PC1", "M4": "PC2"})
    session = tmp_path / "s"
    store.create(load_config(str(cfg)), str(session))
    t0 = dt.datetime(2018, 11, 21, 20, 37, 44).timestamp()
    log = RawLogWriter(str(session / store.RAW), header={"port": "/dev/ttyUSB0"})
    log.write(t0 + 0.14, _tag_line("TN    1    1 M1 20:37:44.13600  6899").encode())
    log.event(t0 + 1.0, "disconnected", "[Errno 5] Input/output error")
    log.event(t0 + 90.0, "timeout")  # the reader's clock ended it: nothing came for 90 s
    log.close()
    (session / store.RESULTS).write_text("")

    r = run_station("import", real / "tag" / "cp540_frames.txt", "--config", cfg, "--into",
                    session)  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "1 already in the session" in r.stderr
    assert "descent 1: joined: PC1 recorded live, PC2 on from the timer's memory" in r.stderr
    df = pd.read_csv(session / "results.csv", comment="#")
    first = df.iloc[0]
    assert first["photocells_used"] == 2 and first["descent_status"] == "complete"
    assert "joined: PC1 recorded live, PC2 on from the timer's memory" in first["flags"]
    assert "lone start" not in first["flags"] and "missing" not in first["flags"]
    got = replay(str(session), store.load_session_config(str(session)))
    d = got.day.results[1].descent
    assert d.photocells == ("PC1", "PC2")
    assert [t % DAY_US for t in d.times_us] == [74_264_136_000, 74_266_613_000]
    # the session replays to the CSV it wrote
    out = tmp_path / "replay.csv"
    assert run_station("replay", session, "--csv", out).returncode == 0
    assert out.read_bytes() == (session / "results.csv").read_bytes()


def _live_then_download(demo_track, live_cells: int, download: bool) -> list:
    """Chunks as a recording has them: descent 1's first ``live_cells`` crossings (TAG TN
    lines), the cable out, the reader's time-out; with ``download`` the timer's memory sent
    on the line after it (DS, every crossing as AN, DE)."""
    from station.session.rawlog import Chunk

    body = _descent_lines(demo_track, 36_000, 1, "TN", 1)
    t0 = 1_767_520_800.0  # 2026-01-04 10:00 UTC: the host clock
    chunks = [Chunk(t0 + 0.01 * k, line.encode()) for k, line in enumerate(body[:live_cells])]
    chunks += [Chunk(t0 + 1.0, b"", "disconnected", "unplugged"), Chunk(t0 + 200.0, b"", "timeout")]
    if download:
        lines = [_frame("DS 01  00 START - FINISH     ")]
        lines += [_frame(s.split("\t")[0].replace("TN", "AN", 1)) for s in body]
        lines.append(_frame("DE 01"))
        chunks += [Chunk(t0 + 300.0 + 0.01 * k, x.encode()) for k, x in enumerate(lines)]
    return chunks


def test_a_download_sent_on_the_line_joins_the_rest_of_the_descent(tmp_path, demo_track):
    """The download comes over the serial line (``DS`` … ``DE``) after the cable went back in:
    its AN lines the station has are not doubled, the rest join the descent they belong to,
    which is then fitted whole."""
    from station.session.config import load_config
    from station.session.processor import Processor

    cfg = load_config(str(write_config(tmp_path, "/dev/null", "tag", TAG_CHANNELS)))
    proc = Processor(cfg, demo_track)
    done = []
    for chunk in _live_then_download(demo_track, 4, download=True):
        done += proc.feed(chunk)
    done += proc.finish()
    assert [d.number for d in done] == [1, 1]  # ended by the time-out, then whole
    d = done[-1]
    assert d.status == "complete" and d.photocells == [f"PC{i + 1}" for i in range(9)]
    assert not d.missing
    assert "joined: PC4 recorded live, PC5 on from the timer's memory" in d.flags
    assert any("timer disconnected" in f for f in d.flags)
    assert not any("missing" in f for f in d.flags)
    assert proc.assembler.count == 1  # no descent of its own for the rest


def test_without_the_timers_memory_an_orphan_crossing_joins_nothing(tmp_path, demo_track):
    """The same crossings as live impulses (TN, no download around them) after the descent
    timed out: an impulse without a start, as before; only the timer's memory joins."""
    from station.session.config import load_config
    from station.session.processor import Processor
    from station.session.rawlog import Chunk

    cfg = load_config(str(write_config(tmp_path, "/dev/null", "tag", TAG_CHANNELS)))
    proc = Processor(cfg, demo_track)
    done = []
    for chunk in _live_then_download(demo_track, 4, download=False):
        done += proc.feed(chunk)
    rest = _descent_lines(demo_track, 36_000, 1, "TN", 1)[4:]
    for k, line in enumerate(rest):
        done += proc.feed(Chunk(1_767_521_100.0 + k, line.encode()))
    done += proc.finish()
    assert [(d.number, d.status, len(d.photocells)) for d in done] == [(1, "incomplete", 4)]
    assert all(not e.kept for e in proc.events[-5:])


@pytest.mark.slow  # a simulated timer on a pty, in real time
def test_a_descent_split_by_an_unplugged_cable_is_whole_after_the_memory_import(
    tmp_path, run_station
):
    """``station record`` on the simulated CP540; the cable comes out after descent 2's 4th
    photocell and goes back in before descent 3. The recording has descent 2 short of PC5 …
    PC9; merged, the timer's memory download (saved by its own program) gives it whole, with
    the timer's crossing times, fitted, and a note that it was joined; replays agree."""
    import json

    from station.session import store
    from station.session.acquisition import replay
    from station.timing.impulses import DAY_US
    from tests.timing_helpers import start_sim

    memory = tmp_path / "download.txt"
    sim, port, truth = start_sim(
        tmp_path, "--protocol", "tag", "--speed", "10", "--descents", "3", "--interval", "40",
        "--first-after", "2", "--hold", "1", "--seed", "7", "--unplug-during", "2:4",
        "--disconnect-s", "2", "--download-to", str(memory),
    )  # fmt: skip
    # the time-out by the device clock (the simulator's runs 10 times faster than the host's)
    cfg = write_config(tmp_path, port, "tag", TAG_CHANNELS, extra="descent: {timeout_s: 15}\n")
    session = tmp_path / "s"
    rec, err = _record_three(cfg, session, sim)
    assert rec.returncode == 0, rec.stderr
    assert "unplugged during descent 2" in err and "plugged in again" in err
    live = pd.read_csv(session / "results.csv", comment="#")
    assert list(live["photocells_used"]) == [9, 4, 9], live
    assert live.loc[1, "descent_status"] == "incomplete"

    r = run_station("import", memory, "--config", cfg, "--into", session)
    assert r.returncode == 0, r.stderr
    assert "27 impulses" in r.stderr and "22 already in the session, 5 added" in r.stderr
    assert "descent 2: joined: PC4 recorded live, PC5 on from the timer's memory" in r.stderr
    assert "27 impulses (5 from the timer's memory), 0 edits" in r.stderr, r.stderr
    df = pd.read_csv(session / "results.csv", comment="#")
    assert list(df["descent"]) == [1, 2, 3]
    assert list(df["photocells_used"]) == [9, 9, 9] and list(df["status"]) == ["ok"] * 3
    assert "joined: PC4 recorded live, PC5 on from the timer's memory" in df.loc[1, "flags"]
    # every crossing time the timer's own (TAG: 10 µs), the truth the simulator sent
    sent = [json.loads(x) for x in truth.read_text().splitlines()][1]
    want = [(sent["start_tod_us"] + round(t * 1e6)) // 10 * 10 for t in sent["t"]]
    got = replay(str(session), store.load_session_config(str(session)))
    d = got.day.results[2].descent
    assert [t % DAY_US for t in d.times_us] == [w % DAY_US for w in want]
    assert got.day.results[2].row.mu is not None
    out = tmp_path / "replay.csv"
    assert run_station("replay", session, "--csv", out).returncode == 0
    assert out.read_bytes() == (session / "results.csv").read_bytes()


def test_two_descents_split_by_two_unplugs_are_both_joined_by_one_import(tmp_path, demo_track):
    """Descents 1 and 3 each lost their last crossings (the cable out twice), descent 2 is
    whole; the import (after an ``import`` event, as ``station import --into`` appends it)
    brings both rests, in the timer's order: each joins its own descent, and no descent of
    its own is made of them."""
    from station.session.config import load_config
    from station.session.processor import Processor
    from station.session.rawlog import Chunk

    cfg = load_config(str(write_config(tmp_path, "/dev/null", "tag", TAG_CHANNELS)))
    proc = Processor(cfg, demo_track)
    days = [_descent_lines(demo_track, 36_000 + 600 * k, k + 1, "TN", 9 * k + 1) for k in range(3)]
    host = 1_767_520_800.0
    chunks = []
    for k, cut in enumerate((5, 9, 3)):
        t0 = host + 600 * k
        chunks += [Chunk(t0 + 0.01 * i, x.encode()) for i, x in enumerate(days[k][:cut])]
        if cut < 9:
            chunks += [Chunk(t0 + 1.0, b"", "disconnected", "unplugged"),
                       Chunk(t0 + 300.0, b"", "timeout")]  # fmt: skip
    rest = days[0][5:] + days[2][3:]
    chunks += [Chunk(host + 2000.0, b"", "import", "imports/download.txt")]
    chunks += [Chunk(host + 2000.0, b"\r\n" + b"".join(x.encode() for x in rest))]
    done = []
    for chunk in chunks:
        done += proc.feed(chunk)
    done += proc.finish()
    final = {d.number: d for d in done}
    assert sorted(final) == [1, 2, 3] and proc.assembler.count == 3
    for n in (1, 3):
        d = final[n]
        assert d.status == "complete" and len(d.photocells) == 9 and not d.missing, d
        assert any(f.startswith("joined: ") for f in d.flags)


def test_a_descent_whose_first_crossings_are_only_in_the_memory_takes_its_live_rest(
    tmp_path, demo_track
):
    """The other split: the cable was out for descent 1's first four crossings and back in for
    the rest, which the recording rejected as without a start; the import brings PC1 … PC4,
    and the descent they make takes its live rest: whole, with a note, no descent of its own
    left short."""
    from station.session.config import load_config
    from station.session.processor import Processor
    from station.session.rawlog import Chunk

    cfg = load_config(str(write_config(tmp_path, "/dev/null", "tag", TAG_CHANNELS)))
    proc = Processor(cfg, demo_track)
    body = _descent_lines(demo_track, 36_000, 1, "TN", 1)
    after = _descent_lines(demo_track, 36_600, 2, "TN", 10)  # descent 2, whole and live
    host = 1_767_520_800.0
    chunks = [
        Chunk(host - 5.0, b"", "disconnected", "unplugged"),
        Chunk(host + 9.0, b"", "connected"),
    ]
    chunks += [Chunk(host + 10.0 + 0.01 * i, x.encode()) for i, x in enumerate(body[4:])]
    chunks += [Chunk(host + 600.0 + 0.01 * i, x.encode()) for i, x in enumerate(after)]
    chunks += [Chunk(host + 2000.0, b"", "import", "imports/download.txt")]
    chunks.append(Chunk(host + 2000.0, b"\r\n" + b"".join(x.encode() for x in body[:4])))
    done = []
    for chunk in chunks:
        done += proc.feed(chunk)
    live_rejected = [e for e in proc.events if not e.kept]
    assert len(live_rejected) == 5 and "without a start" in live_rejected[0].reason
    done += proc.finish()
    final = {d.number: d for d in done}
    assert sorted(final) == [1, 2]
    d = final[2]  # numbered after the live descent: it was made by the import
    assert d.status == "complete" and len(d.photocells) == 9 and not d.missing, d
    assert "joined: PC4 from the timer's memory, PC5 on recorded live" in d.flags
    assert not any("missing" in f for f in d.flags)


def test_a_descent_ended_again_by_the_memory_counts_once_for_max_descents(tmp_path, demo_track):
    """The recorder's loop: descent 1 ended short, then whole by the download on the line, is
    one descent for ``record --max-descents`` (counted twice, the recording stopped a
    descent early, and lost that one), and its result is the whole descent's."""
    from station.session.acquisition import Acquisition
    from station.session.config import load_config
    from station.session.day import Day

    cfg = load_config(str(write_config(tmp_path, "/dev/null", "tag", TAG_CHANNELS)))
    acq = Acquisition(Day.start(cfg, demo_track), threaded=False)
    for chunk in _live_then_download(demo_track, 4, download=True):
        acq.receive(chunk)
    acq.end_of_input()
    assert acq.finished_descents == 1
    (res,) = acq.results()
    assert res.row.photocells_used == 9 and res.row.status == "ok"
    assert any(f.startswith("joined: ") for f in res.row.flags)


def test_two_skiers_cut_short_at_the_same_photocell_each_get_their_own_rest(tmp_path, demo_track):
    """Order pairing, two skiers on the run half a second apart (after a whole descent that
    gives the typical times); the cable comes out when both have passed PC4. The download
    brings both rests in the timer's order: each joins the skier it belongs to, not the one
    whose last crossing was latest (the nearer in time: the skier behind would take the
    first skier's PC5, and the first skier the second's)."""
    from station.session.config import load_config
    from station.session.processor import Processor
    from station.session.rawlog import Chunk

    cfg = load_config(
        str(write_config(tmp_path, "/dev/null", "tag", TAG_CHANNELS,
                         extra="descent: {pairing: order}\n"))
    )  # fmt: skip
    proc = Processor(cfg, demo_track)
    first = _descent_lines(demo_track, 36_000, 1, "TN", 1)
    a = _descent_lines(demo_track, 36_100, 2, "TN", 10)
    b = _descent_lines(demo_track, 36_100.5, 3, "TN", 19)
    host = 1_767_520_800.0
    chunks = [Chunk(host + 0.01 * i, x.encode()) for i, x in enumerate(first)]
    # live: every crossing of A and B before 36 110 s (both past PC4, neither at PC5)
    both = sorted(a + b, key=lambda s: s.split()[4])
    cut = 36_110.0
    live = [x for x in both if float(x.split()[4].split(":")[2]) < cut - 36_060]
    rest = [x for x in both if x not in live]
    assert len(live) == 8 and len(rest) == 10
    chunks += [Chunk(host + 100 + 0.1 * i, x.encode()) for i, x in enumerate(live)]
    chunks += [Chunk(host + 110.0, b"", "disconnected", "unplugged"),
               Chunk(host + 300.0, b"", "timeout")]  # fmt: skip
    chunks += [Chunk(host + 2000.0, b"", "import", "imports/download.txt")]
    chunks.append(Chunk(host + 2000.0, b"\r\n" + b"".join(x.encode() for x in rest)))
    done = []
    for chunk in chunks:
        done += proc.feed(chunk)
    done += proc.finish()
    final = {d.number: d for d in done}
    assert sorted(final) == [1, 2, 3] and proc.assembler.count == 3

    def tod(line: str) -> int:
        h, m, s = line.split()[4].split(":")
        return round((int(h) * 3600 + int(m) * 60 + float(s)) * 1e6)

    for n, lines in ((2, a), (3, b)):
        d = final[n]
        assert d.status == "complete" and len(d.photocells) == 9, d
        assert [t % (86_400 * 10**6) for t in d.times_us] == [tod(x) for x in lines], n
        assert any(f.startswith("joined: ") for f in d.flags)


@pytest.mark.parametrize("seven_in_memory", [True, False])
def test_a_descent_from_the_memory_takes_no_live_crossing_of_another_bib(
    tmp_path, demo_track, seven_in_memory
):
    """Bib pairing; the cable was out while bibs 5 and 7 started; bib 5 fell after PC4, bib 7
    went on, its PC5 … PC9 recorded live and rejected (no open descent of bib 7). The import
    brings both starts: bib 7's descent takes its own live rest, and bib 5's (which ends
    short first) none of it, though bib 7's crossings would continue it plausibly by time.
    Without bib 7's start in the memory either (its start photocell missed it), bib 5's takes
    none of them still: they are another bib's."""
    from station.session.config import load_config
    from station.session.processor import Processor
    from station.session.rawlog import Chunk

    cfg = load_config(
        str(write_config(tmp_path, "/dev/null", "tag", TAG_CHANNELS,
                         extra="descent: {pairing: bib}\n"))
    )  # fmt: skip
    proc = Processor(cfg, demo_track)
    first = _descent_lines(demo_track, 36_000, 1, "TN", 1)
    b5 = _descent_lines(demo_track, 36_100, 5, "TN", 10)[:4]  # fell after PC4
    b7 = _descent_lines(demo_track, 36_102, 7, "TN", 14)
    host = 1_767_520_800.0
    chunks = [Chunk(host + 0.01 * i, x.encode()) for i, x in enumerate(first)]
    chunks += [Chunk(host + 90.0, b"", "disconnected", "unplugged"),
               Chunk(host + 111.0, b"", "connected")]  # fmt: skip
    chunks += [Chunk(host + 112.0 + 0.1 * i, x.encode()) for i, x in enumerate(b7[4:])]
    memory = sorted(b5 + (b7[:4] if seven_in_memory else []), key=lambda s: s.split()[4])
    chunks += [Chunk(host + 2000.0, b"", "import", "imports/download.txt")]
    chunks.append(Chunk(host + 2000.0, b"\r\n" + b"".join(x.encode() for x in memory)))
    done = []
    for chunk in chunks:
        done += proc.feed(chunk)
    assert sum(not e.kept for e in proc.events) == 5  # bib 7's live rest, without a start
    done += proc.finish()
    final = {d.number: d for d in done}
    by_bib = {d.bib: d for d in final.values()}
    assert len(by_bib["5"].photocells) == 4 and by_bib["5"].status == "incomplete"
    assert not any(f.startswith("joined: ") for f in by_bib["5"].flags)
    if not seven_in_memory:
        assert sorted(final) == [1, 2]
        return
    assert sorted(final) == [1, 2, 3]
    seven = by_bib["7"]
    assert seven.status == "complete" and len(seven.photocells) == 9, seven
    assert "joined: PC4 from the timer's memory, PC5 on recorded live" in seven.flags


def test_the_last_live_crossing_held_for_confirmation_is_not_lost_to_the_import(
    tmp_path, demo_track
):
    """The cable was out for descent 2's first four crossings, and the timer's clock was set
    on by a quarter of an hour meanwhile: its live rest came far from the clock, the host's
    clock does not confirm the jump, so each waits for the next impulse to confirm its time,
    and the finish still waits when the import's event comes. It is taken as it is then, as
    at the end of a capture: the memory's first impulse, earlier by nature, called it a
    corrupted time, and the joined descent lost its finish."""
    from station.session.config import load_config
    from station.session.processor import Processor
    from station.session.rawlog import Chunk

    cfg = load_config(str(write_config(tmp_path, "/dev/null", "tag", TAG_CHANNELS)))
    proc = Processor(cfg, demo_track)
    before = _descent_lines(demo_track, 35_000, 1, "TN", 1)  # 1000 s before (110 s by the host)
    body = _descent_lines(demo_track, 36_000, 2, "TN", 10)
    host = 1_767_517_200.0
    chunks = [Chunk(host + 0.01 * i, x.encode()) for i, x in enumerate(before)]
    chunks += [
        Chunk(host + 95.0, b"", "disconnected", "unplugged"),
        Chunk(host + 109.0, b"", "connected"),
    ]
    chunks += [Chunk(host + 110.0 + 0.01 * i, x.encode()) for i, x in enumerate(body[4:])]
    chunks += [Chunk(host + 2000.0, b"", "import", "imports/download.txt")]
    chunks.append(Chunk(host + 2000.0, b"\r\n" + b"".join(x.encode() for x in body[:4])))
    done = []
    for chunk in chunks:
        if chunk.event == "import":  # the live finish waits for confirmation still
            assert proc.events[-1].line == proc.lines - 1
        done += proc.feed(chunk)
    done += proc.finish()
    final = {d.number: d for d in done}
    assert sorted(final) == [1, 2]
    d = final[2]
    assert d.status == "complete" and len(d.photocells) == 9 and not d.missing, d
    assert "joined: PC4 from the timer's memory, PC5 on recorded live" in d.flags
    assert not any("corrupted time" in e.reason for e in proc.events)


def test_in_order_pairing_a_descent_from_the_memory_leaves_the_live_rest_to_its_skier(
    tmp_path, demo_track
):
    """The same day paired by order (no bibs to tell): skier 1 fell after PC4, skier 2 went on
    two seconds behind, its PC5 … PC9 live and rejected. Both descents from the memory end
    at the end, skier 1's first: the live rest goes to the descent that would reach it when
    expected (skier 2's), as the pairing of skiers on the run chooses, not to the first to
    end that could take it."""
    from station.session.config import load_config
    from station.session.processor import Processor
    from station.session.rawlog import Chunk

    cfg = load_config(
        str(write_config(tmp_path, "/dev/null", "tag", TAG_CHANNELS,
                         extra="descent: {pairing: order}\n"))
    )  # fmt: skip
    proc = Processor(cfg, demo_track)
    first = _descent_lines(demo_track, 36_000, 1, "TN", 1)
    fell = _descent_lines(demo_track, 36_100, 5, "TN", 10)[:4]
    on = _descent_lines(demo_track, 36_102, 7, "TN", 14)
    host = 1_767_520_800.0
    chunks = [Chunk(host + 0.01 * i, x.encode()) for i, x in enumerate(first)]
    chunks += [Chunk(host + 90.0, b"", "disconnected", "unplugged"),
               Chunk(host + 111.0, b"", "connected")]  # fmt: skip
    chunks += [Chunk(host + 112.0 + 0.1 * i, x.encode()) for i, x in enumerate(on[4:])]
    memory = sorted(fell + on[:4], key=lambda s: s.split()[4])
    chunks += [Chunk(host + 2000.0, b"", "import", "imports/download.txt")]
    chunks.append(Chunk(host + 2000.0, b"\r\n" + b"".join(x.encode() for x in memory)))
    done = []
    for chunk in chunks:
        done += proc.feed(chunk)
    done += proc.finish()
    final = {d.number: d for d in done}
    assert sorted(final) == [1, 2, 3]
    assert len(final[2].photocells) == 4 and final[2].status == "incomplete", final[2]
    assert not any(f.startswith("joined: ") for f in final[2].flags)
    d = final[3]
    assert d.status == "complete" and len(d.photocells) == 9, d
    assert "joined: PC4 from the timer's memory, PC5 on recorded live" in d.flags


def test_alge_m_lines_give_a_descent_whose_start_the_cable_lost_its_live_rest(tmp_path, demo_track):
    """ALGE: the cable out for a descent's first four crossings, its live rest rejected as
    without a start (the last one still held for confirmation: nothing kept moved the clock
    for an hour), then the timer's memory recalled on the line (``m`` lines, each from the
    memory alone). The descent the ``m`` lines start takes its live rest when it ends, and
    the held finish is not called a corrupted time by the memory's earlier ones."""
    from station.session.config import load_config
    from station.session.processor import Processor
    from station.session.rawlog import Chunk
    from station.timing.wireformats import format_alge

    xs = np.array([pc.x for pc in demo_track.photocells])
    t = (
        StraightRun(demo_track.profile, xs)
        .solve(Params(0.22, 0.0085, 3.4), Conditions(88, 1.079))
        .t
    )

    def lines(start_s: float, flag: str = " ") -> list[bytes]:
        return [(format_alge(f"C{i}", round((start_s + ti) * 1e6), 0, flag) + "\r").encode()
                for i, ti in enumerate(t)]  # fmt: skip

    cfg = load_config(str(write_config(tmp_path, "/dev/null", "alge")))
    proc = Processor(cfg, demo_track)
    host = 1_767_520_800.0
    chunks = [Chunk(host + 0.01 * i, x) for i, x in enumerate(lines(36_000))]
    chunks += [Chunk(host + 3590.0, b"", "disconnected", "unplugged"),
               Chunk(host + 3609.0, b"", "connected")]  # fmt: skip
    chunks += [Chunk(host + 3600.0 + t[i], x) for i, x in enumerate(lines(39_600)) if i >= 4]
    chunks += [Chunk(host + 3700.0 + 0.01 * i, x) for i, x in enumerate(lines(39_600, "m")[:4])]
    done = []
    for chunk in chunks:
        done += proc.feed(chunk)
    done += proc.finish()
    final = {d.number: d for d in done}
    assert sorted(final) == [1, 2]
    d = final[2]
    assert d.status == "complete" and len(d.photocells) == 9 and not d.missing, d
    assert "joined: PC4 from the timer's memory, PC5 on recorded live" in d.flags
    assert not any("corrupted time" in e.reason for e in proc.events)
    # the events list says where the live rest went, after its "without a start"
    went = [
        (e.photocell, e.descent) for e in proc.events if e.kept and e.reason.startswith("joined")
    ]
    assert went == [(f"PC{i}", 2) for i in range(5, 10)]


# -- what a join leaves: the timer's clock, the import's own list, the flags


def _host_aligned(lines: list[str], host0: float) -> list:
    """Chunks of live TAG lines, each at the host time its device time gives (host0 at 00:00
    by the timer's clock, 0.05 s of transfer): a live day whose clocks agree."""
    from station.session.rawlog import Chunk
    from station.timing.wireformats import make_parser

    parser = make_parser("tag")
    return [Chunk(host0 + parser.parse(x.rstrip("\r\n")).tod_us / 1e6 + 0.05, x.encode())
            for x in lines]  # fmt: skip


def test_rejected_live_crossings_after_an_outage_leave_the_timers_clock_as_it_was(
    tmp_path, demo_track
):
    """The cable was out for five minutes, descent 2's first four crossings with it: its live
    rest is rejected (without a start), each at once, and the next skier's start is taken when
    it comes. The host's estimate of the timer's clock (what confirms a time far from the last
    kept one, and ends a descent by its time-out) pairs a kept impulse's device time with the
    host time of its line: a rejected impulse leaves the clock at the last kept one, minutes
    back, and paired with its own host time it put the estimate minutes wrong, so every later
    crossing far from the clock was held until the next one confirmed it (the next live start
    waited for its PC2)."""
    from station.session.config import load_config
    from station.session.processor import Processor
    from station.session.rawlog import Chunk

    cfg = load_config(str(write_config(tmp_path, "/dev/null", "tag", TAG_CHANNELS)))
    proc = Processor(cfg, demo_track)
    host0 = 1_767_484_800.0  # 2026-01-04 00:00 UTC: the host clock at the timer's 00:00
    d1 = _descent_lines(demo_track, 36_000, 1, "TN", 1)
    d2 = _descent_lines(demo_track, 36_300, 2, "TN", 10)
    d3 = _descent_lines(demo_track, 36_600, 3, "TN", 19)
    for chunk in _host_aligned(d1, host0):
        proc.feed(chunk)
    proc.feed(Chunk(host0 + 36_030.0, b"", "disconnected", "unplugged"))
    proc.feed(Chunk(host0 + 36_305.0, b"", "connected"))
    for chunk in _host_aligned(d2[4:], host0):
        proc.feed(chunk)
        e = proc.events[-1]  # its own fate, now: not held for the next impulse
        assert e.line == proc.lines and not e.kept and "without a start" in e.reason, e
    start, *rest = _host_aligned(d3, host0)
    proc.feed(start)
    assert [d.number for d in proc.assembler.open] == [2]  # started at once (descent 2)
    assert proc.start_host.get(2) == start.t
    done = []
    for chunk in rest:
        done += proc.feed(chunk)
    assert [(d.number, d.status) for d in done] == [(2, "complete")]
    assert not any("reset" in f for f in done[0].flags)
    # a stray impulse while the next skier is on the run: rejected, and the time-out (by
    # the host clock) still comes when it is due after PC4, not later by the stray's delay
    d4 = _host_aligned(_descent_lines(demo_track, 36_900, 4, "TN", 28), host0)
    for chunk in d4[:4]:
        proc.feed(chunk)
    due = d4[3].t + proc.assembler.timeout_us[3] / 1e6
    stray = format_tag("2", round((due - 2.05 - host0) * 1e6), 40, 9, DAY, "TN") + "\r\n"
    proc.feed(Chunk(due - 2.0, stray.encode()))  # (PC2 of bib 9, without a start)
    assert not proc.events[-1].kept and proc.events[-1].line == proc.lines
    assert [d.number for d in proc.tick(due - 1.0)] == []
    ended = proc.tick(due + 1.0)
    assert [(d.number, d.status) for d in ended] == [(3, "incomplete")]


def _split_session(tmp_path, demo_track, *, timed_out: bool):
    """A recorded session (TAG): descents 1 and 2, ten minutes apart, each cut short after
    PC4 by the cable (with ``timed_out``, the reader's time-out ended each before the
    recording did); and a download of the timer's memory with descent 1 only, and one with
    both: (config, session, first download, second download)."""
    from station.session import store
    from station.session.config import load_config
    from station.session.rawlog import RawLogWriter

    cfg = write_config(tmp_path, "/dev/null", "tag", TAG_CHANNELS)
    session = tmp_path / "s"
    store.create(load_config(str(cfg)), str(session))
    host0 = 1_767_484_800.0
    days = [_descent_lines(demo_track, 36_000 + 600 * k, k + 1, "TN", 9 * k + 1) for k in range(2)]
    log = RawLogWriter(str(session / store.RAW), header={"port": "/dev/null"})
    for k, body in enumerate(days):
        for c in _host_aligned(body[:4], host0):
            log.write(c.t, c.data)
        log.event(host0 + 36_000 + 600 * k + 8, "disconnected", "unplugged")
        if timed_out:
            log.event(host0 + 36_000 + 600 * k + 100, "timeout")
        log.event(host0 + 36_000 + 600 * k + 300, "connected")
    log.close()
    (session / store.RESULTS).write_text("")
    downloads = []
    for n in (1, 2):
        lines = [_frame("DS 01  00 START - FINISH     ")]
        for body in days[:n]:
            lines += [_frame(s.split("\t")[0].replace("TN", "AN", 1)) for s in body]
        path = tmp_path / f"download{n}.txt"
        path.write_text("".join(lines) + _frame("DE 01"))
        downloads.append(path)
    return cfg, session, *downloads


def test_an_import_lists_the_descents_it_joined_not_those_an_earlier_one_did(
    tmp_path, demo_track, run_station
):
    """Two imports into one session: the first joins descent 1, the second (the whole memory
    again, later) brings descent 2's rest. Each lists the descents it joined: the second
    listed descent 1 again, which it did not touch."""
    cfg, session, first, second = _split_session(tmp_path, demo_track, timed_out=True)
    r = run_station("import", first, "--config", cfg, "--into", session)
    assert r.returncode == 0, r.stderr
    assert "descent 1: joined: PC4 recorded live, PC5 on" in r.stderr
    assert "descent 2:" not in r.stderr
    r = run_station("import", second, "--config", cfg, "--into", session)
    assert r.returncode == 0, r.stderr
    assert "13 already in the session, 5 added" in r.stderr
    assert "descent 2: joined: PC4 recorded live, PC5 on" in r.stderr
    assert "descent 1:" not in r.stderr
    df = pd.read_csv(session / "results.csv", comment="#")
    assert list(df["photocells_used"]) == [9, 9]
    assert all("joined: PC4 recorded live" in f for f in df["flags"])


@pytest.mark.parametrize("how", ["import", "on the line"])
def test_a_descent_the_download_continues_before_its_time_out_says_it_was_joined(
    tmp_path, demo_track, how
):
    """The download comes before the descent cut short timed out (the recording ended at
    once, or the timer sent its memory on the line as soon as the cable was back): the
    memory's rest joins the descent still open. It said only "timer disconnected": the row
    and the events list did not say that its times after PC4 are the timer's memory's."""
    from station.session.config import load_config
    from station.session.processor import Processor
    from station.session.rawlog import Chunk

    cfg = load_config(str(write_config(tmp_path, "/dev/null", "tag", TAG_CHANNELS)))
    proc = Processor(cfg, demo_track)
    chunks = [c for c in _live_then_download(demo_track, 4, download=True) if c.event != "timeout"]
    if how == "import":  # as `station import --into` appends it: an event, then the lines
        memory = [c for c in chunks if c.data and b"AN" in c.data]
        chunks = [c for c in chunks if c.event or b"TN" in c.data]
        chunks.append(Chunk(chunks[-1].t, b"", "import", "imports/download.txt"))
        chunks.append(Chunk(chunks[-1].t, b"\r\n" + b"".join(c.data for c in memory)))
    done = []
    for chunk in chunks:
        done += proc.feed(chunk)
    done += proc.finish()
    assert [d.number for d in done] == [1]
    d = done[0]
    assert d.status == "complete" and len(d.photocells) == 9 and not d.missing, d
    assert "joined: PC4 recorded live, PC5 on from the timer's memory" in d.flags
    assert any("timer disconnected" in f for f in d.flags)
    # the events list (--events) says it at the first crossing from the memory
    joined = [e for e in proc.events if e.kept and e.reason.startswith("joined: ")]
    assert [(e.photocell, e.descent) for e in joined] == [("PC5", 1)]


def test_alge_m_lines_continuing_an_open_descent_say_it_was_joined(tmp_path, demo_track):
    """ALGE: descent 1's first four crossings live, the cable out; the timer repeats its
    memory on the line (``m`` lines of bib 7, no day: the fast paths could take them) before the
    descent timed out. The rest joins it, and the row and events say so."""
    from station.session.config import load_config
    from station.session.processor import Processor
    from station.session.rawlog import Chunk
    from station.timing.wireformats import format_alge

    xs = np.array([pc.x for pc in demo_track.photocells])
    t = (
        StraightRun(demo_track.profile, xs)
        .solve(Params(0.22, 0.0085, 3.4), Conditions(88, 1.079))
        .t
    )

    def lines(flag: str) -> list[bytes]:
        return [(format_alge(f"C{i}", round((36_000 + ti) * 1e6), 7, flag) + "\r").encode()
                for i, ti in enumerate(t)]  # fmt: skip

    cfg = load_config(str(write_config(tmp_path, "/dev/null", "alge")))
    proc = Processor(cfg, demo_track)
    host = 1_767_484_800.0 + 36_000.05
    chunks = [Chunk(host + t[i], x) for i, x in enumerate(lines(" ")[:4])]
    chunks += [Chunk(host + t[3] + 0.5, b"", "disconnected", "unplugged"),
               Chunk(host + t[3] + 2.0, b"", "connected")]  # fmt: skip
    chunks += [Chunk(host + t[3] + 3.0 + 0.01 * i, x) for i, x in enumerate(lines("m"))]
    done = []
    for chunk in chunks:
        done += proc.feed(chunk)
    done += proc.finish()
    assert [d.number for d in done] == [1]
    d = done[0]
    assert d.status == "complete" and len(d.photocells) == 9 and not d.missing, d
    assert "joined: PC4 recorded live, PC5 on from the timer's memory" in d.flags
    joined = [e for e in proc.events if e.kept and e.reason.startswith("joined: ")]
    assert [(e.photocell, e.descent) for e in joined] == [("PC5", 1)]


def test_after_a_download_on_the_line_the_next_live_start_is_taken_at_once(tmp_path, demo_track):
    """The timer sent its memory on the line (``DS`` … ``DE``) after the cable went back in;
    descent 1's rest from it was kept, minutes before the host's now. Paired with the host
    time of their lines, those old times put the host's estimate of the timer's clock minutes
    back: the next live start, far from the clock (the memory's last time), was held until its
    PC2 confirmed it, and an open descent's time-out came late. The memory's times are not the
    timer's now: the estimate stays the live one's, and ticks end nothing while the memory
    comes (its descents are hours old by the live clock: they end by its own impulses)."""
    from station.session.config import load_config
    from station.session.processor import Processor
    from station.session.rawlog import Chunk

    cfg = load_config(str(write_config(tmp_path, "/dev/null", "tag", TAG_CHANNELS)))
    proc = Processor(cfg, demo_track)
    chunks = _live_then_download(demo_track, 4, download=True)
    done = []
    for chunk in chunks:
        done += proc.feed(chunk)
        if chunk.data:  # the recorder ticks after every read
            done += proc.tick(chunk.t + 0.05)
    assert [d.number for d in done] == [1, 1]
    assert "joined: PC4 recorded live, PC5 on from the timer's memory" in done[-1].flags
    host0 = chunks[0].t - 36_000.0  # the host clock at the timer's 00:00 (PC1 at 10:00)
    live = _descent_lines(demo_track, 36_600, 2, "TN", 10)
    start = Chunk(host0 + 36_600.05, live[0].encode())
    proc.feed(start)
    assert [d.number for d in proc.assembler.open] == [2]  # started at once
    assert proc.start_host.get(2) == start.t


def test_a_download_on_the_line_whose_end_was_lost_still_lets_time_outs_come(tmp_path, demo_track):
    """The timer's ``DE`` after its memory was lost on the line (noise): the first live
    ``TN`` ends the memory. A live skier who falls after PC3 is ended by the time-out when
    it is due, not left open for the next skier's crossings."""
    from station.session.config import load_config
    from station.session.processor import Processor

    cfg = load_config(str(write_config(tmp_path, "/dev/null", "tag", TAG_CHANNELS)))
    proc = Processor(cfg, demo_track)
    chunks = _live_then_download(demo_track, 4, download=True)[:-1]  # (no DE)
    host0 = chunks[0].t - 36_000.0
    fell = _host_aligned(_descent_lines(demo_track, 36_600, 2, "TN", 10)[:3], host0)
    done = []
    for chunk in chunks + fell:
        done += proc.feed(chunk)
        if chunk.data:  # the recorder ticks after every read
            done += proc.tick(chunk.t + 0.05)
    assert not proc.assembler.from_memory  # (ended by the live TN)
    assert [d.number for d in done] == [1, 1]
    due = fell[-1].t + proc.assembler.timeout_us[2] / 1e6
    assert proc.tick(due - 1.0) == []
    assert [(d.number, d.status) for d in proc.tick(due + 1.0)] == [(2, "incomplete")]


def test_a_descent_from_the_memory_a_pause_in_the_download_ended_is_not_called_recorded_live(
    tmp_path, demo_track
):
    """The timer's memory comes over the line (``DS`` … ``DE``) and pauses after descent 1's
    PC3 (flow control, a slow line) longer than the time-out: the tick, by the memory's clock,
    ends the descent short; the memory's PC4 then reopens it. Every crossing of it is the
    memory's: its flag said "PC3 recorded live" (and ``station import`` listed it as joined)."""
    from station.session.config import load_config
    from station.session.processor import Processor
    from station.session.rawlog import Chunk

    cfg = load_config(str(write_config(tmp_path, "/dev/null", "tag", TAG_CHANNELS)))
    proc = Processor(cfg, demo_track)
    body = [_frame(s.split("\t")[0]) for s in _descent_lines(demo_track, 36_000, 1, "AN", 1)]
    t0 = 1_767_520_800.0
    lines = [_frame("DS 01  00 START - FINISH     "), *body[:3]]
    chunks = [Chunk(t0 + 0.01 * k, x.encode()) for k, x in enumerate(lines)]
    pause = t0 + 600.0  # the line is silent for ten minutes, then the rest comes
    rest = [*body[3:], _frame("DE 01")]
    chunks += [Chunk(pause + 0.01 * k, x.encode()) for k, x in enumerate(rest)]
    done = []
    for chunk in chunks:
        if chunk.t >= pause and not done:
            done += proc.tick(pause - 1.0)  # the reader's tick in the silence
            assert [(d.number, d.status) for d in done] == [(1, "incomplete")]
        done += proc.feed(chunk)
        done += proc.tick(chunk.t + 0.05)
    done += proc.finish()
    assert [d.number for d in done] == [1, 1]
    d = done[-1]
    assert d.status == "complete" and len(d.photocells) == 9 and not d.missing
    assert not any("recorded live" in f or f.startswith("joined: ") for f in d.flags), d.flags
    assert "reopened: PC4 on from the timer's memory, as were PC3 and those before (a " \
        "time-out while the download came had ended it)" in d.flags  # fmt: skip
    assert not any("missing" in f for f in d.flags)


def test_a_lost_download_end_is_told_by_the_first_live_time_and_said(tmp_path, demo_track):
    """The ``DE`` after a download on the line is lost (noise): THCOM08 sends the memory as
    ``AN`` answers and live times as ``TN`` (the real CP540 capture: ``DS``, ``AN``…, ``DE``,
    then ``T+``, ``TN``), so the first live ``TN`` ends the memory, and an event says so.
    Taken as the memory still, live skier 2, who fell after PC3, was a descent of the
    memory: the timer's memory sent again later reopened it as "all from the timer's
    memory", where its first three crossings were recorded live."""
    from station.session.config import load_config
    from station.session.processor import Processor
    from station.session.rawlog import Chunk

    cfg = load_config(str(write_config(tmp_path, "/dev/null", "tag", TAG_CHANNELS)))
    proc = Processor(cfg, demo_track)
    chunks = _live_then_download(demo_track, 4, download=True)[:-1]  # (no DE)
    host0 = chunks[0].t - 36_000.0
    skier2 = _descent_lines(demo_track, 36_600, 2, "TN", 10)
    fell = _host_aligned(skier2[:3], host0)
    done = []
    for chunk in chunks + fell:
        done += proc.feed(chunk)
        done += proc.tick(chunk.t + 0.05)
    first_live = proc.lines - 2  # (the line of skier 2's PC1)
    said = [e for e in proc.events if e.reason.startswith("download end DE not seen")]
    assert [(e.line, e.kept, e.reason) for e in said] == [
        (first_live, False, f"download end DE not seen; memory taken as ended at line "
                            f"{first_live} (a live TN)")
    ]  # fmt: skip
    # the same in a bulk replay (feed_chunks) and in a plain capture's chunk (no host times)
    for how in ("bulk", "capture"):
        other = Processor(cfg, demo_track)
        if how == "bulk":
            other.feed_chunks(chunks + fell)
        else:
            other.feed(Chunk(None, b"".join(c.data for c in chunks + fell)))  # type: ignore[arg-type]
        assert [e.reason for e in other.events if e.reason.startswith("download end")] == [
            said[0].reason
        ], how
        assert not other.assembler.from_memory, how
    due = fell[-1].t + proc.assembler.timeout_us[2] / 1e6
    assert [(d.number, d.status) for d in proc.tick(due + 1.0)] == [(2, "incomplete")]
    # the memory sent again on the line, whole this time
    again = [_frame("DS 01  00 START - FINISH     ")]
    again += [_frame(x.split("\t")[0].replace("TN", "AN", 1)) for x in skier2]
    again.append(_frame("DE 01"))
    for k, x in enumerate(again):
        done += proc.feed(Chunk(due + 60.0 + 0.01 * k, x.encode()))
    done += proc.finish()
    d = done[-1]
    assert d.number == 2 and d.status == "complete" and len(d.photocells) == 9, d
    assert "joined: PC3 recorded live, PC4 on from the timer's memory" in d.flags, d.flags
    assert not any(f.startswith("reopened: ") for f in d.flags)


def test_an_alge_timers_memory_dump_joins_the_descent_an_unplugged_cable_cut(tmp_path, run_station):
    """As the CP540's above, with an ALGE timer: the simulator's --download-to wrote nothing
    for ALGE (TAG only), so the README's recipe had no ALGE file to import. Its dump sends
    every impulse again, flagged m; merged, descent 2 is whole and said joined."""

    from tests.timing_helpers import start_sim

    memory = tmp_path / "alge-memory.txt"
    sim, port, _truth = start_sim(
        tmp_path, "--speed", "10", "--descents", "3", "--interval", "40", "--first-after", "2",
        "--hold", "1", "--seed", "7", "--unplug-during", "2:4", "--disconnect-s", "2",
        "--download-to", str(memory),
    )  # fmt: skip
    cfg = write_config(tmp_path, port, extra="descent: {timeout_s: 15}\n")
    session = tmp_path / "s"
    rec, _err = _record_three(cfg, session, sim)
    assert rec.returncode == 0, rec.stderr
    lines = memory.read_bytes().decode().split("\r")[:-1]
    assert len(lines) == 27 and all(x.startswith("m") for x in lines), lines[:3]
    r = run_station("import", memory, "--config", cfg, "--into", session)
    assert r.returncode == 0, r.stderr
    assert "22 already in the session, 5 added" in r.stderr
    assert "descent 2: joined: PC4 recorded live, PC5 on from the timer's memory" in r.stderr
    # the memory's m lines are impulses (laid out as edits): the summary counted them as edits
    assert "27 impulses (5 from the timer's memory), 0 edits" in r.stderr, r.stderr
    df = pd.read_csv(session / "results.csv", comment="#")
    assert list(df["photocells_used"]) == [9, 9, 9] and list(df["status"]) == ["ok"] * 3


def _record_three(cfg, session, sim):
    """`station record --max-descents 3` on the simulated timer ``sim`` (then waited for): the
    recording and the simulator's stderr, for the unplugged-cable tests."""
    import subprocess

    from tests.conftest import station_cmd

    try:
        rec = subprocess.run(
            [*station_cmd(), "record", "--config", str(cfg), "--session-dir", str(session),
             "--max-descents", "3"],
            capture_output=True, text=True, timeout=120,
        )  # fmt: skip
    finally:
        _, err = sim.communicate(timeout=60)
    return rec, err
