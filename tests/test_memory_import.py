"""``station import``: a timer's memory into a new session, or merged into one (issue 11)."""

from __future__ import annotations

import numpy as np
import pandas as pd

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
