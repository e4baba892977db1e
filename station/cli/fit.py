"""``station simulate``, ``fit`` and ``fit-traverse``: one descent simulated on the surveyed track
or fitted to its times, and a traverse fitted to its positions."""

from __future__ import annotations

import argparse
import math
from typing import TYPE_CHECKING, Any

from station.cli.common import (
    _add_air,
    _add_gravity,
    _density,
    _fmt,
    _gravity_ms2,
    _load_track,
    _nonnegative,
    _number,
    _positive,
    _print_json,
    _warn,
    add_timer_option,
    open_output,
    output_path,
    plausible,
)
from station.errors import InputError
from station.model.timer import TIMER_PRECISION_S

if TYPE_CHECKING:  # the survey modules import numpy and scipy: loaded when a command runs
    from station.model.estimate import Estimate
    from station.model.fit_result import FitResult
    from station.model.physics import Gravity
    from station.survey.track import Track


def cmd_simulate(args: argparse.Namespace) -> int:
    import numpy as np

    from station.model.physics import Conditions, Params, StraightRun, gravity_for

    output_path(args.csv, "--csv")
    track = _load_track(args.survey)
    if len(track.photocells) < 2:
        raise InputError("the survey needs at least two photocells", path=args.survey)
    rho = _density(args)
    grav = gravity_for(track, args.gravity)
    xs = np.array([pc.x for pc in track.photocells])
    run = StraightRun(track.profile, xs)
    cond = Conditions(mass_kg=args.mass, air_density=rho, wind_ms=args.wind_ms, g=grav.value)
    d = run.solve(Params(args.cda, args.mu, args.v0, args.mu1), cond, sensitivities=False)
    t = d.t.copy()
    if args.noise_ms:
        rng = np.random.default_rng(args.seed)
        t[1:] += rng.normal(0.0, args.noise_ms * 1e-3, len(t) - 1)
    reached = np.isfinite(t)
    if d.stopped_x is not None:
        reached = xs < d.stopped_x
    if args.csv:
        from station import csvfiles

        with open_output(args.csv, "--csv") as fh:
            w = csvfiles.writer(fh)
            w.writerow(["photocell", "time"])
            for pc, ti, ok in zip(track.photocells, t, reached, strict=True):
                if ok:
                    w.writerow([pc.id, f"{args.start_s + ti:.4f}"])
    status = "ok"
    if d.liftoff_x is not None:
        status = "lift-off"
    elif d.stopped_x is not None:
        status = "stopped"
    if args.json:
        _print_json(
            {
                "photocells": [
                    {
                        "id": pc.id,
                        "x": pc.x,
                        "t": float(ti) if ok else None,
                        "v": float(vi) if ok else None,
                    }
                    for pc, ti, vi, ok in zip(track.photocells, t, d.v, reached, strict=True)
                ],
                "min_normal_force_n": d.min_normal_force_n,
                "air_density": rho,
                "gravity_ms2": grav.value,
                "gravity_source": grav.source,
                "status": status,
                "liftoff_x": d.liftoff_x,
                "stopped_x": d.stopped_x,
            }
        )
    else:
        print(
            f"simulate  {track.name}: m {args.mass:g} kg, CdA {args.cda:g} m², μ {args.mu:g}"
            + (f", μ1 {args.mu1:g} s/m" if args.mu1 else "")
            + f", v0 {args.v0:g} m/s, ρ {rho:.3f} kg/m³"
            + (f", wind {args.wind_ms:+g} m/s" if args.wind_ms else "")
            + (f", timing noise {args.noise_ms:g} ms (seed {args.seed})" if args.noise_ms else "")
        )
        print(f"          {grav.describe()}")
        print(f"{'photocell':<10}{'x [m]':>9}{'t [s]':>11}{'v [m/s]':>10}{'v [km/h]':>10}")
        for pc, ti, vi, ok in zip(track.photocells, t, d.v, reached, strict=True):
            if ok:
                print(f"{pc.id:<10}{pc.x:>9.2f}{ti:>11.4f}{vi:>10.2f}{vi * 3.6:>10.1f}")
            else:
                print(f"{pc.id:<10}{pc.x:>9.2f}{'not reached':>21}")
        print(f"minimum normal force {d.min_normal_force_n:.0f} N")
        if d.liftoff_x is not None:
            _warn(f"lift-off: the normal force reaches 0 at x = {d.liftoff_x:.1f} m")
        if d.stopped_x is not None:
            _warn(f"the skier stops at x = {d.stopped_x:.1f} m, before the last photocell")
    return 0


