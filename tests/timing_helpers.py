"""Helpers for the end-to-end tests: start the simulated timer, write a station config."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

from tests.conftest import DEMO_SURVEY

ALGE_CHANNELS = {f"C{i}": f"PC{i + 1}" for i in range(9)}


def sim_cmd() -> list[str]:
    exe = shutil.which("station-sim")
    return [exe] if exe else [sys.executable, "-m", "station.simulators.timer"]


def start_sim(tmp_path: Path, *args: str) -> tuple[subprocess.Popen, str, Path]:
    """Start station-sim; return the process, its port and its truth file."""
    truth = tmp_path / "truth.jsonl"
    proc = subprocess.Popen(
        [*sim_cmd(), *args, "--truth", str(truth)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    first = proc.stdout.readline()
    assert first.startswith("PORT "), (first, proc.stderr.read())
    return proc, first.split(" ", 1)[1].strip(), truth


def write_config(
    tmp_path: Path, port: str, protocol: str = "alge", channels: dict | None = None, extra: str = ""
) -> Path:
    channels = channels or ALGE_CHANNELS
    pcs = ", ".join(f"{k!r}: {v}" for k, v in channels.items())
    path = tmp_path / "station.yaml"
    path.write_text(
        f"serial: {{port: {port}, baudrate: 9600, protocol: {protocol}}}\n"
        f"survey: {DEMO_SURVEY}\n"
        f"photocells: {{{pcs}}}\n"
        "skier: {mass_kg: 88, name: Test skier}\n"
        "air: {density: 1.079}\n" + extra
    )
    return path


def record_with_sim(
    tmp_path: Path, sim_args: list[str], max_descents: int, config_extra: str = ""
) -> tuple[subprocess.CompletedProcess, Path, Path]:
    """Run ``station record`` against a fresh simulated timer until ``max_descents`` descents;
    returns the finished record process, the session directory and the simulator's truth."""
    from tests.conftest import station_cmd

    sim, port, truth = start_sim(tmp_path, *sim_args)
    cfg = write_config(tmp_path, port, extra=config_extra)
    session = tmp_path / "session"
    try:
        r = subprocess.run(
            [*station_cmd(), "record", "--config", str(cfg), "--session-dir", str(session),
             "--max-descents", str(max_descents)],
            capture_output=True, text=True, timeout=120,
        )  # fmt: skip
    finally:
        sim.wait(timeout=30)
    assert r.returncode == 0, r.stderr
    return r, session, truth


def raw_lines(session: Path) -> int:
    """Timer lines in a session's raw log so far (what the station has read)."""
    import json

    path = session / "raw.jsonl"
    if not path.exists():
        return 0
    text = path.read_text()
    lines = 0
    for record in text.splitlines():
        try:
            lines += json.loads(record).get("rx", "").count("\r")
        except ValueError:  # the last record half written: read again at the next look
            break
    return lines


class SimFreeze:
    """Stop the simulated timer (SIGSTOP) as soon as the session's raw log holds ``n_lines``
    timer lines, from a thread of its own: a skier held on the run for as long as the test
    needs, however busy the machine. The simulator keeps its port open while stopped and
    sends what is left when thawed (its clock then catches up: the lines carry the timer's
    times, not the moment they are sent).

    The station reads every line as it comes, and the watch looks every 10 ms, so the timer
    stops within a line or so of ``n_lines``; a test that needs "not past line m" still
    checks :func:`raw_lines` once :attr:`frozen` is set."""

    def __init__(self, sim: subprocess.Popen, session: Path, n_lines: int) -> None:
        import threading

        self.sim = sim
        self.session = session
        self.n_lines = n_lines
        self.frozen = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._watch, daemon=True)
        self._thread.start()

    def _watch(self) -> None:
        import os
        import signal

        while not self._stop.is_set() and self.sim.poll() is None:
            if raw_lines(self.session) >= self.n_lines:
                os.kill(self.sim.pid, signal.SIGSTOP)
                self.frozen.set()
                return
            self._stop.wait(0.01)

    def wait(self, timeout: float = 60.0) -> None:
        """Until the timer is stopped (an assertion error after ``timeout`` seconds)."""
        assert self.frozen.wait(timeout), f"the raw log never reached {self.n_lines} lines"

    def thaw(self) -> None:
        """Let the timer go on (and stop watching); safe to call more than once."""
        import os
        import signal

        self._stop.set()
        self._thread.join()
        if self.frozen.is_set() and self.sim.poll() is None:
            os.kill(self.sim.pid, signal.SIGCONT)
