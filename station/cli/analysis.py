"""``station annotate`` and ``compare``: what the engineer says about descents after the fact,
and which ski or wax glides better, by how much, and how sure."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from station import __version__
from station.cli.common import (
    _celsius,
    _nonnegative,
    _number,
    _numbers,
    _percent,
    _positive,
    _print_json,
    _warn,
)
from station.errors import InputError


def cmd_annotate(args: argparse.Namespace) -> int:
    """Enter metadata, invalid marks or a model for a session's descents, as the UI would."""
    import time as _time

    from station.session import store as sessions

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
    if args.wind_ms and args.wind_from_deg is None:
        raise InputError("--wind-ms needs --wind-from-deg (the direction the wind comes from)")
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
    from station.cli.recording import _replay_run
    from station.model.compare import CompareError, collect, format_comparison, joint_fit
    from station.session import store as sessions

    if not sessions.is_session(args.session):
        raise InputError("not a session directory (no raw.jsonl)", path=args.session)
    args.source, args.config, args.fast, args.date = args.session, None, True, None
    run = _replay_run(args, quiet=True)
    data, excluded, windy = collect(run.day, args.wind_limit)
    try:
        res = joint_fit(
            run.day.track, data, cda_fixed=args.cda, model=args.model, drift=args.drift,
            reference=args.reference, timer_sd_s=args.timer_ms / 1000.0,
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
            if c is None or c.ci90 is None or c.p_a_faster is None:  # no comparison possible
                row = [None] * 5
            else:  # item minus reference: the comparison stores reference minus item
                row = [-c.delta_mu, -c.ci90[1], -c.ci90[0], 1 - c.p_a_faster, -c.delta_t_s]
            w.writerow([k, it.item, len(it.descents), it.mu, it.ci90[0], it.ci90[1], *row])


def add_parsers(sub: Any) -> None:
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
    p.add_argument("--timer-ms", type=_positive, default=0.5, metavar="MS",
                   help="the timer's precision (SD of one time), against which the residuals "
                        "are judged (default 0.5)")  # fmt: skip
    p.add_argument("--wind-limit", type=_positive, default=1.0, metavar="MS",
                   help="flag descents with more along-track wind (m/s)")  # fmt: skip
    p.add_argument("--csv", metavar="OUT")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_compare)
