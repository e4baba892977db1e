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
