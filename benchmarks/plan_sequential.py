"""Decided or not after every descent: does looking after every descent inflate wrong answers?

Days of two items in ABBA order up to the horizon (10 descents per item, 20 descents, 3 minutes
apart, drift 0.005 per hour), simulated as in benchmarks/plan_power.py
(station/simulators/days.py) and fitted by the real joint fit of `station compare` after every
descent from the fourth on (each look a fit of the descents so far); the group-sequential
rule of station/model/sequential.py decides at each look. Per posture scatter (0.5 / 1 / 2 %):

- equal skis: the share of days on which a winner is declared at any look (target ≤ 10 %),
  with its binomial 95 % upper bound, and, for contrast, how often the plain 90 % interval
  excludes 0 at some look (the naive rule of stopping when it first does); the SD of the z
  statistic Δμ̂/se over the days at the middle and last look (1 when the fit's standard error
  is right);
- Δμ = 0.001: the share of days on which the wrong ski is declared at any look (target 0), the
  share decided by the horizon, and the median descents per item at the first decision.

``--per-look`` adds, per scatter, where the equal-ski days' error goes look by look (issue 21's
diagnosis, see :func:`per_look`): α spent against declared, information times (skeleton, the
fit's 1/se², the estimates' own spread), correlations, dof, the spread of z against its t.

The fits do not depend on the rule: ``--cache FILE`` keeps every look's (Δμ̂, se, dof) so the
rule can be judged again without fitting again (the cache is keyed by setup, scatter, Δμ, day).
``--seed0`` moves the equal-ski days to other seeds. ``--variants``: remedies inside the rule
(looks only from 3, 4 or 5 descents a ski; a t at the descents' own degrees of freedom) judged
on the same looks (:func:`variants`).

Measured after the fit's Kenward-Roger correction and Satterthwaite degrees of freedom (issue
21; load 2-4, 2 processes, about 12 minutes of fits per 2000-day row): on the default seeds
(--days 2000 --days-diff 400), winners between equal skis on 9.7 / 8.9 / 10.3 % of days at 0.5
/ 1 / 2 % with the boundaries spending 9 % (10.6 / 9.8 / 11.5 % spending all 10 %), and on the
same looks 9.3 / 8.3 / 9.8 % at 8.5 %, the rule's SPEND; on fresh seeds (--seed0 400000
--days 1500 --days-diff 200) 8.1 / 8.3 / 8.9 % at 8.5 %. Δμ = 0.001: never the wrong ski, all
decided, at 2 descents per item (median). The README has the table.

Run: python benchmarks/plan_sequential.py [--days 200] [--days-diff 100] [--jobs 2]
     [--setup demo|sparse|both] [--cache FILE] [--scatter S] [--seed0 N] [--per-look]
     [--variants]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.plan_power import SETUPS, track  # noqa: E402
from station.model.compare import joint_fit  # noqa: E402
from station.model.plan import run_order  # noqa: E402
from station.model.sequential import (  # noqa: E402
    ALPHA,
    SPEND,
    decide,
    look_boundaries,
    look_fractions,
    spent,
    standard_error,
)
from station.simulators.days import DaySetup, simulate_day  # noqa: E402

HORIZON = 10
SCATTERS = (0.005, 0.01, 0.02)
MU_A = 0.0085
ORDER = "".join("AB"[i] for i in run_order(2, HORIZON))

Look = tuple[float, float, float]  # Δμ̂, se, dof


def looks_of_day(args: tuple[str, float, float, int]) -> list[Look]:
    """Every look's (Δμ̂ = μ_A − μ_B, its standard error, its degrees of freedom) of one
    simulated day, from the fourth descent on."""
    setup, delta, scatter, seed = args
    rng = np.random.default_rng(seed)
    day = DaySetup(scatter=scatter, timer_sd_s=SETUPS[setup][1])
    data = simulate_day(track(setup), ORDER, {"A": MU_A, "B": MU_A + delta}, day, rng)
    out = []
    for k in range(4, len(data) + 1):
        c = joint_fit(track(setup), data[:k]).comparisons[0]
        assert c.ci90 is not None and c.dof is not None
        # the comparison's first item is the reference, the item skied most so far: B at
        # the looks where it leads (ABBAABB)
        sign = 1.0 if c.a == "A" else -1.0
        out.append((sign * c.delta_mu, standard_error(c.ci90, c.dof), c.dof))
    return out


def judge(looks: list[Look], spend: float = SPEND) -> tuple[bool, bool, bool, int | None]:
    """(declared A faster at some look, declared B faster at some look, the naive 90 %
    interval excluded 0 at some look, descents per item at the first decision), the
    boundaries spending ``spend`` (the rule's SPEND; ALPHA for what spending it all gives)."""
    from scipy.special import stdtrit

    a_won = b_won = naive = False
    first = None
    for j, (delta, se, dof) in enumerate(looks):
        k = j + 4
        naive = naive or abs(delta) >= float(stdtrit(dof, 0.95)) * se
        d = decide("A", "B", delta, se, dof, ORDER[:k], horizon=HORIZON, spend=spend)
        if d.state == "decided":
            a_won = a_won or d.faster == "A"
            b_won = b_won or d.faster == "B"
            if first is None:
                first = (k + 1) // 2
    return a_won, b_won, naive, first


def per_look(eq_looks: list[list[Look]], draws: int = 200_000) -> list[str]:
    """Where the rule spends its error on equal-ski days, look by look (issue 21's diagnosis):
    the α the spending function allows by each look against the share of days declared by then;
    the look's information time from the skeleton (sequential.look_fractions) against the fit's
    own information (mean 1/se², as a fraction of the last look's) and the estimates' actual
    information (E Δμ̂² at the last look over that at this one), and the correlation of z with
    the last look's against √(t/t_N), the Brownian motion's; the degrees of freedom the t
    boundary uses; the SD of z = Δμ̂/se against that of the t distribution at those degrees of
    freedom (√(ν/(ν − 2)), what a right standard error gives), and the two-sided share beyond
    the t's 90 % point. Then the rule itself on Brownian motion in information time with the
    timing noise re-estimated at every look (χ² increments at the fit's degrees of freedom):
    the rule's error when the fit's z is exactly t, and when each look's z is spread by its
    measured SD over the t's; and how much more often than the t says z lies beyond its 10,
    5, 2 and 1 % two-sided points (the tails the rule's boundaries sit in)."""
    from scipy.special import ndtr, stdtrit

    fr = np.array(look_fractions(ORDER, "A", "B", HORIZON))
    c = np.array(look_boundaries(list(fr)))
    d = np.array([[x[0] for x in day] for day in eq_looks])
    se = np.array([[x[1] for x in day] for day in eq_looks])
    nu = np.array([[x[2] for x in day] for day in eq_looks])
    z = d / se
    n_days, n_looks = z.shape
    first = np.full(n_days, n_looks)
    for i, day in enumerate(eq_looks):
        for j, (delta, s, dof) in enumerate(day):
            if decide("A", "B", delta, s, dof, ORDER[: j + 4], horizon=HORIZON).state == "decided":
                first[i] = j
                break
    info_fit = np.mean(1 / se**2, axis=0)
    msq = np.mean(d**2, axis=0)
    dof = np.median(nu, axis=0)
    sd_t = np.sqrt(dof / (dof - 2))
    ratio = z.std(axis=0) / sd_t
    ct = np.array([float(stdtrit(v, 1 - ndtr(-b))) for v, b in zip(dof, c, strict=True)])
    q90 = np.array([float(stdtrit(v, 0.95)) for v in dof])
    out = [f"{'descent':>7} | {'t skeleton':>10} | {'fit 1/se²':>9} | {'E Δμ̂²':>7} | "
           f"{'corr z·z_N':>10} | {'√(t/t_N)':>8} | {'dof':>4} | {'c_k (t)':>7} | "
           f"{'α spent':>7} | {'declared':>8} | {'SD z':>5} | {'SD t':>5} | "
           f"{'|z| > t90':>9}"]  # fmt: skip
    for j in range(n_looks):
        corr = float(np.corrcoef(z[:, j], z[:, -1])[0, 1])
        out.append(
            f"{j + 4:>7} | {fr[j]:>10.3f} | {info_fit[j] / info_fit[-1]:>9.3f} | "
            f"{msq[-1] / msq[j]:>7.3f} | {corr:>10.3f} | {np.sqrt(fr[j] / fr[-1]):>8.3f} | "
            f"{dof[j]:>4.0f} | {ct[j]:>7.3f} | {spent(min(fr[j], 1.0)):>7.4f} | "
            f"{np.mean(first <= j):>8.4f} | {z[:, j].std():>5.3f} | {sd_t[j]:>5.3f} | "
            f"{np.mean(np.abs(z[:, j]) >= q90[j]):>9.3f}"
        )  # fmt: skip
    rng = np.random.default_rng(0)
    b = np.cumsum(rng.normal(size=(draws, n_looks)) * np.sqrt(np.diff(fr, prepend=0.0)), axis=1)
    chi = np.cumsum(rng.chisquare(np.diff(dof, prepend=0.0), size=(draws, n_looks)), axis=1)
    zt = b / np.sqrt(fr) / np.sqrt(chi / dof)
    exact = np.mean((np.abs(zt) >= ct).any(axis=1))
    spread = np.mean((np.abs(zt * ratio) >= ct).any(axis=1))
    days = np.mean(first < n_looks)
    tails = []
    for level in (0.10, 0.05, 0.02, 0.01):
        q = np.array([float(stdtrit(v, 1 - level / 2)) for v in dof])
        tails.append(f"{level:g}: {np.mean(np.abs(z) >= q) / level:.2f}")
    out.append("beyond the t's two-sided level, times the level (mean over the looks): "
               + ", ".join(tails))  # fmt: skip
    out.append(f"the rule on Brownian motion with the t's noise ({draws} draws): "
               f"{100 * exact:.1f} %; with each look's z spread as measured (SD z / SD t): "
               f"{100 * spread:.1f} %; on the days: {100 * days:.1f} %")  # fmt: skip
    return out


def variants(eq_looks: list[list[Look]], df_looks: list[list[Look]]) -> list[str]:
    """Remedies inside the rule, judged on the same looks (issue 21): looks only from m
    descents a ski on (the spending starting there, Lan–DeMets at the same information times),
    and a t boundary at the pair's descents − 4 degrees of freedom (items, drift and the
    skier's CdA taken from the descents) where that is fewer than the fit's."""
    from scipy.special import ndtr, stdtrit

    fr = look_fractions(ORDER, "A", "B", HORIZON)

    def judge_with(first: int, between: bool):
        idx = [j for j in range(len(fr)) if j + 4 >= 2 * first]
        c = dict(zip(idx, look_boundaries([fr[j] for j in idx]), strict=True))

        def judge_day(looks: list[Look]) -> tuple[int, int | None]:
            for j in idx:
                delta, se, dof = looks[j]
                nu = min(dof, max(j + 4 - 4, 0.5)) if between else dof
                if abs(delta) >= float(stdtrit(nu, 1 - ndtr(-c[j]))) * se:
                    return (1 if delta < 0 else -1), (j + 5) // 2
            return 0, None

        return judge_day

    out = []
    for name, first, between in [("looks from 3 a ski", 3, False), ("from 4", 4, False),
                                 ("from 5", 5, False), ("t at descents − 4", 2, True)]:  # fmt: skip
        j = judge_with(first, between)
        eq = [j(x) for x in eq_looks]
        df = [j(x) for x in df_looks]
        firsts = [f for w, f in df if f is not None]
        med = np.median(firsts) if firsts else float("nan")
        out.append(f"  {name:>20}: equal skis {100 * np.mean([w != 0 for w, _ in eq]):.1f} %; "
                   f"Δμ 0.001: wrong {sum(w == -1 for w, _ in df)}, decided "
                   f"{100 * np.mean([w == 1 for w, _ in df]):.0f} %, at {med:.1f} a ski "
                   "(median)")  # fmt: skip
    return out


def upper95(hits: int, n: int) -> float:
    """The one-sided 95 % Clopper–Pearson upper bound of a rate."""
    from scipy.special import betaincinv

    return 1.0 if hits >= n else float(betaincinv(hits + 1, n - hits, 0.95))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--days", type=int, default=200, help="simulated equal-ski days per row")
    ap.add_argument("--days-diff", type=int, default=100, help="simulated Δμ 0.001 days per row")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--setup", choices=["demo", "sparse", "both"], default="demo")
    ap.add_argument("--cache", type=Path, help="JSON file of the looks, read and extended")
    ap.add_argument("--scatter", type=float, action="append", help="only this scatter")
    ap.add_argument("--seed0", type=int, help="first seed of the equal-ski days (default per row)")
    ap.add_argument("--per-look", action="store_true",
                    help="also the equal-ski days look by look: α spent and declared, information, "
                         "dof, spread of z")  # fmt: skip
    ap.add_argument("--variants", action="store_true",
                    help="also remedies inside the rule judged on the same looks")  # fmt: skip
    args = ap.parse_args()
    setups = ["demo", "sparse"] if args.setup == "both" else [args.setup]
    cache: dict[str, list[Look]] = {}
    if args.cache is not None and args.cache.exists():
        cache = json.loads(args.cache.read_text())
    print(f"machine: {os.cpu_count()} cores; {args.days} equal-ski days and {args.days_diff} "
          f"Δμ 0.001 days per row, {args.jobs} processes; a look after every descent from the "
          f"4th, horizon {HORIZON} per item")  # fmt: skip
    print(f"binomial SD of a rate of 10 % over {args.days} days: "
          f"{100 * np.sqrt(0.09 / args.days):.1f} %")  # fmt: skip
    t_all = time.perf_counter()

    def days(pool, setup: str, delta: float, scatter: float, n: int, seed0: int):
        keys = [f"{setup}/{scatter}/{delta}/{seed0 + s}" for s in range(n)]
        todo = [k for k in keys if k not in cache]
        jobs = [(setup, delta, scatter, int(k.rsplit("/", 1)[1])) for k in todo]
        for k, looks in zip(todo, pool.map(looks_of_day, jobs, chunksize=2), strict=True):
            cache[k] = looks
        if args.cache is not None and todo:
            args.cache.write_text(json.dumps(cache))
        return [cache[k] for k in keys]

    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        for setup in setups:
            print(f"\nsetup {setup}: {len(track(setup).photocells)} photocells, timer "
                  f"{SETUPS[setup][1] * 1e3:g} ms")  # fmt: skip
            print(f"{'scatter':>7} | {'equal: winner declared':>22} | {'95 % upper':>10} | "
                  f"{'spending all 10 %':>17} | "
                  f"{'naive 90 % rule':>15} | {'SD(z) mid/last':>14} | "
                  f"{'Δμ 0.001: wrong ski':>19} | {'decided':>7} | "
                  f"{'descents/item at decision':>25}")  # fmt: skip
            for scatter in args.scatter or SCATTERS:
                seed0 = 7000 + int(scatter * 1000) * 1000
                eq0 = seed0 if args.seed0 is None else args.seed0
                eq_looks = days(pool, setup, 0.0, scatter, args.days, eq0)
                df_looks = days(pool, setup, 0.001, scatter, args.days_diff, seed0 + 500)
                eq = [judge(x) for x in eq_looks]
                df = [judge(x) for x in df_looks]
                hits = sum(a or b for a, b, _, _ in eq)
                all10 = np.mean([a or b for a, b, _, _ in (judge(x, ALPHA) for x in eq_looks)])
                declared = hits / len(eq)
                naive = np.mean([n for _, _, n, _ in eq])
                z = np.array([[d / s for d, s, _ in x] for x in eq_looks])
                sdz = f"{z[:, z.shape[1] // 2].std():.2f}/{z[:, -1].std():.2f}"
                wrong = np.mean([b for _, b, _, _ in df])
                decided = np.mean([f is not None for *_, f in df])
                firsts = [f for *_, f in df if f is not None]
                med = f"{np.median(firsts):.1f}" if firsts else "—"
                print(f"{scatter * 100:>6.1f}% | {declared * 100:>21.1f}% | "
                      f"{upper95(hits, len(eq)) * 100:>9.1f}% | {all10 * 100:>16.1f}% | "
                      f"{naive * 100:>14.1f}% | "
                      f"{sdz:>14} | {wrong * 100:>18.1f}% | {decided * 100:>6.1f}% | "
                      f"{med:>25}")  # fmt: skip
                if args.per_look:
                    print("\n".join(per_look(eq_looks)) + "\n")
                if args.variants:
                    print("\n".join(variants(eq_looks, df_looks)) + "\n")
    print(f"\n{time.perf_counter() - t_all:.0f} s in all")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
