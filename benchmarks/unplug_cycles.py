"""Unplugging the timer: impulses sent while it was plugged in versus impulses recorded.

The simulated timer's pseudo-terminal (``station.simulators.timer.PtyPort``: a pty behind a stable
symlink, closed and reopened the way a USB-serial adapter disappears and comes back) sends an
ALGE impulse line every ``--period`` seconds to a real ``station record``. Ten times it is
unplugged for ``--off`` seconds and plugged in again; it starts sending again at once, before
the station has reopened the port, which is where impulses used to be lost (pyserial flushed
what the OS had queued, and the reopen backed off to 5 s). Before each unplug it waits until
the station has read everything queued (the pty's input queue is empty), so an impulse lost
is the station's fault, not the simulator's.

Reported: impulses sent while plugged in, impulses in the session's raw log, lost (target 0),
and how long after each replug the station had the port open again.

    python benchmarks/unplug_cycles.py [--cycles 10] [--on 2] [--off 1] [--period 0.05]
"""

from __future__ import annotations

import argparse
import fcntl
import json
import os
import shutil
import signal
import statistics
import struct
import subprocess
import sys
import tempfile
import termios
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from station.simulators.timer import PtyPort  # noqa: E402
from station.timing.wireformats import format_alge  # noqa: E402


def queued(fd: int) -> int:
    """Bytes waiting in the pty's input queue, unread by the station."""
    return struct.unpack("i", fcntl.ioctl(fd, termios.FIONREAD, b"\0\0\0\0"))[0]


def drain(port: PtyPort, timeout: float = 3.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if queued(port.slave) == 0:
            return True
        time.sleep(0.01)
    return False


def station_cmd() -> list[str]:
    exe = shutil.which("station") or str(Path(sys.executable).with_name("station"))
    return [exe] if os.path.exists(exe) else [sys.executable, "-m", "station"]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cycles", type=int, default=10)
    ap.add_argument("--on", type=float, default=2.0, help="seconds plugged in per cycle")
    ap.add_argument("--off", type=float, default=1.0, help="seconds unplugged per cycle")
    ap.add_argument("--period", type=float, default=0.05, help="seconds between impulses")
    ap.add_argument(
        "--station",
        help="command that runs station, e.g. 'python -m station' with PYTHONPATH set to "
        "another checkout (default: this one's)",
    )
    args = ap.parse_args(argv)

    work = Path(tempfile.mkdtemp(prefix="unplug-cycles-"))
    port = PtyPort(str(work / "timer"))
    cfg = work / "station.yaml"
    channels = ", ".join(f"C{i}: PC{i + 1}" for i in range(9))
    cfg.write_text(
        f"serial: {{port: {port.link}, baudrate: 9600, protocol: alge}}\n"
        f"survey: {ROOT / 'surveys' / 'demo_run.yaml'}\n"
        f"photocells: {{{channels}}}\n"
        "skier: {mass_kg: 88}\nair: {density: 1.079}\n"
    )
    session = work / "session"
    rec = subprocess.Popen(
        [
            *(args.station.split() if args.station else station_cmd()),
            "record",
            "--config",
            str(cfg),
            "--session-dir",
            str(session),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    sent: set[int] = set()
    undrained = 0
    plugged_at: list[float] = []
    counter = 0
    tod_us = 10 * 3600 * 1_000_000
    try:
        line = rec.stdout.readline()
        if "connected" not in line:
            print("station record did not connect:", line, rec.stderr.read(), file=sys.stderr)
            return 1
        t_start = time.monotonic()
        for cycle in range(args.cycles + 1):
            end = time.monotonic() + args.on
            while time.monotonic() < end:
                counter += 1
                tod_us += int(args.period * 1e6)
                text = format_alge(f"C{counter % 9}", tod_us, counter % 10000)
                port.write(text.encode("ascii") + b"\r")
                sent.add(counter % 10000)
                time.sleep(args.period)
            if cycle == args.cycles:
                break
            if not drain(port):
                undrained += 1
            port.unplug()
            time.sleep(args.off)
            port.plug()
            plugged_at.append(time.time())
        drain(port)
        time.sleep(0.5)
        elapsed = time.monotonic() - t_start
    finally:
        rec.send_signal(signal.SIGINT)
        try:
            rec.wait(30)
        except subprocess.TimeoutExpired:
            rec.kill()
        port.close()

    rx = b""
    connected_at: list[float] = []
    for text in (session / "raw.jsonl").read_text().splitlines():
        r = json.loads(text)
        if "rx" in r:
            rx += r["rx"].encode("latin-1")
        elif r.get("event") == "connected":
            connected_at.append(r["t"])
    got = {int(ln[1:5]) for ln in rx.split(b"\r") if len(ln) >= 26 and ln[1:5].isdigit()}
    lost = sorted(sent - got)
    delays = []
    for t in plugged_at:
        after = [c - t for c in connected_at if c >= t - 0.05]
        if after:
            delays.append(max(0.0, min(after)))
    if os.environ.get("UNPLUG_KEEP"):
        print(f"kept {work}")
    else:
        shutil.rmtree(work, ignore_errors=True)

    print(
        f"{args.cycles} unplug/replug cycles in {elapsed:.1f} s ({args.on:g} s plugged in, "
        f"{args.off:g} s out, an impulse every {args.period:g} s)"
    )
    print(f"impulses sent while plugged in: {len(sent)}")
    print(f"impulses in the raw log:        {len(got & sent)}")
    print(f"lost:                           {len(lost)}" + (f" {lost[:20]}" if lost else ""))
    print(f"queues not drained before an unplug: {undrained}")
    if delays:
        med, top = statistics.median(delays) * 1000, max(delays) * 1000
        print(
            f"port open again after replug: median {med:.0f} ms, max {top:.0f} ms "
            f"({len(delays)} of {len(plugged_at)} replugs)"
        )
    return 1 if lost else 0


if __name__ == "__main__":
    raise SystemExit(main())
