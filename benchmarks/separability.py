"""Does `station compare`'s per-pair "drift separable" judgement (station/model/compare_result.py:
the pair's items overlap in time and its Δμ correlates with the drift at most 0.9) mark the run
orders whose A–B interval is honest, and "not separable" those where it is not, or where it is
so wide that it decides nothing?

Days with known truth (simulators/days.py ``simulate_day`` on the demo run, nine photocells,
timer 0.5 ms, 1 % posture scatter, μ_A 0.0085 at mid-day, 3 min between descents), drift 0.005
and 0.02 per hour, A and B equal (Δμ = μ_A − μ_B = 0) or Δμ = 0.001, over several run orders.
Each day is fitted once with all its descents by the real ``joint_fit`` (drift ``auto``) and
decided by the real ``day_decisions`` (the last look). Printed per cell: the share judged
separable, the coverage of the A–B 90 % interval (share holding the true Δμ; and within the
separable / not separable days), the median half-width of that interval, the share "decided" at
the last look (as the station says it, the caveat obeyed) and as it would be without the
caveat, and the wrong-ski decisions among those (A and B equal: any decision is wrong).

Measured (200 days a cell, seeds 31000…, 211 s at load 0.4–1.8 on the shared 2-core machine;
"decided 0 %" with "wrong 1" is 1 of 200; cov|sep and cov|not equal cover, as every day of
an order is judged alike, and are left out here)::

  order       drift/h     Δμ   |r|   sep  cover   half-w  decided  wrong  dec0  wrong0
  ABBAx2        0.005      0  0.03  100%    89%  0.00017       0%      0    0%       0
  ABBAx2        0.005  0.001  0.03  100%    90%  0.00017     100%      0  100%       0
  ABBAx2         0.02      0  0.03  100%    92%  0.00017       0%      0    0%       0
  ABBAx2         0.02  0.001  0.03  100%    90%  0.00017     100%      0  100%       0
  ABABABAB      0.005      0  0.21  100%    90%  0.00017       0%      1    0%       1
  ABABABAB      0.005  0.001  0.21  100%    91%  0.00017     100%      0  100%       0
  ABABABAB       0.02      0  0.21  100%    90%  0.00017       0%      1    0%       1
  ABABABAB       0.02  0.001  0.21  100%    90%  0.00017     100%      0  100%       0
  AABB          0.005      0  0.90    0%    88%  0.00055       0%      0    0%       0
  AABB          0.005  0.001  0.90    0%    87%  0.00055       0%      0    0%       0
  AABB           0.02      0  0.90    0%    87%  0.00055       0%      0    0%       0
  AABB           0.02  0.001  0.90    0%    87%  0.00055       0%      0    0%       0
  AAABBB        0.005      0  0.88    0%    92%  0.00042       0%      0    0%       0
  AAABBB        0.005  0.001  0.88    0%    92%  0.00042       0%      0    0%       0
  AAABBB         0.02      0  0.88    0%    91%  0.00042       0%      0    0%       0
  AAABBB         0.02  0.001  0.88    0%    92%  0.00042       0%      0    0%       0
  AAAABBBB      0.005      0  0.87    0%    88%  0.00035       0%      0    0%       0
  AAAABBBB      0.005  0.001  0.87    0%    88%  0.00035       0%      0    2%       0
  AAAABBBB       0.02      0  0.87    0%    88%  0.00035       0%      0    0%       0
  AAAABBBB       0.02  0.001  0.87    0%    89%  0.00036       0%      0    2%       0
  ABBAABBAC     0.005      0  0.02  100%    88%  0.00017       0%      1    0%       1
  ABBAABBAC     0.005  0.001  0.02  100%    86%  0.00017     100%      0  100%       0
  ABBAABBAC      0.02      0  0.02  100%    86%  0.00017       0%      1    0%       1
  ABBAABBAC      0.02  0.001  0.02  100%    87%  0.00017     100%      0  100%       0
  AAAABBBBAB    0.005      0  0.59  100%    89%  0.00019       0%      0    0%       0
  AAAABBBBAB    0.005  0.001  0.59  100%    89%  0.00019     100%      0  100%       0
  AAAABBBBAB     0.02      0  0.59  100%    88%  0.00019       0%      0    0%       0
  AAAABBBBAB     0.02  0.001  0.59  100%    89%  0.00019     100%      0  100%       0

Reading: the judgement is a property of the run order (every day of an order judged alike).
Where it says separable (ABBA×2, ABABABAB, ABBAABBAC, AAAABBBBAB) the interval is honest
(86–92 % against 90 %, binomial SE 2.1 %; the four cells of an order share its 200 seeds, so
ABBAABBAC's 86–88 % is one seed block, not four), half-width 0.00017–0.00019, Δμ 0.001 decided on
every day, an equal pair on 0–1 of 200. Where it says not separable (AABB, AAABBB, AAAABBBB) the
interval is honest too (87–92 %), since the simulated drift is the model's own linear one, but
two to three times as wide (0.00035–0.00055): even with the caveat ignored it decides Δμ 0.001 on
0–2 % of days. So "not separable" marks the orders whose interval decides nothing, not dishonest
ones, and the caveat costs at most 2 % of (right) decisions. Those three orders are all caught by
the "items do not overlap in time" rule: their |corr| is 0.87–0.90, at or under the 0.9
threshold, so the correlation rule alone would pass AAABBB and AAAABBBB (harmlessly here); the
separable orders lie far below it (0.02–0.59). Overlapping orders with a block in them stay
far below too (the probes, ``--order``; measured on 60 days at drift 0.02, seeds 41000…:
AAAABBBBA 0.51, AAABBBA 0.41,
AAABBBAB 0.54, AABBBBAA and ABBBBBBA 0.03; all separable, coverage 87–93 %, Δμ 0.001 decided on
98–100 %): on these days the 0.9 threshold never decides a pair. Not simulated: a drift
that is not linear in time, against which the caveat would matter more.

Run: python benchmarks/separability.py [--days 100] [--jobs 1] [--order NAME ...]
"""

