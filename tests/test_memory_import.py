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
    import subprocess

    from station.session import store
    from station.session.acquisition import replay
    from station.timing.impulses import DAY_US
    from tests.conftest import station_cmd
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
    try:
        rec = subprocess.run(
            [*station_cmd(), "record", "--config", str(cfg), "--session-dir", str(session),
             "--max-descents", "3"],
            capture_output=True, text=True, timeout=120,
        )  # fmt: skip
    finally:
        _, err = sim.communicate(timeout=60)
    assert rec.returncode == 0, rec.stderr
    assert "unplugged during descent 2" in err and "plugged in again" in err
    live = pd.read_csv(session / "results.csv", comment="#")
    assert list(live["photocells_used"]) == [9, 4, 9], live
    assert live.loc[1, "descent_status"] == "incomplete"

    r = run_station("import", memory, "--config", cfg, "--into", session)
    assert r.returncode == 0, r.stderr
    assert "27 impulses" in r.stderr and "22 already in the session, 5 added" in r.stderr
    assert "descent 2: joined: PC4 recorded live, PC5 on from the timer's memory" in r.stderr
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
    """The cable was out for descent 1's first four crossings; its live rest came far from
    the clock (nothing kept since the day before), so each waits for the next impulse to
    confirm its time, and the finish still waits when the import's event comes. It is taken
    as it is then, as at the end of a capture: the memory's first impulse, earlier by nature,
    called it a corrupted time, and the joined descent lost its finish."""
    from station.session.config import load_config
    from station.session.processor import Processor
    from station.session.rawlog import Chunk

    cfg = load_config(str(write_config(tmp_path, "/dev/null", "tag", TAG_CHANNELS)))
    proc = Processor(cfg, demo_track)
    before = _descent_lines(demo_track, 35_000, 1, "TN", 1)  # a descent an hour before
    body = _descent_lines(demo_track, 36_000, 2, "TN", 10)
    host = 1_767_517_200.0
    chunks = [Chunk(host + 0.01 * i, x.encode()) for i, x in enumerate(before)]
    chunks += [
        Chunk(host + 995.0, b"", "disconnected", "unplugged"),
        Chunk(host + 1009.0, b"", "connected"),
    ]
    chunks += [Chunk(host + 1010.0 + 0.01 * i, x.encode()) for i, x in enumerate(body[4:])]
    chunks += [Chunk(host + 2000.0, b"", "import", "imports/download.txt")]
    chunks.append(Chunk(host + 2000.0, b"\r\n" + b"".join(x.encode() for x in body[:4])))
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
