"""End to end on a real pseudo-terminal: station-sim speaks, station records, replays, exports."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time

import pandas as pd
import pytest

from tests.conftest import station_cmd
from tests.timing_helpers import SimFreeze, raw_lines, record_with_sim, start_sim, write_config

SIM_FAST = ["--speed", "10", "--first-after", "2", "--hold", "1"]


def record(cfg, session, *extra, timeout=90) -> subprocess.CompletedProcess:
    return subprocess.run(
        [*station_cmd(), "record", "--config", str(cfg), "--session-dir", str(session), *extra],
        capture_output=True,
        text=True,
        timeout=timeout,
    )


@pytest.mark.slow  # a simulated timer on a pty, in real time
def test_record_gets_the_true_parameters_back_and_replay_reproduces_it(tmp_path, run_station):
    r, session, truth = record_with_sim(
        tmp_path,
        [*SIM_FAST, "--descents", "3", "--vary", "--seed", "11", "--noise-ms", "0.3",
         "--double-trigger", "0.2", "--running-time", "--garbage", "0.05", "--walkthrough", "0.5"],
        max_descents=3,
        config_extra='ski: pair 3\nwax: "=1+2"\nnotes: "hard #snow"\n',
    )  # fmt: skip
    df = pd.read_csv(session / "results.csv", comment="#")
    truths = [json.loads(line) for line in truth.read_text().splitlines()]
    ok = df[df["status"] == "ok"].reset_index(drop=True)
    assert len(ok) == 3 and len(truths) == 3
    for row, tr in zip(ok.itertuples(), truths, strict=True):
        assert row.mu_lo <= tr["mu"] <= row.mu_hi
        assert row.cda_lo <= tr["cda"] <= row.cda_hi
    assert (df["wax"] == "'=1+2").all() and (df["notes"] == "hard #snow").all()
    assert r.stdout.count("descent ") >= 3

    # replay reproduces the live CSV byte for byte; export too
    out = tmp_path / "replay.csv"
    events = tmp_path / "events.csv"
    rr = run_station("replay", session, "--csv", out, "--events", events)
    assert rr.returncode == 0, rr.stderr
    assert out.read_bytes() == (session / "results.csv").read_bytes()
    ev = pd.read_csv(events)
    assert {"line", "channel", "time", "flag", "kept", "reason"} <= set(ev.columns)
    # 27 photocell crossings, plus the start impulse of every walk-through (an aborted descent)
    assert (ev["kept"] == "yes").sum() == 27 + (df["status"] == "aborted").sum()
    exp = tmp_path / "export.csv"
    assert run_station("export", session, "--csv", exp).returncode == 0
    assert exp.read_bytes() == out.read_bytes()
    # the session holds the config and survey it ran with
    assert (session / "config.yaml").exists() and (session / "raw.jsonl").exists()


@pytest.mark.slow  # a simulated timer on a pty, in real time
def test_sigkill_mid_descent_loses_nothing_that_was_flushed(tmp_path, run_station):
    sim, port, _ = start_sim(tmp_path, *SIM_FAST, "--descents", "4", "--seed", "3")
    cfg = write_config(tmp_path, port)
    session = tmp_path / "session"
    rec = subprocess.Popen(
        [*station_cmd(), "record", "--config", str(cfg), "--session-dir", str(session)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    # the timer stops with the third skier five photocells down the run (a fixed sleep
    # "into the third descent" could overshoot it on a busy machine)
    freeze = SimFreeze(sim, session, 18 + 5)
    try:
        printed = []
        while len(printed) < 2:
            line = rec.stdout.readline()
            assert line, rec.stderr.read()
            if line.startswith("descent"):
                printed.append(line)
        freeze.wait()
        assert raw_lines(session) < 27  # the third descent is on the run
        os.kill(rec.pid, signal.SIGKILL)
        rec.wait(timeout=30)
    finally:
        freeze.thaw()
        sim.terminate()
        sim.wait(timeout=30)
    live = pd.read_csv(session / "results.csv", comment="#")
    assert len(live) == 2
    out = tmp_path / "replay.csv"
    r = run_station("replay", session, "--csv", out)
    assert r.returncode == 0, r.stderr
    replayed = pd.read_csv(out, comment="#")
    assert len(replayed) == 3  # the third was cut off by the kill: incomplete, fitted with the rest
    # an all-empty text column reads back as float, a partly filled one as text: compare values
    pd.testing.assert_frame_equal(replayed.iloc[:2], live, check_dtype=False)
    assert replayed.loc[2, "descent_status"] == "incomplete"
    assert "the recording ended" in replayed.loc[2, "flags"]


@pytest.mark.slow  # a simulated timer on a pty, in real time
def test_an_unplugged_timer_is_reported_and_reconnected(tmp_path):
    r, session, _ = record_with_sim(
        tmp_path,
        # the first descent 5 s after the simulator starts: the recorder, which checks at its
        # start that the port exists, must be up before the simulated unplugging (a loaded
        # machine takes seconds to start it)
        ["--speed", "20", "--first-after", "5", "--hold", "1", "--descents", "3",
         "--interval", "80", "--disconnect-after", "1", "--disconnect-s", "1", "--seed", "2"],
        max_descents=3,
    )  # fmt: skip
    assert "timer disconnected" in r.stdout
    events = [json.loads(x).get("event") for x in (session / "raw.jsonl").read_text().splitlines()]
    assert events.count("disconnected") >= 1 and events.count("connected") >= 2
    df = pd.read_csv(session / "results.csv", comment="#")
    assert list(df["status"]) == ["ok", "ok", "ok"]


@pytest.mark.slow  # a simulated timer on a pty, in real time
@pytest.mark.parametrize(
    ("protocol", "channels"),
    [
        ("tag", {str(i + 1): f"PC{i + 1}" for i in range(9)}),
        (
            "microgate",
            {"000": "PC1", **{f"{i:03d}": f"PC{i + 1}" for i in range(1, 8)}, "255": "PC9"},
        ),
    ],
)
def test_tag_and_microgate_timers(tmp_path, protocol, channels):
    sim, port, truth = start_sim(
        tmp_path, *SIM_FAST, "--descents", "1", "--protocol", protocol, "--seed", "4"
    )
    cfg = write_config(tmp_path, port, protocol, channels)
    try:
        r = record(cfg, tmp_path / "s", "--max-descents", "1")
    finally:
        sim.wait(timeout=30)
    assert r.returncode == 0, r.stderr
    df = pd.read_csv(tmp_path / "s" / "results.csv", comment="#")
    assert list(df["status"]) == ["ok"] and df.loc[0, "photocells_used"] == 9
    assert df.loc[0, "mu_lo"] <= 0.0085 <= df.loc[0, "mu_hi"]


def test_replay_of_the_real_tdc_capture(tmp_path, real, run_station):
    cfg = write_config(tmp_path, "/dev/null", channels={"C0": "PC1", "C1": "PC9"})
    out, events = tmp_path / "r.csv", tmp_path / "e.csv"
    cap = real / "alge" / "ALGETdC8001-202002020841.dump"
    r = run_station("replay", cap, "--config", cfg, "--csv", out, "--events", events,
                    "--date", "2020-02-02")  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "299 impulses, 6 edits" in r.stderr and "0 unparsed" in r.stderr
    df = pd.read_csv(out, comment="#")
    assert len(df) > 20
    # two photocells cannot carry three unknowns: said so, never a number
    assert set(df["status"]) <= {"too-few-photocells", "aborted"}
    assert df["start_time"].str.startswith("2020-02-02T").all()
    ev = pd.read_csv(events)
    assert len(ev) == 299 + 6
    # the keypad: two impulses and the operator's two clears of them
    assert (ev["reason"].str.contains("not a photocell", na=False)).sum() == 4


def test_record_against_a_port_that_does_not_exist_says_so_and_lists_the_ports(tmp_path):
    # a typo in the config is said at once, with the ports there are, before a session is made;
    # a port that goes away after the start is reconnected (test_serialport, the unplug tests)
    cfg = write_config(tmp_path, str(tmp_path / "no-such-tty"))
    r = record(cfg, tmp_path / "s", "--duration", "1.5", timeout=30)
    assert r.returncode == 2
    assert "no-such-tty does not exist" in r.stderr and "station ports" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "s").exists()


@pytest.mark.slow  # the simulated timer on a pty, in real time
def test_sigterm_mid_descent_ends_it_as_the_end_of_a_capture_and_replays_the_same(
    tmp_path, run_station
):
    """SIGTERM (and Ctrl-C) end the open descent the way quitting the UI does (test_ui): fitted
    with what it has, flagged "the recording ended", and the session replays to the same CSV."""
    sim, port, _ = start_sim(tmp_path, "--speed", "5", "--first-after", "2", "--hold", "1",
                             "--descents", "3", "--seed", "3")  # fmt: skip
    cfg = write_config(tmp_path, port)
    session = tmp_path / "session"
    rec = subprocess.Popen(
        [*station_cmd(), "record", "--config", str(cfg), "--session-dir", str(session)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    # the timer stops once descent 2 has passed five photocells (enough to fit): polling the
    # raw log alone could let a busy machine read the rest of the descent before the signal
    freeze = SimFreeze(sim, session, 9 + 5)
    try:
        end = time.monotonic() + 60
        while not freeze.frozen.is_set():
            assert time.monotonic() < end and rec.poll() is None, rec.stderr.read()
            time.sleep(0.05)
        assert raw_lines(session) < 18
        rec.send_signal(signal.SIGTERM)
        out, err = rec.communicate(timeout=30)
    finally:
        freeze.thaw()
        sim.terminate()
        sim.wait(timeout=30)
    assert rec.returncode == 0, err
    live = pd.read_csv(session / "results.csv", comment="#")
    assert list(live["descent_status"]) == ["complete", "incomplete"]
    assert "the recording ended" in live.loc[1, "flags"] and live.loc[1, "status"] != "error"
    assert out.count("descent ") == 2
    replayed = tmp_path / "replay.csv"
    r = run_station("replay", session, "--csv", replayed)
    assert r.returncode == 0, r.stderr
    assert replayed.read_bytes() == (session / "results.csv").read_bytes()


def _descents_in(results_csv) -> int:
    """Descents the results CSV has so far (0 before it is written)."""
    try:
        lines = results_csv.read_text().splitlines()
    except FileNotFoundError:
        return 0
    return max(0, len([line for line in lines if line and not line.startswith("#")]) - 1)


@pytest.mark.slow  # a simulated timer on a pty, in real time
def test_record_says_decided_or_not_as_the_day_goes(tmp_path, run_station):
    """`station record`'s console prints whether the day is decided after a descent when it
    changed, through record() itself: two pairs skied ABBAABBA on a real pty, each descent's
    ski entered with `station annotate` while the recording goes on (before it starts)."""
    order = "ABBAABBA"
    sim, port, _truth = start_sim(
        tmp_path, "--speed", "5", "--first-after", "4", "--hold", "1", "--descents", "8",
        "--skis", "0.0085,0.0100", "--order", order, "--noise-ms", "0.3", "--seed", "3",
    )  # fmt: skip
    cfg = write_config(tmp_path, port, extra="wax: blue\n")
    session = tmp_path / "s"
    rec = subprocess.Popen(
        [*station_cmd(), "record", "--config", str(cfg), "--session-dir", str(session),
         "--max-descents", "8"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 30
        while not (session / "raw.jsonl").exists():
            assert time.monotonic() < deadline and rec.poll() is None, "no session made"
            time.sleep(0.05)
        entered = 0  # descents whose ski is entered: the next one's before it starts
        while entered < len(order) and rec.poll() is None:
            n = _descents_in(session / "results.csv")
            if n >= entered:
                a = run_station("annotate", session, "--from", str(n + 1), "--ski", order[n])
                assert a.returncode == 0, a.stderr
                entered = n + 1
            time.sleep(0.1)
        out, err = rec.communicate(timeout=120)
    finally:
        if rec.poll() is None:
            rec.kill()
        sim.wait(timeout=30)
    assert rec.returncode == 0, err
    assert "decided or not after descent 4, with a look after every descent" in out
    assert "decided or not after descent 8, with a look after every descent" in out
    last = out[out.rindex("decided or not after descent 8") :].splitlines()
    assert last[1].startswith("  A / blue vs B / blue: decided: A / blue faster by Δμ"), out