from __future__ import annotations

import argparse
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import station.model.compare_result as compare_mod  # noqa: E402
from benchmarks.plan_power import MU_A, track  # noqa: E402
from simulators.days import DaySetup, simulate_day  # noqa: E402
from station.model.compare import joint_fit  # noqa: E402
from station.model.sequential import day_decisions  # noqa: E402

ORDERS = {
    "ABBAx2": "ABBAABBA",
    "ABABABAB": "ABABABAB",
    "AABB": "AABB",
    "AAABBB": "AAABBB",
    "AAAABBBB": "AAAABBBB",
    "ABBAABBAC": "ABBAABBAC",
    "AAAABBBBAB": "AAAABBBBAB",
}
#: overlapping orders with one item in a block, run only when named (``--order``): how high
#: the correlation gets when the items do overlap in time
PROBES = {name: name for name in ("AAAABBBBA", "AAABBBA", "AAABBBAB", "AABBBBAA", "ABBBBBBA")}
DRIFTS = (0.005, 0.02)
DELTAS = (0.0, 0.001)
SCATTER = 0.01
_seen: list = []
_drift = compare_mod._drift


def _drift_seen(data, lay, inf):
    """compare's own ``_drift``, keeping its layout and inference to read the A–B correlation
    with the drift (the quantity the 0.9 threshold is applied to)."""
    _seen[:] = [lay, inf]
    return _drift(data, lay, inf)


compare_mod._drift = _drift_seen


def corr_ab() -> float:
    """|corr(Δμ_AB, drift)| of the last fit, as compare_result.py computes it (nan: no drift)."""
    lay, inf = _seen
    if not lay.use_drift:
        return float("nan")
    c = np.zeros(len(inf.centre))
    c[lay.mu_index("A")], c[lay.mu_index("B")] = 1.0, -1.0
    sd_c = float(np.sqrt(c @ inf.cov @ c))
    return abs(float(c @ inf.cov[:, lay.i_drift]) / (sd_c * inf.sd[lay.i_drift]))


