"""Do the 90 % intervals that carry the survey hold the truth 90 % of the time?

Each draw re-surveys the simulated run (station/simulators/survey_sim.py: a 1.5" total station from
three setups, centre-line points every ``--spacing`` m with ``--roughness`` of snow, both posts
of every photocell 5 mm off along the run, i.e. as precise as the survey YAML declares), builds
the track, simulates one descent on the *true* profile at the *true* photocells with
``--noise-ms`` of timing noise on every crossing, and fits it with the surveyed track. It counts
how often the total interval (timing + survey) and the timing-only interval hold the true μ,
CdA and v0, and prints the survey's mean share of the variance and the fit statuses.

Binomial standard error of a coverage from N draws: √(0.09/N), 1.9 % at N = 250.

Run: python benchmarks/survey_coverage.py [--draws N] [--spacing M] [--roughness M]
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from station.model.fit import fit_descent  # noqa: E402
from station.model.physics import Conditions, Params, StraightRun  # noqa: E402
from station.model.track_error import survey_error  # noqa: E402
from station.simulators.survey_sim import TrueRun, write_demo  # noqa: E402
from station.survey.load import load_survey  # noqa: E402
from station.survey.track import build_track  # noqa: E402

NAMES = ("mu", "cda", "v0")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=250)
    ap.add_argument("--spacing", type=float, default=5.0)
    ap.add_argument("--roughness", type=float, default=0.015)
    ap.add_argument("--noise-ms", type=float, default=0.3)
    ap.add_argument("--seed", type=int, default=2026)
    args = ap.parse_args(argv)

    run = TrueRun()
    cond = Conditions(88.0, 1.04)
    truth = Params(0.22, 0.0085, 3.4)
    t_true = StraightRun(run.profile(), run.cell_x).solve(truth, cond, sensitivities=False).t
    rng = np.random.default_rng(args.seed)
    hits_total: Counter[str] = Counter()
    hits_timing: Counter[str] = Counter()
    shares: dict[str, list[float]] = {k: [] for k in NAMES}
    mu_err: list[float] = []
    statuses: Counter[str] = Counter()
    refused = 0
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.draws):
            _, yaml_path = write_demo(
                tmp,
                seed=args.seed * 1000 + i,
                stem="draw",
                spacing=args.spacing,
                roughness=args.roughness,
                post_sd=0.005,
            )
            try:
                track = build_track(load_survey(yaml_path))
            except Exception:  # noqa: BLE001 - a refused survey is a result here
                refused += 1
                continue
            ids = track.photocell_ids
            xs = np.array([pc.x for pc in track.photocells])
            t = t_true + rng.normal(0.0, args.noise_ms * 1e-3, len(t_true))
            fit = fit_descent(track.profile, xs, t, cond, ids, survey=survey_error(track, ids))
            statuses[fit.status] += 1
            if not fit.survey_in_intervals:
                continue
            mu_err.append(float(fit.mu.value or math.nan) - truth.mu)
            for k in NAMES:
                value = getattr(truth, k)
                est = getattr(fit, k)
                ci, ct = est.ci90, est.ci90_timing
                hits_total[k] += bool(ci and ci[0] <= value <= ci[1])
                hits_timing[k] += bool(ct and ct[0] <= value <= ct[1])
                shares[k].append(est.survey_share or 0.0)
    n = len(mu_err)
    elapsed = time.perf_counter() - start
    print(
        f"survey coverage: {args.draws} re-surveys ({n} fitted, {refused} refused), points every "
        f"{args.spacing:g} m with {args.roughness * 1000:g} mm roughness, timing noise "
        f"{args.noise_ms:g} ms, {elapsed:.0f} s"
    )
    print(f"{'':<6}{'total 90 % CI':>15}{'timing only':>13}{'survey share':>14}")
    for k in NAMES:
        print(
            f"{k:<6}{hits_total[k] / n:>14.1%} {hits_timing[k] / n:>12.1%}"
            f"{np.mean(shares[k]):>13.0%}"
        )
    se = math.sqrt(0.09 / n)
    print(f"binomial standard error of a 90 % coverage: {se:.1%}")
    print(
        f"μ error: mean {np.mean(mu_err):+.2e}, sd {np.std(mu_err):.2e}; statuses: "
        + ", ".join(f"{s} {c}" for s, c in sorted(statuses.items()))
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
