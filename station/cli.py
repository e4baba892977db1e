"""The ``station`` command line: survey, simulate, fit, fit-traverse.

Thin by design: parse arguments, call the core, print. Bad input of any kind ends in one line
on stderr naming file, line and field, and exit status 2 — never a traceback.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import sys
from typing import Any, NoReturn

import numpy as np

from station import __version__
from station.air import (
    DEFAULT_HUMIDITY_PCT,
    DEFAULT_PRESSURE_HPA,
    DEFAULT_TEMPERATURE_C,
    air_density,
)
from station.errors import InputError

EXIT_BAD_INPUT = 2


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line and exit status 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message} (see --help)\n")


def _positive(text: str) -> float:
    value = _number(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be a number greater than 0, got {text!r}")
    return value


def _nonnegative(text: str) -> float:
    value = _number(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be a number ≥ 0, got {text!r}")
    return value


def _percent(text: str) -> float:
    value = _nonnegative(text)
    if value > 100:
        raise argparse.ArgumentTypeError(f"must lie between 0 and 100 %, got {text!r}")
    return value


def _celsius(text: str) -> float:
    value = _number(text)
    if not -60 <= value <= 50:
        raise argparse.ArgumentTypeError(f"{text!r} °C is not an air temperature on snow")
    return value


def _number(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return value


def _warn(message: str) -> None:
    print(f"warning: {message}", file=sys.stderr)


def _add_air(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("air (station pressure, not sea-level QNH)")
    g.add_argument("--pressure-hpa", type=_positive, metavar="P")
    g.add_argument("--temperature-c", type=_celsius, metavar="T")
    g.add_argument("--humidity-pct", type=_percent, metavar="H")
    g.add_argument("--air-density", type=_positive, metavar="RHO", help="kg/m³, instead of P, T, H")


def _density(args: argparse.Namespace) -> float:
    given = [args.pressure_hpa, args.temperature_c, args.humidity_pct]
    if args.air_density is not None:
        if any(v is not None for v in given):
            raise InputError("give --air-density or pressure/temperature/humidity, not both")
        return args.air_density
    if all(v is None for v in given):
        rho = air_density(DEFAULT_PRESSURE_HPA, DEFAULT_TEMPERATURE_C, DEFAULT_HUMIDITY_PCT)
        _warn(
            f"no air data given; assuming {DEFAULT_PRESSURE_HPA} hPa, "
            f"{DEFAULT_TEMPERATURE_C:g} °C, {DEFAULT_HUMIDITY_PCT:g} % (ρ = {rho:.3f} kg/m³). "
            "Give --pressure-hpa at the run's "
            "altitude: ρ enters CdA one to one"
        )
        return rho
    p = args.pressure_hpa if args.pressure_hpa is not None else DEFAULT_PRESSURE_HPA
    t = args.temperature_c if args.temperature_c is not None else DEFAULT_TEMPERATURE_C
    h = args.humidity_pct if args.humidity_pct is not None else DEFAULT_HUMIDITY_PCT
    assumed = [
        f"{name} {value:g}"
        for name, given, value in (
            ("--pressure-hpa", args.pressure_hpa, p),
            ("--temperature-c", args.temperature_c, t),
            ("--humidity-pct", args.humidity_pct, h),
        )
        if given is None
    ]
    if assumed:
        _warn("assuming " + ", ".join(assumed))
    try:
        return air_density(p, t, h)
    except ValueError as exc:
        raise InputError(str(exc), field="air") from None


def _load_track(path: str):
    from station.survey import load_survey
    from station.track import build_track

    track = build_track(load_survey(path))
    return track


def _fmt(v: float | None, spec: str) -> str:
    return "—" if v is None else format(v, spec)


def _print_json(obj: Any) -> None:
    print(json.dumps(obj, indent=2, allow_nan=False))


# ----------------------------------------------------------------------------- survey


def cmd_survey_points(args: argparse.Namespace) -> int:
    """A bare observation file has no photocells: list the reduced points for checking."""
    from station.survey import load_survey

    survey = load_survey(args.survey)
    pts = list(survey.points.values())
    if args.csv:
        with open(args.csv, "w", newline="", encoding="utf-8") as fh:
            w = csv.writer(fh)
            w.writerow(["point", "e", "n", "h", "sigma_h_m", "setup", "line"])
            for p in pts:
                w.writerow([p.point, f"{p.e:.4f}", f"{p.n:.4f}", f"{p.h:.4f}", f"{p.sigma_h:.4f}",
                            p.setup, p.line])  # fmt: skip
    if args.json:
        _print_json(
            {
                "points": [
                    {
                        "id": p.point,
                        "e": p.e,
                        "n": p.n,
                        "h": p.h,
                        "sigma_h_m": p.sigma_h,
                        "setup": p.setup,
                        "line": p.line,
                    }  # fmt: skip
                    for p in pts
                ],
                "setups": [
                    {
                        "station": s.station,
                        "e": s.e,
                        "n": s.n,
                        "h": s.h,
                        "instrument_height": s.instrument_height,
                        "line": s.line,
                    }  # fmt: skip
                    for s in survey.setups
                ],
                "warnings": survey.warnings,
            }
        )
        return 0
    print(f"observations  {args.survey}: {len(pts)} points from {len(survey.setups)} setup(s)")
    print(f"{'setup':<12}{'E':>12}{'N':>12}{'H':>10}{'hi':>7}  line")
    for s in survey.setups:
        line = "" if s.line is None else str(s.line)
        print(
            f"{s.station:<12}{s.e:>12.3f}{s.n:>12.3f}{s.h:>10.3f}"
            f"{s.instrument_height:>7.3f}  {line}"
        )
    print()
    print(f"{'point':<12}{'E':>12}{'N':>12}{'H':>10}{'σH [mm]':>9}  setup")
    for p in pts:
        print(
            f"{p.point:<12}{p.e:>12.3f}{p.n:>12.3f}{p.h:>10.3f}{p.sigma_h * 1000:>9.1f}  {p.setup}"
        )
    for w in survey.warnings:
        _warn(w)
    _warn(
        "a bare observation file has no photocells; blocks before the first station block "
        "were reduced from station 0, 0, 0 with instrument height 0. Write a survey YAML "
        "(surveys/README.md) to name the photocells and the first setup and get the track"
    )
    return 0


def cmd_survey(args: argparse.Namespace) -> int:
    if args.survey.lower().endswith(".gsi"):
        return cmd_survey_points(args)
    track = _load_track(args.survey)
    prof = track.profile
    xg = np.arange(math.ceil(prof.x_min), math.floor(prof.x_max) + 1e-9, 1.0)
    yg, sg, kg = prof.h(xg), prof.slope_deg(xg), prof.curvature(xg)
    used = [p for p in track.points if p.used]
    sig = float(np.sqrt(np.mean([p.sigma**2 for p in used])))
    if args.csv:
        with open(args.csv, "w", newline="", encoding="utf-8") as fh:
            w = csv.writer(fh)
            w.writerow(["x_m", "y_m", "slope_deg", "curvature_1_per_m"])
            for row in zip(xg, yg, sg, kg, strict=True):
                w.writerow([f"{row[0]:.3f}", f"{row[1]:.4f}", f"{row[2]:.4f}", f"{row[3]:.6f}"])
    if args.json:
        _print_json(
            {
                "name": track.name,
                "length_m": track.length_m,
                "drop_m": track.drop_m,
                "residual_rms_m": track.residual_rms_m,
                "expected_sigma_m": sig,
                "azimuth_deg": track.azimuth_deg,
                "photocells": [
                    {
                        "id": pc.id,
                        "x": pc.x,
                        "y": pc.y,
                        "slope_deg": pc.slope_deg,
                        "lateral_m": pc.lateral_m,
                    }
                    for pc in track.photocells
                ],
                "profile": {
                    "x": xg.tolist(),
                    "y": yg.tolist(),
                    "slope_deg": sg.tolist(),
                    "curvature": kg.tolist(),
                },
                "points": [
                    {
                        "id": p.id,
                        "x": p.x,
                        "y": p.y,
                        "sigma_m": p.sigma,
                        "lateral_m": p.lateral_m,
                        "residual_m": p.residual_m,
                        "used": p.used,
                    }
                    for p in track.points
                ],
                "warnings": track.warnings,
            }
        )
    else:
        lat = [abs(p.lateral_m) for p in used]
        print(f"survey   {track.name}  ({args.survey})")
        if track.photocells:
            print(
                f"timed    {track.length_m:.2f} m along the track, {track.drop_m:.2f} m drop, "
                f"{len(track.photocells)} photocells"
            )
        print(
            f"profile  {len(used)} points over x = {prof.x_min:.1f} .. {prof.x_max:.1f} m, "
            f"axis azimuth {track.azimuth_deg:.2f}°, largest lateral offset {max(lat):.2f} m"
        )
        print(
            f"spline   residual RMS {track.residual_rms_m * 1000:.1f} mm "
            f"(point σ {sig * 1000:.1f} mm), "
            f"curvature {kg.min():+.5f} .. {kg.max():+.5f} 1/m"
        )
        if track.photocells:
            print()
            print(
                f"{'photocell':<10}{'x [m]':>10}{'y [m]':>11}{'slope [°]':>11}{'lateral [m]':>13}"
            )
            for pc in track.photocells:
                print(
                    f"{pc.id:<10}{pc.x:>10.2f}{pc.y:>11.2f}{pc.slope_deg:>11.2f}{pc.lateral_m:>+13.2f}"
                )
        for w in track.warnings:
            _warn(w)
    return 0


# ----------------------------------------------------------------------------- simulate


def cmd_simulate(args: argparse.Namespace) -> int:
    from station.physics import Conditions, Params, StraightRun

    track = _load_track(args.survey)
    if len(track.photocells) < 2:
        raise InputError("the survey needs at least two photocells", path=args.survey)
    rho = _density(args)
    xs = np.array([pc.x for pc in track.photocells])
    run = StraightRun(track.profile, xs)
    cond = Conditions(mass_kg=args.mass, air_density=rho, wind_ms=args.wind_ms)
    d = run.solve(Params(args.cda, args.mu, args.v0, args.mu1), cond, sensitivities=False)
    t = d.t.copy()
    if args.noise_ms:
        rng = np.random.default_rng(args.seed)
        t[1:] += rng.normal(0.0, args.noise_ms * 1e-3, len(t) - 1)
    reached = np.isfinite(t)
    if d.stopped_x is not None:
        reached = xs < d.stopped_x
    if args.csv:
        with open(args.csv, "w", newline="", encoding="utf-8") as fh:
            w = csv.writer(fh)
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


# ----------------------------------------------------------------------------- fit


def cmd_fit(args: argparse.Namespace) -> int:
    from station.fit import CI_METHOD, fit_descent
    from station.physics import Conditions
    from station.timesfile import read_times

    track = _load_track(args.survey)
    times = read_times(args.times, track.photocell_ids)
    rho = _density(args)
    xs = np.array([track.photocell(p).x for p in times.photocells])
    cond = Conditions(mass_kg=args.mass, air_density=rho, wind_ms=args.wind_ms)
    res = fit_descent(track.profile, xs, np.array(times.times), cond, times.photocells, args.model)
    missing = [p for p in track.photocell_ids if p not in times.photocells]
    if args.json:
        out = res.to_dict()
        out.update({"missing": missing, "air_density": rho, "mass_kg": args.mass})
        out["warnings"] = track.warnings
        _print_json(out)
        return 0
    e, ci = res.estimates, res.ci90
    print(
        f"fit     {track.name}, {args.times}: {len(times.photocells)} photocells"
        + (f" (missing {', '.join(missing)})" if missing else "")
        + f", {args.model} model, m {args.mass:g} kg, ρ {rho:.3f} kg/m³"
        + (f", wind {args.wind_ms:+g} m/s" if args.wind_ms else "")
    )
    print(f"status  {res.status}" + (f": {res.message}" if res.message else ""))

    def line(label: str, key: str, unit: str, spec: str) -> None:
        if key not in e:
            return
        c = ci.get(key)
        rng = f"[{format(c[0], spec)}, {format(c[1], spec)}]" if c else "—"
        print(f"  {label:<5}{_fmt(e[key], spec):>10} {unit:<5} 90 % CI {rng}")

    line("μ", "mu", "", ".5f")
    line("μ1", "mu1", "s/m", ".2e")
    line("CdA", "cda", "m²", ".4f")
    line("v0", "v0", "m/s", ".3f")
    if res.sigma_s2 is not None:
        corr = _fmt(res.corr_mu_cda, "+.3f")
        print(
            f"  corr(μ, CdA) {corr}   Σ {res.sigma_s2:.3e} s²   gᵀg {res.grad_norm2:.2e}   "
            f"dof {res.dof}   v0 at {res.photocells[0]}"
        )
        print(f"  intervals: {CI_METHOD}")
        print(f"{'photocell':<10}{'residual [ms]':>15}{'v [m/s]':>10}")
        for pid, r in res.residuals_s.items():
            print(f"{pid:<10}{r * 1000:>15.3f}{res.speeds_ms.get(pid, float('nan')):>10.2f}")
    for w in track.warnings:
        _warn(w)
    return 0


def cmd_fit_traverse(args: argparse.Namespace) -> int:
    from station.traverse import fit_traverse, read_traverse_data

    t, s = read_traverse_data(args.data)
    rho = _density(args)
    res = fit_traverse(t, s, args.slope_deg, args.traverse_deg, args.mass, rho)
    if args.json:
        out = res.to_dict()
        out.update({"air_density": rho, "mass_kg": args.mass})
        _print_json(out)
        return 0
    e, ci = res.estimates, res.ci90
    print(
        f"traverse  {args.data}: {len(t)} positions, plane {args.slope_deg:g}°, "
        f"traverse {args.traverse_deg:g}° to the fall line, m {args.mass:g} kg, ρ {rho:.3f} kg/m³"
    )
    print(f"status  {res.status}" + (f": {res.message}" if res.message else ""))
    for label, key, unit, spec in (
        ("μ", "mu", "", ".4f"),
        ("CdA", "cda", "m²", ".3f"),
        ("v0", "v0", "m/s", ".2f"),
        ("s0", "s0", "m", ".3f"),
    ):
        c = ci.get(key)
        rng = f"[{format(c[0], spec)}, {format(c[1], spec)}]" if c else "—"
        print(f"  {label:<5}{_fmt(e[key], spec):>9} {unit:<4} 90 % CI {rng}")
    rms = math.sqrt(res.sigma_m2 / len(t))
    print(f"  final speed {res.v_final:.2f} m/s   residual RMS {rms * 100:.1f} cm   dof {res.dof}")
    return 0


# ----------------------------------------------------------------------------- timing input


def _date(text: str | None):
    import datetime as dt

    if text is None:
        return None
    try:
        return dt.date.fromisoformat(text)
    except ValueError:
        raise InputError(f"--date {text!r} is not YYYY-MM-DD") from None


def cmd_record(args: argparse.Namespace) -> int:
    from station import session as sessions
    from station.config import load_config
    from station.recorder import record

    cfg = load_config(args.config)
    folder = args.session_dir or sessions.default_dir()
    print(f"recording to {folder} from {cfg.serial.port} ({cfg.serial.protocol}); Ctrl-C ends",
          file=sys.stderr)  # fmt: skip
    run = record(cfg, folder, max_descents=args.max_descents, duration_s=args.duration)
    print(run.summary(), file=sys.stderr)
    print(f"results: {os.path.join(folder, sessions.RESULTS)}", file=sys.stderr)
    return 0


def _replay_config(args: argparse.Namespace):
    """The config of a replay: ``--config``, else a session's own snapshot."""
    from station import session as sessions
    from station.config import load_config

    if not os.path.exists(args.source):
        raise InputError("no such session or capture", path=args.source)
    if getattr(args, "config", None):
        return load_config(args.config)
    if sessions.is_session(args.source):
        return sessions.load_session_config(args.source)
    raise InputError(
        "a plain capture needs --config (protocol, channels, survey)", path=args.source
    )