def one_day(job: tuple[str, float, float, int]) -> dict:
    name, drift, delta, seed = job
    rng = np.random.default_rng(seed)
    order = (ORDERS | PROBES)[name]
    mus = {"A": MU_A, "B": MU_A - delta, "C": MU_A}
    day = DaySetup(scatter=SCATTER, drift_per_hour=drift, timer_sd_s=5e-4)
    data = simulate_day(track("demo"), order, mus, day, rng)
    res = joint_fit(track("demo"), data)
    c = next(c for c in res.comparisons if {c.a, c.b} == {"A", "B"})
    out = {
        "corr": corr_ab(),
        "sep": c.drift_separable,
        "caveat": c.caveat,
        "status": str(res.status),
    }
    if c.ci90 is None:
        return out | {"cover": False, "half": float("nan"), "state": "none", "faster": None,
                      "state0": "none", "faster0": None}  # fmt: skip
    sign = 1.0 if c.a == "A" else -1.0
    lo, hi = sorted((sign * c.ci90[0], sign * c.ci90[1]))
    d = day_decisions([c], list(order))[0]
    d0 = day_decisions([replace(c, caveat="")], list(order))[0]
    return out | {
        "cover": bool(lo <= delta <= hi), "half": (hi - lo) / 2,
        "state": d.state, "faster": d.faster, "state0": d0.state, "faster0": d0.faster,
    }  # fmt: skip


def wrong(faster: str | None, delta: float) -> bool:
    """A decision names the wrong ski: any ski when A and B are equal, A when B is faster."""
    return faster is not None and (delta == 0.0 or faster == "A")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--days", type=int, default=100)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--order", action="append", choices=list(ORDERS | PROBES))
    args = ap.parse_args()
    names = args.order or list(ORDERS)
    print(f"{args.days} days a cell, 1 % scatter, demo run (9 photocells, 0.5 ms)")
    print(f"{'order':<11} {'drift/h':>7} {'Δμ':>6} {'|r|':>5} {'sep':>5} {'cover':>6} "
          f"{'cov|sep':>8} {'cov|not':>8} {'half-w':>8} {'decided':>8} {'wrong':>6} "
          f"{'dec0':>6} {'wrong0':>6} {'s':>5}")  # fmt: skip
    t_all = time.perf_counter()
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        for name in names:
            for drift in DRIFTS:
                for delta in DELTAS:
                    t0 = time.perf_counter()
                    seed0 = 31000 + 1000 * names.index(name)
                    jobs = [(name, drift, delta, seed0 + s) for s in range(args.days)]
                    rows = list(pool.map(one_day, jobs))
                    n = len(rows)
                    sep = [r for r in rows if r["sep"]]
                    nsep = [r for r in rows if not r["sep"]]

                    def share(rs: list[dict], key: str) -> str:
                        return f"{100 * sum(r[key] for r in rs) / len(rs):.0f}" if rs else "–"

                    corr = np.nanmedian([r["corr"] for r in rows])
                    half = np.nanmedian([r["half"] for r in rows])
                    dec = sum(r["state"] == "decided" for r in rows)
                    dec0 = sum(r["state0"] == "decided" for r in rows)
                    wr = sum(wrong(r["faster"], delta) for r in rows)
                    wr0 = sum(wrong(r["faster0"], delta) for r in rows)
                    print(f"{name:<11} {drift:>7g} {delta:>6g} {corr:>5.2f} "
                          f"{100 * len(sep) / n:>4.0f}% {share(rows, 'cover'):>5}% "
                          f"{share(sep, 'cover'):>7}% "
                          f"{share(nsep, 'cover'):>7}% {half:>8.5f} {100 * dec / n:>7.0f}% "
                          f"{wr:>6d} {100 * dec0 / n:>5.0f}% {wr0:>6d} "
                          f"{time.perf_counter() - t0:>5.0f}", flush=True)  # fmt: skip
    print(
        f"total {time.perf_counter() - t_all:.0f} s; sep: share judged separable; cover: "
        "share of 90 % intervals holding the true Δμ (cov|sep, cov|not: within those judged "
        "separable / not); half-w: median half-width; decided/wrong: at the last look as the "
        "station says it (caveat obeyed), dec0/wrong0: the same with the caveat ignored; |r|: "
        "median |corr(Δμ_AB, drift)|, what the 0.9 threshold is applied to"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
