"""A 2000-descent day recorded into a session: what the results CSV costs per descent, and
how much memory each descent keeps.

The demo station's 9 photocells; each descent's ALGE lines go through the acquisition loop as
a recording runs them (raw log first, the processor; the fit and the session's results CSV
on the fit worker), the next descent once the last one is fitted. Two figures:

1. **results CSV**: the time spent writing the session's ``results.csv`` after descent 1, 400
   and 2000 (median of the 5 descents around each). Flat means the day's last descent costs
   what its first did (target: at 2000 ≤ 1.5× at 1 + 0.1 ms).
2. **memory**: the process's resident memory after descent 200 and after the last, with
   garbage collected, per descent in between (target ≤ 2 kB per descent).

At the end the live ``results.csv`` is compared byte for byte with the replay of the session.
``--where N`` also says where the memory goes: the N source lines whose allocations grew most
from descent 200 to the last (tracemalloc, bytes a descent; the day then runs slower, and
its resident memory includes tracemalloc's own: take the memory figure from a run without).

Run: python benchmarks/day_2000.py [--descents N] [--where N]
"""

from __future__ import annotations

import argparse
import gc
import os
import shutil
import statistics
import sys
import tempfile
import threading
import time
import tracemalloc
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from replay_speed import demo_station  # noqa: E402  # the replay benchmark's station

from station.model.physics import Conditions, Params, StraightRun  # noqa: E402
from station.session import folder as sessions  # noqa: E402
from station.session.acquisition import Acquisition  # noqa: E402
from station.session.listener import Listener  # noqa: E402
from station.session.rawlog import Chunk  # noqa: E402
from station.session.runs import replay  # noqa: E402
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


def run_day(
    descents: int, folder: str, where: int = 0
) -> tuple[dict[int, float], tuple[int, int], list[str]]:
    cfg, track = demo_station()
    xs = np.array([pc.x for pc in track.photocells])
    times = (
        StraightRun(track.profile, xs)
        .solve(Params(0.22, 0.0085, 3.4), Conditions(88, 1.079), sensitivities=False)
        .t
    )
    rng = np.random.default_rng(3)
    fitted = threading.Semaphore(0)

    class Fitted(Listener):
        def result(self, result) -> None:  # type: ignore[no-untyped-def]
            fitted.release()

    acq = Acquisition.open(cfg, Fitted(), session_dir=folder)
    csv_ms: dict[int, float] = {}
    timed = acq._write_csv_timed = []  # type: ignore[attr-defined]
    original = acq._save_csv

    def write(*args, **kwargs):  # type: ignore[no-untyped-def]
        t = time.perf_counter()
        original(*args, **kwargs)
        timed.append(time.perf_counter() - t)

    acq._save_csv = write  # type: ignore[method-assign]
    mem = [0, 0]
    traced: list[tracemalloc.Snapshot] = []
    if where:
        tracemalloc.start()
    host = 1.7e9
    for n in range(1, descents + 1):
        before = len(timed)
        for line in descent_lines(times, n, rng):
            host += 4.0
            acq.receive(Chunk(host, line))
        if not fitted.acquire(timeout=60):
            raise SystemExit(f"descent {n} not fitted within 60 s")
        csv_ms[n] = sum(timed[before:]) * 1e3
        if n == 200:
            gc.collect()
            mem[0] = rss_kb()
            if where:
                traced.append(tracemalloc.take_snapshot())
    gc.collect()
    mem[1] = rss_kb()
    lines = []
    if where and traced:
        stats = tracemalloc.take_snapshot().compare_to(traced[0], "lineno")
        tracemalloc.stop()
        n = max(1, descents - 200)
        total = sum(s.size_diff for s in stats) / n
        lines.append(f"  where (tracemalloc, descents 200 to {descents}): {total:.0f} B a descent")
        for s in stats[:where]:
            frame = s.traceback[0]
            name = os.path.relpath(frame.filename, ROOT) if frame.filename.startswith(
                str(ROOT)) else frame.filename  # fmt: skip
            lines.append(f"    {s.size_diff / n:7.0f} B  {name}:{frame.lineno}")
    acq.close()
    assert len(acq.results()) == descents, len(acq.results())
    return csv_ms, (mem[0], mem[1]), lines


def measure(descents: int = 2000, where: int = 0) -> dict:
    """The figures: results CSV ms after descents 1, 400, 2000 (those the day has), memory kB
    per descent, the whole day's wall time and CSV time, and whether replay gives the CSV."""
    tmp = tempfile.mkdtemp(prefix="station-day-")
    folder = os.path.join(tmp, "session")
    try:
        start = time.perf_counter()
        csv_ms, (m200, mend), lines = run_day(descents, folder, where)
        wall = time.perf_counter() - start

        def at(n: int) -> float:
            near = [csv_ms[k] for k in range(max(1, n - 2), min(descents, n + 2) + 1)]
            return statistics.median(near)

        live = Path(folder, sessions.RESULTS).read_bytes()
        out = os.path.join(tmp, "replayed.csv")
        acq = replay(folder, sessions.load_session_config(folder))
        acq.write_csv(out)
        return {
            "descents": descents,
            "wall_s": wall,
            "csv_ms": {m: at(m) for m in (1, 400, 2000) if m <= descents},
            "csv_total_s": sum(csv_ms.values()) / 1e3,
            "mem_mib": (m200 / 1024, mend / 1024),
            "kb_per_descent": (mend - m200) / max(1, descents - 200),
            "replay_same": Path(out).read_bytes() == live,
            "where": lines,
        }
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--descents", type=int, default=2000)
    ap.add_argument("--where", type=int, default=0, metavar="N",
                    help="the N source lines whose memory grew most (tracemalloc)")  # fmt: skip
    args = ap.parse_args()
    f = measure(args.descents, args.where)
    first = f["csv_ms"][1]
    print(f"{f['descents']} descents recorded in {f['wall_s']:.1f} s")
    for m, ms in f["csv_ms"].items():
        print(f"  results CSV after descent {m:>4}: {ms:7.3f} ms  ({ms / first:.2f}× descent 1)")
    print(f"  results CSV, the whole day: {f['csv_total_s']:.2f} s "
          f"({f['csv_total_s'] / f['wall_s'] * 100:.0f} % of it)")  # fmt: skip
    m200, mend = f["mem_mib"]
    print(f"  memory: {m200:.0f} MiB after descent 200, {mend:.0f} MiB after {f['descents']}: "
          f"{f['kb_per_descent']:.2f} kB per descent (target 2 kB: "
          f"{f['kb_per_descent'] / 2:.2f}× the target)")  # fmt: skip
    print(f"  replay of the session gives the live results.csv byte for byte: "
          f"{f['replay_same']}")  # fmt: skip
    for line in f["where"]:
        print(line)
    return 0 if f["replay_same"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
