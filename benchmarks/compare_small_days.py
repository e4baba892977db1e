"""Honest on every size of day and every drift (issue 24): simulated test days, is the answer
of `station compare` still honest with 2–6 descents an item, with little or much posture
scatter, and when μ's drift over the day bends?

Each day: two skis A and B skied ABBA… (n descents each, one every --minutes), 0.5 ms timing
noise on every photocell rounded to 0.1 ms, v0 between 2.5 and 4.5 m/s, each descent's CdA
log-normal around 0.22 m² with the posture scatter. Drift: straight, μ +0.02 per hour; or bent,
μ +0.02 per hour +0.03 per hour² (the sun coming onto the track). Every descent is fitted on its
own first, then the day's joint fit runs, as `station compare` does.

Two kinds of day in every cell:
- fixed: μ_A 0.0085, μ_B 0.0095 (Δμ = −0.001), --days of them;
- tail: Δμ drawn uniformly in ±0.001 per day (μ_B 0.0095), --tail-days of them: P(A faster)
  is then sometimes near 0.5, so its tails can be checked against the truth.

Columns, per cell:
- holds: the 90 % interval of Δμ holds the true Δμ (fixed days; target 86–95 %, done ≥ 85 %);
- interval: days that got an interval at all (fixed days);
- wrong@95: the wrong ski (B) is named faster with P ≥ 0.95 (fixed days; target < 1 %);
- claims, right: tail days where P(A faster) ≥ 0.95 or ≤ 0.05 (a ski named faster at 95 %),
  and among those the share where the named ski is the faster one (target ≥ 95 %);
- warned: fixed days whose answer warns of the drift (it bends, or the day is too small to
  see a bend);
- bent: fixed days where the day model followed a bend (quadratic drift).

Every day is appended to a results file (JSON lines, --out) as it finishes, and days already
there are skipped: the run can be stopped and resumed, or split (--cells) over several runs;
--report only prints the table of what the file holds. --jobs 1 runs in this process.

Run: python benchmarks/compare_small_days.py [--days 200] [--tail-days 100] [--jobs 1]
     [--per-item 2,3,4,6] [--scatter-pct 0.5,1.5,3] [--drift straight,bent]
     [--out tmp/compare_small_days.jsonl] [--report]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Iterator
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

MU_A, MU_B = 0.0085, 0.0095
TAIL_SPAN = 0.001  # tail days: Δμ uniform in ±this
NOISE_S = 5e-4
CDA, MASS, RHO = 0.22, 88.0, 1.079
DRIFTS = {"straight": (0.02, 0.0), "bent": (0.02, 0.03)}
KINDS = ("fixed", "tail")

_track = None


def track():
    global _track
    if _track is None:
        _track = build_track(load_survey(str(ROOT / "surveys" / "demo_run.yaml")))
    return _track


def order(n: int) -> str:
    """ABBA repeated: n descents of each ski."""
    return ("ABBA" * n)[: 2 * n]


Job = tuple[str, str, int, float, int, float]  # kind, drift, per ski, scatter, seed, minutes


def seed_of(kind: str, drift: str, n: int, scatter: float, day: int) -> int:
    return (((KINDS.index(kind) * 10 + list(DRIFTS).index(drift)) * 100 + n) * 1000
            + round(scatter * 1000)) * 10000 + day  # fmt: skip


def one_day(job: Job) -> dict:
    kind, drift, n, scatter, seed, minutes = job
    step_h = minutes / 60.0
    tr = track()
    xs = np.array([pc.x for pc in tr.photocells])
    run = StraightRun(tr.profile, xs)
    rng = np.random.default_rng(seed)
    cond = Conditions(MASS, RHO)
    delta = MU_A - MU_B if kind == "fixed" else float(rng.uniform(-TAIL_SPAN, TAIL_SPAN))
    mus = {"A": MU_B + delta, "B": MU_B}
    lin, quad = DRIFTS[drift]
    seq = order(n)
    t_mid = (len(seq) - 1) * step_h / 2
    data = []
    for k, item in enumerate(seq):
        dt = k * step_h - t_mid
        mu = mus[item] + lin * dt + quad * dt * dt
        cda = CDA * float(np.exp(rng.normal(0.0, scatter)))
        t = run.solve(Params(cda, mu, rng.uniform(2.5, 4.5)), cond, sensitivities=False).t
        t = np.round(36000.0 + t + rng.normal(0.0, NOISE_S, len(t)), 4)
        f = fit_descent(tr.profile, xs, t, cond, run=run)
        guess = (f.cda.value or 0.25, f.mu.value or 0.02, f.v0.value or 3.0)
        data.append(DescentData(k + 1, item, "skier", tuple(tr.photocell_ids), t - t[0],
                                10.0 + k * step_h, MASS, RHO, 0.0, guess))  # fmt: skip
    out: dict = {"kind": kind, "drift": drift, "n": n, "scatter": scatter, "seed": seed,
                 "delta": delta, "lo": None, "hi": None, "p_a": None, "warned": False,
                 "bent": False, "error": None}  # fmt: skip
    try:
        res = joint_fit(tr, data)
    except CompareError as e:
        out["error"] = str(e)
        return out
    c = next(c for c in res.comparisons if {c.a, c.b} == {"A", "B"})
    out["warned"] = any(
        "not straight" in w or w.startswith("drift:") for w in res.warnings
    )  # fmt: skip
    out["bent"] = res.drift_bend is not None
    out["status"] = str(res.status)
    if c.ci90 is not None and c.p_a_faster is not None:
        lo, hi = c.ci90 if c.a == "A" else (-c.ci90[1], -c.ci90[0])
        out["lo"], out["hi"] = lo, hi
        out["p_a"] = c.p_a_faster if c.a == "A" else 1.0 - c.p_a_faster
    return out


def read(path: Path) -> list[dict]:
    if not path.exists():
        return []
    rows = []
    for line in path.read_text().splitlines():
        try:
            rows.append(json.loads(line))
        except json.JSONDecodeError:  # a line cut by a stopped run
            continue
    return rows


def cell_key(kind: str, drift: str, n: int, scatter: float) -> tuple[str, str, int, float]:
    return (kind, drift, n, round(scatter, 6))


def table(rows: list[dict], ns, scatters, drifts) -> Iterator[str]:
    by: dict[tuple, list[dict]] = {}
    for r in rows:
        by.setdefault(cell_key(r["kind"], r["drift"], r["n"], r["scatter"]), []).append(r)
    yield (f"{'drift':>8} | {'per ski':>7} | {'scatter':>7} | {'days':>4} | {'holds':>6} | "
           f"{'interval':>8} | {'wrong@95':>8} | {'claims':>6} | {'right':>6} | "
           f"{'warned':>6} | {'bent':>5}")  # fmt: skip
    pooled = {drift: [0, 0] for drift in drifts}
    for drift in drifts:
        for n in ns:
            for scatter in scatters:
                fixed = by.get(cell_key("fixed", drift, n, scatter), [])
                tail = by.get(cell_key("tail", drift, n, scatter), [])
                if not fixed and not tail:
                    continue
                m = max(len(fixed), 1)
                got = [r for r in fixed if r["lo"] is not None]
                holds = sum(r["lo"] <= r["delta"] <= r["hi"] for r in got) / max(len(got), 1)
                wrong = sum(r["p_a"] <= 0.05 for r in got) / m
                warned = sum(r["warned"] for r in fixed) / m
                bent = sum(r["bent"] for r in fixed) / m
                claims = [r for r in tail if r["p_a"] is not None and not
                          0.05 < r["p_a"] < 0.95]  # fmt: skip
                right = sum((r["p_a"] >= 0.95) == (r["delta"] < 0) for r in claims)
                right_s = f"{100 * right / len(claims):>5.1f}%" if claims else f"{'—':>6}"
                pooled[drift][0] += len(claims)
                pooled[drift][1] += right
                yield (f"{drift:>8} | {n:>7} | {scatter * 100:>6.1f}% | {len(fixed):>4} | "
                       f"{holds * 100:>5.1f}% | {len(got) / m * 100:>7.1f}% | "
                       f"{wrong * 100:>7.1f}% | {len(claims):>3}/{len(tail):<3}| {right_s} | "
                       f"{warned * 100:>5.1f}% | {bent * 100:>4.1f}%")  # fmt: skip
    for drift, (claims_n, right_n) in pooled.items():
        if claims_n:
            yield (f"{drift} drift, every cell: a ski named faster at P ≥ 0.95 on {claims_n} "
                   f"tail days, the faster one on {100 * right_n / claims_n:.1f} %")  # fmt: skip


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--days", type=int, default=200, help="fixed-Δμ days per cell")
    ap.add_argument("--tail-days", type=int, default=100, help="random-Δμ days per cell")
    ap.add_argument("--jobs", type=int, default=1, help="processes (1: this one)")
    ap.add_argument("--minutes", type=float, default=5.0, help="minutes between descents")
    ap.add_argument("--per-item", default="2,3,4,6")
    ap.add_argument("--scatter-pct", default="0.5,1.5,3")
    ap.add_argument("--drift", default="straight,bent")
    ap.add_argument("--out", default=str(ROOT / "tmp" / "compare_small_days.jsonl"))
    ap.add_argument("--report", action="store_true", help="only print the file's table")
    args = ap.parse_args()
    ns = [int(x) for x in args.per_item.split(",")]
    scatters = [float(x) / 100 for x in args.scatter_pct.split(",")]
    drifts = args.drift.split(",")
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    done = {(r["seed"], r["kind"]) for r in read(out)}
    jobs: list[Job] = []
    for drift in drifts:
        for n in ns:
            for scatter in scatters:
                for kind, days in (("fixed", args.days), ("tail", args.tail_days)):
                    for day in range(days):
                        seed = seed_of(kind, drift, n, scatter, day)
                        if (seed, kind) not in done:
                            jobs.append((kind, drift, n, scatter, seed, args.minutes))
    if not args.report and jobs:
        print(f"machine: {os.cpu_count()} cores; {len(jobs)} days to run "
              f"({len(done)} in {out}), {args.jobs} processes, a descent every "
              f"{args.minutes:g} min", flush=True)  # fmt: skip
        t0 = time.perf_counter()
        with out.open("a") as f:
            if args.jobs == 1:
                results: Iterator[dict] = map(one_day, jobs)
                pool = None
            else:
                pool = ProcessPoolExecutor(max_workers=args.jobs)
                results = pool.map(one_day, jobs, chunksize=4)
            for k, r in enumerate(results, start=1):
                f.write(json.dumps(r) + "\n")
                f.flush()
                if k % 100 == 0:
                    secs = (time.perf_counter() - t0) * args.jobs / k
                    print(f"  {k}/{len(jobs)} days, {secs:.2f} s a day", flush=True)
            if pool is not None:
                pool.shutdown()
    rows = [r for r in read(out) if r["drift"] in drifts]
    for line in table(rows, ns, scatters, drifts):
        print(line)
    print(f"binomial SD of a 90 % coverage over {args.days} days: "
          f"{100 * np.sqrt(0.09 / args.days):.1f} %")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
