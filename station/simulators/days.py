"""Simulated test days for the studies of planning and deciding (benchmarks/plan_*.py and the
slow tests): the times a day's descents give under the day model, as ``station compare`` sees
them after the single fits.

Each descent: the item's μ plus a linear drift over the day, centred on the day's middle (the
item's μ is its μ at mid-day, as ``station compare`` reports it and ``station plan`` assumes
it: a drift counted from the first descent put the simulated day at a higher μ than the plan,
where the times say more about μ, and simulated days resolved more than the plan promised,
0.95 against 0.91 at Δμ 0.0005, 1 % scatter on four photocells), the skier's drag area times
exp(u) with u ~ N(0, scatter²) (the posture), v0 uniform in ``v0_range``, the timer's noise on
every photocell (the first too) and the times rounded to 0.1 ms as the timer does. Every
descent is fitted on its own first, the start of the joint fit, as ``station compare`` does.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from station.model.compare import DescentData
from station.model.fit import fit_descent
from station.model.physics import Conditions, Params, StraightRun
from station.survey.track import Track


@dataclass(frozen=True)
class DaySetup:
    mass_kg: float = 88.0
    air_density: float = 1.079
    cda: float = 0.22
    scatter: float = 0.01
    timer_sd_s: float = 5e-4
    #: 0.005 per hour keeps μ above 0 over a two-hour day at μ 0.0085 (0.02 did not)
    drift_per_hour: float = 0.005
    minutes_between: float = 3.0
    v0_range: tuple[float, float] = (2.5, 4.5)


def simulate_day(
    track: Track,
    items: Sequence[str],
    mus: dict[str, float],
    setup: DaySetup,
    rng: np.random.Generator,
) -> list[DescentData]:
    """One day's descents, ``items[k]`` the item of descent k + 1."""
    xs = np.array([pc.x for pc in track.photocells])
    run = StraightRun(track.profile, xs)
    cond = Conditions(setup.mass_kg, setup.air_density)
    step_h = setup.minutes_between / 60.0
    middle = (len(items) - 1) / 2.0
    out = []
    for k, item in enumerate(items):
        mu = mus[item] + setup.drift_per_hour * (k - middle) * step_h
        cda = setup.cda * float(np.exp(rng.normal(0.0, setup.scatter)))
        v0 = rng.uniform(*setup.v0_range)
        t = run.solve(Params(cda, mu, v0), cond, sensitivities=False).t
        t = np.round(36000.0 + t + rng.normal(0.0, setup.timer_sd_s, len(t)), 4)
        f = fit_descent(track.profile, xs, t, cond, run=run)
        guess = (f.cda.value or 0.25, f.mu.value or 0.02, f.v0.value or 3.0)
        out.append(
            DescentData(
                number=k + 1,
                item=item,
                group="skier",
                photocells=tuple(track.photocell_ids),
                times_s=t - t[0],
                start_hours=10.0 + k * step_h,
                mass_kg=setup.mass_kg,
                air_density=setup.air_density,
                wind_ms=0.0,
                start_guess=(float(guess[0]), float(guess[1]), float(guess[2])),
            )
        )
    return out