def _replay_run(args: argparse.Namespace, quiet: bool = False):
    from station.recorder import replay

    cfg = _replay_config(args)
    warnings: list[str] = []
    speed = None if getattr(args, "fast", True) else getattr(args, "speed", None)
    out = (lambda _m: None) if quiet else print
    run = replay(args.source, cfg, out=out, speed=speed, date=_date(getattr(args, "date", None)),
                 warnings=warnings)  # fmt: skip
    for w in warnings:
        _warn(w)
    return run


def cmd_replay(args: argparse.Namespace) -> int:
    from station.recorder import write_events

    if args.ui:
        return _replay_ui(args)
    run = _replay_run(args)
    print(run.summary(), file=sys.stderr)
    if args.csv:
        run.write_csv(args.csv)
    if args.events:
        write_events(run, args.events)
    return 0


def _replay_ui(args: argparse.Namespace) -> int:
    from station.recorder import source_date
    from station.ui.app import StationApp

    cfg = _replay_config(args)
    date = source_date(args.source, _date(args.date))
    speed = None if args.fast else args.speed
    return _run_ui(StationApp(cfg, mode="replay", source=args.source, speed=speed, date=date))


def cmd_export(args: argparse.Namespace) -> int:
    from station import session as sessions

    if not sessions.is_session(args.source):
        raise InputError("not a session directory (no raw.jsonl)", path=args.source)
    run = _replay_run(args, quiet=True)
    run.write_csv(args.csv)
    print(f"{len(run.results)} descents -> {args.csv}", file=sys.stderr)
    return 0


