"""The serial edge on real pseudo-terminals: nothing queued is flushed at open, a replugged
timer is read again within a fraction of a second, and a second reader is refused."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
import tty

import pytest
import serial

from station.session.config import SerialConfig
from station.session.serialport import PortBusy, SerialReader, open_port
from station.simulators.timer import PtyPort
from tests.conftest import station_cmd
from tests.timing_helpers import start_sim, write_config


def _pty() -> tuple[int, int, str]:
    master, slave = os.openpty()
    tty.setraw(slave)
    return master, slave, os.ttyname(slave)


def _read_all(port, n: int, timeout: float = 2.0) -> bytes:
    got = b""
    end = time.monotonic() + timeout
    while len(got) < n and time.monotonic() < end:
        got += port.read(n - len(got))
    return got


def test_bytes_queued_before_the_port_opens_are_read_not_flushed():
    master, slave, path = _pty()
    try:
        # the setup reproduces the loss: plain pyserial flushes what was queued
        os.write(master, b" 0001 C0  09:47:40.3259 00\r")
        with serial.Serial(path, timeout=0.2) as plain:
            assert plain.read(100) == b""
        line = b" 0002 C1  09:47:41.0000 00\r"
        os.write(master, line)
        port = open_port(SerialConfig(port=path, protocol="alge"))
        try:
            assert _read_all(port, len(line)) == line
        finally:
            port.close()
    finally:
        os.close(master)
        os.close(slave)


HOLDER = """
import sys, time
from station.session.config import SerialConfig
from station.session.serialport import open_port
p = open_port(SerialConfig(port=sys.argv[1], protocol="alge"))
print("open", flush=True)
time.sleep(30)
"""


def test_a_second_reader_is_refused_naming_the_process_that_holds_the_port():
    master, slave, path = _pty()
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLDER, path], stdout=subprocess.PIPE, text=True
    )
    try:
        assert holder.stdout.readline().strip() == "open"
        with pytest.raises(PortBusy) as err:
            open_port(SerialConfig(port=path, protocol="alge"))
        assert f"process {holder.pid}" in str(err.value)
        assert "\n" not in str(err.value)
    finally:
        holder.kill()
        holder.wait()
        os.close(master)
        os.close(slave)


def test_reader_reconnects_within_half_a_second_and_loses_nothing_queued():
    port = PtyPort()
    chunks: list[bytes] = []
    events: list[tuple[float, str]] = []
    connected = threading.Event()

    def on_event(t, event, detail):
        events.append((time.monotonic(), event))
        if event == "connected":
            connected.set()

    reader = SerialReader(
        SerialConfig(port=port.link, protocol="alge"), lambda t, d: chunks.append(d), on_event
    )

    def until(condition) -> None:
        """Poll: a fixed sleep stood in for "the reader has caught up", too short when busy."""
        end = time.monotonic() + 30
        while not condition():
            assert time.monotonic() < end, (chunks, events)
            time.sleep(0.01)

    reader.start()
    try:
        assert connected.wait(30)
        port.write(b"A1\r")
        until(lambda: b"".join(chunks) == b"A1\r")  # read before the cable comes out
        port.unplug()
        until(lambda: [e for _, e in events] == ["connected", "disconnected"])
        connected.clear()
        port.plug()
        plugged = time.monotonic()
        port.write(b"B2\r")  # sent before the reader has reopened: queued by the OS
        assert connected.wait(30)
        reopened = [t for t, e in events if e == "connected"][-1]
        assert reopened - plugged < 0.5
        port.write(b"C3\r")
        until(lambda: len(b"".join(chunks)) >= 9)
    finally:
        reader.stop()
        reader.join(2)
        port.close()
    assert reader.error is None
    assert b"".join(chunks) == b"A1\rB2\rC3\r"
    assert [e for _, e in events] == ["connected", "disconnected", "connected"]


def test_second_recorder_exits_2_with_one_line_and_makes_no_session(tmp_path):
    sim, port, _ = start_sim(tmp_path, "--descents", "1", "--first-after", "30", "--hold", "0")
    cfg = write_config(tmp_path, port)
    first = subprocess.Popen(
        [*station_cmd(), "record", "--config", str(cfg), "--session-dir", str(tmp_path / "s1")],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        line = first.stdout.readline()
        assert "timer connected" in line, first.stderr.read()
        second = subprocess.run(
            [*station_cmd(), "record", "--config", str(cfg), "--session-dir",
             str(tmp_path / "s2")],
            capture_output=True, text=True, timeout=60,
        )  # fmt: skip
        assert second.returncode == 2
        err = second.stderr.strip().splitlines()
        assert len(err) == 1  # no "recording to": nothing is recorded
        assert f"held by process {first.pid}" in err[0]
        assert not (tmp_path / "s2").exists()
    finally:
        first.terminate()
        first.wait(30)
        sim.kill()  # it sleeps until its next impulse; nothing to save
        sim.wait(30)


@pytest.mark.slow  # a simulated timer on a pty, in real time
def test_an_open_descent_times_out_while_the_timer_is_unplugged(tmp_path):
    """The cable comes out during descent 2 and stays out: the descent is ended by its time-out
    on the host clock (not left open until the timer returns, which may be never), so
    ``--max-descents 2`` ends the recording, and the session replays to the same CSV."""
    import pandas as pd

    sim, port, _ = start_sim(
        tmp_path, "--speed", "10", "--descents", "2", "--interval", "40", "--first-after", "1",
        "--hold", "0", "--seed", "3", "--unplug-during", "2:4", "--disconnect-s", "90",
    )  # fmt: skip
    # 6 s of the device clock (longer than any gap between photocells at 10× speed), judged by
    # the host's clock while the port is away
    cfg = write_config(tmp_path, port, extra="descent: {timeout_s: 6}\n")
    session = tmp_path / "s"
    try:
        began = time.monotonic()
        rec = subprocess.run(
            [*station_cmd(), "record", "--config", str(cfg), "--session-dir", str(session),
             "--max-descents", "2"],
            capture_output=True, text=True, timeout=60,
        )  # fmt: skip
        took = time.monotonic() - began
    finally:
        sim.kill()  # the cable is still out: nothing more to send
        sim.wait(30)
    assert rec.returncode == 0, rec.stderr
    assert took < 50, took  # well before the timer's return at 90 s
    live = pd.read_csv(session / "results.csv", comment="#")
    assert list(live["photocells_used"]) == [9, 4], live
    assert "no impulse for" in live.loc[1, "flags"], live.loc[1, "flags"]
    assert "the recording ended" not in live.loc[1, "flags"]
    out = tmp_path / "replayed.csv"
    r = subprocess.run(
        [*station_cmd(), "replay", str(session), "--csv", str(out)],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert out.read_bytes() == (session / "results.csv").read_bytes()
