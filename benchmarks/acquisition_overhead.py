"""What the one acquisition loop costs over the bare processor.

A plain ALGE capture of 11 200 descents × 9 photocells (100 800 lines) fed in 4 kB chunks:

1. through the :class:`Processor` alone (framing, parsing, assembly);
2. through :class:`Acquisition` in line (``threaded=False``, as replays run), with the fit
   replaced by a stub, so what is measured is the loop's own work per chunk and per descent
   (the lock, frozen descent records, the fit job with the metadata in force, the result row).

A real fit takes milliseconds per descent; the difference per descent printed here is what
the loop adds to it. Median of 3 runs each. Run: python benchmarks/acquisition_overhead.py
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from replay_speed import demo_station  # noqa: E402  # the replay benchmark's station

from station.model.physics import Conditions, Params, StraightRun  # noqa: E402
from station.session.acquisition import Acquisition  # noqa: E402
from station.session.analysis import DescentResult, FitJob, error_result  # noqa: E402
from station.session.day import Day  # noqa: E402
from station.session.processor import Processor  # noqa: E402
from station.session.rawlog import Chunk  # noqa: E402
from station.timing.wireformats import format_alge  # noqa: E402

DESCENTS = 11_200


class NoFit:
    """Stands in for the analyser: a result row without the fit."""

    def run(self, job: FitJob) -> DescentResult:
        return error_result(job, "not fitted (benchmark)")


def main() -> int:
    cfg, track = demo_station()
    xs = np.array([pc.x for pc in track.photocells])
    times = (
        StraightRun(track.profile, xs)
        .solve(Params(0.22, 0.0085, 3.4), Conditions(88, 1.079), sensitivities=False)
        .t
    )
    lines, t0, n = [], 8 * 3600 * 10**6, 0
    for _ in range(DESCENTS):
        for i, ti in enumerate(times):
            n += 1
            lines.append(format_alge(f"C{i}", (t0 + int(ti * 1e6)) % 86_400_000_000, n) + "\r")
        t0 += 25_000_000
    data = "".join(lines).encode("ascii")
    chunks = [data[k : k + 4096] for k in range(0, len(data), 4096)]

    def processor_alone() -> float:
        proc = Processor(cfg, track)
        start = time.perf_counter()
        for c in chunks:
            proc.feed(Chunk(None, c))  # type: ignore[arg-type]
        proc.finish()
        return time.perf_counter() - start

    def through_the_loop() -> float:
        day = Day.start(cfg, track)
        day.analyser = NoFit()  # type: ignore[assignment]
        acq = Acquisition(day, threaded=False)
        start = time.perf_counter()
        for c in chunks:
            acq.receive(Chunk(None, c))  # type: ignore[arg-type]
        acq.close()
        assert len(acq.results()) == DESCENTS
        return time.perf_counter() - start

    a = statistics.median(processor_alone() for _ in range(3))
    b = statistics.median(through_the_loop() for _ in range(3))
    print(f"{len(lines)} lines, {DESCENTS} descents, {len(chunks)} chunks")
    print(f"  processor alone:          {a:.2f} s ({len(lines) / a:,.0f} lines/s)")
    print(f"  acquisition loop, no fit: {b:.2f} s ({len(lines) / b:,.0f} lines/s)")
    print(f"  the loop adds {(b - a) / DESCENTS * 1e6:.0f} µs per descent")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