# ----------------------------------------------------------------------------- test-day analysis


def _numbers(text: str) -> list[int]:
    out = []
    for part in text.split(","):
        part = part.strip()
        if "-" in part:
            a, b = part.split("-", 1)
            if not (a.isdigit() and b.isdigit()):
                raise InputError(f"--descents {text!r}: {part!r} is not a range like 3-6")
            out += list(range(int(a), int(b) + 1))
        elif part.isdigit():
            out.append(int(part))
        else:
            raise InputError(f"--descents {text!r}: {part!r} is not a descent number")
    return out


def cmd_annotate(args: argparse.Namespace) -> int:
    """Enter metadata, invalid marks or a model for a session's descents, as the UI would."""
    import time as _time

    from station import session as sessions

    if not sessions.is_session(args.session):
        raise InputError("not a session directory (no raw.jsonl)", path=args.session)
    values = {
        k: v
        for k, v in {
            "skier": args.skier, "mass_kg": args.mass, "ski": args.ski, "wax": args.wax,
            "air_temperature_c": args.air_temperature_c,
            "snow_temperature_c": args.snow_temperature_c,
            "pressure_hpa": args.pressure_hpa, "humidity_pct": args.humidity_pct,
            "wind_ms": args.wind_ms, "wind_from_deg": args.wind_from_deg, "notes": args.notes,
        }.items()
        if v is not None
    }  # fmt: skip
    if (args.descents is None) == (args.from_descent is None):
        raise InputError("give --descents N[,M,A-B] or --from N")
    records = []
    t = _time.time()
    if values:
        rec = {"t": t, "type": "metadata", "values": values}
        if args.descents is not None:
            rec["descents"] = _numbers(args.descents)
        else:
            rec["from"] = args.from_descent
        records.append(rec)
    targets = _numbers(args.descents) if args.descents is not None else []
    if (args.invalid or args.valid or args.model) and not targets:
        raise InputError("--invalid, --valid and --model need --descents")
    for n in targets:
        if args.invalid:
            records.append({"t": t, "type": "invalid", "descent": n, "reason": args.invalid})
        if args.valid:
            records.append({"t": t, "type": "valid", "descent": n})
        if args.model:
            records.append({"t": t, "type": "model", "descent": n, "model": args.model})
    if not records:
        raise InputError("nothing to annotate: give metadata, --invalid, --valid or --model")
    for rec in records:
        sessions.append_annotation(args.session, rec)
    print(f"{len(records)} annotation(s) added to {args.session}", file=sys.stderr)
    return 0


