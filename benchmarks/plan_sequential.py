"""Decided or not after every descent: does looking after every descent inflate wrong answers?

Days of two items in ABBA order up to the horizon (10 descents per item, 20 descents, 3 minutes
apart, drift 0.02 per hour), simulated as in benchmarks/plan_power.py (simulators/days.py) and
fitted by the real joint fit of `station compare` after every descent from the fourth on (each
look a fit of the descents so far); the group-sequential rule of station/model/sequential.py
decides at each look. Per posture scatter (0.5 / 1 / 2 %):

- equal skis: the share of days on which a winner is declared at any look (target ≤ 10 %),
  and, for contrast, how often the plain 90 % interval excludes 0 at some look (the naive rule
  of stopping when it first does);
- Δμ = 0.001: the share of days on which the wrong ski is declared at any look (target 0), the
  share decided by the horizon, and the median descents per item at the first decision.

Run: python benchmarks/plan_sequential.py [--days 40] [--jobs 2] [--setup demo|sparse|both]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.plan_power import SETUPS, track  # noqa: E402
from simulators.days import DaySetup, simulate_day  # noqa: E402
from station.model.compare import joint_fit  # noqa: E402
from station.model.plan import run_order  # noqa: E402
from station.model.sequential import decide  # noqa: E402

HORIZON = 10
SCATTERS = (0.005, 0.01, 0.02)
MU_A = 0.0085


def watched_day(args: tuple[str, float, float, int]) -> tuple[bool, bool, bool, int | None]:
    """(declared A faster at some look, declared B faster at some look, the naive 90 %
    interval excluded 0 at some look, descents per item at the first decision)."""
    setup, delta, scatter, seed = args
    rng = np.random.default_rng(seed)
    order = "".join("AB"[i] for i in run_order(2, HORIZON))
    day = DaySetup(scatter=scatter, timer_sd_s=SETUPS[setup][1])
    data = simulate_day(track(setup), order, {"A": MU_A, "B": MU_A + delta}, day, rng)
    a_won = b_won = naive = False
    first = None
    for k in range(4, len(data) + 1):
        c = joint_fit(track(setup), data[:k]).comparisons[0]
        if c.ci90 is None or c.dof is None:
            continue
        from scipy.special import stdtrit

        se = (c.ci90[1] - c.ci90[0]) / 2 / float(stdtrit(c.dof, 0.95))
        naive = naive or c.ci90[0] > 0 or c.ci90[1] < 0
        d = decide(c.a, c.b, c.delta_mu, se, c.dof, order[:k], horizon=HORIZON)
        if d.state == "decided":
            a_won = a_won or d.faster == "A"
            b_won = b_won or d.faster == "B"
            if first is None:
                first = (k + 1) // 2
    return a_won, b_won, naive, first


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--days", type=int, default=40, help="simulated days per row")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--setup", choices=["demo", "sparse", "both"], default="demo")
    args = ap.parse_args()
    setups = ["demo", "sparse"] if args.setup == "both" else [args.setup]
    print(f"machine: {os.cpu_count()} cores; {args.days} days per row, {args.jobs} processes; "
          f"a look after every descent from the 4th, horizon {HORIZON} per item")  # fmt: skip
    print(f"binomial SD of a rate of 10 % over {args.days} days: "
          f"{100 * np.sqrt(0.09 / args.days):.1f} %")  # fmt: skip
    t_all = time.perf_counter()
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        for setup in setups:
            print(f"\nsetup {setup}: {len(track(setup).photocells)} photocells, timer "
                  f"{SETUPS[setup][1] * 1e3:g} ms")  # fmt: skip
            print(f"{'scatter':>7} | {'equal: winner declared':>22} | {'naive 90 % rule':>15} | "
                  f"{'Δμ 0.001: wrong ski':>19} | {'decided':>7} | "
                  f"{'descents/item at decision':>25}")  # fmt: skip
            for scatter in SCATTERS:
                seed0 = 7000 + int(scatter * 1000) * 1000
                eq = list(pool.map(watched_day, [(setup, 0.0, scatter, seed0 + s)
                                                 for s in range(args.days)]))  # fmt: skip
                df = list(pool.map(watched_day, [(setup, 0.001, scatter, seed0 + 500 + s)
                                                 for s in range(args.days)]))  # fmt: skip
                declared = np.mean([a or b for a, b, _, _ in eq])
                naive = np.mean([n for _, _, n, _ in eq])
                wrong = np.mean([b for _, b, _, _ in df])
                decided = np.mean([f is not None for *_, f in df])
                firsts = [f for *_, f in df if f is not None]
                med = f"{np.median(firsts):.1f}" if firsts else "—"
                print(f"{scatter * 100:>6.1f}% | {declared * 100:>21.1f}% | "
                      f"{naive * 100:>14.1f}% | {wrong * 100:>18.1f}% | "
                      f"{decided * 100:>6.1f}% | {med:>25}")  # fmt: skip
    print(f"\n{time.perf_counter() - t_all:.0f} s in all")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
