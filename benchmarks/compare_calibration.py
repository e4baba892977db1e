"""Calibration of `station compare`: simulated test days, is the answer honest?

Each day: two skis A and B (μ 0.0085 and 0.0095: Δμ = −0.001), ABBAABBA (4 descents per ski,
one every 3 minutes), a drift of μ of +0.02 per hour, 0.5 ms timing noise on every photocell
(the first too) and times rounded to 0.1 ms as the timer does, v0 between 2.5 and 4.5 m/s, and
each descent's drag area drawn around the skier's 0.22 m² with the given posture scatter
(log-normal, SD 0, 0.5, 1 or 2 %). Every descent is fitted on its own first (the start of the
joint fit, as `station compare` does), then the day's joint fit runs.

Columns, per scatter level:
- found: Δμ's 90 % interval excludes 0 and says A is faster (the truth);
- wrong: the interval excludes 0 and says B is faster (a 90 % two-sided interval allows 5 %);
- holds: the interval holds the true Δμ = −0.001 (target 88–92 %);
- posture: the median estimated posture scatter;
- poor-fit: days the χ² test against the timer's precision flags (expected ~0.1 %);
- converged: days whose joint fit reached a verified minimum (``--model velocity``: the same
  days fitted with μ + μ1·v per item, whose truth is μ1 = 0, as ``station compare --model
  velocity`` fits them).

The grid for smaller and larger days (2, 3, 4, 6 descents an item × 0.5, 1.5, 3 % scatter ×
straight and bent drift, 200 days a cell, with the share warned, the wrong ski named at
P ≥ 0.95 and P(A faster)'s tails): benchmarks/compare_small_days.py.

Run: python benchmarks/compare_calibration.py [--days 200] [--jobs 2] [--model velocity]
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

from station.model.compare import DescentData, joint_fit  # noqa: E402
from station.model.fit import fit_descent  # noqa: E402
from station.model.physics import Conditions, Params, StraightRun  # noqa: E402
from station.survey.load import load_survey  # noqa: E402
from station.survey.track import build_track  # noqa: E402

MU = {"A": 0.0085, "B": 0.0095}
TRUE_DELTA = MU["A"] - MU["B"]
ORDER = "ABBAABBA"
DRIFT_PER_HOUR = 0.02
NOISE_S = 5e-4
STEP_H = 0.05
CDA, MASS, RHO = 0.22, 88.0, 1.079
SCATTERS = (0.0, 0.005, 0.01, 0.02)

_track = None


def track():
    global _track
    if _track is None:
        _track = build_track(load_survey(str(ROOT / "surveys" / "demo_run.yaml")))
    return _track


def one_day(args: tuple[float, int, str]) -> tuple[float, float, float, float, str]:
    scatter, seed, model = args
    tr = track()
    xs = np.array([pc.x for pc in tr.photocells])
    run = StraightRun(tr.profile, xs)
    rng = np.random.default_rng(seed)
    cond = Conditions(MASS, RHO)
    data = []
    for k, item in enumerate(ORDER):
        mu = MU[item] + DRIFT_PER_HOUR * k * STEP_H
        cda = CDA * float(np.exp(rng.normal(0.0, scatter)))
        t = run.solve(Params(cda, mu, rng.uniform(2.5, 4.5)), cond, sensitivities=False).t
        t = np.round(36000.0 + t + rng.normal(0.0, NOISE_S, len(t)), 4)
        f = fit_descent(tr.profile, xs, t, cond, run=run)
        guess = (f.cda.value or 0.25, f.mu.value or 0.02, f.v0.value or 3.0)
        data.append(
            DescentData(
                k + 1,
                item,
                "skier",
                tuple(tr.photocell_ids),
                t - t[0],
                10.0 + k * STEP_H,
                MASS,
                RHO,
                0.0,
                guess,
            )  # fmt: skip
        )
    res = joint_fit(tr, data, model=model)
    c = res.comparisons[0]
    assert (c.a, c.b) == ("A", "B") and c.ci90 is not None
    return c.ci90[0], c.ci90[1], c.p_a_faster, res.posture_sd, res.status


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--days", type=int, default=200, help="simulated days per scatter level")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument(
        "--model",
        choices=("constant", "velocity"),
        default="constant",
        help="the joint fit's model of μ (the days are simulated with constant μ)",
    )
    args = ap.parse_args()
    print(f"machine: {os.cpu_count()} cores; {args.days} days per level, {args.jobs} processes, "
          f"model {args.model}")  # fmt: skip
    print(f"{'CdA scatter':>11} | {'Δμ = 0.001 found, interval excludes 0':>37} | "
          f"{'wrong ski declared faster':>25} | {'Δμ interval holds the truth':>27} | "
          f"{'posture (median)':>16} | {'poor-fit':>8} | {'converged':>9} | "
          f"{'s/day':>5}")  # fmt: skip
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        for scatter in SCATTERS:
            t0 = time.perf_counter()
            jobs = [(scatter, 1000 * int(scatter * 1000) + s, args.model)
                    for s in range(args.days)]  # fmt: skip
            out = list(pool.map(one_day, jobs, chunksize=8))
            secs = (time.perf_counter() - t0) * args.jobs / args.days
            lo = np.array([o[0] for o in out])
            hi = np.array([o[1] for o in out])
            found = np.mean(hi < 0)
            wrong = np.mean(lo > 0)
            holds = np.mean((lo <= TRUE_DELTA) & (hi >= TRUE_DELTA))
            posture = float(np.median([o[3] for o in out]))
            poor = np.mean([o[4] == "poor-fit" for o in out])
            conv = np.mean([o[4] != "not-converged" for o in out])
            print(f"{scatter * 100:>10.1f}% | {found * 100:>36.1f}% | {wrong * 100:>24.1f}% | "
                  f"{holds * 100:>26.1f}% | {posture * 100:>15.2f}% | {poor * 100:>7.1f}% | "
                  f"{conv * 100:>8.1f}% | {secs:>5.2f}")  # fmt: skip
    print("binomial SD of a 90 % coverage over", args.days, "days:",
          f"{100 * np.sqrt(0.09 / args.days):.1f} %")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
