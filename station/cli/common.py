"""What every ``station`` command shares: one-line usage errors with exit status 2, number
parsers that say which option is wrong, the air options, and small output helpers."""

from __future__ import annotations

import argparse
import datetime as dt
import json
import math
import sys
from typing import Any, NoReturn

from station.errors import InputError
from station.model.air import (
    DEFAULT_HUMIDITY_PCT,
    DEFAULT_PRESSURE_HPA,
    DEFAULT_TEMPERATURE_C,
    air_density,
)

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


def _gravity_ms2(text: str) -> float:
    value = _number(text)
    if not 9.7 <= value <= 9.9:
        raise argparse.ArgumentTypeError(
            f"{text!r} m/s² is not gravity on the earth's surface (9.7 .. 9.9)"
        )
    return value


def _add_gravity(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--gravity",
        type=_gravity_ms2,
        metavar="G",
        help="m/s²; default: normal gravity at the survey's latitude_deg and height, "
        "else standard gravity 9.80665",
    )


def _load_track(path: str):
    from station.survey.load import load_survey
    from station.survey.track import build_track

    track = build_track(load_survey(path))
    return track


def _fmt(v: float | None, spec: str) -> str:
    return "—" if v is None else format(v, spec)


def _print_json(obj: Any) -> None:
    print(json.dumps(obj, indent=2, allow_nan=False))


def _date(text: str | None):

    if text is None:
        return None
    try:
        return dt.date.fromisoformat(text)
    except ValueError:
        raise InputError(f"--date {text!r} is not YYYY-MM-DD") from None


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
