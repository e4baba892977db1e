"""Is the season's comparison across days honest? Coverage of its 90 % intervals over many
simulated seasons, and no item declared best where it was never tested.

Stage two (station.model.season) is checked on many seasons whose days' item effects are drawn
as a day fit gives them (each day's own level, its items' μ with a correlated within-day error,
and between-day heterogeneity τ), in four designs:

- ``network``: six items, 30 days of two or three items each (connected through shared items),
  no heterogeneity;
- ``heterogeneous``: the same with τ = 0.0005 (an item's advantage differs from day to day by
  about half the items' spread);
- ``at``: the effects linear in snow temperature (each item its own slope), compared at −12 °C
  with ``--at``;
- ``few days``: eight days, τ = 0.0003 (Student t on few degrees of freedom).

Then the whole chain on fewer seasons (``end to end``): each day's descents are simulated times
on the demo run (1 % posture scatter, 0.5 ms timing noise), fitted by the day model
(station.model.compare.joint_fit), and its item μ and covariance joined across days.

Pass: each design's intervals hold the truth 88–92 % of the time. ``never near``: an item
tested only on warm days (−4 … −1 °C), best there and worst in the cold, compared at −14 °C:
it must never be declared best (P(best) ≥ 0.5) there.

Run: python benchmarks/season_coverage.py [--seasons 1000] [--e2e-seasons 60]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from station.model.season import DayEffects, compare_season  # noqa: E402

ITEMS = ("A", "B", "C", "D", "E", "F")
THETA = {"A": 0.0, "B": 0.0010, "C": -0.0005, "D": 0.0003, "E": 0.0006, "F": -0.0002}
SLOPE = {"A": 0.0, "B": 4e-5, "C": -3e-5, "D": 0.0, "E": 6e-5, "F": -2e-5}  # per °C
T0 = -8.0


def day_effects(rng, its, temp, tau, se, slope=False, name="d") -> DayEffects:
    k = len(its)
    rho = 0.5  # the day's items share its posture and drift estimate: correlated errors
    cov = se**2 * ((1 - rho) * np.eye(k) + rho * np.ones((k, k)))
    level = 0.02 + 0.0008 * temp
    truth = np.array([THETA[i] + (SLOPE[i] * (temp - T0) if slope else 0.0) for i in its])
    mu = level + truth + rng.normal(0, tau / np.sqrt(2), k) + rng.multivariate_normal(
        np.zeros(k), cov)  # fmt: skip
    return DayEffects(name, tuple(its), mu, cov, (6,) * k, {"snow_temperature_c": temp})


def season(rng, n_days, tau, slope=False):
    days = []
    for d in range(n_days):
        k = int(rng.integers(2, 4))
        its = [str(x) for x in rng.choice(ITEMS, size=k, replace=False)]
        se = float(rng.uniform(0.0002, 0.0004))
        days.append(day_effects(rng, its, float(rng.uniform(-16, -1)), tau, se, slope, f"d{d}"))
    return days


def truth(item: str, ref: str, at: float | None) -> float:
    t = THETA[item] - THETA[ref]
    if at is not None:
        t += (SLOPE[item] - SLOPE[ref]) * (at - T0)
    return t


def coverage(rng, seasons, n_days, tau, at=None) -> tuple[float, float, int, float, float]:
    """Coverage, its standard error (over seasons: a season's intervals share its reference,
    so they are not independent), intervals, mean τ̂, and mean z² (1: honest standard errors)."""
    per_season, z2, taus = [], [], []
    n = 0
    for _ in range(seasons):
        days = season(rng, n_days, tau, slope=at is not None)
        cond = {"snow_temperature_c": at} if at is not None else None
        try:
            res = compare_season(days, "A", cond, p_best_draws=0)
        except ValueError:  # A on no day with another item (few days): no comparison
            continue
        taus.append(res.tau)
        hits = []
        for it in res.items:
            if it.item == "A" or it.ci90 is None or it.delta_mu is None or not it.stderr:
                continue
            t = truth(it.item, "A", at)
            hits.append(it.ci90[0] <= t <= it.ci90[1])
            z2.append(((it.delta_mu - t) / it.stderr) ** 2)
        if hits:
            per_season.append(np.mean(hits))
            n += len(hits)
    cov = float(np.mean(per_season))
    se = float(np.std(per_season) / np.sqrt(len(per_season)))
    return cov, se, n, float(np.mean(taus)), float(np.mean(z2))


def never_near(rng, seasons) -> tuple[int, int, int]:
    """G is best on warm days only (the only days it was tested); asked at −14 °C."""
    THETA["G"], SLOPE["G"] = -0.0020, -0.0004  # at −2 °C: −0.0044 (best); at −14 °C: +0.0004
    declared = ranked = n = 0
    try:
        for _ in range(seasons):
            days = season(rng, 24, 0.0002, slope=True)
            for d in range(4):
                its = ["G", str(rng.choice(["A", "B", "C"]))]
                days.append(day_effects(rng, its, float(rng.uniform(-4, -1)), 0.0002, 0.0003,
                                        True, f"w{d}"))  # fmt: skip
            res = compare_season(days, "A", {"snow_temperature_c": -14.0})
            g = next(i for i in res.items if i.item == "G")
            n += 1
            ranked += g.p_best is not None
            declared += (g.p_best or 0.0) >= 0.5
    finally:
        del THETA["G"], SLOPE["G"]
    return declared, ranked, n


def end_to_end(rng, seasons, n_days) -> tuple[float, int]:
    from station.model.compare import DescentData, joint_fit
    from station.model.physics import Conditions, Params, StraightRun
    from station.survey.load import load_survey
    from station.survey.track import build_track

    track = build_track(load_survey(str(ROOT / "surveys" / "demo_run.yaml")))
    xs = np.array([pc.x for pc in track.photocells])
    run = StraightRun(track.profile, xs)
    cond = Conditions(88.0, 1.079)
    hits = n = 0
    for _ in range(seasons):
        days = []
        for d in range(n_days):
            its = [str(x) for x in rng.choice(ITEMS[:4], size=2, replace=False)]
            temp = float(rng.uniform(-16, -1))
            level = 0.02 + 0.0008 * temp
            offsets = {i: rng.normal(0, 0.0003 / np.sqrt(2)) for i in its}  # τ = 0.0003
            data = []
            for k, item in enumerate([its[j] for j in (0, 1, 1, 0) * 3]):
                mu = level + THETA[item] + offsets[item]
                cda = 0.22 * float(np.exp(rng.normal(0, 0.01)))
                v0 = float(rng.uniform(2.5, 4.0))
                t = run.solve(Params(cda, mu, v0), cond, sensitivities=False).t
                t = np.round(t + rng.normal(0.0, 5e-4, len(t)), 4)
                data.append(DescentData(k + 1, item, "skier", tuple(track.photocell_ids),
                                        t - t[0], 10 + 0.08 * k, 88.0, 1.079, 0.0,
                                        (0.22, mu, v0)))  # fmt: skip
            res = joint_fit(track, data)
            cov = np.array(res.item_cov)
            days.append(DayEffects(f"d{d}", tuple(i.item for i in res.items),
                                   np.array([i.mu for i in res.items]), cov,
                                   tuple(len(i.descents) for i in res.items),
                                   {"snow_temperature_c": temp}))  # fmt: skip
        try:
            out = compare_season(days, "A")
        except ValueError:
            continue
        for it in out.items:
            if it.item == "A" or it.ci90 is None:
                continue
            n += 1
            hits += it.ci90[0] <= truth(it.item, "A", None) <= it.ci90[1]
    return hits / max(n, 1), n


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seasons", type=int, default=1000)
    ap.add_argument("--e2e-seasons", type=int, default=60)
    args = ap.parse_args()
    rng = np.random.default_rng(2026)
    ok = True
    print(f"{'design':<15}{'seasons':>8}{'days':>6}{'true τ':>9}{'mean τ̂':>9}{'intervals':>10}"
          f"{'coverage':>10}{'± se':>7}{'z²':>6}{'time s':>8}")  # fmt: skip
    for name, n_days, tau, at in (
        ("network", 30, 0.0, None),
        ("heterogeneous", 30, 0.0005, None),
        ("at -12 °C", 30, 0.0003, -12.0),
        ("few days", 8, 0.0003, None),
    ):
        t = time.perf_counter()
        cov, se, n, mean_tau, z2 = coverage(rng, args.seasons, n_days, tau, at)
        good = 0.88 <= cov <= 0.92
        ok &= good
        print(f"{name:<15}{args.seasons:>8}{n_days:>6}{tau:>9.4f}{mean_tau:>9.5f}{n:>10}"
              f"{cov:>10.3f}{se:>7.3f}{z2:>6.2f}{time.perf_counter() - t:>8.1f}"
              f"{'' if good else '  OUTSIDE 88-92 %'}")  # fmt: skip
    if args.e2e_seasons:
        t = time.perf_counter()
        cov, n = end_to_end(rng, args.e2e_seasons, 10)
        print(
            f"{'end to end':<15}{args.e2e_seasons:>8}{10:>6}{0.0003:>9.4f}{'':>9}{n:>10}"
            f"{cov:>10.3f}{time.perf_counter() - t:>8.1f}  (day fits of simulated times)"
        )
    declared, ranked, n = never_near(rng, max(args.seasons // 5, 50))
    print(
        f"never near: an item tested only at -4 … -1 °C, asked at -14 °C: ranked in {ranked} "
        f"of {n} seasons, declared best (P(best) >= 0.5) in {declared}"
    )
    ok &= declared == 0
    print("PASS" if ok else "FAIL")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
