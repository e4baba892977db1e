"""Honest on every size of day and every drift (issue 24): simulated test days, is the answer
of `station compare` still honest with 2–6 descents an item, with little or much posture
scatter, and when μ's drift over the day bends?

Each day: two skis A and B (μ 0.0085 and 0.0095: Δμ = −0.001) skied ABBA… (n descents each,
one every --minutes), 0.5 ms timing noise on every photocell rounded to 0.1 ms, v0 between 2.5
and 4.5 m/s, each descent's CdA log-normal around 0.22 m² with the posture scatter. Drift:
straight, μ +0.02 per hour; or bent, μ +0.02 per hour +0.03 per hour² (the sun coming onto the
track). Every descent is fitted on its own first, then the day's joint fit runs, as `station
compare` does.

Columns, per cell:
- holds: the 90 % interval of Δμ holds the true −0.001 (target 86–95 %);
- interval: days that got an interval at all;
- wrong@95: the wrong ski (B) is named faster with P ≥ 0.95 (target < 1 %);
- warned: days whose answer warns that the drift is not straight;
- bent: days where the day model followed a bend (quadratic drift).

Run: python benchmarks/compare_small_days.py [--days 200] [--jobs 2] [--minutes 5]
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

from station.model.compare import CompareError, DescentData, joint_fit  # noqa: E402
from station.model.fit import fit_descent  # noqa: E402
from station.model.physics import Conditions, Params, StraightRun  # noqa: E402
from station.survey.load import load_survey  # noqa: E402
from station.survey.track import build_track  # noqa: E402

MU = {"A": 0.0085, "B": 0.0095}
TRUE_DELTA = MU["A"] - MU["B"]
NOISE_S = 5e-4
CDA, MASS, RHO = 0.22, 88.0, 1.079
DRIFTS = {"straight": (0.02, 0.0), "bent": (0.02, 0.03)}

_track = None


def track():
    global _track
    if _track is None:
        _track = build_track(load_survey(str(ROOT / "surveys" / "demo_run.yaml")))
    return _track


def order(n: int) -> str:
    """ABBA repeated: n descents of each ski."""
    return ("ABBA" * n)[: 2 * n]


def one_day(job: tuple[int, float, str, float, int]):
    n, scatter, drift, step_h, seed = job
    tr = track()
    xs = np.array([pc.x for pc in tr.photocells])
    run = StraightRun(tr.profile, xs)
    rng = np.random.default_rng(seed)
    cond = Conditions(MASS, RHO)
    lin, quad = DRIFTS[drift]
    seq = order(n)
    t_mid = (len(seq) - 1) * step_h / 2
    data = []
    for k, item in enumerate(seq):
        dt = k * step_h - t_mid
        mu = MU[item] + lin * dt + quad * dt * dt
        cda = CDA * float(np.exp(rng.normal(0.0, scatter)))
        t = run.solve(Params(cda, mu, rng.uniform(2.5, 4.5)), cond, sensitivities=False).t
        t = np.round(36000.0 + t + rng.normal(0.0, NOISE_S, len(t)), 4)
        f = fit_descent(tr.profile, xs, t, cond, run=run)
        guess = (f.cda.value or 0.25, f.mu.value or 0.02, f.v0.value or 3.0)
        data.append(DescentData(k + 1, item, "skier", tuple(tr.photocell_ids), t - t[0],
                                10.0 + k * step_h, MASS, RHO, 0.0, guess))  # fmt: skip
    try:
        res = joint_fit(tr, data)
    except CompareError:
        return None
    c = next(c for c in res.comparisons if {c.a, c.b} == {"A", "B"})
    if c.ci90 is None or c.p_a_faster is None:
        return (None, None, None, False, False)
    lo, hi = c.ci90 if c.a == "A" else (-c.ci90[1], -c.ci90[0])
    p_a = c.p_a_faster if c.a == "A" else 1.0 - c.p_a_faster
    warned = any("not straight" in w for w in res.warnings)
    return (lo, hi, p_a, warned, res.drift_bend is not None)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--days", type=int, default=200, help="simulated days per cell")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--minutes", type=float, default=5.0, help="minutes between descents")
    ap.add_argument("--per-item", default="2,3,4,6")
    ap.add_argument("--scatter-pct", default="0.5,1.5,3")
    args = ap.parse_args()
    ns = [int(x) for x in args.per_item.split(",")]
    scatters = [float(x) / 100 for x in args.scatter_pct.split(",")]
    step_h = args.minutes / 60.0
    print(f"machine: {os.cpu_count()} cores; {args.days} days a cell, {args.jobs} processes, "
          f"a descent every {args.minutes:g} min")  # fmt: skip
    print(f"{'drift':>8} | {'per ski':>7} | {'scatter':>7} | {'holds':>6} | {'interval':>8} | "
          f"{'wrong@95':>8} | {'warned':>6} | {'bent':>5} | {'s/day':>5}")  # fmt: skip
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        for drift in DRIFTS:
            for n in ns:
                for scatter in scatters:
                    t0 = time.perf_counter()
                    base = (
                        (list(DRIFTS).index(drift) * 100 + n) * 1000 + round(scatter * 1000)
                    ) * 1000
                    jobs = [(n, scatter, drift, step_h, base + s) for s in range(args.days)]
                    out = [o for o in pool.map(one_day, jobs, chunksize=4)]
                    secs = (time.perf_counter() - t0) * args.jobs / args.days
                    got = [o for o in out if o is not None and o[0] is not None]
                    m = len(out)
                    holds = sum(lo <= TRUE_DELTA <= hi for lo, hi, *_ in got) / max(len(got), 1)
                    wrong = sum(p <= 0.05 for _lo, _hi, p, *_ in got) / m
                    warned = sum(bool(o and o[3]) for o in out) / m
                    bent = sum(bool(o and o[4]) for o in out) / m
                    print(f"{drift:>8} | {n:>7} | {scatter * 100:>6.1f}% | {holds * 100:>5.1f}% |"
                          f" {len(got) / m * 100:>7.1f}% | {wrong * 100:>7.1f}% | "
                          f"{warned * 100:>5.1f}% | {bent * 100:>4.1f}% | {secs:>5.2f}",
                          flush=True)  # fmt: skip
    print("binomial SD of a 90 % coverage over", args.days, "days:",
          f"{100 * np.sqrt(0.09 / args.days):.1f} %")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