def cmd_compare(args: argparse.Namespace) -> int:
    from station import session as sessions
    from station.compare import CompareError, collect, format_comparison, joint_fit

    if not sessions.is_session(args.session):
        raise InputError("not a session directory (no raw.jsonl)", path=args.session)
    args.source, args.config, args.fast, args.date = args.session, None, True, None
    run = _replay_run(args, quiet=True)
    data, excluded, windy = collect(run.day, args.wind_limit)
    try:
        res = joint_fit(
            run.day.track, data, cda_fixed=args.cda, model=args.model, drift=args.drift,
            reference=args.reference,
        )  # fmt: skip
    except CompareError as exc:
        raise InputError(str(exc), path=args.session) from None
    res.excluded, res.wind_flagged = excluded, windy
    if windy:
        res.warnings.append(
            f"descents {', '.join(map(str, windy))} had more than {args.wind_limit:g} m/s of "
            "along-track wind: check them, or mark them invalid"
        )
    if args.csv:
        _write_compare_csv(res, args.csv, run)
    if args.json:
        _print_json(res.to_dict())
        return 0
    print(format_comparison(res, len(data)))
    for w in res.warnings:
        _warn(w)
    return 0


def _write_compare_csv(res, path: str, run) -> None:
    import csv as _csv

    with open(path, "w", newline="", encoding="utf-8") as fh:
        fh.write(f"# station {__version__} comparison; reference {res.reference}; "
                 f"drift {'on' if res.drift_per_hour else 'off'}\n")  # fmt: skip
        w = _csv.writer(fh, quoting=_csv.QUOTE_NONNUMERIC, lineterminator="\n")
        w.writerow(["rank", "item", "descents", "mu", "mu_lo", "mu_hi", "delta_mu_vs_reference",
                    "delta_lo", "delta_hi", "p_faster_than_reference", "delta_t_s"])  # fmt: skip
        for k, name in enumerate(res.ranking, start=1):
            it = next(i for i in res.items if i.item == name)
            c = next((c for c in res.comparisons if c.b == name and c.a == res.reference), None)
            if c is None:
                row = [None] * 5
            else:  # item minus reference: the comparison stores reference minus item
                row = [-c.delta_mu, -c.ci90[1], -c.ci90[0], 1 - c.p_a_faster, -c.delta_t_s]
            w.writerow([k, it.item, len(it.descents), it.mu, it.ci90[0], it.ci90[1], *row])


