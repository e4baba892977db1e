"""The trackside UI with the comparison open: the time from a descent's last impulse to its fit
on the screen, early in the day and at descent 2000.

The real Textual app (``StationApp`` in ``App.run_test``, this process), live mode with the
serial reader left out: a thread feeds each descent's ALGE lines to the acquisition as the
reader does (``Acquisition.receive``), skis A and B alternating (metadata entered before each
descent, as at the trackside). The comparison screen is open all day, so the day's joint fit
is recomputed all day beside the fits. For each descent: the time from just before its last
line is received to the end of the UI's handling of its fit (the table row and the result
panel updated). The next descent starts when the fit is shown. Target: ≤ 50 ms at descent
2000 with the comparison open (it was 191 ms median near descent 40 and 407 ms near 400 when
the fit worker ran the comparison itself after every descent).

Run: python benchmarks/ui_fit_latency.py [--descents N]
"""

from __future__ import annotations

import argparse
import asyncio
import os
import statistics
import sys
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from replay_speed import demo_station  # noqa: E402

from station.model.physics import Conditions, Params, StraightRun  # noqa: E402
from station.session.acquisition import Acquisition  # noqa: E402
from station.session.rawlog import Chunk  # noqa: E402
from station.timing.wireformats import format_alge  # noqa: E402
from station.ui.app import StationApp  # noqa: E402
from station.ui.messages import ComparisonUpdated, DescentFitted  # noqa: E402
from station.ui.screens import ComparisonScreen  # noqa: E402


class TimedApp(StationApp):
    """The station's app, noting when each fit has been shown and each comparison arrived."""

    CSS_PATH = str(ROOT / "station" / "ui" / "station.tcss")

    def __init__(self, *args, **kwargs) -> None:  # type: ignore[no-untyped-def]
        super().__init__(*args, **kwargs)
        self.shown_at: dict[int, float] = {}
        self.shown_event: dict[int, threading.Event] = {}
        self.comparisons: list[tuple[float, int]] = []

    def on_descent_fitted(self, msg: DescentFitted) -> None:
        super().on_descent_fitted(msg)
        n = msg.result.number
        self.shown_at.setdefault(n, time.perf_counter())
        self.shown_event.setdefault(n, threading.Event()).set()

    def on_comparison_updated(self, msg: ComparisonUpdated) -> None:
        super().on_comparison_updated(msg)
        self.comparisons.append((time.perf_counter(), len(self.results)))


def descents(n: int) -> list[list[bytes]]:
    cfg, track = demo_station()
    xs = np.array([pc.x for pc in track.photocells])
    run = StraightRun(track.profile, xs)
    rng = np.random.default_rng(11)
    out = []
    for k in range(1, n + 1):
        mu = 0.0085 if k % 2 else 0.0095
        t = run.solve(Params(0.22, mu, rng.uniform(2.5, 4)), Conditions(88, 1.079)).t
        t = t + np.concatenate([[0], rng.normal(0, 3e-4, len(t) - 1)])
        t0 = 8 * 3600 * 10**6 + k * 40_000_000
        out.append([
            (format_alge(f"C{i}", (t0 + round(ti * 1e6)) % 86_400_000_000, k * 10 + i)
             + "\r").encode()
            for i, ti in enumerate(t)
        ])  # fmt: skip
    return out


async def run(n: int, shown: bool = True) -> tuple[dict[int, float], TimedApp]:
    cfg, _track = demo_station()
    lines = descents(n)
    Acquisition.start_serial = lambda self, serial=None: None  # type: ignore[method-assign]
    app = TimedApp(cfg, mode="live")
    latency: dict[int, float] = {}
    async with app.run_test(size=(120, 40)) as pilot:
        while app.acq is None:
            await pilot.pause(0.05)
        if shown:
            await pilot.press("c")
            while not isinstance(app.screen, ComparisonScreen):
                await pilot.pause(0.05)
        acq = app.acq
        last: dict[int, float] = {}
        failed: list[str] = []

        def feed() -> None:
            host = time.time()
            for k, d in enumerate(lines, start=1):
                acq.add_metadata({"ski": "A" if k % 2 else "B"})
                for line in d[:-1]:
                    host += 1.0
                    acq.receive(Chunk(host, line))
                event = app.shown_event.setdefault(k, threading.Event())
                last[k] = time.perf_counter()
                acq.receive(Chunk(host + 1.0, d[-1]))
                if not event.wait(30):
                    failed.append(f"descent {k} not shown within 30 s")
                    return

        feeder = threading.Thread(target=feed)
        feeder.start()
        while feeder.is_alive():
            await pilot.pause(0.1)
        feeder.join()
        if failed:
            raise SystemExit(failed[0])
        for k, t in last.items():
            latency[k] = (app.shown_at[k] - t) * 1e3
    return latency, app


def measure(descents: int = 2000, shown: bool = True) -> dict:
    """Latency (ms) of each descent's fit on screen, and the comparisons computed."""
    start = time.perf_counter()
    latency, app = asyncio.run(run(descents, shown))
    tail = [latency[k] for k in range(max(1, descents - 19), descents + 1)]
    return {
        "descents": descents,
        "wall_s": time.perf_counter() - start,
        "latency_ms": latency,
        "comparisons": len(app.comparisons),
        "median_end_ms": statistics.median(tail),
        "max_end_ms": max(tail),
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--descents", type=int, default=2000)
    ap.add_argument("--closed", action="store_true", help="the comparison not shown")
    args = ap.parse_args()
    f = measure(args.descents, not args.closed)
    n, latency = args.descents, f["latency_ms"]
    shown = "closed" if args.closed else "open"
    print(f"{n} descents through the UI with the comparison {shown}: {f['wall_s']:.0f} s, "
          f"{f['comparisons']} comparisons computed beside the fits, "
          f"load {os.getloadavg()[0]:.1f}")  # fmt: skip
    for lo, hi in ((1, 20), (max(1, n // 5 - 9), n // 5 + 10), (max(1, n - 19), n)):
        window = [latency[k] for k in range(lo, hi + 1) if k in latency]
        if window:
            print(f"  descents {lo:>4}–{hi:<4}: last impulse → fit on screen median "
                  f"{statistics.median(window):6.1f} ms, max {max(window):6.1f} ms")  # fmt: skip
    print(f"  at descent {n}: median {f['median_end_ms']:.1f} ms "
          f"({f['median_end_ms'] / 50:.2f}× the 50 ms target)")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
