"""Does `station plan` keep its promise? Days simulated with the planned descents, fitted by the
real joint fit of `station compare`.

For each cell (Δμ 0.0005 / 0.001 / 0.002 × posture scatter 0.5 / 1 / 2 %) the plan is made
(`station.model.plan.plan_day`, 90 % power, 2 items, drift 0.02 per hour, 3 minutes between
descents), then days are simulated in the plan's order (simulators/days.py: v0 uniform in
2.5–4.5 m/s, the timer's noise on every photocell, times rounded to 0.1 ms), every descent
fitted on its own and the day by `joint_fit`. "Resolved": the 90 % interval of Δμ excludes 0 on
the right side. Printed per cell: the plan (descents per item, its stated power), the
simulated power at the plan and at one descent per item fewer (the plan is at most one descent
per item larger than needed when the simulated power two fewer is below the target: simulated
when one fewer reaches it; or the plan is the minimum of 2).

Two setups: the demo run (9 photocells, 0.5 ms timer: every descent pins its own posture, so
two descents per item are plenty) and a sparse one (4 of the photocells, a 1 ms timer), where
the posture scatter costs descents and the plan has something to say.

Run: python benchmarks/plan_power.py [--days 100] [--jobs 2] [--setup demo|sparse|both]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from simulators.days import DaySetup, simulate_day  # noqa: E402
from station.model.compare import joint_fit  # noqa: E402
from station.model.plan import DayAssumptions, plan_day, run_order  # noqa: E402
from station.survey.load import load_survey  # noqa: E402
from station.survey.track import build_track  # noqa: E402

DELTAS = (0.0005, 0.001, 0.002)
SCATTERS = (0.005, 0.01, 0.02)
MU_A = 0.0085
SETUPS = {
    "demo": (None, 5e-4),
    "sparse": (("PC1", "PC3", "PC6", "PC9"), 1e-3),
}

_tracks: dict[str, object] = {}


def track(setup: str):
    if setup not in _tracks:
        tr = build_track(load_survey(str(ROOT / "surveys" / "demo_run.yaml")))
        ids = SETUPS[setup][0]
        if ids is not None:
            tr = dataclasses.replace(tr, photocells=[p for p in tr.photocells if p.id in ids])
        _tracks[setup] = tr
    return _tracks[setup]


def assumptions(setup: str, scatter: float) -> DayAssumptions:
    return DayAssumptions(
        mass_kg=88.0, air_density=1.079, cda=0.22, v0=3.5, mu=MU_A, timer_sd_s=SETUPS[setup][1],
        posture_sd=scatter, drift_per_hour=0.02, minutes_between=3.0,
    )  # fmt: skip


def resolved(args: tuple[str, float, float, str, int]) -> bool:
    """One simulated day in ``order``: does its 90 % interval resolve Δμ?"""
    setup, delta, scatter, order, seed = args
    rng = np.random.default_rng(seed)
    day = DaySetup(scatter=scatter, timer_sd_s=SETUPS[setup][1])
    data = simulate_day(track(setup), order, {"A": MU_A, "B": MU_A + delta}, day, rng)
    c = joint_fit(track(setup), data).comparisons[0]
    return c.ci90 is not None and c.ci90[1] < 0


def power_sim(pool, setup, delta, scatter, per, days, seed0) -> float:
    order = "".join("AB"[i] for i in run_order(2, per))
    jobs = [(setup, delta, scatter, order, seed0 + s) for s in range(days)]
    return float(np.mean(list(pool.map(resolved, jobs, chunksize=4))))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--days", type=int, default=100, help="simulated days per cell and n")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--setup", choices=["demo", "sparse", "both"], default="both")
    args = ap.parse_args()
    setups = ["demo", "sparse"] if args.setup == "both" else [args.setup]
    print(f"machine: {os.cpu_count()} cores; {args.days} days per cell, {args.jobs} processes")
    print(f"binomial SD of a power of 0.9 over {args.days} days: "
          f"{100 * np.sqrt(0.09 / args.days):.1f} %")  # fmt: skip
    t_all = time.perf_counter()
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        for setup in setups:
            tr = track(setup)
            print(f"\nsetup {setup}: {len(tr.photocells)} photocells, timer "
                  f"{SETUPS[setup][1] * 1e3:g} ms")  # fmt: skip
            print(f"{'Δμ':>7} | {'scatter':>7} | {'n/item':>6} | {'stated':>6} | "
                  f"{'simulated':>9} | {'n−1: stated':>11} | {'n−1: sim':>8} | "
                  "verdict")  # fmt: skip
            for delta in DELTAS:
                for scatter in SCATTERS:
                    p = plan_day(tr, delta, assumptions(setup, scatter))
                    n = p.descents_per_item
                    seed0 = int(1e6 * delta) * 1000 + int(scatter * 1000) * 10
                    sim = power_sim(pool, setup, delta, scatter, n, args.days, seed0)
                    if n > 2:
                        sim1 = power_sim(pool, setup, delta, scatter, n - 1, args.days, seed0 + 7)
                        st1 = f"{p.power_by_n.get(n - 1, float('nan')):.3f}"
                        s1 = f"{sim1:.3f}"
                        # at most one descent per item more than needed: n − 2 must fall short
                        ok_size = (
                            sim1 < p.target_power
                            or n - 2 < 2
                            or power_sim(pool, setup, delta, scatter, n - 2, args.days, seed0 + 8)
                            < p.target_power
                        )
                    else:
                        st1, s1, ok_size = "—", "—", True
                    ok_pw = abs(sim - p.power) <= 0.05
                    verdict = "ok" if ok_pw and ok_size else (
                        "POWER OFF" if not ok_pw else "PLAN TOO LARGE"
                    )  # fmt: skip
                    print(f"{delta:>7.4f} | {scatter * 100:>6.1f}% | {n:>6} | {p.power:>6.3f} | "
                          f"{sim:>9.3f} | {st1:>11} | {s1:>8} | {verdict}")  # fmt: skip
    print(f"\n{time.perf_counter() - t_all:.0f} s in all")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