# ----------------------------------------------------------------------------- UI


def _run_ui(app) -> int:
    app.run()
    return 0


def cmd_live(args: argparse.Namespace) -> int:
    from station import session as sessions
    from station.config import load_config
    from station.ui.app import StationApp

    cfg = load_config(args.config)
    folder = args.session_dir or sessions.default_dir()
    return _run_ui(StationApp(cfg, mode="live", session_dir=folder))


DEMO_SKIS = [("demo pair A", 0.0080), ("demo pair B", 0.0095), ("demo pair C", 0.0110)]


def demo_config_path() -> str:
    """The bundled demo station config (package data, so it works without a checkout)."""
    from importlib.resources import files

    return str(files("surveys") / "demo_station.yaml")


def cmd_demo(args: argparse.Namespace) -> int:
    import random
    import tempfile

    from station import session as sessions
    from station.config import load_config
    from station.ui.app import StationApp

    cfg = load_config(demo_config_path())
    folder = args.session_dir or sessions.default_dir("sessions").replace(
        os.sep + "20", os.sep + "demo-20", 1
    )
    link = os.path.join(tempfile.mkdtemp(prefix="station-demo-"), "timer")
    # the simulated timer runs as a process of its own, as a real timer would
    sim = [
        sys.executable, "-m", "simulators.timer", "--survey", cfg.survey_path, "--link", link,
        "--descents", "100000", "--interval", str(args.interval), "--first-after", "3",
        "--speed", str(args.speed), "--skis", ",".join(f"{mu}" for _n, mu in DEMO_SKIS),
        "--seed", str(args.seed if args.seed is not None else random.randrange(1 << 30)),
        "--noise-ms", "0.3", "--double-trigger", "0.05", "--hold", "0",
        "--air-density", f"{cfg.air_density}", "--mass", f"{cfg.mass_kg}",
    ]  # fmt: skip
    app = StationApp(
        cfg,
        mode="demo",
        session_dir=folder,
        sim_command=sim,
        demo_skis=[n for n, _mu in DEMO_SKIS],
    )
    return _run_ui(app)


