"""A 2000-descent day recorded into a session: what the results CSV costs per descent, and
how much memory each descent keeps.

The demo station's 9 photocells; each descent's ALGE lines go through the acquisition loop as
a recording runs them (raw log first, the processor, the fit, the session's results CSV), in
line (``threaded=False``) so the cost of each step is timed where it happens. Two figures:

1. **results CSV**: the time spent writing the session's ``results.csv`` after descent 1, 400
   and 2000 (median of the 5 descents around each). Flat means the day's last descent costs
   what its first did (target: at 2000 ≤ 1.5× at 1 + 0.1 ms).
2. **memory**: the process's resident memory after descent 200 and after the last, with
   garbage collected, per descent in between (target ≤ 2 kB per descent).

At the end the live ``results.csv`` is compared byte for byte with the replay of the session.

Run: python benchmarks/day_2000.py [--descents N]
"""

from __future__ import annotations

import argparse
import gc
import os
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from replay_speed import demo_station  # noqa: E402  # the replay benchmark's station

from station.model.physics import Conditions, Params, StraightRun  # noqa: E402
from station.session import store as sessions  # noqa: E402
from station.session.acquisition import Acquisition, Listener, replay  # noqa: E402
from station.session.rawlog import Chunk  # noqa: E402
from station.timing.wireformats import format_alge  # noqa: E402


def rss_kb() -> int:
    """Resident memory of this process, kB (Linux)."""
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") // 1024


def descent_lines(times: np.ndarray, n: int, rng: np.random.Generator) -> list[bytes]:
    """Descent ``n``'s ALGE lines, 40 s after the one before, timing noise of 0.3 ms."""
    t0 = 8 * 3600 * 10**6 + n * 40_000_000
    noisy = times + np.concatenate([[0], rng.normal(0, 3e-4, len(times) - 1)])
    return [
        (format_alge(f"C{i}", (t0 + round(ti * 1e6)) % 86_400_000_000, n * 10 + i) + "\r").encode()
        for i, ti in enumerate(noisy)
    ]


def run_day(descents: int, folder: str) -> tuple[dict[int, float], tuple[int, int]]:
    cfg, track = demo_station()
    xs = np.array([pc.x for pc in track.photocells])
    times = (
        StraightRun(track.profile, xs)
        .solve(Params(0.22, 0.0085, 3.4), Conditions(88, 1.079), sensitivities=False)
        .t
    )
    rng = np.random.default_rng(3)
    acq = Acquisition.open(cfg, Listener(), session_dir=folder, threaded=False)
    csv_ms: dict[int, float] = {}
    timed = acq._write_csv_timed = []  # type: ignore[attr-defined]
    original = acq._save_csv

    def write(*args, **kwargs):  # type: ignore[no-untyped-def]
        t = time.perf_counter()
        original(*args, **kwargs)
        timed.append(time.perf_counter() - t)

    acq._save_csv = write  # type: ignore[method-assign]
    mem = [0, 0]
    host = 1.7e9
    for n in range(1, descents + 1):
        before = len(timed)
        for line in descent_lines(times, n, rng):
            host += 4.0
            acq.receive(Chunk(host, line))
        csv_ms[n] = sum(timed[before:]) * 1e3
        if n == 200:
            gc.collect()
            mem[0] = rss_kb()
    gc.collect()
    mem[1] = rss_kb()
    acq.close()
    assert len(acq.results()) == descents, len(acq.results())
    return csv_ms, (mem[0], mem[1])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--descents", type=int, default=2000)
    args = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="station-day-")
    folder = os.path.join(tmp, "session")
    try:
        start = time.perf_counter()
        csv_ms, (m200, mend) = run_day(args.descents, folder)
        wall = time.perf_counter() - start

        def at(n: int) -> float:
            near = [csv_ms[k] for k in range(max(1, n - 2), min(args.descents, n + 2) + 1)]
            return statistics.median(near)

        first = at(1)
        print(f"{args.descents} descents recorded in {wall:.1f} s")
        marks = [m for m in (1, 400, 2000) if m <= args.descents]
        for m in marks:
            print(f"  results CSV after descent {m:>4}: {at(m):7.3f} ms  ({at(m) / first:.2f}× "
                  "descent 1)")  # fmt: skip
        total = sum(csv_ms.values()) / 1e3
        print(f"  results CSV, the whole day: {total:.2f} s ({total / wall * 100:.0f} % of it)")
        per = (mend - m200) / max(1, args.descents - 200)
        print(f"  memory: {m200 / 1024:.0f} MiB after descent 200, {mend / 1024:.0f} MiB after "
              f"{args.descents}: {per:.2f} kB per descent (target 2 kB: "
              f"{per / 2:.2f}× the target)")  # fmt: skip
        live = Path(folder, sessions.RESULTS).read_bytes()
        out = os.path.join(tmp, "replayed.csv")
        acq = replay(folder, sessions.load_session_config(folder))
        acq.write_csv(out)
        same = Path(out).read_bytes() == live
        print(f"  replay of the session gives the live results.csv byte for byte: {same}")
        return 0 if same else 1
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    raise SystemExit(main())
