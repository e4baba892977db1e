"""``station plan``: how many descents per item resolve a difference, in which order, how long.

The computation is :mod:`station.model.plan` (the day model of ``station compare``); this module
reads the options, takes the posture scatter from a past session when asked, and prints."""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any

from station.cli.common import (
    _add_air,
    _add_gravity,
    _density,
    _load_track,
    _nonnegative,
    _number,
    _positive,
    _print_json,
    plausible,
)
from station.errors import InputError


def _fraction(text: str) -> float:
    value = _nonnegative(text)
    if value >= 0.5:
        raise argparse.ArgumentTypeError(
            f"{text!r} is a fraction of CdA (0.015 = 1.5 %), less than 0.5"
        )
    return value


def _power(text: str) -> float:
    value = _number(text)
    if not 0.5 <= value < 1.0:
        raise argparse.ArgumentTypeError(f"must lie between 0.5 and 1 (e.g. 0.9), got {text!r}")
    return value


def _items(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number, got {text!r}") from None
    if not 2 <= value <= 12:
        raise argparse.ArgumentTypeError(f"a day compares 2 to 12 items, got {text!r}")
    return value


def _past_day(args: argparse.Namespace) -> Any:
    """The past session's :class:`station.model.plan.PastDay`, from its joint fit."""
    from station.cli.console import replayed
    from station.model.plan import PastDay
    from station.session.recorded import RecordedSession

    session = replayed(RecordedSession(args.from_session))
    day = session.compare(timer_sd_s=args.timer_ms / 1000.0)
    if day.result is None:
        raise InputError(f"--from: {day.error}", path=args.from_session)
    try:
        return PastDay.of(day.result, [d.air_density for d in day.compared])
    except ValueError as exc:
        raise InputError(f"--from: {exc}: give --posture-scatter", path=args.from_session) from None


def _given(args: argparse.Namespace, air_given: bool) -> set[str]:
    """The assumptions the options give (a past session's do not replace them)."""
    flags = {"posture_sd": args.posture_scatter is not None, "air_density": air_given,
             "drift_per_hour": args.drift_per_hour_given, "cda": args.cda_given,
             "v0": args.v0_given, "mu": args.mu_given}  # fmt: skip
    return {name for name, flag in flags.items() if flag}


def cmd_plan(args: argparse.Namespace) -> int:
    from station.model.physics import gravity_for
    from station.model.plan import DayAssumptions, Source, delta_mu_of_ms, plan_day, prior

    track = _load_track(args.survey)
    if len(track.photocells) < 3:
        raise InputError("a plan needs at least three photocells", path=args.survey)
    air_given = args.air_density is not None or any(
        v is not None for v in (args.pressure_hpa, args.temperature_c, args.humidity_pct)
    )
    # without air options a past session's air is taken (and no assumed air is warned of)
    rho = _density(args) if air_given or args.from_session is None else math.nan
    g = gravity_for(track, args.gravity).value
    if args.from_session is None and args.posture_scatter is None:
        raise InputError("give the posture scatter (--posture-scatter) or a past session (--from)")
    past = _past_day(args) if args.from_session is not None else None
    # what the options say (NaN: not given, so the past session's is taken)
    stated = DayAssumptions(
        mass_kg=args.mass,
        air_density=rho,
        cda=args.cda,
        v0=args.v0,
        mu=args.mu,
        timer_sd_s=args.timer_ms / 1000.0,
        posture_sd=math.nan if args.posture_scatter is None else args.posture_scatter,
        drift_per_hour=args.drift_per_hour,
        minutes_between=args.minutes_between,
        g=g,
    )
    pri = prior(stated, _given(args, air_given), past)
    a = pri.assumptions
    if pri.posture is Source.DEFAULT and pri.past is not None:
        print(f"warning: --from {args.from_session}: the session's posture scatter is estimated "
              f"at {pri.past.posture_sd * 100:.2f} % and its descents say too little about it; "
              f"planning with {a.posture_sd * 100:.1f} % (give --posture-scatter for another)",
              file=sys.stderr)  # fmt: skip
    source, drift_source = _sources(pri, args.from_session)
    try:
        delta = args.delta_mu if args.delta_mu is not None else delta_mu_of_ms(
            track, args.delta_ms, a
        )  # fmt: skip
        plan = plan_day(track, delta, a, n_items=args.items, target_power=args.power)
    except ValueError as exc:
        raise InputError(str(exc), path=args.survey) from None
    if args.json:
        out = plan.to_dict()
        out["assumptions"]["posture_source"] = source
        out["assumptions"]["drift_source"] = drift_source
        if args.delta_ms is not None:
            out["assumptions"]["delta_ms"] = args.delta_ms
        _print_json(out)
        return 0
    print(format_plan(plan, source, args.delta_ms, drift_source))
    if not plan.reached:
        print(
            f"warning: {plan.target_power * 100:.0f} % power is out of reach within "
            f"{plan.descents_per_item} descents per item; more photocells, a steadier tuck or a "
            "larger difference",
            file=sys.stderr,
        )
    return 0


def _sources(pri: Any, session: str | None) -> tuple[str, str]:
    """The words for where the posture scatter and the drift of a plan came from."""
    from station.model.plan import Source

    past = pri.past
    if pri.posture is Source.PAST:
        ci = past.posture_ci90
        posture = (f"estimated from {session} ({past.descents} descents, 90 % CI "
                   f"[{ci[0] * 100:.2f}, {ci[1] * 100:.2f}] %)")  # fmt: skip
    elif pri.posture is Source.DEFAULT:
        posture = (f"the default: {session}'s {past.descents} descents put it at "
                   f"{past.posture_sd * 100:.2f} % with no interval")  # fmt: skip
    else:
        posture = "given"
    drift = f"estimated from {session}" if pri.drift is Source.PAST else str(pri.drift)
    return posture, drift


def format_plan(
    plan: Any, posture_source: str, delta_ms: float | None, drift_source: str = "given"
) -> str:
    a = plan.assumptions
    n = plan.descents_per_item
    ms = f" ({delta_ms:g} ms over the run)" if delta_ms is not None else ""
    reach = "" if plan.reached else " OUT OF REACH; the largest day considered gives"
    lines = [
        f"to resolve Δμ {plan.delta_mu:.5f}{ms} between {len(plan.items)} items with "
        f"{plan.target_power * 100:.0f} % power (90 % intervals):{reach}",
        f"  {n} descents per item, {len(plan.order)} in all, in this order: {plan.order}",
        f"  about {plan.minutes:.0f} minutes at {a.minutes_between:g} minutes between descents",
        f"  power {plan.power:.3f}; expected 90 % interval of Δμ ±{plan.halfwidth_mu:.5f}",
    ]
    if n - 1 in plan.power_by_n:
        lines.append(f"  ({n - 1} descents per item: power {plan.power_by_n[n - 1]:.3f})")
    if plan.power_watched is not None:
        lines.append(
            f"  watched after every descent (station compare --horizon {n}): power "
            f"{plan.power_watched:.3f}, and the day may end early"
        )
    lines.append(
        f"assumed: {a.mass_kg:g} kg, air {a.air_density:.3f} kg/m³, CdA {a.cda:.3f} m², "
        f"v0 {a.v0:.1f} m/s, μ {a.mu:.4f}, timer {a.timer_sd_s * 1e3:.2f} ms, posture scatter "
        f"{a.posture_sd * 100:.2f} % ({posture_source}), drift {a.drift_per_hour:.4g} per hour"
        + ("" if drift_source in ("given", "default") else f" ({drift_source})")
    )
    return "\n".join(lines)


class _Given(argparse.Action):
    """Store the value and note that the user gave it (so --from does not override it)."""

    def __call__(self, parser: Any, namespace: Any, values: Any, option_string: Any = None):
        setattr(namespace, self.dest, values)
        setattr(namespace, f"{self.dest}_given", True)


def add_parsers(sub: Any) -> None:
    p = sub.add_parser(
        "plan", help="how many descents per item resolve a difference, in which order, how long"
    )
    p.add_argument(
        "--survey", required=True, help="survey YAML with the photocells (surveys/README.md)"
    )
    p.add_argument("--mass", type=plausible("mass_kg"), required=True, metavar="KG",
                   help="skier with equipment, kg")  # fmt: skip
    d = p.add_mutually_exclusive_group(required=True)
    d.add_argument("--delta-mu", type=_positive, metavar="DMU",
                   help="the difference of μ to resolve, e.g. 0.001")  # fmt: skip
    d.add_argument("--delta-ms", type=_positive, metavar="MS",
                   help="the difference to resolve as time over the run (first to last "
                        "photocell), ms")  # fmt: skip
    p.add_argument("--posture-scatter", type=_fraction, metavar="FRAC",
                   help="SD of the drag area between descents, a fraction (0.015 = 1.5 %%); "
                        "with --from it wins over the session's")  # fmt: skip
    p.add_argument("--from", dest="from_session", metavar="SESSION",
                   help="take the posture scatter, the drift (and CdA, v0, μ) from a past "
                        "session's joint fit; a scatter the session put at 0 falls back to "
                        # station.model.plan.DEFAULT_POSTURE: not imported here, where every
                        # command's parser is built (it loads numpy and scipy)
                        "1 %% with a warning")  # fmt: skip
    p.add_argument("--power", type=_power, default=0.9,
                   help="probability that the day's 90 %% interval excludes 0 "
                        "(default 0.9)")  # fmt: skip
    p.add_argument("--items", type=_items, default=2, help="skis or waxes to compare (default 2)")
    p.add_argument("--timer-ms", type=_positive, default=0.5, metavar="MS",
                   help="the timer's precision, SD of one time in ms (default 0.5)")  # fmt: skip
    p.add_argument("--drift-per-hour", type=_number, default=0.0, metavar="DMU",
                   action=_Given, help="expected drift of μ per hour (the fit estimates it; "
                                       "default 0, or the session's with --from)")  # fmt: skip
    p.add_argument("--minutes-between", type=_positive, default=3.0, metavar="MIN",
                   help="from one descent's start to the next (default 3)")  # fmt: skip
    p.add_argument("--cda", type=_positive, default=0.22, metavar="M2", action=_Given,
                   help="the skier's drag area, m² (default 0.22)")  # fmt: skip
    p.add_argument("--v0", type=_positive, default=3.5, metavar="M_S", action=_Given,
                   help="typical speed at the first photocell, m/s (default 3.5)")  # fmt: skip
    p.add_argument("--mu", type=_positive, default=0.01, action=_Given,
                   help="typical μ of the items (default 0.01)")  # fmt: skip
    p.add_argument("--json", action="store_true", help="machine-readable output")
    _add_air(p)
    _add_gravity(p)
    p.set_defaults(func=cmd_plan, cda_given=False, v0_given=False, mu_given=False,
                   drift_per_hour_given=False)  # fmt: skip