# ----------------------------------------------------------------------------- main


def build_parser() -> argparse.ArgumentParser:
    ap = _Parser(
        prog="station",
        description="Measurement station for ski-friction test days "
        "(Kaps, Nachbauer & Mössner 1996).",
    )
    ap.add_argument("--version", action="version", version=f"station {__version__}")
    sub = ap.add_subparsers(dest="command", required=True, parser_class=_Parser)

    p = sub.add_parser("survey", help="reduce a survey to the track profile and photocells")
    p.add_argument("survey", help="survey YAML (or a bare .gsi file)")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.add_argument("--csv", metavar="OUT", help="write the profile (every metre) as CSV")
    p.set_defaults(func=cmd_survey)

    p = sub.add_parser("simulate", help="times and speeds of a skier with given μ and CdA")
    p.add_argument("--survey", required=True)
    p.add_argument("--mass", type=_positive, required=True, metavar="KG")
    p.add_argument("--cda", type=_nonnegative, required=True, metavar="M2")
    p.add_argument("--mu", type=_nonnegative, required=True)
    p.add_argument("--v0", type=_nonnegative, required=True, metavar="M_S")
    p.add_argument("--mu1", type=_nonnegative, default=0.0, help="velocity-dependent part, s/m")
    p.add_argument("--wind-ms", type=_number, default=0.0, help="along-track wind, + = tailwind")
    p.add_argument("--noise-ms", type=_nonnegative, default=0.0, help="add timing noise (sd)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--start-s", type=_number, default=0.0, help="time at the first photocell")
    p.add_argument("--csv", metavar="OUT", help="write the times as a fit input (photocell,time)")
    p.add_argument("--json", action="store_true")
    _add_air(p)
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser("fit", help="fit μ, CdA and v0 to the photocell times of one descent")
    p.add_argument("--survey", required=True)
    p.add_argument("--times", required=True, help="CSV with columns photocell,time")
    p.add_argument("--mass", type=_positive, required=True, metavar="KG")
    p.add_argument("--model", choices=["constant", "velocity"], default="constant")
    p.add_argument("--wind-ms", type=_number, default=0.0, help="along-track wind, + = tailwind")
    p.add_argument("--json", action="store_true")
    _add_air(p)
    p.set_defaults(func=cmd_fit)

    p = sub.add_parser("fit-traverse", help="fit μ and CdA to (t, s) data of a traverse")
    p.add_argument("--data", required=True, help="CSV with columns t,s")
    p.add_argument("--slope-deg", type=_positive, required=True, metavar="A")
    p.add_argument("--traverse-deg", type=_nonnegative, required=True, metavar="B")
    p.add_argument("--mass", type=_positive, required=True, metavar="KG")
    p.add_argument("--json", action="store_true")
    _add_air(p)
    p.set_defaults(func=cmd_fit_traverse)

    p = sub.add_parser("record", help="record a timer headless: raw log, descents, fits, CSV")
    p.add_argument("--config", required=True, help="station config YAML")
    p.add_argument("--session-dir", metavar="DIR", help="default: sessions/DATE_TIME")
    p.add_argument(
        "--max-descents",
        type=int,
        metavar="N",
        help="stop after N descents (aborted ones not counted)",
    )
    p.add_argument("--duration", type=_positive, metavar="S", help="stop after S seconds")
    p.set_defaults(func=cmd_record)

    p = sub.add_parser("replay", help="replay a session or a plain capture of a timer's output")
    p.add_argument("source", metavar="CAPTURE_OR_SESSION")
    p.add_argument("--config", help="station config (default: the session's own)")
    p.add_argument("--csv", metavar="OUT", help="write the results CSV")
    p.add_argument("--events", metavar="OUT", help="write every parsed impulse and its fate")
    p.add_argument("--date", help="date of a plain capture, YYYY-MM-DD (default: file date)")
    pace = p.add_mutually_exclusive_group()
    pace.add_argument("--speed", type=_positive, metavar="X", help="replay at X times real time")
    pace.add_argument("--fast", action="store_true", help="as fast as possible (the default)")
    p.add_argument("--ui", action="store_true", help="show the replay in the terminal UI")
    p.set_defaults(func=cmd_replay)

    p = sub.add_parser("annotate", help="enter metadata, invalid marks or a model for descents")
    p.add_argument("session", metavar="SESSION")
    who = p.add_mutually_exclusive_group()
    who.add_argument("--descents", metavar="LIST", help="e.g. 1,4,5-8")
    who.add_argument("--from", dest="from_descent", type=int, metavar="N",
                     help="this and all later descents")  # fmt: skip
    p.add_argument("--skier")
    p.add_argument("--mass", type=_positive, metavar="KG")
    p.add_argument("--ski", help="ski or pair id")
    p.add_argument("--wax")
    p.add_argument("--air-temperature-c", type=_celsius)
    p.add_argument("--snow-temperature-c", type=_celsius)
    p.add_argument("--pressure-hpa", type=_positive)
    p.add_argument("--humidity-pct", type=_percent)
    p.add_argument("--wind-ms", type=_nonnegative, help="wind speed")
    p.add_argument("--wind-from-deg", type=_number, help="direction the wind comes from")
    p.add_argument("--notes")
    p.add_argument("--invalid", metavar="REASON", help="mark the descents invalid")
    p.add_argument("--valid", action="store_true", help="mark them valid again")
    p.add_argument("--model", choices=["constant", "velocity"], help="refit with this model")
    p.set_defaults(func=cmd_annotate)

    p = sub.add_parser("compare", help="which ski or wax glides better, by how much, how sure")
    p.add_argument("session", metavar="SESSION")
    p.add_argument("--reference", metavar="ITEM", help="compare every item with this one")
    p.add_argument("--cda", type=_positive, metavar="M2", help="fix CdA instead of fitting it")
    p.add_argument("--model", choices=["constant", "velocity"], default="constant")
    p.add_argument("--drift", choices=["auto", "on", "off"], default="auto")
    p.add_argument("--wind-limit", type=_positive, default=1.0, metavar="MS",
                   help="flag descents with more along-track wind (m/s)")  # fmt: skip
    p.add_argument("--csv", metavar="OUT")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_compare)

    p = sub.add_parser("live", help="the trackside terminal UI on a timer")
    p.add_argument("--config", required=True, help="station config YAML")
    p.add_argument("--session-dir", metavar="DIR", help="default: sessions/DATE_TIME")
    p.set_defaults(func=cmd_live)

    p = sub.add_parser("demo", help="the terminal UI on a simulated timer and the demo run")
    p.add_argument("--session-dir", metavar="DIR", help="default: sessions/demo-DATE_TIME")
    p.add_argument("--interval", type=_positive, default=20.0, help="seconds between descents")
    p.add_argument("--speed", type=_positive, default=1.0, help="run the timer's clock faster")
    p.add_argument("--seed", type=int, help="seed of the simulated descents")
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("export", help="write a session's results CSV")
    p.add_argument("source", metavar="SESSION")
    p.add_argument("--csv", required=True, metavar="OUT")
    p.set_defaults(func=cmd_export)
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except InputError as exc:
        print(f"station: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        # the reader went away (`station fit … | head`): stop quietly, as other tools do
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 141


if __name__ == "__main__":
    raise SystemExit(main())
