"""Does `station plan` keep its promise? Days simulated with the planned descents, fitted by the
real joint fit of `station compare`.

For each cell (Δμ 0.0005 / 0.001 / 0.002 × posture scatter 0.5 / 1 / 2 %) the plan is made
(`station.model.plan.plan_day`, 90 % power, 2 items, drift 0.005 per hour, 3 minutes between
descents: the simulated day's own values, station/simulators/days.DaySetup), then days are
simulated in the plan's order (station/simulators/days.py: v0 uniform in 2.5–4.5 m/s, the
timer's noise on every photocell, times rounded to 0.1 ms, μ drifting about its mid-day value),
every descent fitted on its own and the day by `joint_fit`. "Resolved": the 90 % interval of Δμ
excludes 0 on the right side. Printed per cell: the plan (descents per item, its stated power),
the simulated power at the plan and at one descent per item fewer, and the smallest number of
descents per item whose simulated days reach the target (the plan is at most one descent per
item larger than needed when that is n or n − 1; "ok" also needs the simulated power within
± 5 % of the stated).

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

from station.model.compare import joint_fit  # noqa: E402
from station.model.plan import DayAssumptions, plan_day, run_order  # noqa: E402
from station.simulators.days import DaySetup, simulate_day  # noqa: E402
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
    """The plan's assumptions: the simulated day's own values (v0 the middle of its range)."""
    d = DaySetup()
    return DayAssumptions(
        mass_kg=d.mass_kg, air_density=d.air_density, cda=d.cda, v0=sum(d.v0_range) / 2,
        mu=MU_A, timer_sd_s=SETUPS[setup][1], posture_sd=scatter,
        drift_per_hour=d.drift_per_hour, minutes_between=d.minutes_between,
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
    ap.add_argument("--delta", type=float, action="append", help="only this Δμ (repeatable)")
    ap.add_argument("--scatter", type=float, action="append", help="only this scatter")
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
                  f"{'smallest n (sim)':>16} | verdict")  # fmt: skip
            for delta in args.delta or DELTAS:
                for scatter in args.scatter or SCATTERS:
                    p = plan_day(tr, delta, assumptions(setup, scatter))
                    n = p.descents_per_item
                    seed0 = int(1e6 * delta) * 1000 + int(scatter * 1000) * 10
                    sims: dict[int, float] = {}

                    def sim(per: int, setup=setup, delta=delta, scatter=scatter, seed0=seed0,
                            sims=sims) -> float:  # fmt: skip
                        """Simulated power with ``per`` descents per item (each n its own
                        seeds: the days of different n are independent)."""
                        if per not in sims:
                            sims[per] = power_sim(pool, setup, delta, scatter, per, args.days,
                                                  seed0 + 7 * per)  # fmt: skip
                        return sims[per]

                    # the smallest n whose simulated days reach the target: down from the plan
                    # while they do, up from it while they do not (at most 4 steps)
                    smallest = n
                    if sim(n) >= p.target_power:
                        while (
                            smallest > 2
                            and n - smallest < 4
                            and (sim(smallest - 1) >= p.target_power)
                        ):
                            smallest -= 1
                    else:
                        while smallest - n < 4 and sim(smallest) < p.target_power:
                            smallest += 1
                        if sim(smallest) < p.target_power:
                            smallest = -1  # not within 4 more
                    st1 = f"{p.power_by_n[n - 1]:.3f}" if n - 1 in p.power_by_n else "—"
                    s1 = f"{sim(n - 1):.3f}" if n > 2 else "—"
                    ok_pw = abs(sim(n) - p.power) <= 0.05
                    ok_size = smallest < 0 or n - smallest <= 1
                    verdict = "ok" if ok_pw and ok_size else (
                        "POWER OFF" if not ok_pw else "PLAN TOO LARGE"
                    )  # fmt: skip
                    sm = str(smallest) if smallest > 0 else f">{n + 4}"
                    print(f"{delta:>7.4f} | {scatter * 100:>6.1f}% | {n:>6} | {p.power:>6.3f} | "
                          f"{sim(n):>9.3f} | {st1:>11} | {s1:>8} | {sm:>16} | {verdict}",
                          flush=True)  # fmt: skip
    print(f"\n{time.perf_counter() - t_all:.0f} s in all")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