def cmd_fit(args: argparse.Namespace) -> int:
    import numpy as np

    from station.model.fit import fit_descent
    from station.model.physics import Conditions, gravity_for
    from station.model.track_error import survey_error
    from station.timing.timesfile import read_times

    track = _load_track(args.survey)
    times = read_times(args.times, track.photocell_ids)
    rho = _density(args)
    xs = np.array([track.photocell(p).x for p in times.photocells])
    grav = gravity_for(track, args.gravity)
    cond = Conditions(mass_kg=args.mass, air_density=rho, wind_ms=args.wind_ms, g=grav.value)
    res = fit_descent(
        track.profile,
        xs,
        np.array(times.times),
        cond,
        times.photocells,
        args.model,
        timer_precision_s=args.timer_ms * 1e-3,
        survey=None if args.timing_only else survey_error(track, times.photocells),
    )
    missing = [p for p in track.photocell_ids if p not in times.photocells]
    if args.json:
        out = res.to_dict()
        out.update({"missing": missing, "air_density": rho, "mass_kg": args.mass})
        out.update({"gravity_ms2": grav.value, "gravity_source": grav.source})
        out["warnings"] = track.warnings
        _print_json(out)
        return 0
    _print_fit(args, track, times.photocells, res, grav.describe(), rho, missing)
    return 0


def _print_fit(
    args: argparse.Namespace,
    track: Track,
    photocells: list[str],
    res: FitResult,
    gravity: str,
    rho: float,
    missing: list[str],
) -> None:
    """``station fit``'s text: what was fitted, the estimates with their intervals, the
    goodness of fit and the residual at every photocell."""
    from station.model.fit_result import CI_METHOD

    print(
        f"fit     {track.name}, {args.times}: {len(photocells)} photocells"
        + (f" (missing {', '.join(missing)})" if missing else "")
        + f", {args.model} model, m {args.mass:g} kg, ρ {rho:.3f} kg/m³"
        + (f", wind {args.wind_ms:+g} m/s" if args.wind_ms else "")
    )
    print(f"        {gravity}")
    print(f"status  {res.status}" + (f": {res.message}" if res.message else ""))

    def line(label: str, est: Estimate | None, unit: str, spec: str) -> None:
        if est is None:  # not a parameter of this model, or not fitted
            return
        c = est.ci90
        rng = f"[{format(c[0], spec)}, {format(c[1], spec)}]" if c else "—"
        extra = ""
        if res.survey_in_intervals and c:
            ct, share = est.ci90_timing, est.survey_share
            if ct:
                extra = f"   timing only [{format(ct[0], spec)}, {format(ct[1], spec)}]"
            if share is not None:
                extra += f", survey {share * 100:.0f} % of the variance"
        print(f"  {label:<5}{_fmt(est.value, spec):>10} {unit:<5} 90 % CI {rng}{extra}")

    line("μ", res.mu, "", ".5f")
    line("μ1", res.mu1, "s/m", ".2e")
    if res.mu1 is not None and res.mu1.consistent_with_zero:
        print("        μ1 is not distinguishable from 0: its 90 % interval includes 0")
    line("CdA", res.cda, "m²", ".4f")
    line("v0", res.v0, "m/s", ".3f")
    line("δt1", res.dt0, "s", "+.5f")  # the first photocell's time is data: its fitted offset
    if res.sigma_s2 is not None:
        corr = _fmt(res.corr_mu_cda, "+.3f")
        print(
            f"  corr(μ, CdA) {corr}   Σ {res.sigma_s2:.3e} s²   gᵀg {res.grad_norm2:.2e}   "
            f"dof {res.dof}   v0 at {res.photocells[0]}"
        )
        print(f"  intervals: {CI_METHOD}")
        if res.survey_in_intervals:
            print(
                "  the 90 % CI carries the survey (profile spline and photocell positions, "
                "linearised); 'timing only' leaves it out"
            )
        elif not args.timing_only:
            print("  the survey's uncertainty is not in these intervals (no profile uncertainty)")
        if res.chi2_p is not None:
            print(
                f"  goodness of fit: χ² {res.chi2:.1f} on {res.dof} dof against a timer "
                f"precision of {args.timer_ms:g} ms, p = {res.chi2_p:.2g}"
            )
        print(f"{'photocell':<10}{'residual [ms]':>15}{'v [m/s]':>10}")
        for pid, r in res.residuals_s.items():
            print(f"{pid:<10}{r * 1000:>15.3f}{res.speeds_ms.get(pid, float('nan')):>10.2f}")
    for w in track.warnings:
        _warn(w)


