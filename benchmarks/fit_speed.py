"""Fit speed: station's fit against the straightforward way, on the same descents.

The straightforward way (numerics.md): the Cartesian DAE integrated by scipy's ``solve_ivp`` at
its default tolerances, the photocell times by event location, and ``least_squares`` with a
finite-difference Jacobian, bounded, from the same start as ours. Both fit the same model: the
physical parameters and a time offset at the first photocell (its time is data with noise).

For each case it prints the median time per fit, the ratio, whether each fit reached the
minimum (its parameters re-evaluated with an accurate model give Σ within 1 % of the best Σ,
and μ within a tenth of its 90 % half-width), and how well station's computed times agree
with the independent DAE at rtol 1e-12.

Run: python benchmarks/fit_speed.py [--repeats N]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))  # the independent DAE reference lives with the tests

from reference_dae import simulate_dae  # noqa: E402

from station.model.fit import fit_descent, initial_guess  # noqa: E402
from station.model.physics import Conditions, Params, StraightRun  # noqa: E402
from station.survey.load import load_survey  # noqa: E402
from station.survey.track import build_track  # noqa: E402

#: the straightforward way at scipy's defaults, and at the tolerance where it can converge
VARIANTS = {
    "solve_ivp defaults (RK45, rtol 1e-3)": {"rtol": 1e-3, "atol": 1e-6, "method": "RK45"},
    "solve_ivp DOP853, rtol 1e-10": {"rtol": 1e-10, "atol": 1e-10, "method": "DOP853"},
}


def straightforward_fit(profile, xs, t, cond, x0, n_params, tol):
    def fun(p):
        par = Params(*p[:3], mu1=p[3] if n_params == 4 else 0.0)
        r = simulate_dae(profile, xs, par, cond, **tol)
        tt = np.nan_to_num(r.t, nan=1e3)
        return tt + p[-1] - (t - t[0])

    upper = np.array([5.0, 1.0, 60.0, 0.05])[:n_params]
    lower = np.append(np.zeros(n_params), -1.0)
    upper = np.append(upper, 1.0)
    return least_squares(fun, np.append(x0, 0.0), bounds=(lower, upper), method="trf")


def case(name, track, xs, truth, cond, model, noise_s, repeats, slow_repeats, station_only=False):
    n_params = 4 if model == "velocity" else 3
    prof = track.profile
    run = StraightRun(prof, xs)
    rng = np.random.default_rng(42)
    t = run.solve(truth, cond, n_params=n_params, sensitivities=False).t
    t = t + rng.normal(0.0, noise_s, len(t))

    times, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        res = fit_descent(prof, xs, t, cond, model=model)  # grid built inside: the full cost
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    ours = statistics.median(times)
    ours_cpu = statistics.median(cpu)
    p_best = np.array([e.value for _, e in res.parameters()])  # cda, mu, v0, [mu1], dt0
    solves = res.nfev

    x0 = initial_guess(run, t - t[0], cond, n_params)
    slow = {}
    for label, tol in ({} if station_only else VARIANTS).items():
        slow_times = []
        for _ in range(slow_repeats):
            t0 = time.perf_counter()
            sres = straightforward_fit(prof, xs, t, cond, x0, n_params, tol)
            slow_times.append(time.perf_counter() - t0)
        slow[label] = (statistics.median(slow_times), sres)

    def sigma(p):
        par = Params(*p[:3], mu1=p[3] if n_params == 4 else 0.0)
        d = run.solve(par, cond, n_params=n_params, sensitivities=False)
        r = d.t + p[-1] - (t - t[0])
        return float(r @ r)

    s_best = sigma(p_best)
    half_mu = res.mu.ci90[1] - res.mu.value

    def reached(p):
        return sigma(p) <= 1.01 * s_best and abs(p[1] - p_best[1]) <= 0.1 * half_mu

    par = Params(*p_best[:3], mu1=p_best[3] if n_params == 4 else 0.0)
    ref = simulate_dae(prof, xs, par, cond)
    ours_t = run.solve(par, cond, n_params=n_params, sensitivities=False).t
    agree = float(np.max(np.abs(ours_t - ref.t)))

    print(f"\n{name}: {len(xs)} photocells, {model} model, {n_params} parameters")
    print(f"  station fit          median {ours * 1e3:8.2f} ms over {repeats} fits "
          f"(fastest {min(times) * 1e3:.2f} ms; median CPU time {ours_cpu * 1e3:.2f} ms: "
          f"on a shared machine these are distorted least), "
          f"{solves} model solves, status {res.status}, "
          f"reached minimum: {reached(p_best)}")  # fmt: skip
    for label, (secs, sres) in slow.items():
        print(f"  straightforward, {label}: median {secs * 1e3:8.1f} ms over {slow_repeats} "
              f"fits, reached minimum: {reached(sres.x)} (μ {sres.x[1]:.6f} vs {p_best[1]:.6f}, "
              f"Σ {sigma(sres.x):.3e} vs {s_best:.3e} s²); "
              f"station is {secs / ours:.0f}× faster")  # fmt: skip
    print(f"  times vs DAE (rtol 1e-12): max |Δt| = {agree:.2e} s")
    return ours, slow, agree


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--slow-repeats", type=int, default=1)
    ap.add_argument("--station-only", action="store_true", help="skip the straightforward fits")
    args = ap.parse_args()
    track = build_track(load_survey(str(ROOT / "surveys" / "demo_run.yaml")))
    cond = Conditions(88.0, 1.04)
    print(f"machine: {os.cpu_count()} cores; numpy {np.__version__}")
    xs9 = np.array([pc.x for pc in track.photocells])
    case(
        "9-photocell descent (demo run)",
        track,
        xs9,
        Params(0.22, 0.0085, 3.4),
        cond,
        "constant",
        1e-4,
        args.repeats,
        args.slow_repeats,
        args.station_only,
    )
    xs20 = np.linspace(xs9[0], xs9[-1], 20)
    case(
        "20-photocell descent with velocity-dependent friction",
        track,
        xs20,
        Params(0.22, 0.0081, 3.1, mu1=8.3e-5),
        cond,
        "velocity",
        1e-4,
        args.repeats,
        args.slow_repeats,
        args.station_only,
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
