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
    return [exe] if exe else [sys.executable, "-m", "simulators.timer"]


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