def cmd_fit_traverse(args: argparse.Namespace) -> int:
    from station.model.traverse import fit_traverse, read_traverse_data

    t, s = read_traverse_data(args.data)
    grav = _traverse_gravity(args)  # before the air: a refused site says nothing else first
    rho = _density(args)
    if args.traverse_deg is not None:
        beta = args.traverse_deg
        given = f"traverse {beta:g}° from the fall line"
    else:
        beta = 90.0 - args.traverse_from_horizontal_deg
        given = (
            f"traverse {beta:g}° from the fall line "
            f"(given as {args.traverse_from_horizontal_deg:g}° from the horizontal)"
        )
    res = fit_traverse(t, s, args.slope_deg, beta, args.mass, rho, grav.value)
    if args.json:
        out = res.to_dict()
        out.update({"air_density": rho, "mass_kg": args.mass, "gravity_ms2": grav.value,
                    "gravity_source": grav.source})  # fmt: skip
        out.update(
            {
                "traverse_from_fall_line_deg": beta,
                "traverse_given_as": (
                    "from the fall line" if args.traverse_deg is not None else "from the horizontal"
                ),
            }
        )
        _print_json(out)
        return 0
    print(
        f"traverse  {args.data}: {len(t)} positions, plane {args.slope_deg:g}°, "
        f"{given}, m {args.mass:g} kg, ρ {rho:.3f} kg/m³"
    )
    print(f"          g {grav.value:.5f} m/s² ({grav.source})")
    print(f"status  {res.status}" + (f": {res.message}" if res.message else ""))
    for label, est, unit, spec in (
        ("μ", res.mu, "", ".4f"),
        ("CdA", res.cda, "m²", ".3f"),
        ("v0", res.v0, "m/s", ".2f"),
        ("s0", res.s0, "m", ".3f"),
    ):
        c = est.ci90
        rng = f"[{format(c[0], spec)}, {format(c[1], spec)}]" if c else "—"
        print(f"  {label:<5}{_fmt(est.value, spec):>9} {unit:<4} 90 % CI {rng}")
    rms = math.sqrt(res.sigma_m2 / len(t))
    print(f"  final speed {res.v_final:.2f} m/s   residual RMS {rms * 100:.1f} cm   dof {res.dof}")
    return 0


def _traverse_gravity(args: argparse.Namespace) -> Gravity:
    """The traverse's g: given, else normal gravity at the site's latitude and altitude (a
    traverse has no survey to take them from), else standard gravity, as every model uses."""
    from station.model.physics import G_STANDARD, Gravity, local_gravity

    if args.gravity is not None:
        return Gravity(args.gravity, "given")
    if args.latitude_deg is not None:
        h = args.altitude_m if args.altitude_m is not None else 0.0
        return Gravity(
            local_gravity(args.latitude_deg, h),
            f"GRS80 normal gravity at {args.latitude_deg:.3f}° and {h:.0f} m",
        )
    if args.altitude_m is not None:
        raise InputError("needs --latitude-deg: normal gravity needs the site's latitude",
                         field="--altitude-m")  # fmt: skip
    return Gravity(G_STANDARD, "standard gravity: no --latitude-deg; at 47° N, 1700 m g is "
                   "0.03 % lower")  # fmt: skip


def _angle_below_90(text: str) -> float:
    value = _nonnegative(text)
    if value >= 90:
        raise argparse.ArgumentTypeError(f"must lie between 0 and 90 degrees, got {text!r}")
    return value


def _angle_above_0(text: str) -> float:
    value = _number(text)
    if not 0 < value <= 90:
        raise argparse.ArgumentTypeError(f"must lie above 0 and up to 90 degrees, got {text!r}")
    return value


def add_parsers(sub: Any) -> None:
    _add_simulate(sub)
    _add_fit(sub)
    _add_fit_traverse(sub)


