"""What ``station report`` costs at 8 and at 40 descents, and where the time goes (issue 19:
"the report's cost is mostly fixed", 40 descents ≤ 1.5× the time of 8).

Sessions of 8 and 40 descents (ABAB…, as tests/session_helpers.py makes them: the model's own
times as ALGE lines in a raw log) are reported ``--runs`` times each (default 3), in this
process, alternating 8 and 40 so a busy machine loads both alike; the figure is the median.
Wall time is what a user waits; the process's CPU time is printed too, since on a shared
machine the wall time of one run also measures the neighbours. The first report of the
process is run once beforehand and not counted (it imports
matplotlib, which every ``station report`` pays once, the same at 8 and at 40). Then one
report of each size is profiled by part: replaying and fitting the day, the joint fit, and
each picture.

Run: python benchmarks/report_cost.py [--runs N]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from station.cli.main import main  # noqa: E402
from tests.session_helpers import make_session  # noqa: E402

SIZES = (8, 40)


def _report(session: str, out: str, clock=time.perf_counter) -> float:
    t0 = clock()
    with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
        code = main(["report", session, "--out", out])
    assert code == 0, session
    return clock() - t0


def _parts(session: str) -> dict[str, float]:
    """One report's time by part, drawn as ``station report`` draws it."""
    import station.report.day_report as dr

    timed: dict[str, float] = {}
    names = ("profile_figure", "descents_figure", "time_of_day_figure", "comparison_figure")
    saved = {n: getattr(dr, n) for n in names if hasattr(dr, n)}

    def wrap(name, fn):
        def inner(*a, **k):
            t0 = time.process_time()
            try:
                return fn(*a, **k)
            finally:
                timed[name] = timed.get(name, 0.0) + time.process_time() - t0

        return inner

    for n, fn in saved.items():
        setattr(dr, n, wrap(n, fn))
    try:
        with tempfile.TemporaryDirectory() as out:
            total = _report(session, out, time.process_time)
    finally:
        for n, fn in saved.items():
            setattr(dr, n, fn)
    timed["everything else (replay, fits, page)"] = total - sum(timed.values())
    timed["total"] = total
    return timed


def run(runs: int) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        sessions = {}
        for n in SIZES:
            folder = Path(tmp) / f"d{n}"
            folder.mkdir()
            sessions[n] = str(make_session(folder, order="AB" * (n // 2)))
        out = str(Path(tmp) / "out")
        Path(out).mkdir()
        _report(sessions[SIZES[0]], out)  # imports matplotlib: once per process, not counted
        for label, clock in (("wall", time.perf_counter), ("CPU", time.process_time)):
            times: dict[int, list[float]] = {n: [] for n in SIZES}
            for _ in range(runs):
                for n in SIZES:
                    times[n].append(_report(sessions[n], out, clock))
            med = {n: statistics.median(times[n]) for n in SIZES}
            for n in SIZES:
                print(f"{n:3d} descents: report {med[n]:6.2f} s {label:<4} (runs: "
                      f"{', '.join(f'{t:.2f}' for t in times[n])})")  # fmt: skip
            print(f"ratio 40 / 8 ({label}): {med[40] / med[8]:.2f}  (target ≤ 1.5)")
        print("by part, CPU (one report each):")
        parts = {n: _parts(sessions[n]) for n in SIZES}
        for name in parts[SIZES[0]]:
            a, b = parts[8][name], parts[40][name]
            print(f"  {name:<40} {a:6.3f} s  {b:6.3f} s  ×{b / a if a else float('nan'):.2f}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    run(ap.parse_args().runs)
