"""The smaller items of issue 18, each with the test that failed before its fix."""

from __future__ import annotations

import json
import os
import threading
import time

from tests.session_helpers import make_session
from tests.timing_helpers import write_config


def test_an_annotation_value_out_of_range_is_refused_when_read_back(tmp_path, run_station):
    session = make_session(tmp_path, order="AB")
    path = session / "annotations.jsonl"
    n = len(path.read_text().splitlines()) + 1
    with open(path, "a") as fh:
        rec = {"type": "metadata", "values": {"mass_kg": 1e308}, "descents": [1]}
        fh.write(json.dumps(rec) + "\n")
    r = run_station("replay", session)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert f"{path}:{n}: field values.mass_kg: 1e+308 is outside 20 to 200 kg" in r.stderr


def test_a_descent_number_read_back_is_a_whole_number_of_a_day(tmp_path, run_station):
    session = make_session(tmp_path, order="AB")
    path = session / "annotations.jsonl"
    good = path.read_bytes()
    n = len(good.splitlines()) + 1
    for bad in ("1e300", "1.5", "0", "-3"):
        path.write_bytes(good + f'{{"type": "invalid", "descent": {bad}}}\n'.encode())
        r = run_station("replay", session)
        assert r.returncode == 2, (bad, r.stderr)
        assert f"{path}:{n}: field descent: expected a descent number (1 to 1000000)" in r.stderr
    nested = b'{"type": "metadata", "values": ' + b'{"a": ' * 100_000 + b"1" + b"}" * 100_001
    path.write_bytes(good + nested + b"\n" + good.splitlines(keepends=True)[0])
    r = run_station("replay", session)
    assert r.returncode == 2 and f"{path}:{n}: not an annotation record" in r.stderr


def test_record_says_recording_to_only_once_the_folder_is_accepted(tmp_path, run_station):
    (tmp_path / "old").mkdir()
    taken = make_session(tmp_path / "old", order="A")
    cfg = write_config(tmp_path, "loop://")
    r = run_station("record", "--config", cfg, "--session-dir", taken, "--duration", "0.5")
    assert r.returncode == 2 and "a session is already recorded there" in r.stderr
    assert "recording to" not in r.stderr
    new = tmp_path / "new"
    r = run_station("record", "--config", cfg, "--session-dir", new, "--duration", "0.5")
    assert r.returncode == 0, r.stderr
    lines = r.stderr.splitlines()
    assert lines[0].startswith(f"recording to {new} from loop://")
    assert lines[-1] == f"results: {new / 'results.csv'}"


def test_after_a_csv_write_failure_the_last_line_claims_no_results_file(
    tmp_path, run_station, demo_track
):
    from tests.test_acquisition import descent_lines

    master, slave = os.openpty()  # a real pseudo-terminal: the timer's end is ours
    cfg = write_config(tmp_path, os.ttyname(slave))
    session = tmp_path / "s"
    results = session / "results.csv"

    def timer() -> None:  # once the first (empty) CSV is there, its place becomes a folder
        deadline = time.monotonic() + 20
        while not results.is_file() and time.monotonic() < deadline:
            time.sleep(0.01)
        os.remove(results)
        results.mkdir()
        for line in descent_lines(demo_track, [36000])[0]:
            os.write(master, line.encode())  # a descent: fitted, its row cannot be written

    t = threading.Thread(target=timer)
    t.start()
    try:
        r = run_station("record", "--config", cfg, "--session-dir", session, "--duration", "4")
    finally:
        t.join()
        os.close(master)
        os.close(slave)
    assert r.returncode == 0, r.stderr
    assert "1 descent" in r.stderr
    last = r.stderr.splitlines()[-1]
    assert last.startswith("results: not written") and f"station export {session}" in last
    assert f"cannot write {results}" in r.stdout


def test_a_timer_reset_to_midnight_is_flagged(tmp_path):
    import datetime as dt

    import numpy as np

    from station.model.physics import Conditions, Params, StraightRun
    from station.session import folder as session_folder
    from station.session.config import load_config
    from station.session.rawlog import RawLogWriter
    from station.session.runs import replay
    from station.survey.load import load_survey
    from station.survey.track import build_track
    from station.timing.wireformats import format_alge
    from tests.timing_helpers import ALGE_CHANNELS

    session = tmp_path / "s"
    session_folder.create(load_config(str(write_config(tmp_path, "/dev/null"))), str(session))
    cfg = session_folder.load_session_config(str(session))
    track = build_track(load_survey(cfg.survey_path))
    run = StraightRun(track.profile, np.array([pc.x for pc in track.photocells]))
    times = run.solve(Params(0.22, 0.0085, 3.4), Conditions(88, 1.079), sensitivities=False).t
    t0 = dt.datetime(2026, 2, 2, 10, 0).timestamp()
    log = RawLogWriter(str(session / "raw.jsonl"), header={"port": "x"})
    bib = 0
    # two descents at 10:00 and 10:05; at 10:10 the timer is reset and counts from 00:00:00
    for host_s, tod_s in ((0, 36_000), (300, 36_300), (600, 30), (900, 330)):
        for ch, ti in zip(ALGE_CHANNELS, times, strict=True):
            bib += 1
            line = format_alge(ch, int((tod_s + ti) * 1e6), bib)
            log.write(t0 + host_s + ti + 0.01, (line + "\r").encode())
    log.close()
    res = replay(str(session), cfg).results()
    assert [r.row.start_time[11:19] for r in res] == ["10:00:00", "10:05:00", "00:00:30",
                                                      "00:05:30"]  # fmt: skip
    assert [bool(r.row.flags) for r in res] == [False, False, True, False]
    assert res[2].row.flags[0].startswith("starts 10.07 h before descent 2 by the timer's clock")


def test_replay_of_a_folder_without_a_raw_log_says_so(tmp_path, run_station):
    folder = tmp_path / "empty"
    folder.mkdir()
    for extra in ((), ("--config", str(write_config(tmp_path, "/dev/null")))):
        r = run_station("replay", folder, *extra)
        assert r.returncode == 2 and "Traceback" not in r.stderr
        assert r.stderr.strip() == f"station: error: {folder}: is a folder without raw.jsonl: " \
            "not a session, and a capture is a file"  # fmt: skip
