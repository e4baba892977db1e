"""Scale of the joint fit of a day: time and peak memory for 40, 200, 400 and 2000 descents.

Each day: four skiers (their own mean CdA, 1 % posture scatter), four skis in rotation, a drift
of +0.02 μ per hour, 0.5 ms timing noise, every descent on the demo run's 9 photocells. The
single fits (the joint fit's start) are done first and not timed. Peak memory is what
tracemalloc sees numpy allocate during the joint fit. The local parameters of each descent are
eliminated block by block (Schur complement), so both should grow linearly.

Run: python benchmarks/compare_scale.py [--sizes 40,200,400,2000]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from station.model.compare import DescentData, joint_fit  # noqa: E402
from station.model.fit import fit_descent  # noqa: E402
from station.model.physics import Conditions, Params, StraightRun  # noqa: E402
from station.survey.load import load_survey  # noqa: E402
from station.survey.track import build_track  # noqa: E402

SKIS = {"A": 0.0085, "B": 0.0095, "C": 0.0090, "D": 0.0088}
SKIERS = {"anna": (0.22, 88.0), "ben": (0.25, 95.0), "cleo": (0.20, 70.0), "dan": (0.24, 82.0)}
RHO = 1.079


def day(track, n: int, seed: int = 0) -> list[DescentData]:
    xs = np.array([pc.x for pc in track.photocells])
    run = StraightRun(track.profile, xs)
    rng = np.random.default_rng(seed)
    skiers = list(SKIERS)
    skis = list(SKIS)
    out = []
    for k in range(n):
        who = skiers[k % 4]
        ski = skis[(k // 4 + k) % 4]
        cda0, mass = SKIERS[who]
        hours = 9.0 + k * 0.01
        mu = SKIS[ski] + 0.02 * (hours - 9.0) * 40 / max(n, 40)  # same drift over the day
        cond = Conditions(mass, RHO)
        cda = cda0 * float(np.exp(rng.normal(0.0, 0.01)))
        t = run.solve(Params(cda, mu, rng.uniform(2.5, 4.5)), cond, sensitivities=False).t
        t = np.round(t + rng.normal(0.0, 5e-4, len(t)), 4)
        f = fit_descent(track.profile, xs, t, cond, run=run)
        guess = (f.cda.value or 0.25, f.mu.value or 0.02, f.v0.value or 3.0)
        out.append(
            DescentData(
                k + 1, ski, who, tuple(track.photocell_ids), t - t[0], hours, mass, RHO, 0.0, guess
            )  # fmt: skip
        )
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="40,200,400,2000")
    args = ap.parse_args()
    track = build_track(load_survey(str(ROOT / "surveys" / "demo_run.yaml")))
    print(f"machine: {os.cpu_count()} cores; numpy {np.__version__}")
    print(f"{'descents':>8} {'time [s]':>9} {'per descent [ms]':>17} {'peak memory [MiB]':>18} "
          f"{'posture %':>9} {'status':>8}")  # fmt: skip
    joint_fit(track, day(track, 8))  # imports and caches outside the measurement
    for n in (int(x) for x in args.sizes.split(",")):
        data = day(track, n)
        tracemalloc.start()
        t0 = time.perf_counter()
        res = joint_fit(track, data)
        secs = time.perf_counter() - t0
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        print(f"{n:>8} {secs:>9.2f} {secs / n * 1e3:>17.2f} {peak / 2**20:>18.1f} "
              f"{res.posture_sd * 100:>9.2f} {res.status:>8}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
