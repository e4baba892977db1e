"""Unplug and replug the simulated timer N times during a recording; count impulses lost.

The simulated timer (a real pty) unplugs after every descent for ``--disconnect-s`` seconds,
after draining what it wrote (so an impulse it sent is in the station's hands before the cable
comes out), and sends nothing while unplugged. Every impulse it sent was sent while connected,
so every one missing from the session's descents is lost by the station (its reconnect).

    python benchmarks/unplug_timing.py [--cycles 10]

Prints impulses sent, impulses in descents, lost, and descents ok. About a minute.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.timing_helpers import write_config  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cycles", type=int, default=10)
    ap.add_argument("--disconnect-s", type=float, default=0.5)
    ap.add_argument("--keep", action="store_true", help="keep the session folder")
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="unplug-"))
    truth = tmp / "truth.jsonl"
    sim_exe = shutil.which("station-sim")
    sim_cmd = [sim_exe] if sim_exe else [sys.executable, "-m", "simulators.timer"]
    n = args.cycles + 1
    sim = subprocess.Popen(
        [*sim_cmd, "--descents", str(n), "--speed", "10", "--interval", "40", "--first-after",
         "1", "--hold", "2", "--disconnect-every", "1", "--disconnect-s", str(args.disconnect_s),
         "--seed", "7", "--truth", str(truth)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    port = sim.stdout.readline().split(" ", 1)[1].strip()
    cfg = write_config(tmp, port)
    station_exe = shutil.which("station")
    station = [station_exe] if station_exe else [sys.executable, "-m", "station"]
    session = tmp / "s"
    rec = subprocess.run(
        [*station, "record", "--config", str(cfg), "--session-dir", str(session),
         "--max-descents", str(n), "--duration", str(12 + n * 6)],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    sim.wait(timeout=60)
    sent = [json.loads(s) for s in truth.read_text().splitlines()]
    n_sent = sum(len(t["photocells"]) for t in sent)
    times = tmp / "times.csv"
    subprocess.run([*station, "export", str(session), "--times", str(times)],
                   capture_output=True, text=True, timeout=120, check=True)  # fmt: skip
    rows = times.read_text().splitlines()[1:]
    kept = len(rows)
    per: dict[str, list[str]] = {}
    for row in rows:
        d, _bib, pc = row.split(",")[:3]
        per.setdefault(d, []).append(pc)
    for d, pcs in per.items():
        if len(pcs) < 9:
            print(f"  descent {d}: {len(pcs)} photocells ({' '.join(pcs)})")
    raw = (session / "raw.jsonl").read_text()
    ok = rec.stderr.count(" ok")
    cycles = raw.count('"event":"disconnected"')
    print(f"unplug/replug cycles: {cycles}")
    print(f"impulses sent (all while connected): {n_sent}")
    print(f"impulses in descents: {kept}")
    print(f"impulses lost: {n_sent - kept}")
    print(f"record: exit {rec.returncode}; {rec.stderr.strip().splitlines()[-2] if ok else ''}")
    if args.keep:
        print(f"session: {session}")
    else:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