def _add_simulate(sub: Any) -> None:
    """``station simulate``'s options."""
    p = sub.add_parser("simulate", help="times and speeds of a skier with given μ and CdA")
    p.add_argument(
        "--survey", required=True, help="survey YAML with the photocells (surveys/README.md)"
    )
    p.add_argument("--mass", type=plausible("mass_kg"), required=True, metavar="KG",
                   help="skier with equipment, kg")  # fmt: skip
    p.add_argument("--cda", type=_nonnegative, required=True, metavar="M2",
                   help="drag area CdA, m²")  # fmt: skip
    p.add_argument("--mu", type=_nonnegative, required=True,
                   help="kinetic friction coefficient μ (no unit), e.g. 0.0085")  # fmt: skip
    p.add_argument("--v0", type=_nonnegative, required=True, metavar="M_S",
                   help="speed at the first photocell, m/s")  # fmt: skip
    p.add_argument("--mu1", type=_nonnegative, default=0.0, help="velocity-dependent part, s/m")
    p.add_argument(
        "--wind-ms", type=_number, default=0.0, help="along-track wind, m/s, + = tailwind"
    )
    p.add_argument(
        "--noise-ms",
        type=_nonnegative,
        default=0.0,
        help="add timing noise, standard deviation in ms",
    )
    p.add_argument("--seed", type=int, default=1, help="seed of the timing noise")
    p.add_argument("--start-s", type=_number, default=0.0, help="time at the first photocell, s")
    p.add_argument("--csv", metavar="OUT", help="write the times as a fit input (photocell,time)")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    _add_air(p)
    _add_gravity(p)
    p.set_defaults(func=cmd_simulate)


def _add_fit(sub: Any) -> None:
    """``station fit``'s options."""
    p = sub.add_parser("fit", help="fit μ, CdA and v0 to the photocell times of one descent")
    p.add_argument(
        "--survey", required=True, help="survey YAML with the photocells (surveys/README.md)"
    )
    p.add_argument(
        "--times", required=True, help="CSV with columns photocell,time (s or hh:mm:ss.ssss)"
    )
    p.add_argument("--mass", type=plausible("mass_kg"), required=True, metavar="KG",
                   help="skier with equipment, kg")  # fmt: skip
    p.add_argument("--model", choices=["constant", "velocity"], default="constant",
                   help="friction μ constant, or μ + μ1·v (μ1 in s/m)")  # fmt: skip
    p.add_argument(
        "--wind-ms", type=_number, default=0.0, help="along-track wind, m/s, + = tailwind"
    )
    add_timer_option(
        p, TIMER_PRECISION_S * 1e3, "0.5: a 1 ms timer resolution and typical photocell jitter"
    )
    p.add_argument(
        "--timing-only",
        action="store_true",
        help="leave the survey's uncertainty out of the intervals",
    )
    p.add_argument("--json", action="store_true", help="machine-readable output")
    _add_air(p)
    _add_gravity(p)
    p.set_defaults(func=cmd_fit)


def _add_fit_traverse(sub: Any) -> None:
    """``station fit-traverse``'s options."""
    p = sub.add_parser("fit-traverse", help="fit μ and CdA to (t, s) data of a traverse")
    p.add_argument("--data", required=True, help="CSV with columns t,s (s, m)")
    p.add_argument("--slope-deg", type=_positive, required=True, metavar="A",
                   help="slope of the plane, degrees")  # fmt: skip
    angle = p.add_mutually_exclusive_group(required=True)
    angle.add_argument(
        "--traverse-deg",
        type=_angle_below_90,
        metavar="B",
        help="direction of travel, degrees measured from the fall line (0 = straight down, as "
        "the paper's β)",
    )
    angle.add_argument(
        "--traverse-from-horizontal-deg",
        type=_angle_above_0,
        metavar="H",
        help="direction of travel, degrees measured from the horizontal (the paper's '40° to "
        "the horizontal' is B = 50°)",
    )
    p.add_argument("--mass", type=plausible("mass_kg"), required=True, metavar="KG",
                   help="skier with equipment, kg")  # fmt: skip
    p.add_argument("--json", action="store_true", help="machine-readable output")
    _add_air(p)
    p.add_argument("--gravity", type=_gravity_ms2, metavar="G",
                   help="m/s²; default: normal gravity at --latitude-deg and --altitude-m, "
                        "else standard gravity 9.80665")  # fmt: skip
    p.add_argument("--latitude-deg", type=plausible("latitude_deg"), metavar="LAT",
                   help="the site's latitude (°, + north), for local gravity")  # fmt: skip
    p.add_argument("--altitude-m", type=plausible("altitude_m"), metavar="H",
                   help="the site's height (m), for local gravity (default 0)")  # fmt: skip
    p.set_defaults(func=cmd_fit_traverse)
